"""POST /v1/simulate and /v1/simulate/batch (app/api/routes/simulate.py)."""

from __future__ import annotations

from typing import Any

import httpx

from engine.constants import CHANNELS, EVENT_INDEX, N_SAMPLES, SAMPLE_INTERVAL


def test_simulate_returns_a_record_and_event_time(sim_record: dict[str, Any]) -> None:
    rec = sim_record
    assert set(rec["channels"]) == set(CHANNELS)
    assert all(len(v) == N_SAMPLES for v in rec["channels"].values())
    assert rec["sample_interval"] == SAMPLE_INTERVAL and rec["event_index"] == EVENT_INDEX
    assert rec["conditions"] == {"J1": 0.87, "c": 1.0, "c1": 0.2, "K": 0.005}
    assert 0.0 < rec["event_time"] < 1.0
    assert rec["channels"]["m_el"][EVENT_INDEX] == 0.0  # torque is off from the event on


def test_simulate_takes_conditions_and_effects(client: httpx.Client, sim_record: dict[str, Any]) -> None:
    r = client.post(
        "/v1/simulate", json={"K": 0.005, "J1": 0.8, "c": 1.25, "c1": 0.1, "effects": {"motor_coulomb_friction": 0.05}}
    )
    assert r.status_code == 200, r.text
    rec = r.json()
    assert rec["conditions"] == {"J1": 0.8, "c": 1.25, "c1": 0.1, "K": 0.005}
    assert rec["channels"]["v2"] != sim_record["channels"]["v2"]


def test_simulate_csv_form(client: httpx.Client, sim_record: dict[str, Any]) -> None:
    r = client.post("/v1/simulate", json={"K": 0.005}, headers={"Accept": "text/csv"})
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/csv")
    assert float(r.headers["x-event-time"]) == sim_record["event_time"]
    assert int(r.headers["x-event-index"]) == EVENT_INDEX
    lines = r.text.splitlines()
    assert lines[0].split(",") == list(CHANNELS)
    assert len(lines) == N_SAMPLES + 1
    assert float(lines[1].split(",")[4]) == sim_record["channels"]["v2"][0]  # exact round trip


def test_batch_simulates_cases_in_order(client: httpx.Client) -> None:
    cases = [{"K": 0.0025}, {"K": 0.01, "J1": 0.9135}]
    r = client.post("/v1/simulate/batch", json={"cases": cases})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["count"] == 2
    assert [d["conditions"]["K"] for d in body["data"]] == [0.0025, 0.01]
    assert body["data"][1]["conditions"]["J1"] == 0.9135
    assert all(d["event_time"] > 0 for d in body["data"])


def test_batch_names_the_failing_case(client: httpx.Client) -> None:
    bad = {"K": 0.0025, "effects": {"contact_stiffness": 0.1, "contact_damping": 20.0}}
    r = client.post("/v1/simulate/batch", json={"cases": [{"K": 0.005}, bad]})
    assert r.status_code == 422
    assert "case 1: no backlash event" in r.json()["detail"]
