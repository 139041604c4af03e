"""Many-case work on Dask (issue 13): the same report wherever it runs, and a run that survives a lost worker.

The cases are clean records (the quickest real diagnoses, a few seconds each) of a protocol-2 run:
the real diagnosis, not a stand-in, because what must not change between runs is its answers.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from engine.distributed import SchedulerUnreachable, dask_client
from engine.validation.layout import RunLayout
from engine.validation.run import run_validation

MIX = {"clean": 1.0}
N_CASES = 2
SEED = 5


def _without_timings(x: Any) -> Any:
    """``x`` without the keys that legitimately differ between runs: wall times, how the diagnoses
    shared the machine and the code version."""
    if isinstance(x, dict):
        return {
            k: _without_timings(v) for k, v in x.items() if "seconds" not in k and k not in ("code_version", "ran_with")
        }
    if isinstance(x, list):
        return [_without_timings(v) for v in x]
    return x


def _answers(root: Path) -> dict[str, Any]:
    """Every case's answer, everything but timings compared exactly."""
    layout = RunLayout(root)
    return {case_id: _without_timings(layout.read_result(case_id)) for case_id in sorted(layout.done())}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _dask_cli() -> str:
    exe = shutil.which("dask", path=str(Path(sys.executable).parent))
    assert exe is not None, "the dask command comes with dask[distributed]"
    return exe


class _Cluster:
    """A scheduler and workers started as the dask commands start them, on the loopback interface."""

    def __init__(self, tmp: Path, workers: int) -> None:
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
        log = (tmp / "dask.log").open("w")
        self.scheduler = subprocess.Popen(
            [_dask_cli(), "scheduler", "--host", "127.0.0.1", "--port", str(self.port), "--no-dashboard"],
            stdout=log,
            stderr=subprocess.STDOUT,
            env=env,
        )
        self.workers = [
            subprocess.Popen(
                [_dask_cli(), "worker", self.address, "--nthreads", "1", "--no-dashboard", "--no-nanny"],
                stdout=log,
                stderr=subprocess.STDOUT,
                env=env,
            )
            for _ in range(workers)
        ]
        from distributed import Client

        deadline = time.monotonic() + 60
        while True:
            try:
                with Client(self.address, timeout=5) as c:
                    if len(c.scheduler_info()["workers"]) == workers:
                        return
            except OSError:
                pass
            if time.monotonic() > deadline:
                self.close()
                raise RuntimeError("the test cluster did not come up within 60 s")
            time.sleep(0.5)

    def close(self) -> None:
        for p in [*self.workers, self.scheduler]:
            if p.poll() is None:
                p.terminate()
        for p in [*self.workers, self.scheduler]:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.fixture(scope="module")
def in_process(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("run0") / "run"
    run_validation(N_CASES, SEED, root, workers=0, mix=MIX)
    return _answers(root)


@pytest.mark.slow  # as are the two below; the default run keeps the refusal of an unreachable scheduler
@pytest.mark.parametrize("workers", [1, 2])
def test_a_validation_gives_the_same_answers_on_local_clusters_of_any_size(
    in_process: dict[str, Any], tmp_path: Path, workers: int
) -> None:
    root = tmp_path / "run"
    doc = run_validation(N_CASES, SEED, root, workers=workers, mix=MIX)
    assert doc["n_cases"] == N_CASES
    assert _answers(root) == in_process
    assert doc["ran_with"] == [{"at_once": workers, "threads_each": 1, "host_cores": os.cpu_count()}]


@pytest.mark.slow  # 70 s: a scheduler and two workers started, two validation cases, one worker killed
def test_a_separate_scheduler_gives_the_same_answers_and_survives_a_lost_worker(
    in_process: dict[str, Any], tmp_path: Path
) -> None:
    """Two workers started by ``dask worker``; one is killed as soon as the first result is written."""
    cluster = _Cluster(tmp_path, workers=2)
    root = tmp_path / "run"
    killed: list[int] = []

    def kill_one_when_a_result_appears() -> None:
        results = root / "results"
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            if results.is_dir() and any(results.glob("*.json")):
                victim = cluster.workers[0]
                os.kill(victim.pid, signal.SIGKILL)
                killed.append(victim.pid)
                return
            time.sleep(0.05)

    watcher = threading.Thread(target=kill_one_when_a_result_appears, daemon=True)
    watcher.start()
    try:
        doc = run_validation(N_CASES, SEED, root, mix=MIX, scheduler=cluster.address)
    finally:
        watcher.join(timeout=5)
        cluster.close()
    assert killed, "the watcher never saw a result"
    assert doc["n_cases"] == N_CASES and len(RunLayout(root).done()) == N_CASES
    assert _answers(root) == in_process
    # a remote scheduler's machines are not this process's to count
    assert [w["host_cores"] for w in doc["ran_with"]] == [None] and doc["ran_with"][0]["threads_each"] == 1


def test_an_unreachable_scheduler_is_refused_with_what_to_do(monkeypatch: pytest.MonkeyPatch) -> None:
    import engine.distributed

    monkeypatch.setattr(engine.distributed, "CONNECT_TIMEOUT", 2.0)
    with (
        pytest.raises(SchedulerUnreachable, match="cannot reach the Dask scheduler"),
        dask_client(f"tcp://127.0.0.1:{_free_port()}"),
    ):
        pass


@pytest.mark.slow  # 30 s: a scheduler, a worker and a training
def test_the_service_trains_on_the_cluster_of_its_scheduler_with_the_same_job_api(tmp_path: Path) -> None:
    """``BACKLASH_DASK_SCHEDULER`` set: a training job runs on that cluster's worker, the set is stored here."""
    from fastapi.testclient import TestClient

    from app.core.config import Settings
    from app.main import create_app

    cluster = _Cluster(tmp_path, workers=1)
    try:
        app = create_app(Settings(db_path=tmp_path / "patterns.sqlite3", dask_scheduler=cluster.address))
        with TestClient(app) as client:
            request = {"channel": "v2", "c": 1.0, "J1_values": [0.87, 0.8482], "kind": "template"}
            r = client.post("/v1/pattern-sets", json=request)
            assert r.status_code == 202, r.text
            accepted = r.json()
            deadline = time.monotonic() + 120
            while (job := client.get(f"/v1/jobs/{accepted['job_id']}").json())["state"] not in ("done", "failed"):
                assert time.monotonic() < deadline, job
                time.sleep(0.1)
            assert job["state"] == "done", job
            assert client.get(f"/v1/pattern-sets/{accepted['pattern_set_id']}").status_code == 200
            ran = app.state.dask.run_on_scheduler(lambda dask_scheduler: sorted(dask_scheduler.task_prefixes))
            assert "train" in ran  # the task ran on the cluster, keyed train-<set id>
    finally:
        cluster.close()


def test_the_service_refuses_to_start_on_a_scheduler_that_does_not_answer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from fastapi.testclient import TestClient

    import engine.distributed
    from app.core.config import Settings
    from app.core.instance import hold_database
    from app.main import create_app

    monkeypatch.setattr(engine.distributed, "CONNECT_TIMEOUT", 2.0)
    app = create_app(Settings(db_path=tmp_path / "p.sqlite3", dask_scheduler=f"tcp://127.0.0.1:{_free_port()}"))
    with pytest.raises(SchedulerUnreachable, match="cannot reach the Dask scheduler"), TestClient(app):
        pass
    # the failed start gave its service lock back: another start in this process may take it
    hold_database(tmp_path / "p.sqlite3").close()
