"""Load benchmark of the HTTP service on the loopback interface (issue 12, "Contract and load"; issue 51).

    .venv/bin/python bench/bench_load.py [--clients 20] [--seconds 60] [--out out/bench-load.json]

Starts a real server (``python -m app.cli serve``, the ``backlash serve`` command) on a free loopback
port with a fresh database in a temporary directory, prepares what the mix needs (a pattern set, simulated
records), then runs ``--clients`` clients, each a thread with its own HTTP connection, for ``--seconds``:
every client repeats one operation after the other, drawn by the weights of ``--mix``:

* ``simulate``: ``POST /v1/simulate`` of one case (a width of the paper's grid);
* ``batch``: ``POST /v1/simulate/batch`` of two cases;
* ``identify``: ``POST /v1/identify`` of a simulated record (JSON) with the stored pattern set (one in four
  names an asset, so the identification is stored);
* ``diagnosis``: ``POST /v1/diagnoses`` of a simulated record (for an asset), or ``POST
  /v1/records/{id}/diagnoses`` of a stored one, then ``GET /v1/jobs/{id}`` every ``--poll`` seconds until the
  job has finished. At most ``--max-diagnoses`` diagnosis jobs are in flight at once (a client that draws one
  while they are takes another operation): a diagnosis keeps a core busy for seconds to tens of seconds, and
  clients blocked on it would otherwise stop loading the rest of the service. A server without ``POST
  /v1/diagnoses`` (it is not in ``/openapi.json``) gets the synchronous ``POST /v1/diagnose`` instead, and
  the report says so;
* ``cancel_retry``: a diagnosis submitted, cancelled (``POST /v1/jobs/{id}/cancel``), retried twice (``POST
  /v1/jobs/{id}/retry``: the second is answered with the first retry or a 409, never a second run) and the
  retry cancelled;
* ``delete``: ``DELETE /v1/diagnoses/{id}`` of a finished diagnosis of this load, or ``DELETE
  /v1/identifications/{id}`` of a stored identification;
* ``read``: one ``GET`` of every other route in turn (lists of records, diagnoses, jobs, pattern sets and
  assets; a record, its body, a diagnosis, its figure; an asset's history, trend and trend figure; the
  page, the API docs, the schema).

Among them, at instants spread over the load, the clients send ``--large-bodies`` bodies of about 20 MB
(a simulated record with its pre-event stretch lengthened, as a diagnosis job and as an identification, in
turn) and ``--abandoned`` synchronous diagnoses (``POST /v1/diagnose``) that they give up after
``--abandon-after`` seconds; half way, one ``POST /v1/maintenance/retention`` (it compacts the file under
load). After the load one more synchronous diagnosis must find a free slot (no 429).

When the time is up, no operation is started any more; the clients waiting for their diagnosis jobs keep
polling for at most ``--drain`` seconds. Then every job submitted is read once more: a job that is missing
(404) or has not finished is *lost*; so is a diagnosis whose ``GET /v1/diagnoses/{id}`` is missing (unless
the load deleted it).

Then a retention run (``backlash store prune`` on the server's database, with the server stopped, keeping
nothing older than a second: ``--retention``) and the database file's size before the load, after it and after the
retention run. The server's memory (resident set of its process and every child, sampled every 0.25 s) is
reported at its peak.

The report (stdout; progress goes to the log on stderr), per operation: count, throughput [1/s over the
load], latency p50/p90/p99 [ms], the answers by status, the 5xx; the diagnosis jobs' time from submission
to the end; the lost jobs. The baseline is measured in the same run: the latency of ``GET /healthz``
from a single client before the load, against the same request sent every ``--probe-interval`` seconds
during the load by an observer in a process of its own (``--probe``: not one more thread of this process,
whose GIL the 20 client threads keep busy); the report gives the ratio of the medians (and of the 90th percentiles) and
the p99 and maximum under load. The issue's limits (0 5xx, 0 lost jobs, ``/healthz`` p99 under 1 s) are
checked in the report's last line; ``--out`` writes the whole summary as JSON.

Speed is measured here, never timed in tests; this is a benchmark, not a test (it fails on nothing).
"""

from __future__ import annotations

import argparse
import itertools
import json
import logging
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import psutil

logger = logging.getLogger("bench_load")

#: Widths [m] of the simulated records and cases (the paper's grid).
WIDTHS = (0.0025, 0.00375, 0.005, 0.0075, 0.009, 0.01)
#: The pattern set the identifications use: the paper's grid (all J1 values) at c = 1 on v2, the default kind.
TRAINING = {"channel": "v2", "c": 1.0}
#: Job states after which a job changes no more.
FINISHED = ("done", "failed", "cancelled", "interrupted")
#: Seconds a single request may take before it counts as a transport error.
REQUEST_TIMEOUT = 300.0
#: Requests of the baseline ``GET /healthz`` before the load.
BASELINE_REQUESTS = 50
#: The repository (the server runs from here, as ``backlash serve`` from a checkout).
REPO = Path(__file__).resolve().parents[1]
#: Size of the large bodies [bytes] (issue 51's "20 MB record").
LARGE_BODY = 20_000_000
#: The issue's limit on ``GET /healthz`` under load: its 99th percentile [s].
HEALTHZ_P99_LIMIT = 1.0
#: Interval of the server's memory samples [s].
MEMORY_INTERVAL = 0.25
#: The retention run after the load: the CLI command (``backlash ...``) that deletes what is older than the cutoff
#: and compacts the file.
RETENTION_COMMAND = ("store", "prune", "--older-than-days", "0.00001")  # ~1 s: nothing of the load is kept
#: Every operation a client may draw (``--mix``).
OPERATIONS = ("simulate", "batch", "identify", "diagnosis", "cancel_retry", "delete", "read")


