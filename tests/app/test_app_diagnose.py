"""POST /v1/diagnose: validates its input, then 501 until the engine's diagnosis is wired."""

from __future__ import annotations

from typing import Any

import httpx


def test_diagnose_is_not_available_yet(client: httpx.Client, sim_record: dict[str, Any]) -> None:
    r = client.post("/v1/diagnose", json={"record": sim_record})
    assert r.status_code == 501
    assert "not available yet" in r.json()["detail"]
    assert r.json()["error"] == "NotAvailableError"


def test_diagnose_validates_its_input_first(client: httpx.Client, sim_record: dict[str, Any]) -> None:
    r = client.post("/v1/diagnose", json={"record": sim_record, "effects": ["no_such_effect"]})
    assert r.status_code == 422 and "unknown effect 'no_such_effect'" in r.json()["detail"]
    r = client.post("/v1/diagnose", json={"record": {"channels": {"v2": [0.0] * 10}}})
    assert r.status_code == 422 and "exactly 2048 samples" in r.json()["detail"]
