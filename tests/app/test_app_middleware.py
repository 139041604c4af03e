"""The API key and the body-size limit (app/api/middleware.py)."""

from __future__ import annotations

from collections.abc import Iterator

import httpx
import pytest
from servicekit import Server, make_factory

KEY = "s3cret-test-key"


@pytest.fixture(scope="module")
def keyed_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    servers: list[Server] = []
    yield make_factory(tmp_path_factory.mktemp("keyed"), servers)(api_key=KEY, max_body_bytes="100000")
    for s in servers:
        s.stop()


@pytest.mark.parametrize(
    ("method", "path"),
    [
        ("GET", "/v1/pattern-sets"),
        ("POST", "/v1/simulate"),
        ("GET", "/v1/jobs/x"),
        ("POST", "/v1/identify"),
        ("GET", "/docs"),
        ("GET", "/openapi.json"),
    ],
)
def test_api_key_is_required_everywhere_but_healthz(keyed_server: Server, method: str, path: str) -> None:
    with keyed_server.client() as c:
        r = c.request(method, path, json={"K": 0.005})
        assert r.status_code == 401
        assert "missing API key" in r.json()["detail"] and "X-API-Key" in r.json()["detail"]
        r = c.request(method, path, json={"K": 0.005}, headers={"X-API-Key": "wrong-key-123"})
        assert r.status_code == 401 and "wrong API key" in r.json()["detail"]


def test_healthz_needs_no_key_and_the_key_opens_everything(keyed_server: Server) -> None:
    with keyed_server.client() as c:
        assert c.get("/healthz").status_code == 200
    with keyed_server.client(headers={"X-API-Key": KEY}) as c:
        assert c.get("/v1/pattern-sets").status_code == 200
        assert c.get("/docs").status_code == 200
        doc = c.get("/openapi.json").json()
        assert doc["components"]["securitySchemes"]["APIKeyHeader"] == {
            "type": "apiKey",
            "in": "header",
            "name": "X-API-Key",
        }
        r = c.post("/v1/simulate", json={"K": 0.005})
        assert r.status_code == 200 and r.json()["event_time"] > 0


def test_without_a_key_setting_no_key_is_needed(client: httpx.Client) -> None:
    assert client.get("/v1/pattern-sets").status_code == 200


def test_oversize_body_with_content_length_is_413(keyed_server: Server) -> None:
    with keyed_server.client(headers={"X-API-Key": KEY}) as c:
        r = c.post("/v1/simulate", content=b"x" * 200_000, headers={"Content-Type": "application/json"})
        assert r.status_code == 413
        assert "the limit is 100000 bytes (BACKLASH_MAX_BODY_BYTES)" in r.json()["detail"]
        assert c.get("/healthz").status_code == 200


def test_oversize_chunked_body_is_413(keyed_server: Server) -> None:
    def chunks() -> Iterator[bytes]:
        for _ in range(20):
            yield b" " * 10_000

    with keyed_server.client(headers={"X-API-Key": KEY}) as c:
        for path, ctype in (("/v1/simulate", "application/json"), ("/v1/identify", "text/csv")):
            r = c.post(path, content=chunks(), headers={"Content-Type": ctype}, params={"channel": "v2"})
            assert r.status_code == 413, (path, r.text)
            assert "more than 100000 bytes" in r.json()["detail"]
        assert c.get("/healthz").status_code == 200


def test_default_limit_refuses_a_large_body(client: httpx.Client) -> None:
    r = client.post("/v1/identify", content=b"0" * (33 << 20), headers={"Content-Type": "text/csv"})
    assert r.status_code == 413 and "33554432 bytes" in r.json()["detail"]