def free_port() -> int:
    """A free TCP port on the loopback interface."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def db_path(workdir: Path) -> Path:
    """The server's database in ``workdir``."""
    return workdir / "load.sqlite3"


def file_bytes(path: Path) -> int:
    """Bytes of a SQLite database on disk: the file and its write-ahead log, if any."""
    return sum(p.stat().st_size for p in (path, path.with_name(path.name + "-wal")) if p.exists())


class MemoryProbe:
    """The resident memory of a process and all its children, sampled every :data:`MEMORY_INTERVAL` seconds
    from a thread of its own (psutil); ``peak_total`` is the largest sum seen [bytes], ``peak_process`` the
    largest single process."""

    def __init__(self, pid: int) -> None:
        self.root = psutil.Process(pid)
        self.peak_total = 0
        self.peak_process = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="memory-probe", daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            total = 0
            try:
                procs = [self.root, *self.root.children(recursive=True)]
            except psutil.NoSuchProcess:
                return
            for proc in procs:
                try:
                    rss = proc.memory_info().rss
                except psutil.NoSuchProcess:  # a worker that ended between the listing and the reading
                    continue
                total += rss
                self.peak_process = max(self.peak_process, rss)
            self.peak_total = max(self.peak_total, total)
            self._stop.wait(MEMORY_INTERVAL)

    def __enter__(self) -> MemoryProbe:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(10)


@contextmanager
def serve(workdir: Path, settings: dict[str, str]) -> Iterator[tuple[str, int]]:
    """Run ``python -m app.cli serve`` on a free loopback port with its database in ``workdir``; yield its URL
    and process id.

    Parameters
    ----------
    workdir : Path
        Holds the database and the server's log (``server.log``).
    settings : dict of str to str
        Further ``BACKLASH_*`` environment variables of the server.
    """
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("BACKLASH_")}
    env.update({"BACKLASH_DB_PATH": str(db_path(workdir)), "BACKLASH_LOG_LEVEL": "WARNING", **settings})
    command = [sys.executable, "-m", "app.cli", "serve", "--host", "127.0.0.1", "--port", str(port)]
    base_url = f"http://127.0.0.1:{port}"
    log_path = workdir / "server.log"
    with open(log_path, "ab") as log:
        proc = subprocess.Popen(command, env=env, cwd=REPO, stdout=log, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 120
        while True:
            if proc.poll() is not None:
                raise RuntimeError(f"the server exited with {proc.returncode}; see {log_path}")
            try:
                if httpx.get(f"{base_url}/healthz", timeout=2).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"the server did not answer /healthz within 120 s; see {log_path}")
            time.sleep(0.1)
        logger.info("server %s (pid %d), log %s", base_url, proc.pid, log_path)
        yield base_url, proc.pid
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                logger.warning("the server did not stop within 60 s of SIGINT; killing it")
                proc.kill()
                proc.wait()


# -- what the clients record ------------------------------------------------------------------


def percentiles_ms(latencies: list[float], qs: tuple[float, ...]) -> list[float | None]:
    """The ``qs`` percentiles of ``latencies`` [s] in ms (None each when there are none)."""
    if not latencies:
        return [None for _ in qs]
    ms = np.asarray(latencies) * 1e3
    return [float(np.percentile(ms, q)) for q in qs]


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


@dataclass
class Samples:
    """Latencies [s] and statuses of one operation (status 0: a transport error, e.g. a timeout)."""

    latencies: list[float] = field(default_factory=list)
    statuses: Counter[int] = field(default_factory=Counter)

    def add(self, seconds: float, status: int) -> None:
        self.latencies.append(seconds)
        self.statuses[status] += 1

    def summary(self, seconds: float) -> dict[str, Any]:
        """Count, throughput over ``seconds``, latency percentiles [ms] (None without samples) and statuses."""
        p50, p90, p99 = percentiles_ms(self.latencies, (50, 90, 99))
        return {
            "count": len(self.latencies),
            "throughput_per_s": len(self.latencies) / seconds if seconds > 0 else 0.0,
            "p50_ms": p50,
            "p90_ms": p90,
            "p99_ms": p99,
            "statuses": {str(k): v for k, v in sorted(self.statuses.items())},
            "errors": {str(k): v for k, v in sorted(self.statuses.items()) if not 200 <= k < 300},
            "server_errors": sum(v for k, v in self.statuses.items() if k >= 500),
            "transport_errors": self.statuses.get(0, 0),
        }


@dataclass
class Submitted:
    """A diagnosis job the load submitted."""

    job_id: str
    diagnosis_id: str
    submitted_at: float
    finished_at: float | None = None
    state: str | None = None
    deleted: bool = False


