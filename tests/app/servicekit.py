"""Helpers of the service tests: real uvicorn servers, talked to with httpx.

Most servers run ``python -m app.cli serve`` (the ``backlash serve`` command) in a
subprocess on a free local port with ``BACKLASH_DB_PATH`` in a temporary
directory. Tests that hold a training job while they look at it serve the
application in a thread of the test process instead (:class:`InProcessServer`),
with the training replaced by :class:`GatedTraining`.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import uvicorn
from fastapi import FastAPI

#: Small, fast training request of the paper's identifier (2 J1 values instead of 7); identifies K = 0.005 on v2.
SMALL_TRAINING = {"channel": "v2", "c": 1.0, "J1_values": [0.87, 0.8482], "kind": "paper", "max_epochs": 200}
#: Longest a test waits for something that must happen (a bound against hanging, not a timing assumption).
TIMEOUT = 30.0
#: A request whose simulation has no backlash event: the training job fails.
FAILING_TRAINING = {
    "channel": "v2",
    "c": 1.0,
    "J1_values": [0.87],
    "effects": {"contact_stiffness": 0.1, "contact_damping": 20.0},
}


def wait_until(condition: Callable[[], Any], timeout: float = TIMEOUT, what: str = "the condition") -> Any:
    """Poll ``condition`` until it is truthy (return it) or ``timeout`` [s] passes (AssertionError naming ``what``)."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(0.02)


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def sleeping_job(db_path: Path, spec: dict[str, Any], progress: Callable[[float, str], None]) -> dict[str, Any]:
    """A process job of the tests: writes its pid to ``spec["pid_file"]``, then sleeps ``spec["seconds"]``."""
    Path(spec["pid_file"]).write_text(str(os.getpid()))
    progress(0.1, "sleeping")
    deadline = time.monotonic() + float(spec["seconds"])
    while time.monotonic() < deadline:
        time.sleep(0.01)
    return {"slept": spec["seconds"]}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def clean_env(**extra: str) -> dict[str, str]:
    """The test process's environment without BACKLASH_* variables, plus ``extra``."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("BACKLASH_")}
    env.update(extra)
    return env


class Server:
    """A service process; ``start`` waits until /healthz answers."""

    def __init__(self, command: list[str], env: dict[str, str], port: int, log_path: Path, cwd: Path) -> None:
        self.command, self.env, self.port, self.log_path, self.cwd = command, env, port, log_path, cwd
        self.base_url = f"http://127.0.0.1:{port}"
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self, timeout: float = 120.0) -> Server:
        with open(self.log_path, "ab") as log:
            self.proc = subprocess.Popen(self.command, env=self.env, cwd=self.cwd, stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited with {self.proc.returncode}:\n{self.log()}")
            try:
                if httpx.get(f"{self.base_url}/healthz", timeout=2).status_code == 200:
                    return self
            except httpx.TransportError:
                pass
            time.sleep(0.1)
        self.stop()
        raise RuntimeError(f"server did not answer /healthz within {timeout} s:\n{self.log()}")

    def stop(self) -> int | None:
        if self.proc is None or self.proc.poll() is not None:
            return None if self.proc is None else self.proc.returncode
        self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait()

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")[-5000:]

    def client(self, **kwargs: Any) -> httpx.Client:
        return httpx.Client(base_url=self.base_url, timeout=120, **kwargs)


def serve_command(port: int) -> list[str]:
    return [sys.executable, "-m", "app.cli", "serve", "--host", "127.0.0.1", "--port", str(port)]


def wait_for_job(client: httpx.Client, job_id: str, timeout: float = 120.0) -> dict[str, Any]:
    """Poll the job until it is done or failed; return its last state."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = client.get(f"/v1/jobs/{job_id}").json()
        if job["state"] in ("done", "failed", "interrupted", "cancelled"):
            return job
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} did not finish within {timeout} s: {job}")


