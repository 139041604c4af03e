"""Background jobs: the JobManager (app/jobs.py) and GET /v1/jobs/{id} (app/api/routes/jobs.py).

No test waits a fixed time for a job: the jobs block on events the test sets, and
the test waits for the manager's notifications (:meth:`JobManager.wait`) or for
events the jobs set (see ``GatedTraining`` in servicekit.py).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import httpx
import pytest
from servicekit import FAILING_TRAINING, SMALL_TRAINING, TIMEOUT, GatedTraining, InProcessServer, wait_for_job

from app.jobs import JobManager, JobState
from app.services.errors import NotFoundError, QueueFullError

# -- the manager, in process ------------------------------------------------------------


def test_manager_runs_a_job_with_monotonic_progress() -> None:
    manager = JobManager(workers=1, max_pending=4)
    go, inside, release = threading.Event(), threading.Event(), threading.Event()
    seen: list[float] = []

    def work(progress: Callable[..., None]) -> str:
        assert go.wait(TIMEOUT)  # `job` is assigned before the job looks itself up
        progress(0.5, "half")
        progress(0.2, "back")  # never decreases
        seen.append(manager.get(job.id).progress)
        progress(7.0)  # clamped to 1
        seen.append(manager.get(job.id).progress)
        inside.set()
        assert release.wait(TIMEOUT)
        return "result"

    job = manager.submit(work, kind="test", meta={"k": "v"})
    assert job.state is JobState.queued
    go.set()
    assert inside.wait(TIMEOUT)
    running = manager.get(job.id)
    assert running.state is JobState.running and running.started_at is not None and running.finished_at is None
    assert (running.progress, running.stage) == (1.0, "back")  # the latest stage, the highest progress
    release.set()
    done = manager.wait(job.id, TIMEOUT)
    assert seen == [0.5, 1.0]
    assert (done.state, done.progress, done.result, done.error) == (JobState.done, 1.0, "result", None)
    assert done.created_at <= done.started_at <= done.finished_at
    assert manager.find(k="v")[0].id == job.id
    manager.shutdown()


def test_manager_records_a_failure_and_keeps_going() -> None:
    manager = JobManager(workers=1, max_pending=4)

    def boom(progress: Callable[..., None]) -> None:
        progress(0.3, "about to fail")
        raise ValueError("the reason")

    failed = manager.wait(manager.submit(boom, kind="test").id, TIMEOUT)
    assert failed.state is JobState.failed
    assert failed.error == "ValueError: the reason"
    assert failed.progress == pytest.approx(0.3)
    ok = manager.wait(manager.submit(lambda progress: 1, kind="test").id, TIMEOUT)
    assert (ok.state, ok.result) == (JobState.done, 1)
    manager.shutdown()


def test_manager_limits_pending_jobs_and_fails_queued_jobs_on_shutdown() -> None:
    manager = JobManager(workers=1, max_pending=2)
    started, release = threading.Event(), threading.Event()

    def first_job(progress: Callable[..., None]) -> bool:
        started.set()
        return release.wait(TIMEOUT)

    first = manager.submit(first_job, kind="test")
    second = manager.submit(lambda progress: None, kind="test")
    with pytest.raises(QueueFullError, match="limit is 2"):
        manager.submit(lambda progress: None, kind="test")
    assert started.wait(TIMEOUT)  # the first job runs, the second is queued behind it
    assert manager.get(second.id).state is JobState.queued

    def release_once_the_queued_job_failed() -> None:
        manager.wait(second.id, TIMEOUT)  # shutdown fails the queued job first ...
        release.set()  # ... then the running one may finish

    helper = threading.Thread(target=release_once_the_queued_job_failed)
    helper.start()
    manager.shutdown(wait=True)  # returns only once the running job has finished
    at_return = manager.get(first.id)
    helper.join(TIMEOUT)
    assert at_return.state is JobState.done and at_return.result is True
    assert manager.get(second.id).state is JobState.failed
    assert "shut down" in (manager.get(second.id).error or "")
    with pytest.raises(QueueFullError, match="shutting down"):
        manager.submit(lambda progress: None, kind="test")
    with pytest.raises(NotFoundError, match="no job with id"):
        manager.get("nope")


# -- over HTTP, with training held by the test -------------------------------------------


def test_job_life_cycle_and_training_does_not_block(inprocess: InProcessServer, gated: GatedTraining) -> None:
    manager: JobManager = inprocess.app.state.jobs
    with inprocess.client() as client:
        _life_cycle(client, manager, gated)


def _life_cycle(client: httpx.Client, manager: JobManager, gated: GatedTraining) -> None:
    first = client.post("/v1/pattern-sets", json=SMALL_TRAINING)
    second = client.post("/v1/pattern-sets", json=SMALL_TRAINING)
    assert first.status_code == second.status_code == 202  # answered while the training is held
    first_id, second_id = first.json()["job_id"], second.json()["job_id"]
    progress: list[float] = []

    assert gated.gates[0].started.wait(TIMEOUT)
    job = client.get(f"/v1/jobs/{first_id}").json()
    assert (job["state"], job["progress"], job["stage"]) == ("running", 0.5, "held by the test")
    progress.append(job["progress"])
    queued = client.get(f"/v1/jobs/{second_id}").json()
    assert (queued["state"], queued["progress"], queued["started_at"]) == ("queued", 0.0, None)  # one worker
    assert client.get("/healthz").status_code == 200  # other requests are served while training runs

    gated.gates[0].release.set()
    assert gated.gates[1].started.wait(TIMEOUT)
    assert manager.wait(first_id, TIMEOUT).state.value == "done"
    job = client.get(f"/v1/jobs/{first_id}").json()
    progress.append(job["progress"])
    assert client.get(f"/v1/jobs/{second_id}").json()["state"] == "running"

    gated.gates[1].release.set()
    assert manager.wait(second_id, TIMEOUT).state.value == "done"
    later = client.get(f"/v1/jobs/{second_id}").json()
    assert progress == [0.5, 1.0] and later["progress"] == 1.0
    assert job["started_at"] <= job["finished_at"] <= later["started_at"]  # the second ran after the first
    assert job["error"] is None and later["error"] is None
    for r in (first, second):
        assert client.delete(r.json()["pattern_set_url"]).status_code == 204  # each job stored its set


def test_pattern_set_of_a_running_job_says_so(inprocess: InProcessServer, gated: GatedTraining) -> None:
    manager: JobManager = inprocess.app.state.jobs
    with inprocess.client() as client:
        _running_job_says_so(client, manager, gated)


def _running_job_says_so(client: httpx.Client, manager: JobManager, gated: GatedTraining) -> None:
    answer: dict[str, Any] = client.post("/v1/pattern-sets", json=SMALL_TRAINING).json()
    assert gated.gates[0].started.wait(TIMEOUT)
    missing = client.get(answer["pattern_set_url"])
    assert missing.status_code == 404
    detail = missing.json()["detail"]
    assert "not stored yet" in detail and answer["job_id"] in detail and "progress 50%" in detail
    gated.gates[0].release.set()
    assert manager.wait(answer["job_id"], TIMEOUT).state.value == "done"
    assert client.get(answer["pattern_set_url"]).status_code == 200
    assert client.delete(answer["pattern_set_url"]).status_code == 204


# -- over HTTP, against the real server -------------------------------------------------


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