class Recorder:
    """What every client records, by operation (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.ops: defaultdict[str, Samples] = defaultdict(Samples)
        self.jobs: list[Submitted] = []

    def add(self, op: str, seconds: float, status: int) -> None:
        with self._lock:
            self.ops[op].add(seconds, status)

    def submitted(self, job: Submitted) -> None:
        with self._lock:
            self.jobs.append(job)


def timed(client: httpx.Client, method: str, url: str, **kwargs: Any) -> tuple[float, httpx.Response | None]:
    """Send one request; its latency [s] and answer (None after a transport error, which is logged)."""
    t0 = time.perf_counter()
    try:
        response = client.request(method, url, **kwargs)
    except httpx.TransportError as exc:
        logger.warning("%s %s: %s: %s", method, url, type(exc).__name__, exc)
        return time.perf_counter() - t0, None
    return time.perf_counter() - t0, response


# -- the load ---------------------------------------------------------------------------------


@dataclass
class Fixture:
    """What the operations send: simulated records and the pattern set's id."""

    records: list[dict[str, Any]]
    pattern_set: str
    async_diagnoses: bool
    large_record: dict[str, Any] = field(default_factory=dict)


def large_record(record: dict[str, Any], size: int = LARGE_BODY) -> dict[str, Any]:
    """``record`` with its pre-event stretch lengthened (its first samples repeated) until its JSON is about
    ``size`` bytes: a valid record of the same event whose diagnosis reads the same test window."""
    first = [values[0] for values in record["channels"].values()]
    per_sample = sum(len(json.dumps(v)) + 2 for v in first)  # a repeated sample's bytes ("value, " per channel)
    extra = max(0, int((size - len(json.dumps(record))) / per_sample))
    channels = {name: [values[0]] * extra + list(values) for name, values in record["channels"].items()}
    return {**record, "channels": channels, "event_index": record["event_index"] + extra}


def prepare(client: httpx.Client) -> Fixture:
    """Train the pattern set, simulate one record per width and see whether diagnosis jobs exist."""
    r = client.post("/v1/pattern-sets", json=TRAINING)
    r.raise_for_status()
    accepted = r.json()
    deadline = time.monotonic() + 600
    while (job := client.get(f"/v1/jobs/{accepted['job_id']}").json())["state"] not in FINISHED:
        if time.monotonic() > deadline:
            raise RuntimeError(f"the training job did not finish within 600 s: {job}")
        time.sleep(0.2)
    if job["state"] != "done":
        raise RuntimeError(f"the training job ended {job['state']}: {job.get('error')}")
    records = []
    for K in WIDTHS:
        r = client.post("/v1/simulate", json={"K": K})
        r.raise_for_status()
        records.append({k: r.json()[k] for k in ("sample_interval", "event_index", "channels", "conditions")})
    paths = client.get("/openapi.json").json().get("paths", {})
    async_diagnoses = "post" in paths.get("/v1/diagnoses", {})
    if not async_diagnoses:
        logger.warning("the server has no POST /v1/diagnoses; the diagnoses are the synchronous POST /v1/diagnose")
    return Fixture(records, accepted["pattern_set_id"], async_diagnoses, large_record(records[-1]))


