"""The application as a process (app/main.py): restart persistence, startup failure, clean shutdown.

The shutdown test serves the application in a thread of the test process, so that
it can hold the training job with an event while the server stops.
"""

from __future__ import annotations

import subprocess
import threading
from pathlib import Path
from typing import Any

import pytest
from servicekit import (
    SMALL_TRAINING,
    TIMEOUT,
    GatedTraining,
    InProcessServer,
    ServerFactory,
    clean_env,
    free_port,
    serve_command,
    train,
)

from app.jobs import JobManager, JobState
from engine.storage import PatternStore


def test_pattern_sets_survive_a_restart(
    start_server: ServerFactory, tmp_path: Path, sim_record: dict[str, Any]
) -> None:
    db = tmp_path / "persist" / "patterns.sqlite3"
    first = start_server(db_path=db)
    with first.client() as c:
        out = train(c)
        assert out["job"]["state"] == "done"
        set_id = out["pattern_set_id"]
        stored = c.get(f"/v1/pattern-sets/{set_id}").json()
        request = {"record": sim_record, "channel": "v2", "pattern_set": set_id}
        identified = c.post("/v1/identify", json=request).json()
    assert first.stop() == 0  # clean shutdown on SIGINT

    second = start_server(db_path=db)
    with second.client() as c:
        assert c.get("/healthz").json()["pattern_sets"] == 1
        assert c.get(f"/v1/pattern-sets/{set_id}").json() == stored
        assert c.post("/v1/identify", json=request).json() == identified
        job = c.get(f"/v1/jobs/{out['job_id']}").json()  # jobs are stored too
        assert {k: job[k] for k in ("state", "pattern_set_id", "progress")} == {
            "state": "done",
            "pattern_set_id": set_id,
            "progress": 1.0,
        }


def test_server_refuses_to_start_on_a_file_that_is_not_a_pattern_store(tmp_path: Path) -> None:
    db = tmp_path / "not-a-db.sqlite3"
    db.write_text("hello, I am not SQLite\n" * 100)
    port = free_port()
    proc = subprocess.run(
        serve_command(port),
        env=clean_env(BACKLASH_DB_PATH=str(db)),
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert f"pattern store {db} is unreadable: file is not a database" in proc.stderr


def test_invalid_settings_stop_the_command_with_a_message(tmp_path: Path) -> None:
    proc = subprocess.run(
        serve_command(free_port()),
        env=clean_env(BACKLASH_WORKERS="0"),
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "invalid settings" in proc.stderr and "workers" in proc.stderr


def test_shutdown_interrupts_a_running_training_job_which_can_be_retried(
    inprocess: InProcessServer, gated: GatedTraining, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A shutdown does not wait for a long job: the job stops at its next progress report, ends ``interrupted``
    with what to do, stores nothing, and a retry (on the next start, here on the same manager's file) runs it."""
    manager: JobManager = inprocess.app.state.jobs
    shutting_down = threading.Event()
    real_shutdown = JobManager.shutdown

    def recording_shutdown(self: JobManager, wait: bool = True) -> None:
        shutting_down.set()
        real_shutdown(self, wait=wait)

    monkeypatch.setattr(JobManager, "shutdown", recording_shutdown)
    with inprocess.client() as c:
        r = c.post("/v1/pattern-sets", json=SMALL_TRAINING)
        assert r.status_code == 202
        job_id, set_id = r.json()["job_id"], r.json()["pattern_set_id"]
    assert gated.gates[0].started.wait(TIMEOUT)  # the job is running, held at its gate
    inprocess.request_stop()
    assert shutting_down.wait(TIMEOUT)  # the application is shutting down while the job runs
    gated.gates[0].release.set()
    inprocess.join()
    job = manager.get(job_id)
    assert job.state is JobState.interrupted and "retry" in (job.error or ""), job
    assert set_id not in PatternStore(inprocess.app.state.settings.db_path)


@pytest.mark.parametrize("bad", ["", "1x"])
def test_cli_serve_rejects_a_bad_port(bad: str, tmp_path: Path) -> None:
    cmd = serve_command(8000)
    cmd[-1] = bad
    proc = subprocess.run(cmd, env=clean_env(), cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "--port" in proc.stderr
