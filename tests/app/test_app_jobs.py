"""Background jobs: the JobManager (app/jobs/) and /v1/jobs (app/api/routes/jobs.py).

No test waits a fixed time for a job: the jobs block on events the test sets, and
the test waits for the manager's notifications (:meth:`JobManager.wait`) or for
events the jobs set (see ``GatedTraining`` in servicekit.py).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest
from servicekit import (
    FAILING_TRAINING,
    SMALL_TRAINING,
    TIMEOUT,
    GatedTraining,
    InProcessServer,
    process_alive,
    sleeping_job,
    wait_for_job,
    wait_until,
)

from app.db.jobs import JobRepository
from app.jobs import JobKind, JobManager, JobState
from app.services.errors import ConflictError, NotFoundError, QueueFullError
from engine.storage import PatternStore

# -- the manager, in process ------------------------------------------------------------


def make_manager(tmp_path: Path, run: Callable[..., Any], *, workers: int = 1, max_pending: int = 4) -> JobManager:
    """A manager of one thread kind ``test`` and one process kind ``sleep`` on a fresh file."""
    kinds = {
        "test": JobKind("test", "thread", run),
        "sleep": JobKind("sleep", "process", sleeping_job),
    }
    return JobManager(
        PatternStore(tmp_path / "jobs.sqlite3"), kinds, workers=workers, pools={"default": 1}, max_pending=max_pending
    )


def test_manager_runs_a_job_with_monotonic_progress(tmp_path: Path) -> None:
    go, inside, release = threading.Event(), threading.Event(), threading.Event()
    seen: list[float] = []

    def work(spec: dict[str, Any], progress: Callable[..., None]) -> dict[str, Any]:
        assert go.wait(TIMEOUT)  # `job` is assigned before the job looks itself up
        progress(0.5, "half")
        progress(0.2, "back")  # never decreases
        seen.append(manager.get(job.id).progress)
        progress(7.0, None)  # clamped to 1; the stage stays
        seen.append(manager.get(job.id).progress)
        inside.set()
        assert release.wait(TIMEOUT)
        return {"answer": spec["question"] * 2}

    manager = make_manager(tmp_path, work)
    job = manager.submit("test", {"question": 21}, meta={"k": "v"})
    assert job.state is JobState.queued
    go.set()
    assert inside.wait(TIMEOUT)
    running = manager.get(job.id)
    assert running.state is JobState.running and running.started_at is not None and running.finished_at is None
    assert (running.progress, running.stage) == (1.0, "back")  # the latest stage, the highest progress
    release.set()
    done = manager.wait(job.id, TIMEOUT)
    assert seen == [0.5, 1.0]
    assert (done.state, done.progress, done.meta, done.error) == (JobState.done, 1.0, {"k": "v", "answer": 42}, None)
    assert done.spec == {"question": 21}
    assert done.created_at <= done.started_at <= done.finished_at  # type: ignore[operator]
    assert manager.find(k="v")[0].id == job.id
    manager.shutdown()


def test_manager_records_a_failure_and_keeps_going(tmp_path: Path) -> None:
    def work(spec: dict[str, Any], progress: Callable[..., None]) -> None:
        progress(0.3, "about to fail")
        if spec["fail"]:
            raise ValueError("the reason")

    manager = make_manager(tmp_path, work)
    failed = manager.wait(manager.submit("test", {"fail": True}).id, TIMEOUT)
    assert failed.state is JobState.failed
    assert failed.error == "ValueError: the reason"
    assert failed.progress == pytest.approx(0.3)
    ok = manager.wait(manager.submit("test", {"fail": False}).id, TIMEOUT)
    assert ok.state is JobState.done
    manager.shutdown()


def test_manager_limits_pending_jobs_and_interrupts_unfinished_ones_on_shutdown(tmp_path: Path) -> None:
    started, release = threading.Event(), threading.Event()

    def work(spec: dict[str, Any], progress: Callable[..., None]) -> None:
        started.set()
        assert release.wait(TIMEOUT)
        progress(0.9, "after the gate")  # a shut-down manager stops the job here

    manager = make_manager(tmp_path, work, max_pending=2)
    first = manager.submit("test", {})
    second = manager.submit("test", {})
    with pytest.raises(QueueFullError, match="limit is 2") as refused:
        manager.submit("test", {})
    assert refused.value.retry_after > 0
    assert started.wait(TIMEOUT)  # the first job runs, the second is queued behind it
    assert manager.get(second.id).state is JobState.queued
    threading.Timer(0.2, release.set).start()
    manager.shutdown(wait=True)
    for job_id in (first.id, second.id):
        job = manager.get(job_id)
        assert job.state is JobState.interrupted, job
        assert "shut down" in (job.error or "") and "retry" in (job.error or "")
    with pytest.raises(QueueFullError, match="shutting down"):
        manager.submit("test", {})
    with pytest.raises(NotFoundError, match="no job with id"):
        manager.get("nope")


def test_a_restart_marks_unfinished_jobs_interrupted_and_a_retry_runs_them_again(tmp_path: Path) -> None:
    def work(spec: dict[str, Any], progress: Callable[..., None]) -> dict[str, Any]:
        return {"ran": spec["n"]}

    store = PatternStore(tmp_path / "jobs.sqlite3")
    repo = JobRepository(store)
    queued = repo.create("test", meta={}, spec={"n": 1})  # a previous process queued one ...
    running = repo.create("test", meta={}, spec={"n": 2})
    assert repo.start(running.id)  # ... and was running another when it died
    finished = repo.create("test", meta={}, spec={"n": 3})
    assert repo.start(finished.id) and repo.finish(finished.id)
    manager = make_manager(tmp_path, work)
    assert sorted(manager.recover()) == sorted([queued.id, running.id])
    for job_id in (queued.id, running.id):
        job = manager.get(job_id)
        assert job.state is JobState.interrupted and "retry" in (job.error or "")
    assert manager.get(finished.id).state is JobState.done
    with pytest.raises(ConflictError, match="only failed, interrupted or cancelled"):
        manager.retry(finished.id)
    again = manager.wait(manager.retry(running.id).job.id, TIMEOUT)
    assert (again.state, again.retry_of, again.meta) == (JobState.done, running.id, {"ran": 2})
    manager.shutdown()


@pytest.mark.serial  # asserts the worker ends within 1 s of the cancel
def test_cancelling_a_running_process_job_terminates_its_worker_at_once(tmp_path: Path) -> None:
    manager = make_manager(tmp_path, lambda spec, progress: None)
    pid_file = tmp_path / "worker.pid"
    job = manager.submit("sleep", {"pid_file": str(pid_file), "seconds": 120})
    running = wait_until(lambda: manager.get(job.id).stage == "sleeping", what="the process job to start")
    assert running
    pid = int(pid_file.read_text())
    assert process_alive(pid)
    cancelled_at = time.monotonic()
    assert manager.cancel(job.id).state is JobState.cancelled
    assert wait_until(lambda: not process_alive(pid), timeout=5, what="the worker to end")
    freed_after = time.monotonic() - cancelled_at
    assert freed_after < 1.0, f"the worker ran on for {freed_after:.2f} s after the cancel"
    with pytest.raises(ConflictError, match="already finished"):
        manager.cancel(job.id)
    quick = manager.wait(manager.submit("sleep", {"pid_file": str(pid_file), "seconds": 0}).id, TIMEOUT)
    assert quick.state is JobState.done  # the pool started a fresh worker
    manager.shutdown()


def test_cancelling_a_queued_job_means_it_never_starts(tmp_path: Path) -> None:
    started, release = threading.Event(), threading.Event()

    def work(spec: dict[str, Any], progress: Callable[..., None]) -> None:
        started.set()
        assert release.wait(TIMEOUT)

    manager = make_manager(tmp_path, work)
    first = manager.submit("test", {"n": 1})
    second = manager.submit("test", {"n": 2})
    assert started.wait(TIMEOUT)
    assert manager.cancel(second.id).state is JobState.cancelled
    release.set()
    assert manager.wait(first.id, TIMEOUT).state is JobState.done
    assert manager.get(second.id).started_at is None
    manager.shutdown()


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