class Load:
    """The clients' loop and its operations."""

    def __init__(
        self,
        base_url: str,
        fixture: Fixture,
        mix: dict[str, float],
        max_diagnoses: int,
        poll: float,
        recorder: Recorder,
        abandon_after: float = 2.0,
    ) -> None:
        self.base_url, self.fixture, self.recorder, self.poll = base_url, fixture, recorder, poll
        self.mix = mix
        self.abandon_after = abandon_after
        self.diagnosis_slots = threading.BoundedSemaphore(max_diagnoses)
        self.stop_at = 0.0  # no operation starts after this (time.monotonic)
        self.drain_until = 0.0  # diagnosis jobs are polled until this at the latest
        self._lock = threading.Lock()
        self._specials: list[tuple[float, str]] = []  # (when, what): large bodies, abandoned diagnoses
        self.record_ids: list[str] = []  # records the load stored
        self.done: list[Submitted] = []  # diagnoses that finished done (read, then maybe deleted)
        self._read_turn = 0
        self.identifications: list[str] = []  # identifications the load stored
        self._large_sent = 0  # large bodies sent so far (they alternate: a diagnosis job, an identification)

    def schedule(self, start: float, seconds: float, large_bodies: int, abandoned: int) -> None:
        """Spread ``large_bodies`` 20 MB bodies and ``abandoned`` abandoned synchronous diagnoses over the load,
        alternating, with one retention run half way; each due at its own instant in the middle 80 % of
        ``seconds`` after ``start``."""
        pairs = itertools.zip_longest(["large"] * large_bodies, ["abandon"] * abandoned)
        kinds = [k for pair in pairs for k in pair if k is not None]  # the two kinds in turn
        kinds.insert(len(kinds) // 2, "retention")  # and one retention run, half way
        n = len(kinds)
        self._specials = [(start + seconds * (0.1 + 0.8 * (i + 0.5) / n), k) for i, k in enumerate(kinds)]

    def _due_special(self) -> str | None:
        with self._lock:
            if self._specials and self._specials[0][0] <= time.monotonic():
                return self._specials.pop(0)[1]
        return None

    def client(self) -> httpx.Client:
        return httpx.Client(base_url=self.base_url, timeout=REQUEST_TIMEOUT)

    def run_client(self, index: int) -> None:
        rng = random.Random(index)
        ops: dict[str, Callable[[httpx.Client, random.Random, int], None]] = {
            "simulate": self.simulate,
            "batch": self.batch,
            "identify": self.identify,
            "diagnosis": self.diagnosis,
            "cancel_retry": self.cancel_retry,
            "delete": self.delete,
            "read": self.read,
            "large": self.large,
            "abandon": self.abandon,
            "retention": self.retention,
        }
        slotted = ("diagnosis", "cancel_retry")  # operations that start a diagnosis job
        names = [n for n in OPERATIONS if self.mix.get(n, 0) > 0]
        weights = [self.mix[n] for n in names]
        with self.client() as client:
            while time.monotonic() < self.stop_at:
                name = self._due_special() or rng.choices(names, weights)[0]
                try:
                    if name in slotted:
                        if self.diagnosis_slots.acquire(blocking=False):
                            try:
                                ops[name](client, rng, index)
                            finally:
                                self.diagnosis_slots.release()
                            continue
                        others = [(n, w) for n, w in zip(names, weights, strict=True) if n not in slotted]
                        if not others:
                            time.sleep(self.poll)
                            continue
                        name = rng.choices([n for n, _ in others], [w for _, w in others])[0]
                    ops[name](client, rng, index)
                except Exception:  # an answer the client cannot read: logged, counted, the client goes on
                    logger.exception("client %d: %s failed", index, name)
                    self.recorder.add(f"{name} (unreadable answer)", 0.0, -1)

    def _record(self, op: str, seconds: float, response: httpx.Response | None) -> None:
        self.recorder.add(op, seconds, 0 if response is None else response.status_code)

    def simulate(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        seconds, r = timed(client, "POST", "/v1/simulate", json={"K": rng.choice(WIDTHS)})
        self._record("simulate", seconds, r)

    def batch(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        body = {"cases": [{"K": rng.choice(WIDTHS)}, {"K": rng.choice(WIDTHS), "J1": 0.8}]}
        seconds, r = timed(client, "POST", "/v1/simulate/batch", json=body)
        self._record("simulate batch", seconds, r)

    def identify(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        """An identification; one in four names an asset (it is then stored, and may be deleted later)."""
        record = rng.choice(self.fixture.records)
        stored = rng.random() < 0.25
        if stored:
            record = {**record, "asset": f"bench-{index}", "measured_at": f"2026-11-{rng.randint(1, 27):02d}T08:00:00Z"}
        body = {"record": record, "channel": "v2", "pattern_set": self.fixture.pattern_set}
        seconds, r = timed(client, "POST", "/v1/identify", json=body)
        self._record("identify (stored)" if stored else "identify", seconds, r)
        if r is not None and r.status_code == 200 and r.json().get("identification_id"):
            with self._lock:
                self.identifications.append(r.json()["identification_id"])

    def _submit(
        self, client: httpx.Client, rng: random.Random, index: int, op: str, stored_ok: bool = True
    ) -> Submitted | None:
        """Submit a diagnosis job: a new record, or (every third time, once the load has stored some, if
        ``stored_ok``) a stored record again; the job, tracked for the final check (None when it was not
        accepted)."""
        with self._lock:
            again = stored_ok and self.record_ids and rng.random() < 1 / 3
            stored = rng.choice(self.record_ids) if again else None
        submitted_at = time.monotonic()
        if stored is not None:
            seconds, r = timed(client, "POST", f"/v1/records/{stored}/diagnoses")
            self._record(f"{op} submit (stored record)", seconds, r)
        else:
            record = rng.choice(self.fixture.records)
            body = {"record": {**record, "asset": f"bench-{index}", "measured_at": "2026-11-20T08:00:00Z"}}
            seconds, r = timed(client, "POST", "/v1/diagnoses", json=body)
            self._record(f"{op} submit", seconds, r)
        if r is None or r.status_code != 202:
            return None
        job = Submitted(r.json()["job_id"], r.json()["diagnosis_id"], submitted_at)
        self.recorder.submitted(job)
        if stored is None:
            with self._lock:
                self.record_ids.append(r.json()["record_id"])
        return job

    def _wait(self, client: httpx.Client, job: Submitted, op: str) -> None:
        """Poll the job until it finishes (or the drain ends); a done diagnosis joins :attr:`done`."""
        while time.monotonic() < self.drain_until:
            time.sleep(self.poll)
            seconds, r = timed(client, "GET", f"/v1/jobs/{job.job_id}")
            self._record("job poll", seconds, r)
            if r is not None and r.status_code == 200 and r.json()["state"] in FINISHED:
                job.finished_at, job.state = time.monotonic(), r.json()["state"]
                self.recorder.add(f"{op} job (submit to end)", job.finished_at - job.submitted_at, 200)
                if job.state == "done":
                    with self._lock:
                        self.done.append(job)
                return

    def diagnosis(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        if not self.fixture.async_diagnoses:
            seconds, r = timed(client, "POST", "/v1/diagnose", json={"record": rng.choice(self.fixture.records)})
            self._record("diagnose (sync)", seconds, r)
            return
        job = self._submit(client, rng, index, "diagnosis")
        if job is not None:
            self._wait(client, job, "diagnosis")

    def cancel_retry(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        """Submit, cancel, retry twice (the second must not start a second run), cancel the retry."""
        if not self.fixture.async_diagnoses:
            return
        job = self._submit(client, rng, index, "cancel_retry", stored_ok=False)
        if job is None:
            return
        seconds, r = timed(client, "POST", f"/v1/jobs/{job.job_id}/cancel")
        self._record("job cancel", seconds, r)
        retries: set[str] = set()
        for _ in range(2):
            seconds, r = timed(client, "POST", f"/v1/jobs/{job.job_id}/retry")
            self._record("job retry", seconds, r)
            if r is not None and r.status_code in (200, 202):
                retries.add(r.json()["id"])
        if len(retries) > 1:
            self.recorder.add("retry ran twice (two live retries of one job)", 0.0, -1)
        for retry_id in retries:
            retry = Submitted(retry_id, job.diagnosis_id, time.monotonic())
            self.recorder.submitted(retry)
            seconds, r = timed(client, "POST", f"/v1/jobs/{retry_id}/cancel")
            self._record("job cancel", seconds, r)
            self._wait(client, retry, "cancel_retry")

    def delete(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        """Delete a diagnosis this load saw finish (it is then expected to be gone, not lost), or a stored
        identification, in turn."""
        with self._lock:
            identification = self.identifications.pop() if self.identifications and rng.random() < 0.5 else None
            job = None
            if identification is None and self.done:
                job = self.done.pop(rng.randrange(len(self.done)))
                job.deleted = True
        if identification is not None:
            seconds, r = timed(client, "DELETE", f"/v1/identifications/{identification}")
            self._record("identification delete", seconds, r)
        elif job is not None:
            seconds, r = timed(client, "DELETE", f"/v1/diagnoses/{job.diagnosis_id}")
            self._record("diagnosis delete", seconds, r)
        else:
            self.read(client, rng, index)

    def retention(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        """``POST /v1/maintenance/retention`` under load (the server's settings decide what it deletes; it
        compacts the file)."""
        seconds, r = timed(client, "POST", "/v1/maintenance/retention")
        self._record("retention run (under load)", seconds, r)

    def read(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        """One ``GET`` of the next read route in turn (one that needs an id it has not got is skipped)."""
        with self._lock:
            record = self.record_ids[-1] if self.record_ids else None
            done = self.done[-1].diagnosis_id if self.done else None
            turn = self._read_turn
            self._read_turn += 1
        asset = f"bench-{index}"
        routes: list[tuple[str, str | None]] = [
            ("GET /v1/records", "/v1/records"),
            ("GET /v1/diagnoses", "/v1/diagnoses"),
            ("GET /v1/jobs", "/v1/jobs"),
            ("GET /v1/pattern-sets", "/v1/pattern-sets"),
            ("GET /v1/pattern-sets/{id}", f"/v1/pattern-sets/{self.fixture.pattern_set}"),
            ("GET /v1/assets", "/v1/assets"),
            ("GET /v1/assets/{a}/history", f"/v1/assets/{asset}/history"),
            ("GET /v1/assets/{a}/trend", f"/v1/assets/{asset}/trend"),
            ("GET /v1/assets/{a}/trend/figure", f"/v1/assets/{asset}/trend/figure"),
            ("GET /v1/records/{id}", record and f"/v1/records/{record}"),
            ("GET /v1/records/{id}/body", record and f"/v1/records/{record}/body"),
            ("GET /v1/diagnoses/{id}", done and f"/v1/diagnoses/{done}"),
            ("GET /v1/diagnoses/{id}/figures/{f}", done and f"/v1/diagnoses/{done}"),
            ("GET / (page)", "/"),
            ("GET /docs", "/docs"),
            ("GET /openapi.json", "/openapi.json"),
        ]
        op, url = routes[turn % len(routes)]
        if url is None:
            return
        if op.endswith("figures/{f}"):  # the figure named by the diagnosis (it may have been deleted since)
            r0 = client.get(url)
            figures = r0.json().get("figures", []) if r0.status_code == 200 else []
            if not figures:
                return
            url = figures[0] if figures[0].startswith("/") else f"{url}/figures/{figures[0]}"
        seconds, r = timed(client, "GET", url)
        self._record(op, seconds, r)

    def large(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        """A 20 MB body: as a diagnosis job and as an identification, in turn."""
        with self._lock:
            as_job = self._large_sent % 2 == 0 and self.fixture.async_diagnoses
            self._large_sent += 1
        record = self.fixture.large_record
        if as_job:
            body: dict[str, Any] = {
                "record": {**record, "asset": f"bench-{index}", "measured_at": "2026-11-20T09:00:00Z"}
            }
            submitted_at = time.monotonic()
            seconds, r = timed(client, "POST", "/v1/diagnoses", json=body)
            self._record("20 MB diagnosis submit", seconds, r)
            if r is not None and r.status_code == 202:
                self.recorder.submitted(Submitted(r.json()["job_id"], r.json()["diagnosis_id"], submitted_at))
        else:
            body = {"record": record, "channel": "v2", "pattern_set": self.fixture.pattern_set}
            seconds, r = timed(client, "POST", "/v1/identify", json=body)
            self._record("20 MB identify", seconds, r)

    def abandon(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        """A synchronous diagnosis given up after :attr:`abandon_after` seconds (its own connection, closed)."""
        with httpx.Client(base_url=self.base_url, timeout=self.abandon_after) as own:
            seconds, r = timed(own, "POST", "/v1/diagnose", json={"record": rng.choice(self.fixture.records)})
        self._record("diagnose (sync, abandoned)", seconds, r)


def probe_healthz(client: httpx.Client, n: int | None, interval: float, until: float | None = None) -> list[float]:
    """Latencies [s] of ``GET /healthz``: ``n`` in a row, or one every ``interval`` seconds until ``until``."""
    out: list[float] = []
    while (n is not None and len(out) < n) or (until is not None and time.monotonic() < until):
        seconds, r = timed(client, "GET", "/healthz")
        if r is not None and r.status_code == 200:
            out.append(seconds)
        if n is None:
            time.sleep(interval)
    return out


@contextmanager
def healthz_probe(base_url: str, n: int | None, interval: float, seconds: float | None = None) -> Iterator[list[float]]:
    """:func:`probe_healthz` from a process of its own (this script with ``--probe``): the latencies of an
    observer that is not one of the load's threads (in this process they would also wait for this process's
    GIL, which 20 client threads keep busy). The list is filled when the block ends."""
    command = [sys.executable, __file__, "--probe", base_url, "--probe-interval", str(interval)]
    command += ["--probe-count", str(n)] if n is not None else ["--probe-for", str(seconds)]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    out: list[float] = []
    try:
        yield out
    finally:
        stdout, _ = proc.communicate(timeout=(seconds or 0) + 600)
        if proc.returncode != 0:
            raise RuntimeError(f"the /healthz probe exited with {proc.returncode}")
        out.extend(json.loads(stdout))


def final_check(client: httpx.Client, jobs: list[Submitted]) -> dict[str, Any]:
    """Read every submitted job (and its diagnosis) once more: the states, and the lost ones."""
    states: Counter[str] = Counter()
    lost: list[dict[str, Any]] = []
    deleted = {job.diagnosis_id for job in jobs if job.deleted}
    for job in jobs:
        if job.diagnosis_id in deleted:  # deleted by the load, with its jobs: expected gone
            d = client.get(f"/v1/diagnoses/{job.diagnosis_id}")
            states["deleted"] += 1
            if d.status_code != 404:
                lost.append({"job_id": job.job_id, "job": "deleted", "diagnosis_status": d.status_code})
            continue
        r = client.get(f"/v1/jobs/{job.job_id}")
        d = client.get(f"/v1/diagnoses/{job.diagnosis_id}")
        state = r.json()["state"] if r.status_code == 200 else f"missing ({r.status_code})"
        states[state] += 1
        if r.status_code != 200 or state not in FINISHED or d.status_code != 200:
            lost.append({"job_id": job.job_id, "job": state, "diagnosis_status": d.status_code})
    return {"submitted": len(jobs), "final_states": dict(states), "lost": len(lost), "lost_jobs": lost}


def sync_slot_free(client: httpx.Client, record: dict[str, Any]) -> int:
    """The status of one synchronous diagnosis after the load (200: the abandoned ones gave their slots back)."""
    return client.post("/v1/diagnose", json={"record": record}).status_code


# -- the report -------------------------------------------------------------------------------


def table(summary: dict[str, Any]) -> str:
    """The report as text."""
    rows = [
        f"load: {summary['clients']} clients for {summary['seconds']:g} s on {summary['base_url']} "
        f"(mix {summary['mix']}; at most {summary['max_diagnoses']} diagnosis jobs in flight)",
    ]
    if summary["note"]:
        rows.append(f"note: {summary['note']}")
    head = f"{'operation':32s} {'count':>6s} {'req/s':>7s} {'p50 ms':>9s} {'p90 ms':>9s} {'p99 ms':>9s} {'5xx':>4s}  other answers"
    rows += [head, "-" * len(head)]
    for op, s in summary["operations"].items():
        other = ", ".join(f"{k}: {v}" for k, v in s["errors"].items()) or "-"
        rows.append(
            f"{op:32s} {s['count']:6d} {s['throughput_per_s']:7.2f} {_ms(s['p50_ms']):>9s} {_ms(s['p90_ms']):>9s} "
            f"{_ms(s['p99_ms']):>9s} {s['server_errors']:4d}  {other}"
        )
    jobs = summary["jobs"]
    if jobs is not None:
        rows.append(
            f"diagnosis jobs: {jobs['submitted']} submitted, final states {jobs['final_states']}, "
            f"lost jobs: {jobs['lost']} (drain {summary['drain_seconds']:.1f} s)"
        )
    b = summary["baseline"]
    rows.append(
        f"GET /healthz, one client: before the load p50 {_ms(b['before_p50_ms'])} ms, p90 {_ms(b['before_p90_ms'])} "
        f"ms; under load p50 {_ms(b['under_load_p50_ms'])} ms, p90 {_ms(b['under_load_p90_ms'])} ms"
    )
    ratios = (b["ratio_p50"], b["ratio_p90"])
    rows.append(
        "ratio under load / before: "
        + ", ".join(
            f"{name} {'-' if r is None else f'{r:.2f}x'}" for name, r in zip(("p50", "p90"), ratios, strict=True)
        )
    )
    rows.append(
        f"GET /healthz under load: p99 {_ms(b['under_load_p99_ms'])} ms, max {_ms(b['under_load_max_ms'])} ms "
        f"over {b['under_load_n']} requests"
    )
    rows.append(f"a synchronous diagnosis after the load: {summary['sync_after_load']}")
    m = summary["memory"]
    rows.append(
        f"server memory (resident, process and children): peak {m['peak_total_mib']:.0f} MiB in all, "
        f"{m['peak_process_mib']:.0f} MiB in one process"
    )
    f = summary["file_bytes"]
    rows.append(
        "database file: "
        + ", ".join(f"{k.replace('_', ' ')} {v / 2**20:.1f} MiB" for k, v in f.items() if v is not None)
    )
    if summary["retention"] is not None:
        rows.append(f"retention run: {summary['retention']}")
    lost = jobs["lost"] if jobs is not None else 0
    p99 = b["under_load_p99_ms"]
    ok = summary["server_errors"] == 0 and lost == 0 and p99 is not None and p99 < HEALTHZ_P99_LIMIT * 1e3
    rows.append(
        f"5xx in all: {summary['server_errors']} (limit 0); lost jobs: {jobs['lost'] if jobs is not None else 'n/a'} "
        f"(limit 0); GET /healthz p99 {_ms(p99)} ms (limit {HEALTHZ_P99_LIMIT * 1e3:.0f} ms): "
        + ("within the issue's limits" if ok else "OUTSIDE the issue's limits")
    )
    return "\n".join(rows)


def retention_run(workdir: Path, settings: dict[str, str]) -> str:
    """Run the retention command on the server's database (the server stopped) and return what it printed."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("BACKLASH_")}
    env.update({"BACKLASH_DB_PATH": str(db_path(workdir)), "BACKLASH_LOG_LEVEL": "WARNING", **settings})
    done = subprocess.run(
        [sys.executable, "-m", "app.cli", *RETENTION_COMMAND],
        env=env,
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    )
    return " ".join((done.stdout + done.stderr).split())


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Start the server, prepare, measure the baseline, run the load, drain, check, stop the server, run the
    retention; return the summary."""
    mix = parse_mix(args.mix)
    settings = parse_settings(args.set)
    with tempfile.TemporaryDirectory(prefix="bench-load-") as tmp:
        workdir = args.workdir or Path(tmp)
        with (
            serve(workdir, settings) as (base_url, pid),
            httpx.Client(base_url=base_url, timeout=REQUEST_TIMEOUT) as client,
            MemoryProbe(pid) as memory,
        ):
            logger.info("preparing: training the pattern set, simulating %d records", len(WIDTHS))
            fixture = prepare(client)
            for record in fixture.records[:2]:  # warm-up: the first identification loads the set
                body = {"record": record, "channel": "v2", "pattern_set": fixture.pattern_set}
                client.post("/v1/identify", json=body)
            with healthz_probe(base_url, BASELINE_REQUESTS, 0.0) as before:
                pass
            size_before = file_bytes(db_path(workdir))
            recorder = Recorder()
            load = Load(base_url, fixture, mix, args.max_diagnoses, args.poll, recorder, args.abandon_after)
            start = time.monotonic()
            load.stop_at = start + args.seconds
            load.drain_until = load.stop_at + args.drain
            load.schedule(start, args.seconds, args.large_bodies, args.abandoned)
            threads = [
                threading.Thread(target=load.run_client, args=(i,), name=f"client-{i}") for i in range(args.clients)
            ]
            logger.info("load: %d clients for %g s", args.clients, args.seconds)
            for t in threads:
                t.start()
            with healthz_probe(
                base_url, None, args.probe_interval, seconds=load.stop_at - time.monotonic()
            ) as under_load:
                for t in threads:
                    t.join()
            drain_seconds = max(0.0, time.monotonic() - load.stop_at)
            logger.info("load done; drained in %.1f s; checking %d jobs", drain_seconds, len(recorder.jobs))
            jobs = final_check(client, recorder.jobs) if fixture.async_diagnoses else None
            sync_after = sync_slot_free(client, fixture.records[0])
            size_after = file_bytes(db_path(workdir))
        retention = None
        size_retained = None
        if args.retention:
            retention = retention_run(workdir, settings)
            size_retained = file_bytes(db_path(workdir))
    b50, b90 = percentiles_ms(before, (50, 90))
    u50, u90, u99 = percentiles_ms(under_load, (50, 90, 99))
    operations = {op: s.summary(args.seconds) for op, s in sorted(recorder.ops.items())}
    return {
        "base_url": base_url,
        "code": code_version(),
        "clients": args.clients,
        "seconds": args.seconds,
        "mix": mix,
        "max_diagnoses": args.max_diagnoses,
        "large_bodies": args.large_bodies,
        "large_body_bytes": len(json.dumps(fixture.large_record)),
        "abandoned": args.abandoned,
        "abandon_after_s": args.abandon_after,
        "server_settings": settings,
        "note": None
        if fixture.async_diagnoses
        else "the server has no POST /v1/diagnoses: the diagnoses were the synchronous POST /v1/diagnose",
        "operations": operations,
        "server_errors": sum(s["server_errors"] for s in operations.values()),
        "jobs": jobs,
        "drain_seconds": drain_seconds,
        "sync_after_load": sync_after,
        "memory": {"peak_total_mib": memory.peak_total / 2**20, "peak_process_mib": memory.peak_process / 2**20},
        "file_bytes": {
            "before_the_load": size_before,
            "after_the_load": size_after,
            "after_the_retention_run": size_retained,
        },
        "retention": retention,
        "baseline": {
            "before_n": len(before),
            "before_p50_ms": b50,
            "before_p90_ms": b90,
            "under_load_n": len(under_load),
            "under_load_p50_ms": u50,
            "under_load_p90_ms": u90,
            "under_load_p99_ms": u99,
            "under_load_max_ms": max(under_load) * 1e3 if under_load else None,
            "ratio_p50": _ratio(u50, b50),
            "ratio_p90": _ratio(u90, b90),
        },
    }


def code_version() -> str:
    """The commit the server ran (``git describe``), marked ``-dirty`` when the work tree had changes."""
    done = subprocess.run(
        ["git", "describe", "--always", "--dirty", "--abbrev=7"], cwd=REPO, capture_output=True, text=True
    )
    return done.stdout.strip() or "unknown"


def _ratio(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None or b == 0 else a / b


def parse_settings(items: list[str]) -> dict[str, str]:
    """``BACKLASH_NAME=VALUE`` items as environment variables of the server."""
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.startswith("BACKLASH_"):
            raise SystemExit(f"--set {item!r}: give BACKLASH_NAME=VALUE")
        out[name] = value
    return out


def parse_mix(text: str) -> dict[str, float]:
    """``simulate=4,identify=4,diagnosis=1`` as a dict of weights (operations not named: weight 0)."""
    mix = {}
    for part in text.split(","):
        name, _, weight = part.partition("=")
        if name.strip() not in OPERATIONS:
            raise argparse.ArgumentTypeError(f"unknown operation {name.strip()!r} in --mix")
        mix[name.strip()] = float(weight)
    if not any(w > 0 for w in mix.values()):
        raise argparse.ArgumentTypeError("--mix needs a positive weight")
    return mix


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clients", type=int, default=20, help="concurrent clients (threads)")
    ap.add_argument("--seconds", type=float, default=60.0, help="duration of the load [s]")
    ap.add_argument(
        "--mix",
        default="simulate=3,batch=1,identify=3,diagnosis=1,cancel_retry=0.5,delete=0.5,read=6",
        help=f"weights of the operations, of {', '.join(OPERATIONS)}",
    )
    ap.add_argument("--large-bodies", type=int, default=4, help="20 MB bodies sent during the load")
    ap.add_argument("--abandoned", type=int, default=4, help="synchronous diagnoses given up during the load")
    ap.add_argument("--abandon-after", type=float, default=2.0, help="when those are given up [s]")
    ap.add_argument(
        "--retention",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="after the load, stop the server and run the retention on its database (keeping nothing older than a second)",
    )
    ap.add_argument("--max-diagnoses", type=int, default=2, help="diagnosis jobs in flight at once")
    ap.add_argument("--poll", type=float, default=0.5, help="interval of the job polls [s]")
    ap.add_argument("--drain", type=float, default=180.0, help="longest wait for the jobs after the load [s]")
    ap.add_argument("--probe-interval", type=float, default=0.2, help="interval of GET /healthz under load [s]")
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="BACKLASH_NAME=VALUE",
        help="a setting of the server (repeatable), e.g. BACKLASH_DIAGNOSIS_WORKERS=2",
    )
    ap.add_argument("--out", type=Path, default=None, help="write the summary as JSON here")
    ap.add_argument(
        "--workdir",
        type=Path,
        default=None,
        help="keep the server's database and log (server.log) here (default: a temporary directory, removed)",
    )
    ap.add_argument("--probe", metavar="URL", help=argparse.SUPPRESS)  # the /healthz observer (healthz_probe)
    ap.add_argument("--probe-count", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--probe-for", type=float, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.probe:
        with httpx.Client(base_url=args.probe, timeout=REQUEST_TIMEOUT) as client:
            until = None if args.probe_for is None else time.monotonic() + args.probe_for
            sys.stdout.write(json.dumps(probe_healthz(client, args.probe_count, args.probe_interval, until)))
        return 0
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)
    logging.getLogger("httpx").setLevel(logging.WARNING)
    if args.workdir is not None:
        args.workdir.mkdir(parents=True, exist_ok=True)
    summary = run(args)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(summary, indent=1, default=str) + "\n")
        logger.info("summary written to %s", args.out)
    sys.stdout.write(table(summary) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
