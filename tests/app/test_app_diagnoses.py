"""Diagnoses as stored jobs, stored records, restarts, cancellation, the synchronous cap and time limit, and a
drive's history and trend (issue 12), over HTTP against real servers.

The records are simulated by the service itself; diagnoses consider two catalogue effects (the
``effects`` field) so that each takes seconds, not a minute.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from servicekit import InProcessServer, ServerFactory, wait_for_job, wait_until

from app.core.config import Settings
from app.main import create_app

PNG = b"\x89PNG\r\n\x1a\n"
#: Two effects: the diagnosis is the real one, on a short candidate list.
EFFECTS = ["contact_stiffness", "motor_viscous_friction"]


def noisy(channels: dict[str, list[float]], seed: int, snr_db: float = 40.0) -> dict[str, list[float]]:
    """White noise at ``snr_db`` of each channel's RMS, as a bench's record carries."""
    rng = np.random.default_rng(seed)
    out = {}
    for name, values in channels.items():
        x = np.asarray(values)
        sd = float(np.sqrt(np.mean(x**2))) * 10 ** (-snr_db / 20)
        out[name] = (x + rng.normal(0.0, sd, x.size)).tolist()
    return out


def record_in(client: httpx.Client, K: float = 0.005, seed: int = 3, **extra: Any) -> dict[str, Any]:
    """A simulated record (noisy, as a bench gives it) in the JSON record format, with ``extra`` fields."""
    r = client.post("/v1/simulate", json={"K": K})
    assert r.status_code == 200, r.text
    rec = r.json()
    out = {k: rec[k] for k in ("sample_interval", "event_index") if k in rec}
    out["channels"] = noisy(rec["channels"], seed)
    out["conditions"] = {k: v for k, v in rec["conditions"].items() if k != "K"}  # the width is what is sought
    return {**out, **extra}


def submit(client: httpx.Client, record: dict[str, Any]) -> dict[str, Any]:
    r = client.post("/v1/diagnoses", json={"record": record, "effects": EFFECTS})
    assert r.status_code == 202, r.text
    assert r.headers["location"] == r.json()["diagnosis_url"]
    return r.json()


def test_a_diagnosis_job_is_stored_with_its_record_figures_and_asset(client: httpx.Client) -> None:
    record = record_in(client, asset="press-7", measured_at="2026-11-20T08:00:00+01:00")
    accepted = submit(client, record)
    job = wait_for_job(client, accepted["job_id"])
    assert job["state"] == "done", job
    assert (job["kind"], job["diagnosis_id"], job["progress"]) == ("diagnose", accepted["diagnosis_id"], 1.0)

    d = client.get(accepted["diagnosis_url"]).json()
    assert (d["state"], d["asset"], d["plant"]) == ("done", "press-7", "backlash_drive")
    assert d["measured_at"] == "2026-11-20T07:00:00Z"  # stored in UTC
    assert d["status"] == d["result"]["verdict"]["status"] and d["status"] in (
        "no_gap",
        "weak_gap",
        "explained",
        "unexplained",
    )
    assert d["K"] is not None and d["K_sigma"] > 0 and abs(d["K"] - 0.005) < 5e-4  # the width the calibration found
    width = d["result"]["width"]  # the stored width is the answer's, from the model the answer ends with
    assert (d["K"], d["K_sigma"]) == (width["K"], width["sigma_K"])
    assert width["K"] == d["result"]["answer_calibration"]["values"]["K"]
    assert {"residual_map_before", "overlays"} <= set(d["figures"])
    for name in d["figures"]:
        fig = client.get(f"{accepted['diagnosis_url']}/figures/{name}")
        assert fig.status_code == 200 and fig.headers["content-type"] == "image/png" and fig.content.startswith(PNG)
    missing = client.get(f"{accepted['diagnosis_url']}/figures/nope")
    assert missing.status_code == 404 and "residual_map_before" in missing.json()["detail"]

    listed = client.get("/v1/diagnoses", params={"asset": "press-7"}).json()["items"]
    assert accepted["diagnosis_id"] in [i["id"] for i in listed] and all(i["result"] is None for i in listed)
    stored = client.get(f"/v1/records/{accepted['record_id']}").json()
    assert (stored["asset"], stored["media"], stored["n_samples"]) == ("press-7", "json", len(record["channels"]["v2"]))
    body = client.get(f"/v1/records/{accepted['record_id']}/body")
    assert body.json() == {"record": record, "effects": EFFECTS}  # the body exactly as sent
    history = client.get("/v1/assets/press-7/history").json()["points"]
    assert [(p["kind"], p["id"]) for p in history] == [("diagnosis", accepted["diagnosis_id"])]
    assert history[0]["K"] == width["K"]

    assert client.delete(accepted["diagnosis_url"]).status_code == 204
    assert client.get(accepted["diagnosis_url"]).status_code == 404
    assert client.get(f"/v1/records/{accepted['record_id']}").status_code == 200  # the record stays


def test_the_csv_form_with_its_query_parameters_is_stored_and_diagnosed_again(client: httpx.Client) -> None:
    rec = record_in(client, K=0.004, seed=4)
    names = list(rec["channels"])
    rows = zip(*(rec["channels"][n] for n in names), strict=True)
    csv_text = ",".join(names) + "\n" + "".join(",".join(repr(v) for v in row) + "\n" for row in rows)
    params = {
        "sample_interval": 1e-4,
        "event_index": 48,
        "J1": 0.87,
        "c": 1.0,
        "c1": 0.2,
        "asset": "mill-2",
        "measured_at": "2026-10-01T00:00:00Z",
    }
    r = client.post("/v1/diagnoses", content=csv_text, headers={"Content-Type": "text/csv"}, params=params)
    assert r.status_code == 202, r.text
    first = r.json()
    again = client.post(f"/v1/records/{first['record_id']}/diagnoses")
    assert again.status_code == 202, again.text
    for accepted in (first, again.json()):
        assert wait_for_job(client, accepted["job_id"])["state"] == "done"
    a, b = (client.get(x["diagnosis_url"]).json() for x in (first, again.json()))
    assert a["asset"] == b["asset"] == "mill-2" and a["record_id"] == b["record_id"]
    assert a["result"]["calibration"]["values"] == b["result"]["calibration"]["values"]  # the same reading
    assert client.get(f"/v1/records/{first['record_id']}/body").text == csv_text


@pytest.mark.parametrize(
    ("send", "status", "says"),
    [
        ({"json": {"record": {"channels": {"v2": [1.0, 2.0]}, "event_index": 1}}}, 422, "ms before the event"),
        (
            {"json": {"record": {"channels": {"v2": [0.0] * 3000}, "measured_at": "2026-11-20T08:00:00"}}},
            422,
            "timezone",
        ),
        ({"json": {"record": {"channels": {"v2": [0.0] * 3000}, "asset": "a b"}}}, 422, "asset"),
        ({"json": {"record": {"channels": {"v2": [0.0] * 3000}}, "effects": ["warp_drive"]}}, 422, "warp_drive"),
        (
            {"content": "v2\n1\n2\n", "headers": {"Content-Type": "text/csv"}, "params": {"measured_at": "yesterday"}},
            422,
            "measured_at",
        ),
        ({"content": b"\x00\x01", "headers": {"Content-Type": "application/octet-stream"}}, 415, "Content-Type"),
    ],
)
def test_a_refused_diagnosis_stores_nothing(client: httpx.Client, send: dict[str, Any], status: int, says: str) -> None:
    before = client.get("/v1/records").json()["items"]
    r = client.post("/v1/diagnoses", **send)
    assert r.status_code == status, r.text
    assert says in r.text
    assert client.get("/v1/records").json()["items"] == before


def test_jobs_and_results_survive_a_crash_and_an_interrupted_job_can_be_retried(
    start_server: ServerFactory, tmp_path: Path
) -> None:
    db = tmp_path / "service.sqlite3"
    server = start_server(db_path=db)
    with server.client() as c:
        record = record_in(c, asset="press-9")
        done = submit(c, record)
        assert wait_for_job(c, done["job_id"])["state"] == "done"
        running = submit(c, record)
        wait_until(lambda: c.get(running["job_url"]).json()["state"] == "running", what="the second diagnosis to run")
    assert server.proc is not None
    server.proc.kill()  # no shutdown: as a power cut or an OOM kill would stop it
    server.proc.wait()

    server = start_server(db_path=db)
    with server.client() as c:
        kept = c.get(done["diagnosis_url"]).json()
        assert kept["state"] == "done" and kept["result"]["verdict"]
        job = c.get(running["job_url"]).json()
        assert job["state"] == "interrupted" and "retry" in job["error"]
        assert c.get(running["diagnosis_url"]).json()["state"] == "interrupted"
        retried = c.post(f"{running['job_url']}/retry")
        assert retried.status_code == 202, retried.text
        assert retried.json()["retry_of"] == running["job_id"]
        assert wait_for_job(c, retried.json()["id"])["state"] == "done"
        d = c.get(running["diagnosis_url"]).json()
        assert (d["state"], d["job_id"]) == ("done", retried.json()["id"]) and d["result"]["verdict"]
        # cancel a running diagnosis; a finished job cannot be cancelled
        third = submit(c, record)
        wait_until(lambda: c.get(third["job_url"]).json()["state"] == "running", what="the third diagnosis to run")
        cancelled = c.post(f"{third['job_url']}/cancel")
        assert cancelled.status_code == 200 and cancelled.json()["state"] == "cancelled"
        again = c.post(f"{third['job_url']}/cancel")
        assert again.status_code == 409 and "already finished" in again.json()["detail"]
        assert c.get("/v1/jobs", params={"state": "cancelled"}).json()["items"][0]["id"] == third["job_id"]
    with pytest.raises(RuntimeError, match="another backlash service"):  # one service per database file
        start_server(db_path=db)


def test_synchronous_diagnoses_are_capped_and_time_limited(tmp_path: Path, client: httpx.Client) -> None:
    record = record_in(client)
    server = InProcessServer(
        create_app(Settings(db_path=tmp_path / "sync.sqlite3", max_sync_diagnoses=1, sync_diagnose_timeout=2.0))
    )
    server.start()
    try:
        answers: list[httpx.Response] = []
        with server.client() as c:
            first = threading.Thread(target=lambda: answers.append(c.post("/v1/diagnose", json={"record": record})))
            first.start()
            sync = server.app.state.sync_diagnoses
            wait_until(lambda: sync.running == 1, what="the first diagnosis to take the only slot")
            refused = c.post("/v1/diagnose", json={"record": record})
            assert refused.status_code == 429, refused.text
            assert int(refused.headers["retry-after"]) > 0 and "POST /v1/diagnoses" in refused.json()["detail"]
            first.join(120)
        (limited,) = answers
        assert limited.status_code == 504, limited.text
        assert "limit of 2 s" in limited.json()["detail"] and "POST /v1/diagnoses" in limited.json()["detail"]
        with server.client() as c:
            assert c.get("/healthz").status_code == 200  # the server stays up
    finally:
        server.request_stop()
        server.join()


def test_an_assets_width_history_gives_a_trend_and_a_crossing_date(
    client: httpx.Client, trained_set: dict[str, Any]
) -> None:
    asset = "press-trend"
    widths = {"2026-01-05T08:00:00Z": 0.004, "2026-03-02T08:00:00Z": 0.005, "2026-05-04T08:00:00Z": 0.006}
    for i, (when, K) in enumerate(widths.items()):
        record = record_in(client, K=K, asset=asset, measured_at=when)
        r = client.post("/v1/identify", json={"record": record, "channel": "v2", "any_set": True})
        assert r.status_code == 200, r.text
        answer = r.json()
        assert answer["identification_id"] and answer["asset"] == asset and answer["continuous"]["K"] > 0
        if i == 1:
            short = client.get(f"/v1/assets/{asset}/trend", params={"limit": 0.009})
            assert short.status_code == 422 and asset in short.json()["detail"]
    history = client.get(f"/v1/assets/{asset}/history").json()["points"]
    assert [p["measured_at"] for p in history] == [w.replace("+00:00", "Z") for w in widths]
    assert all(p["kind"] == "identification" and p["used_in_trend"] and p["K_sigma"] > 0 for p in history)
    assert [abs(p["K"] - K) < 5e-4 for p, K in zip(history, widths.values(), strict=True)] == [True] * 3

    trend = client.get(f"/v1/assets/{asset}/trend", params={"limit": 0.009}).json()
    assert trend["n_points"] == 3 and trend["method"]
    assert trend["rate_m_per_day"] == pytest.approx(0.001 / 59, rel=0.3)  # about 1 mm per two months
    assert trend["rate_sigma_m_per_day"] > 0
    earliest, latest = trend["crossing_interval"]
    assert earliest is not None and earliest <= trend["crossing_date"]
    assert trend["crossing_date"] > "2026-05-04"
    assert latest is None or trend["crossing_date"] <= latest
    figure = client.get(f"/v1/assets/{asset}/trend/figure", params={"limit": 0.009})
    assert figure.status_code == 200 and figure.content.startswith(PNG)
    assets = {a["asset"]: a for a in client.get("/v1/assets").json()["items"]}
    assert assets[asset]["n_identifications"] == 3
    assert client.get("/v1/assets/nobody/history").status_code == 404
