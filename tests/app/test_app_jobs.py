"""Background jobs: the JobManager (app/jobs.py) and GET /v1/jobs/{id} (app/api/routes/jobs.py)."""

from __future__ import annotations

import threading
import time
from typing import Any

import httpx
import pytest
from servicekit import FAILING_TRAINING, SMALL_TRAINING, wait_for_job

from app.jobs import JobManager, JobState
from app.services.errors import NotFoundError, QueueFullError

#: Runs every pattern network to its epoch cap: about 2 s of training.
SLOW_TRAINING = {**SMALL_TRAINING, "delta1": 1e-9, "max_epochs": 1500}


# -- the manager, in process ------------------------------------------------------------


def _wait(manager: JobManager, job_id: str, timeout: float = 10.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = manager.get(job_id)
        if job.finished:
            return job
        time.sleep(0.01)
    raise AssertionError(f"job {job_id} did not finish")


def test_manager_runs_a_job_with_monotonic_progress() -> None:
    manager = JobManager(workers=1)
    go, release = threading.Event(), threading.Event()
    seen: list[float] = []

    def work(progress):
        go.wait(5)
        progress(0.5, "half")
        progress(0.2, "back")  # never decreases
        seen.append(manager.get(job.id).progress)
        progress(7.0)  # clamped to 1
        seen.append(manager.get(job.id).progress)
        release.wait(5)
        return "result"

    job = manager.submit(work, kind="test", meta={"k": "v"})
    assert job.state is JobState.queued
    go.set()
    time.sleep(0.2)
    running = manager.get(job.id)
    assert running.state is JobState.running and running.started_at is not None
    release.set()
    done = _wait(manager, job.id)
    assert seen == [0.5, 1.0]
    assert (done.state, done.progress, done.result, done.error) == (JobState.done, 1.0, "result", None)
    assert done.created_at <= done.started_at <= done.finished_at
    assert manager.find(k="v")[0].id == job.id
    manager.shutdown()


def test_manager_records_a_failure_and_keeps_going() -> None:
    manager = JobManager(workers=1)

    def boom(progress):
        progress(0.3, "about to fail")
        raise ValueError("the reason")

    failed = _wait(manager, manager.submit(boom, kind="test").id)
    assert failed.state is JobState.failed
    assert failed.error == "ValueError: the reason"
    assert failed.progress == pytest.approx(0.3)
    ok = _wait(manager, manager.submit(lambda progress: 1, kind="test").id)
    assert ok.state is JobState.done
    manager.shutdown()


def test_manager_limits_pending_jobs_and_fails_queued_jobs_on_shutdown() -> None:
    manager = JobManager(workers=1, max_pending=2)
    release = threading.Event()
    first = manager.submit(lambda progress: release.wait(5), kind="test")
    second = manager.submit(lambda progress: None, kind="test")
    with pytest.raises(QueueFullError, match="limit is 2"):
        manager.submit(lambda progress: None, kind="test")
    time.sleep(0.1)
    threading.Timer(0.2, release.set).start()
    manager.shutdown(wait=True)
    assert manager.get(first.id).state is JobState.done
    assert manager.get(second.id).state is JobState.failed
    assert "shut down" in manager.get(second.id).error
    with pytest.raises(QueueFullError, match="shutting down"):
        manager.submit(lambda progress: None, kind="test")
    with pytest.raises(NotFoundError, match="no job with id"):
        manager.get("nope")


# -- over HTTP ------------------------------------------------------------------------


def test_job_life_cycle_and_training_does_not_block(client: httpx.Client) -> None:
    slow = client.post("/v1/pattern-sets", json=SLOW_TRAINING)
    quick = client.post("/v1/pattern-sets", json=SMALL_TRAINING)
    assert slow.status_code == quick.status_code == 202
    slow_id, quick_id = slow.json()["job_id"], quick.json()["job_id"]
    states: dict[str, list[tuple[str, float]]] = {slow_id: [], quick_id: []}
    latencies: list[float] = []
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        for job_id in states:
            job = client.get(f"/v1/jobs/{job_id}").json()
            states[job_id].append((job["state"], job["progress"]))
        t0 = time.monotonic()
        assert client.get("/healthz").status_code == 200
        latencies.append(time.monotonic() - t0)
        if all(s[-1][0] in ("done", "failed") for s in states.values()):
            break
        time.sleep(0.02)
    slow_states = [s for s, _ in states[slow_id]]
    quick_states = [s for s, _ in states[quick_id]]
    assert slow_states[-1] == quick_states[-1] == "done"
    assert "running" in slow_states
    assert any(0.0 < p < 1.0 for s, p in states[slow_id] if s == "running")
    progress = [p for _, p in states[slow_id]]
    assert progress == sorted(progress)  # never decreases
    # one worker: the second job waits while the first runs
    assert "queued" in quick_states
    assert quick_states.index("running" if "running" in quick_states else "done") > slow_states.index("running")
    assert max(latencies) < 1.0, latencies  # other requests are served while training runs
    job = client.get(f"/v1/jobs/{slow_id}").json()
    assert job["started_at"] <= job["finished_at"] and job["error"] is None
    for r in (slow, quick):
        assert client.delete(r.json()["pattern_set_url"]).status_code == 204


def test_failing_job_ends_failed_with_the_reason_and_stores_nothing(client: httpx.Client) -> None:
    before = client.get("/v1/pattern-sets").json()
    r = client.post("/v1/pattern-sets", json=FAILING_TRAINING)
    assert r.status_code == 202  # valid values: only the simulation can tell
    job = wait_for_job(client, r.json()["job_id"])
    assert job["state"] == "failed"
    assert "SimulationError" in job["error"] and "no backlash event" in job["error"]
    assert job["progress"] < 1.0
    missing = client.get(r.json()["pattern_set_url"])
    assert missing.status_code == 404 and "failed" in missing.json()["detail"]
    assert client.get("/v1/pattern-sets").json() == before


def test_unknown_job_is_404(client: httpx.Client) -> None:
    r = client.get("/v1/jobs/0123456789abcdef")
    assert r.status_code == 404 and "no job with id" in r.json()["detail"]


def test_pattern_set_of_a_running_job_says_so(client: httpx.Client) -> None:
    r = client.post("/v1/pattern-sets", json=SLOW_TRAINING)
    answer: dict[str, Any] = r.json()
    try:
        missing = client.get(answer["pattern_set_url"])
        assert missing.status_code == 404
        assert "not stored yet" in missing.json()["detail"] and answer["job_id"] in missing.json()["detail"]
    finally:
        assert wait_for_job(client, answer["job_id"])["state"] == "done"
        client.delete(answer["pattern_set_url"])
