"""The application as a process (app/main.py): restart persistence, startup failure, clean shutdown."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path
from typing import Any

import pytest
from servicekit import SMALL_TRAINING, Server, ServerFactory, clean_env, free_port, serve_command, train


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
        r = c.get(f"/v1/jobs/{out['job_id']}")  # jobs live in memory only
        assert r.status_code == 404 and "forgotten when the server restarts" in r.json()["detail"]


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


def test_shutdown_waits_for_a_running_training_job(start_server: ServerFactory, tmp_path: Path) -> None:
    db = tmp_path / "shutdown" / "patterns.sqlite3"
    server: Server = start_server(db_path=db)
    with server.client() as c:
        r = c.post("/v1/pattern-sets", json={**SMALL_TRAINING, "delta1": 1e-9, "max_epochs": 600})
        set_id = r.json()["pattern_set_id"]
        deadline = time.monotonic() + 60
        # the job can finish between two polls (it takes ~0.1-0.3 s): stop once it has left
        # the queue; when it is still running the stop must wait for it
        while c.get(f"/v1/jobs/{r.json()['job_id']}").json()["state"] == "queued":
            assert time.monotonic() < deadline
            time.sleep(0.01)
    assert server.stop() == 0
    again = start_server(db_path=db)
    with again.client() as c:
        assert c.get(f"/v1/pattern-sets/{set_id}").status_code == 200  # the running job finished and was stored


@pytest.mark.parametrize("bad", ["", "1x"])
def test_cli_serve_rejects_a_bad_port(bad: str, tmp_path: Path) -> None:
    cmd = serve_command(8000)
    cmd[-1] = bad
    proc = subprocess.run(cmd, env=clean_env(), cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "--port" in proc.stderr
