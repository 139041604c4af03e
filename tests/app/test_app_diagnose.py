"""POST /v1/diagnose against the live server: a record with a hidden effect, and input validation."""

from __future__ import annotations

from typing import Any

import httpx
import numpy as np

from engine.records import Record
from engine.simulation import PlantParameters, add_white_noise, simulate


def test_diagnose_names_a_hidden_effect(client: httpx.Client) -> None:
    rng = np.random.default_rng(11)
    truth = simulate(PlantParameters(K=0.006, J1=0.82, c=1.2), effects={"load_inertia": 1.4})
    record = Record({k: add_white_noise(v, 40.0, rng) for k, v in truth.channels.items()}, conditions={"c1": 0.2})
    # a small candidate list keeps the test short; the full catalogue is the default
    r = client.post(
        "/v1/diagnose", json={"record": record.to_dict(), "effects": ["load_inertia", "supply_voltage"]}, timeout=300
    )
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["verdict"]["status"] == "explained" and body["verdict"]["effect"] == "load_inertia"
    assert abs(body["verdict"]["value"] - 1.4) < 0.02
    assert {c["effect"] for c in body["candidates"]} == {"load_inertia", "supply_voltage"}
    assert body["cells"] and {"channel", "band_hz", "window_ms", "share"} <= set(body["cells"][0])
    assert body["gap"]["after"]["rms_over_noise"] < 0.1 * body["gap"]["before"]["rms_over_noise"]
    for key in ("before", "after"):
        Record.from_dict(body["records"][key])  # both are valid records
    assert set(body["identification"]["channels"]) == set(record.channels)


def test_diagnose_validates_its_input_first(client: httpx.Client, sim_record: dict[str, Any]) -> None:
    r = client.post("/v1/diagnose", json={"record": sim_record, "effects": ["no_such_effect"]})
    assert r.status_code == 422 and "unknown effect 'no_such_effect'" in r.json()["detail"]
    r = client.post("/v1/diagnose", json={"record": {"channels": {"v2": [0.0] * 10}, "event_index": 5}})
    assert r.status_code == 422 and "4.3 ms before the event and 199.5 ms after it missing" in r.json()["detail"]
