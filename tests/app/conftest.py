"""Fixtures of the service tests (see servicekit.py): real uvicorn servers on free local ports."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from servicekit import Server, ServerFactory, make_factory, train


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
