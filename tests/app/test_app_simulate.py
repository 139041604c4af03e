"""POST /v1/simulate and /v1/simulate/batch (app/api/routes/simulate.py)."""

from __future__ import annotations

import math
from typing import Any

import httpx
import numpy as np
import pytest

from app.records_io import parse_units, record_from_csv
from app.schemas.common import RecordIn
from engine.constants import CHANNELS, EVENT_INDEX, N_SAMPLES, POST_EVENT_TIME, PRE_EVENT_TIME, SAMPLE_INTERVAL
from engine.records import SampleGrid


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


# -- rendering a case the ways a bench gives it ------------------------------------------


def test_simulate_on_a_bench_grid_in_rpm(client: httpx.Client) -> None:
    grid = SampleGrid.around_event(5e-5, 0.01, 0.3)
    render = {"sample_interval": 5e-5, "before": 0.01, "after": 0.3}
    r = client.post("/v1/simulate", json={"K": 0.005, **render, "units": {"omega1": "rpm"}})
    assert r.status_code == 200, r.text
    rec = r.json()
    assert grid.n_samples == 6200 and grid.event_index == 200  # 10 ms / 50 us before, 300 ms / 50 us after
    assert all(len(v) == grid.n_samples for v in rec["channels"].values())
    assert (rec["sample_interval"], rec["event_index"], rec["units"]) == (5e-5, grid.event_index, {"omega1": "rpm"})
    assert "event_location" not in rec  # nothing was located: the simulation knows its event
    m_el = np.asarray(rec["channels"]["m_el"])
    assert np.all(m_el[grid.event_index :] == 0.0) and m_el[grid.event_index - 1] != 0.0  # the event is there
    plain = client.post("/v1/simulate", json={"K": 0.005, **render}).json()
    assert "units" not in plain
    np.testing.assert_allclose(
        rec["channels"]["omega1"], np.asarray(plain["channels"]["omega1"]) * 60.0 / (2.0 * math.pi), rtol=1e-12
    )
    assert rec["channels"]["v2"] == plain["channels"]["v2"]  # the other channels stay in model units


def test_simulate_without_event_index_subset_and_csv_form(client: httpx.Client) -> None:
    grid = SampleGrid.around_event(1e-4, 0.02, 0.25)
    body = {
        "K": 0.0075,
        "sample_interval": 1e-4,
        "before": 0.02,
        "after": 0.25,
        "channels": ["m_el", "v2"],
        "units": {"v2": "mm/s", "m_el": "N*m"},
        "base_torque": 40.0,
        "include_event_index": False,
    }
    r = client.post("/v1/simulate", json=body)
    assert r.status_code == 200, r.text
    rec = r.json()
    assert "event_index" not in rec and set(rec["channels"]) == {"m_el", "v2"}
    assert rec["conditions"]["base_torque"] == 40.0 and rec["units"] == {"v2": "mm/s", "m_el": "N*m"}
    located = RecordIn.model_validate(rec).to_record()  # a reader locates the event
    assert located.event_location is not None and located.event_index == grid.event_index

    r = client.post("/v1/simulate", json={**body, "time_column": True}, headers={"Accept": "text/csv"})
    assert r.status_code == 200, r.text
    assert "x-event-index" not in r.headers and parse_units(r.headers["x-units"]) == rec["units"]
    lines = r.text.splitlines()
    assert lines[0] == "t,m_el,v2" and len(lines) == grid.n_samples + 1
    back = record_from_csv(r.text, units=parse_units(r.headers["x-units"]), conditions={"base_torque": 40.0})
    assert back.sample_interval == pytest.approx(1e-4, rel=1e-9) and back.event_index == grid.event_index
    np.testing.assert_allclose(back["v2"], located["v2"], rtol=1e-12)


def test_batch_renders_every_case_alike(client: httpx.Client) -> None:
    r = client.post(
        "/v1/simulate/batch",
        json={"cases": [{"K": 0.0025}, {"K": 0.01}], "sample_interval": 2e-4, "channels": ["a2"], "units": {"a2": "g"}},
    )
    assert r.status_code == 200, r.text
    grid = SampleGrid.around_event(2e-4, PRE_EVENT_TIME, POST_EVENT_TIME)
    for d in r.json()["data"]:
        assert list(d["channels"]) == ["a2"] and len(d["channels"]["a2"]) == grid.n_samples
        assert (d["units"], d["event_index"], d["sample_interval"]) == ({"a2": "g"}, grid.event_index, 2e-4)
    r = client.post("/v1/simulate/batch", json={"cases": [{"K": 0.005, "sample_interval": 2e-4}]})
    assert r.status_code == 422 and "sample_interval: Extra inputs are not permitted" in r.json()["detail"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"sample_interval": 2e-3}, "outside the accepted range"),
        ({"sample_interval": 5e-6}, "outside the accepted range"),
        ({"before": 0.001}, "3.8 ms before the event"),
        ({"after": 0.15}, "50 ms after it missing"),
        ({"units": {"omega1": "rpmm"}}, "unknown unit 'rpmm' for channel 'omega1'; accepted units: rad/s, rpm, pu"),
        ({"units": {"m_el": "N*m"}}, "needs conditions.base_torque"),
        ({"units": {"a1": "g"}, "channels": ["v2"]}, "units are given for channel 'a1'"),
        ({"units": {"speed": "rpm"}}, "units.speed.[key]: Input should be 'a1'"),
        ({"channels": []}, "channels: List should have at least 1 item"),
        ({"sample_interval": 1e-5, "after": 10.0}, "at most 1000000 are rendered per request"),
    ],
)
def test_simulate_render_errors(client: httpx.Client, extra: dict[str, Any], message: str) -> None:
    r = client.post("/v1/simulate", json={"K": 0.005, **extra})
    assert r.status_code == 422, r.text
    assert message in r.json()["detail"]
