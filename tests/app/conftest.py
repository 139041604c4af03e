"""Fixtures of the service tests (see servicekit.py): real uvicorn servers on free local ports."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from servicekit import GatedTraining, InProcessServer, Server, ServerFactory, gated_in_process, make_factory, train

from app.core.config import Settings
from app.main import create_app
from app.services import training


@pytest.fixture
def start_server(tmp_path: Path) -> Iterator[ServerFactory]:
    """Start servers (``start_server(db_path=..., api_key=...)``); they are stopped after the test."""
    servers: list[Server] = []
    yield make_factory(tmp_path, servers)
    for s in servers:
        s.stop()


@pytest.fixture(scope="session")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """The shared server of the session (one training worker, no API key)."""
    servers: list[Server] = []
    yield make_factory(tmp_path_factory.mktemp("server"), servers)()
    for s in servers:
        s.stop()


@pytest.fixture(scope="session")
def client(server: Server) -> Iterator[httpx.Client]:
    with server.client() as c:
        yield c


@pytest.fixture(scope="session")
def trained_set(client: httpx.Client) -> dict[str, Any]:
    """A small v2 pattern set at c = 1.0 stored in the shared server."""
    out = train(client)
    assert out["job"]["state"] == "done", out["job"]
    return out


@pytest.fixture(scope="session")
def sim_record(client: httpx.Client) -> dict[str, Any]:
    """A simulated record (K = 0.005 m, nominal J1, c) in the JSON record format."""
    r = client.post("/v1/simulate", json={"K": 0.005})
    assert r.status_code == 200, r.text
    return r.json()


@pytest.fixture
def gated(monkeypatch: pytest.MonkeyPatch) -> Iterator[GatedTraining]:
    """Training jobs of the in-process server wait at a gate the test opens (two calls)."""
    fake = GatedTraining(training.train_pattern_set, gates=2)
    monkeypatch.setattr(training, "train_pattern_set", fake)
    yield fake
    fake.release_all()  # never leave a job waiting


@pytest.fixture
def inprocess(tmp_path: Path, gated: GatedTraining) -> Iterator[InProcessServer]:
    """The application served in a thread of this process (one training worker), its training gated."""
    settings = Settings(db_path=tmp_path / "inprocess" / "patterns.sqlite3", workers=1, training_runs_in="thread")
    with gated_in_process(create_app(settings), gated) as server:  # training on a thread here: the gate holds it
        yield server


@pytest.hookimpl(trylast=True)  # after -m/-k have deselected
def pytest_collection_modifyitems(session: pytest.Session, config: pytest.Config, items: list[pytest.Item]) -> None:
    """Run the container's tests last: their image is built when they start, after the session's latency tests,
    which a build beside them (both cores) made fail."""
    boxed = [item for item in items if item.path.name == "test_container.py"]
    if boxed and not config.option.collectonly:
        items[:] = [item for item in items if item.path.name != "test_container.py"] + boxed


@pytest.fixture
def env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """No BACKLASH_* variables but the database path (of the CLI tests); returns the database path."""
    for k in list(os.environ):
        if k.startswith("BACKLASH_"):
            monkeypatch.delenv(k)
    db = tmp_path / "db" / "patterns.sqlite3"
    monkeypatch.setenv("BACKLASH_DB_PATH", str(db))
    return db
