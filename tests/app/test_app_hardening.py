"""Service hardening (issue 51), over HTTP against real servers (uvicorn on a loopback port).

Each test names the item of the issue it checks: large bodies parsed off the event loop (1), a refused
submission stores nothing (3), one cap on samples per
record stated in the schema (2), deep JSON and an empty trend answered with a 4xx (6), abandoned synchronous
diagnoses give their slots back (7), one service per database file, whatever its path (9), leaks and exposure
(10), the schema's contract (11).
"""

from __future__ import annotations

import json
import re
import socket
import sqlite3
import subprocess
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import pytest
from servicekit import (
    SMALL_TRAINING,
    TIMEOUT,
    GatedTraining,
    InProcessServer,
    Server,
    ServerFactory,
    clean_env,
    free_port,
    serve_command,
    wait_for_job,
    wait_until,
)
from test_app_diagnoses import EFFECTS, record_in

from app.core.config import Settings
from app.core.instance import hold_database
from app.main import create_app
from app.schemas.common import PLANT_RANGES
from app.services import training
from app.services.simulation import SIMULATED_EFFECTS, make_case, prepare
from engine.constants import CHANNELS, MAX_SAMPLE_INTERVAL, MIN_SAMPLE_INTERVAL
from engine.records.limits import MAX_SAMPLES
from engine.simulation import ParameterError
from engine.storage import PatternStoreError
from engine.storage.schema import APPLICATION_ID, MIGRATIONS

JSON = {"Content-Type": "application/json"}
KEY = "s3cret-test-key"
#: Size of the large bodies [bytes] (the issue's "20 MB record").
LARGE_BODY = 20_000_000
#: Longest ``GET /healthz`` may take while a large body is parsed [s].
HEALTHZ_BUDGET = 1.0


@contextmanager
def healthz_latencies(base_url: str, interval: float = 0.02) -> Iterator[list[float]]:
    """Poll ``GET /healthz`` from a thread of its own while the block runs; the list holds every latency [s]."""
    latencies: list[float] = []
    stop = threading.Event()

    def poll() -> None:
        with httpx.Client(base_url=base_url, timeout=60) as c:
            while not stop.is_set():
                started = time.monotonic()
                assert c.get("/healthz").status_code == 200
                latencies.append(time.monotonic() - started)
                stop.wait(interval)

    thread = threading.Thread(target=poll, name="healthz-probe")
    thread.start()
    wait_until(lambda: latencies, what="the first GET /healthz")
    try:
        yield latencies
    finally:
        stop.set()
        thread.join(60)


