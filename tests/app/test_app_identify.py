"""POST /v1/identify: JSON and CSV bodies, choice of the pattern set (app/api/routes/identify.py)."""

from __future__ import annotations

from typing import Any

import httpx
import pytest
from servicekit import SMALL_TRAINING, train

from engine.constants import K_GRID


def _check_result(res: dict[str, Any], set_id: str) -> None:
    assert len(res["D"]) == 6 and all(d >= 0 for d in res["D"])
    assert res["index"] == 1 + min(range(6), key=res["D"].__getitem__)
    assert res["widths"] == list(K_GRID)
    assert res["width"] == K_GRID[res["index"] - 1]
    assert res["epochs"] >= 1
    assert res["pattern_set"] == set_id


def test_identify_named_set(client: httpx.Client, trained_set: dict[str, Any], sim_record: dict[str, Any]) -> None:
    set_id = trained_set["pattern_set_id"]
    r = client.post("/v1/identify", json={"record": sim_record, "channel": "v2", "pattern_set": set_id})
    assert r.status_code == 200, r.text
    res = r.json()
    _check_result(res, set_id)
    assert res["width"] == 0.005 and res["index"] == 3  # the simulated width
    assert (res["selection"], res["c_used"], res["c_source"]) == ("requested", None, None)


def test_identify_chooses_by_the_records_c(
    client: httpx.Client, trained_set: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    set_id = trained_set["pattern_set_id"]
    res = client.post("/v1/identify", json={"record": sim_record, "channel": "v2", "any_set": True}).json()
    _check_result(res, set_id)
    assert (res["selection"], res["c_used"], res["c_source"], res["pattern_set_c"]) == ("exact", 1.0, "record", 1.0)

    near = {**sim_record, "conditions": {"c": 1.2}}
    res = client.post("/v1/identify", json={"record": near, "channel": "v2", "any_set": True}).json()
    assert (res["selection"], res["c_used"], res["c_source"]) == ("nearest", 1.2, "record")
    assert res["c_distance"] == pytest.approx(0.2) and res["max_c_distance"] == 0.25

    far = {**sim_record, "conditions": {"c": 1.4}}  # 0.4 pu from the only set: refused, with what to do
    r = client.post("/v1/identify", json={"record": far, "channel": "v2", "any_set": True})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert "0.4 pu from the record's c = 1.4" in detail and "limit is 0.25 pu" in detail and '"c": 1.4' in detail

    # a set trained on another J1 grid than the paper's (these two inertias) is chosen only when asked
    r = client.post("/v1/identify", json={"record": sim_record, "channel": "v2"})
    assert r.status_code == 404, r.text
    assert "chosen only when named" in r.json()["detail"] and set_id in r.json()["detail"]

    bare = {"channels": {"v2": sim_record["channels"]["v2"]}, "event_index": 48}  # no conditions: nominal c
    res = client.post("/v1/identify", json={"record": bare, "channel": "v2", "any_set": True}).json()
    assert (res["selection"], res["c_used"], res["c_source"]) == ("exact", 1.0, "nominal")


def test_identify_prefers_the_set_with_the_nearest_c(
    client: httpx.Client, trained_set: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    other = train(client, {**SMALL_TRAINING, "c": 1.4})
    try:
        rec = {**sim_record, "conditions": {"c": 1.3}}
        res = client.post("/v1/identify", json={"record": rec, "channel": "v2", "any_set": True}).json()
        assert (res["pattern_set"], res["selection"]) == (other["pattern_set_id"], "nearest")
    finally:
        client.delete(f"/v1/pattern-sets/{other['pattern_set_id']}")


def test_identify_csv_form(client: httpx.Client, trained_set: dict[str, Any], sim_record: dict[str, Any]) -> None:
    csv_text = client.post("/v1/simulate", json={"K": 0.005}, headers={"Accept": "text/csv"}).text
    r = client.post(
        "/v1/identify",
        content=csv_text,
        headers={"Content-Type": "text/csv"},
        params={"channel": "v2", "c": 1.0, "sample_interval": 1e-4, "event_index": 48, "any_set": True},
    )
    assert r.status_code == 200, r.text
    res = r.json()
    json_res = client.post("/v1/identify", json={"record": sim_record, "channel": "v2", "any_set": True}).json()
    assert res["D"] == json_res["D"]  # the same record as CSV gives the same answer
    assert (res["selection"], res["c_source"]) == ("exact", "record")


def test_identify_a_record_with_one_channel(
    client: httpx.Client, trained_set: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    lines = ["v2", *map(repr, sim_record["channels"]["v2"])]
    r = client.post(
        "/v1/identify",
        content="\n".join(lines) + "\n",
        headers={"Content-Type": "text/csv"},
        params={"channel": "v2", "pattern_set": trained_set["pattern_set_id"], "event_index": 48},
    )
    assert r.status_code == 200, r.text
    assert r.json()["selection"] == "requested"


def test_identify_prefers_the_default_kind_among_equally_near_sets(
    client: httpx.Client, sim_record: dict[str, Any], trained_set: dict[str, Any]
) -> None:
    from engine.identification.training import DEFAULT_KIND

    other_kind = next(k for k in ("paper", "template") if k != DEFAULT_KIND)
    request = {"channel": "a1", "c": 1.0, "J1_values": [0.87, 0.8482]}
    default = train(client, {**request, "kind": DEFAULT_KIND})
    newer = train(client, {**request, "kind": other_kind})  # newest, same c, other kind
    try:
        res = client.post("/v1/identify", json={"record": sim_record, "channel": "a1", "any_set": True}).json()
        assert res["pattern_set"] == default["pattern_set_id"]
        res = client.post(
            "/v1/identify", json={"record": sim_record, "channel": "a1", "kind": other_kind, "any_set": True}
        ).json()
        assert res["pattern_set"] == newer["pattern_set_id"]
    finally:
        for out in (default, newer):
            client.delete(out["pattern_set_url"])


def test_identify_offers_the_calibrated_K_as_a_continuous_width(
    client: httpx.Client, trained_set: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    plain = client.post("/v1/identify", json={"record": sim_record, "channel": "v2", "any_set": True}).json()
    assert plain["continuous"] is None  # only on request: it fits the simulator (seconds)
    r = client.post("/v1/identify", json={"record": sim_record, "channel": "v2", "continuous": True, "any_set": True})
    assert r.status_code == 200, r.text
    res = r.json()
    assert res["D"] == plain["D"]
    cont = res["continuous"]
    assert abs(cont["K"] - 0.005) < 1e-3 * 0.005 and 0 < cont["sigma_K"] < 1e-4 * 0.005
    assert cont["nearest_width"] == 0.005
    assert set(cont["fitted"]) | set(cont["fixed"]) == {"K", "J1", "c", "c1"} and "K" in cont["fitted"]
    # CSV form: the query flag; a non-boolean is a 422 that names the parameter
    csv_text = "v2\n" + "\n".join(map(repr, sim_record["channels"]["v2"])) + "\n"
    r = client.post(
        "/v1/identify",
        content=csv_text,
        headers={"Content-Type": "text/csv"},
        params={
            "channel": "v2",
            "continuous": "true",
            "any_set": "true",
            "event_index": 48,
            **{k: sim_record["conditions"][k] for k in ("J1", "c", "c1")},
        },
    )
    assert r.status_code == 200, r.text
    assert abs(r.json()["continuous"]["K"] - cont["K"]) < 1e-6 * cont["K"]
    r = client.post("/v1/identify", json={"record": sim_record, "channel": "v2", "continuous": "perhaps"})
    assert r.status_code == 422 and "continuous" in r.text


def test_identify_a_20_khz_csv_with_time_in_rpm_and_g_as_its_json(
    client: httpx.Client, trained_set: dict[str, Any]
) -> None:
    """A bench's CSV (t column, rpm and g, the event located) reads as the same record as its JSON form."""
    render = {"K": 0.005, "sample_interval": 5e-5, "before": 0.01, "after": 0.3, "units": {"omega1": "rpm", "a1": "g"}}
    csv_r = client.post(
        "/v1/simulate",
        json={**render, "include_event_index": False, "time_column": True},
        headers={"Accept": "text/csv"},
    )
    json_rec = client.post("/v1/simulate", json=render).json()
    assert csv_r.status_code == 200 and csv_r.text.startswith("t,a1,m_el,omega1,a2,v2\n")
    by_csv = client.post(
        "/v1/identify",
        content=csv_r.text,
        headers={"Content-Type": "text/csv"},
        params={
            "channel": "v2",
            "units": csv_r.headers["x-units"],
            "c": 1.0,
            "any_set": True,
        },  # Ts from t, no event_index
    )
    assert by_csv.status_code == 200, by_csv.text
    by_json = client.post("/v1/identify", json={"record": json_rec, "channel": "v2", "any_set": True})
    assert by_json.status_code == 200, by_json.text
    assert by_csv.json()["D"] == by_json.json()["D"]
    assert by_csv.json()["width"] == 0.005