def train(client: httpx.Client, request: dict[str, Any] | None = None) -> dict[str, Any]:
    """Train a pattern set and wait for it; return the accepted answer plus the finished job."""
    r = client.post("/v1/pattern-sets", json=request or SMALL_TRAINING)
    assert r.status_code == 202, r.text
    accepted = r.json()
    return {**accepted, "job": wait_for_job(client, accepted["job_id"])}


ServerFactory = Callable[..., Server]


def make_factory(tmp_dir: Path, servers: list[Server]) -> ServerFactory:
    """A function that starts servers with their database under ``tmp_dir`` and appends them to ``servers``."""

    def start(
        db_path: Path | None = None, command: list[str] | None = None, port: int | None = None, **env: str
    ) -> Server:
        port = port or free_port()
        db_path = db_path or tmp_dir / f"db-{port}" / "patterns.sqlite3"
        environment = clean_env(
            BACKLASH_DB_PATH=str(db_path),
            BACKLASH_LOG_LEVEL="INFO",
            **{f"BACKLASH_{k.upper()}": v for k, v in env.items()},
        )
        server = Server(command or serve_command(port), environment, port, tmp_dir / f"server-{port}.log", tmp_dir)
        servers.append(server)
        return server.start()

    return start


# -- in process: training held by the test -------------------------------------------


class Gate:
    """One training call: ``started`` once it has reported progress 0.5; it then waits for ``release``."""

    def __init__(self) -> None:
        self.started, self.release = threading.Event(), threading.Event()


class GatedTraining:
    """Stands in for :func:`app.services.training.train_pattern_set`: call ``i`` reports progress 0.5 with the
    stage "held by the test", sets ``gates[i].started``, waits for ``gates[i].release``, then trains and stores
    for real."""

    def __init__(self, real: Callable[..., Any], gates: int) -> None:
        self.real, self.gates, self.calls = real, [Gate() for _ in range(gates)], 0

    def __call__(
        self,
        spec: Any,
        store: Any,
        *,
        set_id: str | None = None,
        progress: Any = None,
        cluster: Any = None,
        **more: Any,
    ) -> Any:
        gate = self.gates[self.calls]
        self.calls += 1
        progress(0.5, "held by the test")
        gate.started.set()
        if not gate.release.wait(TIMEOUT):
            raise TimeoutError("the test never released the training")
        return self.real(spec, store, set_id=set_id, progress=progress, cluster=cluster, **more)

    def release_all(self) -> None:
        for gate in self.gates:
            gate.release.set()


class InProcessServer:
    """``app`` served by uvicorn in a thread of the test process; ``start`` waits until it listens."""

    def __init__(self, app: FastAPI) -> None:
        self.app, self.port = app, free_port()
        self.base_url = f"http://127.0.0.1:{self.port}"
        self.server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=self.port, log_level="warning"))
        self.thread = threading.Thread(target=self.server.run, name="test-uvicorn")

    def start(self) -> InProcessServer:
        self.thread.start()
        deadline = time.monotonic() + TIMEOUT
        while not self.server.started:  # readiness: a bounded poll
            if not self.thread.is_alive() or time.monotonic() > deadline:
                raise RuntimeError("the in-process server did not start")
            time.sleep(0.01)
        return self

    def request_stop(self) -> None:
        """Ask the server to shut down (what SIGINT does to ``backlash serve``); :meth:`join` waits for it."""
        self.server.should_exit = True

    def join(self, timeout: float = TIMEOUT) -> None:
        self.thread.join(timeout)
        if self.thread.is_alive():
            raise RuntimeError(f"the in-process server did not stop within {timeout} s")

    def client(self) -> httpx.Client:
        return httpx.Client(base_url=self.base_url, timeout=TIMEOUT)


@contextmanager
def gated_in_process(app: FastAPI, gated: GatedTraining) -> Iterator[InProcessServer]:
    """``app`` served in a thread of this process while the block runs; on leaving, the gated trainings are
    released and the server stopped."""
    server = InProcessServer(app).start()
    try:
        yield server
    finally:
        gated.release_all()
        server.request_stop()
        server.join()
