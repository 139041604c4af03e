"""Pattern sets: train (202 + background job), list, read, delete (app/api/routes/pattern_sets.py)."""

from __future__ import annotations

from typing import Any

import httpx
import pytest
from servicekit import SMALL_TRAINING, train


def test_training_answers_202_and_stores_the_set(client: httpx.Client, trained_set: dict[str, Any]) -> None:
    set_id = trained_set["pattern_set_id"]
    assert trained_set["job_url"] == f"/v1/jobs/{trained_set['job_id']}"
    assert trained_set["job"]["pattern_set_id"] == set_id
    assert trained_set["job"]["progress"] == 1.0
    r = client.get(f"/v1/pattern-sets/{set_id}")
    assert r.status_code == 200, r.text
    ps = r.json()
    assert ps["id"] == set_id
    assert (ps["kind"], ps["channel"], ps["c"]) == ("paper", "v2", 1.0)
    assert ps["J1_values"] == SMALL_TRAINING["J1_values"]
    assert ps["wavelet"] == "sym5"
    assert ps["params"]["max_epochs"] == SMALL_TRAINING["max_epochs"]
    assert ps["params"]["effects"] == {}
    assert ps["arrays"]["patterns"] == [6, 15]


def test_location_header_points_at_the_job(client: httpx.Client) -> None:
    r = client.post("/v1/pattern-sets", json={**SMALL_TRAINING, "channel": "a1"})
    assert r.status_code == 202
    assert r.headers["location"] == r.json()["job_url"]
    from servicekit import wait_for_job

    assert wait_for_job(client, r.json()["job_id"])["state"] == "done"
    client.delete(r.json()["pattern_set_url"])


def test_list_filters_and_newest_first(client: httpx.Client, trained_set: dict[str, Any]) -> None:
    other = train(client, {**SMALL_TRAINING, "c": 1.25, "effects": {"motor_viscous_friction": 0.01}})
    try:
        listed = client.get("/v1/pattern-sets").json()
        ids = [s["id"] for s in listed["data"]]
        assert listed["count"] == len(ids)
        assert ids.index(other["pattern_set_id"]) < ids.index(trained_set["pattern_set_id"])
        only = client.get("/v1/pattern-sets", params={"channel": "v2", "c": 1.25}).json()
        assert [s["id"] for s in only["data"]] == [other["pattern_set_id"]]
        assert only["data"][0]["params"]["effects"] == {"motor_viscous_friction": 0.01}
        assert client.get("/v1/pattern-sets", params={"channel": "m_el"}).json() == {"data": [], "count": 0}
    finally:
        client.delete(f"/v1/pattern-sets/{other['pattern_set_id']}")


def test_delete_removes_the_set(client: httpx.Client) -> None:
    out = train(client)
    url = f"/v1/pattern-sets/{out['pattern_set_id']}"
    assert client.get(url).status_code == 200
    r = client.delete(url)
    assert r.status_code == 204 and r.content == b""
    r = client.get(url)
    assert r.status_code == 404 and "no pattern set with id" in r.json()["detail"]
    assert client.delete(url).status_code == 404


def test_default_kind_is_the_engines(client: httpx.Client, sim_record: dict[str, Any]) -> None:
    from engine.identification.training import DEFAULT_KIND

    out = train(client, {"channel": "a2", "c": 1.0, "J1_values": [0.87, 0.8482, 0.8265]})
    try:
        assert out["job"]["state"] == "done", out["job"]
        ps = client.get(out["pattern_set_url"]).json()
        assert ps["kind"] == DEFAULT_KIND
        res = client.post("/v1/identify", json={"record": sim_record, "channel": "a2", "any_set": True}).json()
        assert res["pattern_set"] == out["pattern_set_id"] and res["kind"] == DEFAULT_KIND
        assert len(res["D"]) == 6 and 1 <= res["index"] <= 6
    finally:
        client.delete(out["pattern_set_url"])


@pytest.mark.parametrize(
    ("params", "says"),
    [
        ({"n_hidden": 100_000_000}, "n_hidden must be an integer from 1 to 1000"),
        ({"wavelet": "nope"}, "not a discrete wavelet"),
        ({"level": 1000}, "level must be an integer from 1 to 11"),
        ({"mode": "xx"}, "mode must be one of"),
    ],
)
def test_identifier_values_are_checked_before_a_job_is_queued(
    client: httpx.Client, params: dict[str, Any], says: str
) -> None:
    """Values the identifier would refuse only once training are refused with the request (422), no job queued."""
    jobs_before = client.get("/v1/jobs").json()["items"]
    r = client.post("/v1/pattern-sets", json={**SMALL_TRAINING, "kind": "paper", "params": params})
    assert r.status_code == 422, r.text
    assert says in r.json()["detail"]
    assert client.get("/v1/jobs").json()["items"] == jobs_before
