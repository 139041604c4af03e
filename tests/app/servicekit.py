"""Helpers of the service tests: real uvicorn servers in subprocesses, talked to with httpx.

Every server runs ``python -m app.cli serve`` (the ``backlash serve`` command) on a
free local port with ``BACKLASH_DB_PATH`` in a temporary directory.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx

#: Small, fast training request of the paper's identifier (2 J1 values instead of 7); identifies K = 0.005 on v2.
SMALL_TRAINING = {"channel": "v2", "c": 1.0, "J1_values": [0.87, 0.8482], "kind": "paper", "max_epochs": 200}
#: A request whose simulation has no backlash event: the training job fails.
FAILING_TRAINING = {
    "channel": "v2",
    "c": 1.0,
    "J1_values": [0.87],
    "effects": {"contact_stiffness": 0.1, "contact_damping": 20.0},
}


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
        log = open(self.log_path, "ab")
        self.proc = subprocess.Popen(self.command, env=self.env, cwd=self.cwd, stdout=log, stderr=subprocess.STDOUT)
        log.close()
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
        if job["state"] in ("done", "failed"):
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