def large_csv() -> bytes:
    """A CSV record of about :data:`LARGE_BODY` bytes: every channel, short numbers (many cells per byte)."""
    row = ",".join("0.1" for _ in CHANNELS) + "\n"
    return (",".join(CHANNELS) + "\n" + row * (LARGE_BODY // len(row))).encode()


def large_json_record() -> dict[str, object]:
    """A JSON record of about :data:`LARGE_BODY` bytes whose event index lies past its end (refused once read)."""
    n = LARGE_BODY // (5 * len(CHANNELS))  # "0.1, " per sample
    return {"channels": {c: [0.1] * n for c in CHANNELS}, "event_index": n + 10}


# -- 1. large bodies are parsed off the event loop ------------------------------------------------------


@pytest.mark.serial  # the health check's latency budget: run alone, after the parallel run
def test_large_bodies_do_not_hold_other_requests(start_server: ServerFactory) -> None:
    """Issue 51, item 1: while a ~20 MB body (CSV or JSON) is read, parsed and refused by every route that takes
    one, ``GET /healthz`` keeps answering within a second."""
    server = start_server()
    csv_body = large_csv()
    json_record = large_json_record()
    requests: list[tuple[str, dict[str, object]]] = [
        ("/v1/identify", {"content": csv_body, "headers": {"Content-Type": "text/csv"}, "params": {"channel": "v2"}}),
        ("/v1/diagnose", {"content": csv_body, "headers": {"Content-Type": "text/csv"}}),
        ("/v1/diagnoses", {"content": csv_body, "headers": {"Content-Type": "text/csv"}}),
        ("/v1/identify", {"content": json.dumps({"record": json_record, "channel": "v2"}), "headers": JSON}),
        ("/v1/diagnose", {"content": json.dumps({"record": json_record}), "headers": JSON}),
        ("/v1/diagnoses", {"content": json.dumps({"record": json_record}), "headers": JSON}),
        (
            "/v1/simulate/batch",
            {"content": json.dumps({"cases": [{"K": 0.005}] * (LARGE_BODY // 14)}), "headers": JSON},
        ),
    ]
    with server.client() as c:
        for path, send in requests:
            with healthz_latencies(server.base_url) as latencies:
                r = c.post(path, **send)  # type: ignore[arg-type]
            assert r.status_code in (400, 404, 413, 422), (path, r.status_code, r.text[:300])
            assert max(latencies) < HEALTHZ_BUDGET, (path, f"GET /healthz took {max(latencies):.2f} s")
        assert c.get("/v1/records").json()["items"] == []  # nothing refused was stored


@pytest.mark.serial  # the health check's latency budget: run alone, after the parallel run
def test_healthz_does_not_wait_for_the_threads_that_compute(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 51's load limit (``GET /healthz`` p99 under 1 s with 20 busy clients): the requests that compute
    share ``BACKLASH_REQUEST_THREADS`` threads, and ``/healthz`` (which reads the store) never waits for one.
    With both of two threads held by simulations, ``/healthz`` answers at once while a ``GET /v1/records``
    waits for a thread, and is answered once one is free."""
    from app.api.routes import simulate as simulate_route

    release = threading.Event()
    entered = threading.Semaphore(0)
    real = simulate_route._simulate

    def held(*args: Any, **kwargs: Any) -> Any:
        entered.release()
        release.wait(TIMEOUT)
        return real(*args, **kwargs)

    monkeypatch.setattr(simulate_route, "_simulate", held)
    settings = Settings(db_path=tmp_path / "p.sqlite3", request_threads=2, log_level="WARNING")
    server = InProcessServer(create_app(settings)).start()
    answers: dict[str, int] = {}

    def post(name: str) -> None:
        with server.client() as c:
            answers[name] = c.post("/v1/simulate", json={"K": 0.005}).status_code

    def get_records() -> None:
        with server.client() as c:
            answers["records"] = c.get("/v1/records").status_code

    try:
        workers = [threading.Thread(target=post, args=(f"simulate {i}",)) for i in range(2)]
        for w in workers:
            w.start()
        for _ in workers:  # both threads are held
            assert entered.acquire(timeout=TIMEOUT)
        waiting = threading.Thread(target=get_records)
        waiting.start()
        with server.client() as c:
            for _ in range(5):
                started = time.monotonic()
                assert c.get("/healthz").status_code == 200
                assert time.monotonic() - started < HEALTHZ_BUDGET
        waiting.join(0.5)
        assert waiting.is_alive() and "records" not in answers  # it waits for a thread
        release.set()
        for t in (*workers, waiting):
            t.join(TIMEOUT)
        assert answers == {"simulate 0": 200, "simulate 1": 200, "records": 200}
    finally:
        release.set()
        server.request_stop()
        server.join()


# -- 2. one cap on samples per record, stated in the schema ----------------------------------------------


def test_the_schema_caps_every_series_at_the_engines_limit(client: httpx.Client) -> None:
    """Issue 51, item 2: every series of every record format states ``maxItems`` = the engine's ``MAX_SAMPLES``
    (the drive's channels and time column, EMPS's signals, BRFD's rows), and a record one sample over it is
    refused with a 422 that names the limit, before any record is built."""
    schemas = client.get("/openapi.json").json()["components"]["schemas"]

    def array(schema: dict[str, Any]) -> dict[str, Any]:  # the array of a series that may be null
        return next(s for s in schema.get("anyOf", [schema]) if s.get("type") == "array")

    record = schemas["RecordIn"]["properties"]
    assert record["channels"]["additionalProperties"]["maxItems"] == MAX_SAMPLES
    assert array(record["t"])["maxItems"] == MAX_SAMPLES
    emps = schemas["EmpsRecordIn"]["properties"]
    for name in ("t", "qm", "qg", "vir", "pulses_N"):
        assert array(emps[name])["maxItems"] == MAX_SAMPLES, name
    assert schemas["BrfdRecordIn"]["properties"]["data"]["maxItems"] == MAX_SAMPLES

    r = client.post("/v1/diagnose", json={"record": {"channels": {"a1": [0] * (MAX_SAMPLES + 1)}}})
    assert r.status_code == 422, (r.status_code, r.text[:300])
    assert str(MAX_SAMPLES) in r.json()["detail"], r.text[:300]


# -- 3. a refused submission stores nothing ----------------------------------------------------------


def test_a_submission_refused_for_a_full_queue_stores_nothing(tmp_path: Path, gated: GatedTraining) -> None:
    """Issue 51, item 3: with the queue full (one job allowed, a training held running), ``POST /v1/diagnoses``
    (JSON and CSV) and ``POST /v1/records/{id}/diagnoses`` answer 429 and store no record, diagnosis or job."""
    settings = Settings(db_path=tmp_path / "full.sqlite3", workers=1, training_runs_in="thread", max_pending_jobs=1)
    server = InProcessServer(create_app(settings)).start()
    try:
        with server.client() as c:
            sim = c.post("/v1/simulate", json={"K": 0.005})
            assert sim.status_code == 200, sim.text
            record = {k: sim.json()[k] for k in ("sample_interval", "event_index", "channels", "conditions")}
            first = c.post("/v1/diagnoses", json={"record": record})
            assert first.status_code == 202, first.text
            c.delete(first.json()["job_url"])  # cancelled (or done): its record and diagnosis stay
            wait_until(lambda: c.get(first.json()["job_url"]).json()["state"] in ("cancelled", "done"))
            training = c.post("/v1/pattern-sets", json=SMALL_TRAINING)
            assert training.status_code == 202, training.text
            assert gated.gates[0].started.wait(TIMEOUT)  # the only slot is taken
            stored = {path: c.get(path).json()["items"] for path in ("/v1/records", "/v1/diagnoses", "/v1/jobs")}
            csv_text = "\n".join(
                [
                    ",".join(record["channels"]),
                    *(",".join(map(repr, row)) for row in zip(*record["channels"].values(), strict=True)),
                ]
            )
            refused = [
                c.post("/v1/diagnoses", json={"record": record}),
                c.post(
                    "/v1/diagnoses",
                    content=csv_text,
                    headers={"Content-Type": "text/csv"},
                    params={"sample_interval": record["sample_interval"], "event_index": record["event_index"]},
                ),
                c.post(f"/v1/records/{first.json()['record_id']}/diagnoses"),
            ]
            for r in refused:
                assert r.status_code == 429, r.text
                assert "jobs are queued or running" in r.json()["detail"] and int(r.headers["retry-after"]) > 0
            for path, items in stored.items():
                assert c.get(path).json()["items"] == items, path
    finally:
        gated.release_all()
        server.request_stop()
        server.join()


# -- 6. answers, not 500s: deep JSON, a trend figure with nothing to draw -------------------------------

#: Every operation that reads a JSON body.
JSON_BODY_PATHS = [
    "/v1/simulate",
    "/v1/simulate/batch",
    "/v1/pattern-sets",
    "/v1/identify",
    "/v1/diagnose",
    "/v1/diagnoses",
]


@pytest.mark.parametrize("depth", [1000, 100_000])
def test_deeply_nested_json_is_refused_with_a_message(client: httpx.Client, depth: int) -> None:
    """Issue 51, item 6: JSON nested 1000 deep (was 500) or 100 000 deep (was a reset connection) gets a 400 that
    says so, on every operation with a JSON body, as an array or inside an object; the server stays up."""
    nested = "[" * depth + "]" * depth
    for path in JSON_BODY_PATHS:
        for body in (nested, '{"record": ' + nested + "}", '{"plant": "brfd", "record": ' + nested + "}"):
            r = client.post(path, content=body, headers=JSON)
            assert r.status_code == 400, (path, r.status_code, r.text[:300])
            assert "nested too deeply" in r.json()["detail"], (path, r.text[:300])
    assert client.get("/healthz").status_code == 200


def test_the_trend_figure_of_an_asset_without_identified_widths_is_a_404_with_a_message(
    client: httpx.Client, sim_record: dict[str, Any]
) -> None:
    """Issue 51, item 6: an asset whose history holds only diagnoses has no width to draw: 404 saying why and what
    to do (was 500), with or without a limit."""
    record = {k: sim_record[k] for k in ("sample_interval", "event_index", "channels", "conditions")}
    accepted = client.post(
        "/v1/diagnoses", json={"record": {**record, "asset": "diagnosed-only", "measured_at": "2026-11-20T08:00:00Z"}}
    )
    assert accepted.status_code == 202, accepted.text
    client.delete(accepted.json()["job_url"])  # the diagnosis stays in the history, without a result
    assert client.get("/v1/assets/diagnosed-only/history").status_code == 200
    for params in ({}, {"limit": 0.009}):
        r = client.get("/v1/assets/diagnosed-only/trend/figure", params=params)
        assert r.status_code == 404, r.text
        assert "no identified width to draw" in r.json()["detail"] and "POST /v1/identify" in r.json()["detail"]
    assert client.get("/v1/assets/nobody/trend/figure").status_code == 404  # unknown asset: 404 as before


# -- 7. an abandoned synchronous diagnosis gives its slot back ------------------------------------------


def post_then_hang_up(port: int, body: dict[str, Any]) -> socket.socket:
    """Send ``POST /v1/diagnose`` with ``body`` on a raw connection and return it, unread (close it to hang up)."""
    data = json.dumps(body).encode()
    conn = socket.create_connection(("127.0.0.1", port))
    head = (
        f"POST /v1/diagnose HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\n"
        f"Content-Length: {len(data)}\r\n\r\n"
    )
    conn.sendall(head.encode() + data)
    return conn


@pytest.mark.serial  # slots freed within 5 s: run alone, after the parallel run
def test_abandoned_synchronous_diagnoses_give_their_slots_back(tmp_path: Path, client: httpx.Client) -> None:
    """Issue 51, item 7: two clients start synchronous diagnoses (the whole catalogue: long) and hang up; their
    slots are free within seconds (not at the 120 s limit), and a third client's diagnosis is run, not refused."""
    record = record_in(client)
    settings = Settings(db_path=tmp_path / "sync.sqlite3", max_sync_diagnoses=2, sync_diagnose_timeout=120.0)
    server = InProcessServer(create_app(settings)).start()
    try:
        sync = server.app.state.sync_diagnoses
        abandoned = [post_then_hang_up(server.port, {"record": record}) for _ in range(2)]
        wait_until(lambda: sync.running == 2, what="both diagnoses to run")
        time.sleep(1.0)  # well into their work
        for conn in abandoned:
            conn.close()
        hung_up = time.monotonic()
        wait_until(lambda: sync.running == 0, timeout=5.0, what="the abandoned diagnoses to free their slots")
        assert time.monotonic() - hung_up < 5.0
        with server.client() as c:
            c.timeout = httpx.Timeout(120.0)
            r = c.post("/v1/diagnose", json={"record": record, "effects": EFFECTS})
        assert r.status_code == 200, r.text
        assert r.json()["verdict"]
    finally:
        server.request_stop()
        server.join(timeout=60)


# -- 9. one service per database file, whatever its name ------------------------------------------------


def start_on(db: Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``backlash serve`` on the database ``db``, run until it exits (a refused start exits at once)."""
    return subprocess.run(
        serve_command(free_port()),
        env=clean_env(BACKLASH_DB_PATH=str(db)),
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.mark.slow  # 24 s: three service starts and a training
def test_a_second_service_on_a_hard_link_of_the_database_is_refused(
    start_server: ServerFactory, tmp_path: Path
) -> None:
    """Issue 51, item 9: the service lock belongs to the file, not its path: a second service started on a hard
    link (or a symbolic link) of a running service's database exits with a message naming the file; the first
    one's jobs are untouched."""
    db = tmp_path / "first" / "patterns.sqlite3"
    first = start_server(db_path=db)
    with first.client() as c:
        accepted = c.post("/v1/pattern-sets", json=SMALL_TRAINING).json()
    links = tmp_path / "elsewhere"
    links.mkdir()
    (links / "hard.sqlite3").hardlink_to(db)
    (links / "soft.sqlite3").symlink_to(db)
    for other in (links / "hard.sqlite3", links / "soft.sqlite3"):
        proc = start_on(other, tmp_path)
        assert proc.returncode == 2, proc.stderr
        assert "another backlash service" in proc.stderr and str(other) in proc.stderr, proc.stderr
    with first.client() as c:  # the refused starts interrupted nothing
        assert wait_for_job(c, accepted["job_id"])["state"] == "done"


def test_the_lock_is_taken_before_the_store_is_opened(tmp_path: Path) -> None:
    """Issue 51, item 9: a start refused because another service holds the file leaves the file as it was: an
    older schema is not migrated under the running service (the lock comes before any migration)."""
    db = tmp_path / "old-schema.sqlite3"
    with sqlite3.connect(db) as conn:  # a pattern store of schema version 1 (the first migration only)
        MIGRATIONS[0](conn)
        conn.execute("PRAGMA user_version = 1")
        conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
    conn.close()
    before = db.read_bytes()
    with hold_database(db):  # as a running service holds it
        proc = start_on(db, tmp_path)
        assert proc.returncode == 2, proc.stderr
        assert "another backlash service" in proc.stderr, proc.stderr
        assert db.read_bytes() == before  # neither migrated nor switched to WAL
        assert not Path(f"{db}-wal").exists()
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == 1
    conn.close()


# -- 10. leaks and exposure -----------------------------------------------------------------------------


def test_a_job_error_does_not_show_where_the_database_is(
    tmp_path: Path, gated: GatedTraining, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 51, item 10: a job that fails on its store reads "the service's database", not its absolute path."""
    db = tmp_path / "secret-folder" / "patterns.sqlite3"

    def failing_training(spec: Any, store: Any, **kwargs: Any) -> Any:
        raise PatternStoreError(f"pattern store {store.path} is unreadable: disk I/O error (in {store.path.parent})")

    monkeypatch.setattr(training, "train_pattern_set", failing_training)
    server = InProcessServer(create_app(Settings(db_path=db, workers=1, training_runs_in="thread"))).start()
    try:
        with server.client() as c:
            accepted = c.post("/v1/pattern-sets", json=SMALL_TRAINING).json()
            job = wait_for_job(c, accepted["job_id"])
            missing = c.get(accepted["pattern_set_url"]).json()["detail"]  # names the failed job and its error
    finally:
        server.request_stop()
        server.join()
    assert job["state"] == "failed", job
    for text in (job["error"], missing):
        assert "secret-folder" not in text and str(tmp_path) not in text, text
        assert "the service's database is unreadable: disk I/O error" in text, text


def test_healthz_says_only_ok_to_a_caller_without_the_key(start_server: ServerFactory, client: httpx.Client) -> None:
    """Issue 51, item 10: with an API key set, /healthz answers {"status": "ok"} alone without the key (or with a
    wrong one), and the versions and counts with it; without a key set, everyone gets them."""
    keyed = start_server(api_key=KEY)
    with keyed.client() as c:
        assert c.get("/healthz").json() == {"status": "ok"}
        assert c.get("/healthz", headers={"X-API-Key": "wrong-key-123"}).json() == {"status": "ok"}
        full = c.get("/healthz", headers={"X-API-Key": KEY}).json()
    assert full["status"] == "ok" and {"version", "model_version", "pattern_sets"} <= set(full)
    assert {"version", "model_version", "pattern_sets"} <= set(client.get("/healthz").json())


def test_an_unknown_parameter_message_names_a_few(server: Server, client: httpx.Client) -> None:
    """Issue 51, item 10: 10 000 unknown identifier parameters get a short 422 naming five of them and how many
    more, and the log line is as short (was 150 KB in the answer and the log)."""
    names = [f"param_{i:05d}" for i in range(10_000)]
    r = client.post("/v1/pattern-sets", json={"channel": "v2", "c": 1.0, "params": dict.fromkeys(names, 1.0)})
    assert r.status_code == 422, r.text[:300]
    assert len(r.content) < 2000, len(r.content)
    detail = r.json()["detail"]
    assert "'param_00000'" in detail and "and 9995 more" in detail and "param_09999" not in detail, detail
    wait_until(lambda: "and 9995 more" in server.log_path.read_text(errors="replace"), what="the log line")
    assert "param_09999" not in server.log_path.read_text(errors="replace")


@pytest.mark.serial  # a 2 s read timeout measured: run alone, after the parallel run
def test_slow_clients_are_timed_out(start_server: ServerFactory) -> None:
    """Issue 51, item 10: with BACKLASH_READ_TIMEOUT=2, a connection that sends nothing is closed, one that sends
    part of a request head gets 408 and is closed, and one whose body stalls gets 408 and is closed, each within
    a few seconds (uvicorn alone keeps all three open for ever)."""
    server = start_server(read_timeout="2")
    head = "POST /v1/simulate HTTP/1.1\r\nHost: 127.0.0.1\r\n"
    for sent, expected in (
        ("", b""),
        (head, b"HTTP/1.1 408 "),
        (head + "Content-Type: application/json\r\nContent-Length: 100\r\n\r\n" + '{"K": ', b"HTTP/1.1 408 "),
    ):
        conn = socket.create_connection(("127.0.0.1", server.port))
        conn.sendall(sent.encode())
        started = time.monotonic()
        answer = read_until_closed(conn, limit=15.0)
        assert time.monotonic() - started < 10.0, (sent, "the connection stayed open")
        assert answer.startswith(expected), (sent, answer[:200])
    with server.client() as c:  # ordinary requests are not affected
        assert c.post("/v1/simulate", json={"K": 0.005}).status_code == 200


def read_until_closed(conn: socket.socket, limit: float) -> bytes:
    """Everything ``conn`` receives until the server closes it (or ``limit`` [s] passes: then what came)."""
    conn.settimeout(limit)
    received = b""
    try:
        while chunk := conn.recv(65536):
            received += chunk
    except TimeoutError:
        pass
    finally:
        conn.close()
    return received


def test_the_service_refuses_to_serve_a_network_without_a_key(start_server: ServerFactory, tmp_path: Path) -> None:
    """Issue 51, item 10: ``backlash serve --host 0.0.0.0`` without an API key exits with a message saying what to
    set; with BACKLASH_ALLOW_NO_KEY=1 it serves (with a key on 0.0.0.0: the image's command, tests/app/test_app_docker.py)."""
    port = free_port()
    command = [*serve_command(port)]
    command[command.index("--host") + 1] = "0.0.0.0"
    proc = subprocess.run(
        command,
        env=clean_env(BACKLASH_DB_PATH=str(tmp_path / "open.sqlite3")),
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    assert "without an API key" in proc.stderr and "BACKLASH_ALLOW_NO_KEY=1" in proc.stderr, proc.stderr
    server = start_server(command=command, port=port, allow_no_key="1")
    with server.client() as c:
        assert c.get("/healthz").status_code == 200
    assert server.stop() == 0


def test_the_docs_load_nothing_from_outside(client: httpx.Client) -> None:
    """Issue 51, item 10: /docs and /redoc reference only the service's own URLs, and the service serves them
    (Swagger UI's script and style sheet, ReDoc's script): the pages work offline."""
    for page, assets in (("/docs", ("swagger-ui-bundle.js", "swagger-ui.css")), ("/redoc", ("redoc.standalone.js",))):
        r = client.get(page)
        assert r.status_code == 200, page
        urls = re.findall(r"""(?:src|href)=["']([^"']+)["']""", r.text)
        assert urls and all(u.startswith("/") and not u.startswith("//") for u in urls), (page, urls)
        assert "http://" not in r.text and "https://" not in r.text, page
        for name in assets:
            assert any(u.endswith(name) for u in urls), (page, name)
        for url in urls:
            served = client.get(url)
            assert served.status_code == 200 and len(served.content) > 1000, url
    assert "SwaggerUIBundle" in client.get("/static/docs/swagger-ui-bundle.js").text


# -- 11. the schema's contract --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("method", "path", "allowed"),
    [
        ("POST", "/v1/jobs/x", {"GET", "HEAD", "DELETE"}),
        ("PUT", "/v1/pattern-sets/x", {"GET", "HEAD", "DELETE"}),
        ("PATCH", "/v1/diagnoses/x", {"GET", "HEAD", "DELETE"}),
        ("POST", "/v1/records/x", {"GET", "HEAD", "DELETE"}),
        ("PUT", "/v1/pattern-sets", {"GET", "HEAD", "POST"}),
        ("DELETE", "/v1/simulate", {"POST"}),
    ],
)
def test_a_405_names_every_method_of_the_path(client: httpx.Client, method: str, path: str, allowed: set[str]) -> None:
    """Issue 51, item 11: the Allow header of a 405 lists every method the path answers (DELETE was left out
    where another route of the path came first), and so does the message."""
    r = client.request(method, path)
    assert r.status_code == 405, r.text
    assert set(r.headers["allow"].split(", ")) == allowed, r.headers["allow"]
    assert r.json()["error"] == "MethodNotAllowed" and all(m in r.json()["detail"] for m in allowed)


def test_head_is_answered_wherever_get_is(client: httpx.Client) -> None:
    """Issue 51, item 11: HEAD / (the report page) and HEAD /healthz answer 200 with no body (was 405)."""
    for path in ("/", "/healthz", "/docs"):
        r = client.head(path)
        assert r.status_code == 200 and r.content == b"", path


@pytest.mark.parametrize(
    ("path", "body", "field"),
    [
        ("/v1/simulate", {"K": 0.005, "base_torque": False}, "base_torque"),
        ("/v1/simulate", {"K": 0.005, "time_column": 0}, "time_column"),
        ("/v1/simulate", {"K": "0.005"}, "K"),
        ("/v1/simulate", {"K": True}, "K"),
        ("/v1/simulate/batch", {"cases": [{"K": 0.005}], "include_event_index": "false"}, "include_event_index"),
        ("/v1/identify", {"record": {"channels": {"v2": ["0.1"] * 3000}}, "channel": "v2"}, "record.channels.v2.0"),
        ("/v1/identify", {"record": {"channels": {"v2": [0.1] * 3000}, "event_index": 48.0}, "channel": "v2"}, ""),
        ("/v1/identify", {"record": {"channels": {"v2": [0.1] * 3000}}, "channel": "v2", "continuous": 1}, ""),
        ("/v1/diagnose", {"record": {"channels": {"v2": [False] * 3000}}}, "record.channels.v2.0"),
        ("/v1/pattern-sets", {"channel": "v2", "c": "1.0"}, "c"),
        ("/v1/pattern-sets", {"channel": "v2", "c": 1.0, "max_epochs": 10.0}, "max_epochs"),
    ],
)
def test_numbers_and_booleans_are_strict(client: httpx.Client, path: str, body: dict[str, Any], field: str) -> None:
    """Issue 51, item 11: a boolean where a number belongs (``base_torque: false``), a number where a boolean
    belongs, a string for a number or a sample, a decimal for a count: 422 naming the field (they were read as
    0, false, 0.1, ...)."""
    r = client.post(path, json=body)
    assert r.status_code == 422, (path, body, r.status_code, r.text[:300])
    assert r.json()["error"] == "RequestValidationError", r.text[:300]
    assert field in r.json()["detail"], r.text[:300]


def test_the_schema_states_the_ranges_the_engine_checks(client: httpx.Client) -> None:
    """Issue 51, item 11: the schema states the accepted ranges (a case's K, J1, c, c1; sample intervals; the event
    index; each effect by name), they are the engine's, and a value outside its range stays refused when an
    effect would overwrite it."""
    schemas = client.get("/openapi.json").json()["components"]["schemas"]

    def number(schema: dict[str, Any]) -> dict[str, Any]:  # the schema of a number that may be null: its number's
        return next((s for s in schema.get("anyOf", [schema]) if s.get("type") in ("number", "integer")), schema)

    case = schemas["SimulateCase"]["properties"]
    for name, (lo, hi) in PLANT_RANGES.items():
        assert (number(case[name])["minimum"], number(case[name])["maximum"]) == (lo, hi), name
        for value, accepted in ((lo, True), (hi, True), (lo - 1e-6 * max(1.0, abs(lo)), False), (hi * 1.000001, False)):
            try:
                prepare([make_case(**{"K": 0.005, name: value})], [{}])
                ok = True
            except ParameterError:
                ok = False
            assert ok is accepted, (name, value)
    for model in ("SimulateCreate", "RecordIn"):
        interval = number(schemas[model]["properties"]["sample_interval"])
        assert (interval["minimum"], interval["maximum"]) == (MIN_SAMPLE_INTERVAL, MAX_SAMPLE_INTERVAL), model
    assert number(schemas["RecordIn"]["properties"]["event_index"])["minimum"] == 0
    effects = case["effects"]["properties"]
    assert set(effects) == set(SIMULATED_EFFECTS) and case["effects"]["additionalProperties"] is False
    for name, effect in SIMULATED_EFFECTS.items():
        assert (effects[name]["minimum"], effects[name]["maximum"]) == tuple(effect.bounds), name
    r = client.post("/v1/simulate", json={"K": 0.005, "c1": -1.0, "effects": {"absorber_discontinuity": 0.1}})
    assert r.status_code == 422 and "c1 = -1.0" in r.json()["detail"], r.text[:300]


def test_healthz_is_documented_without_the_key(start_server: ServerFactory) -> None:
    """Issue 51, item 11: with an API key, the schema requires it everywhere but on /healthz."""
    server = start_server(api_key=KEY)
    with server.client(headers={"X-API-Key": KEY}) as c:
        doc = c.get("/openapi.json").json()
    assert doc["security"] == [{"APIKeyHeader": []}]
    assert doc["paths"]["/healthz"]["get"]["security"] == []
    assert all(
        "security" not in op for path, item in doc["paths"].items() if path != "/healthz" for op in item.values()
    )
