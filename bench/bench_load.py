"""Load benchmark of the HTTP service on the loopback interface (issue 12, "Contract and load").

    .venv/bin/python bench/bench_load.py [--clients 20] [--seconds 60] [--out out/bench-load.json]

Starts a real server (``python -m app.cli serve``, the ``backlash serve`` command) on a free loopback
port with a fresh database in a temporary directory, prepares what the mix needs (a pattern set, simulated
records), then runs ``--clients`` clients, each a thread with its own HTTP connection, for ``--seconds``:
every client repeats one operation after the other, drawn by the weights of ``--mix``:

* ``simulate``: ``POST /v1/simulate`` of one case (a width of the paper's grid);
* ``identify``: ``POST /v1/identify`` of a simulated record (JSON) with the stored pattern set;
* ``diagnosis``: ``POST /v1/diagnoses`` of a simulated record (for an asset), then ``GET /v1/jobs/{id}``
  every ``--poll`` seconds until the job has finished. At most ``--max-diagnoses`` diagnosis jobs are in
  flight at once (a client that draws one while they are takes another operation): a diagnosis keeps a core
  busy for tens of seconds, and clients blocked on it would otherwise stop loading the rest of the service.
  A server without ``POST /v1/diagnoses`` (it is not in ``/openapi.json``) gets the synchronous
  ``POST /v1/diagnose`` instead, and the report says so.

When the time is up, no operation is started any more; the clients waiting for their diagnosis jobs keep
polling for at most ``--drain`` seconds. Then every job submitted is read once more: a job that is missing
(404) or has not finished is *lost*; so is a diagnosis whose ``GET /v1/diagnoses/{id}`` is missing.

The report (stdout; progress goes to the log on stderr), per operation: count, throughput [1/s over the
load], latency p50/p90/p99 [ms], the answers by status, the 5xx; the diagnosis jobs' time from submission
to the end; the lost jobs. The baseline is measured in the same process: the latency of ``GET /healthz``
from a single client before the load, against the same request sent every ``--probe-interval`` seconds by
one more client during the load; the report gives the ratio of the medians (and of the 90th percentiles).
``--out`` writes the whole summary as JSON.

Speed is measured here, never timed in tests; this is a benchmark, not a test (it fails on nothing).
"""

from __future__ import annotations

import argparse
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


def free_port() -> int:
    """A free TCP port on the loopback interface."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@contextmanager
def serve(workdir: Path, settings: dict[str, str]) -> Iterator[str]:
    """Run ``python -m app.cli serve`` on a free loopback port with its database in ``workdir``; yield its URL.

    Parameters
    ----------
    workdir : Path
        Holds the database and the server's log (``server.log``).
    settings : dict of str to str
        Further ``BACKLASH_*`` environment variables of the server.
    """
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("BACKLASH_")}
    env.update({"BACKLASH_DB_PATH": str(workdir / "load.sqlite3"), "BACKLASH_LOG_LEVEL": "WARNING", **settings})
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
        yield base_url
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
    return Fixture(records, accepted["pattern_set_id"], async_diagnoses)


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
    ) -> None:
        self.base_url, self.fixture, self.recorder, self.poll = base_url, fixture, recorder, poll
        self.mix = mix
        self.diagnosis_slots = threading.BoundedSemaphore(max_diagnoses)
        self.stop_at = 0.0  # no operation starts after this (time.monotonic)
        self.drain_until = 0.0  # diagnosis jobs are polled until this at the latest

    def client(self) -> httpx.Client:
        return httpx.Client(base_url=self.base_url, timeout=REQUEST_TIMEOUT)

    def run_client(self, index: int) -> None:
        rng = random.Random(index)
        ops: dict[str, Callable[[httpx.Client, random.Random, int], None]] = {
            "simulate": self.simulate,
            "identify": self.identify,
            "diagnosis": self.diagnosis,
        }
        names = [n for n in ops if self.mix.get(n, 0) > 0]
        weights = [self.mix[n] for n in names]
        with self.client() as client:
            while time.monotonic() < self.stop_at:
                name = rng.choices(names, weights)[0]
                try:
                    if name == "diagnosis":
                        if self.diagnosis_slots.acquire(blocking=False):
                            try:
                                self.diagnosis(client, rng, index)
                            finally:
                                self.diagnosis_slots.release()
                            continue
                        others = [(n, w) for n, w in zip(names, weights, strict=True) if n != "diagnosis"]
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

    def identify(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        body = {"record": rng.choice(self.fixture.records), "channel": "v2", "pattern_set": self.fixture.pattern_set}
        seconds, r = timed(client, "POST", "/v1/identify", json=body)
        self._record("identify", seconds, r)

    def diagnosis(self, client: httpx.Client, rng: random.Random, index: int) -> None:
        record = rng.choice(self.fixture.records)
        if not self.fixture.async_diagnoses:
            seconds, r = timed(client, "POST", "/v1/diagnose", json={"record": record})
            self._record("diagnose (sync)", seconds, r)
            return
        body = {"record": {**record, "asset": f"bench-{index}", "measured_at": "2026-11-20T08:00:00Z"}}
        submitted_at = time.monotonic()
        seconds, r = timed(client, "POST", "/v1/diagnoses", json=body)
        self._record("diagnosis submit", seconds, r)
        if r is None or r.status_code != 202:
            return
        job = Submitted(r.json()["job_id"], r.json()["diagnosis_id"], submitted_at)
        self.recorder.submitted(job)
        while time.monotonic() < self.drain_until:
            time.sleep(self.poll)
            seconds, r = timed(client, "GET", f"/v1/jobs/{job.job_id}")
            self._record("job poll", seconds, r)
            if r is not None and r.status_code == 200 and r.json()["state"] in FINISHED:
                job.finished_at, job.state = time.monotonic(), r.json()["state"]
                self.recorder.add("diagnosis job (submit to end)", job.finished_at - submitted_at, 200)
                return


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


def final_check(client: httpx.Client, jobs: list[Submitted]) -> dict[str, Any]:
    """Read every submitted job (and its diagnosis) once more: the states, and the lost ones."""
    states: Counter[str] = Counter()
    lost: list[dict[str, Any]] = []
    for job in jobs:
        r = client.get(f"/v1/jobs/{job.job_id}")
        d = client.get(f"/v1/diagnoses/{job.diagnosis_id}")
        state = r.json()["state"] if r.status_code == 200 else f"missing ({r.status_code})"
        states[state] += 1
        if r.status_code != 200 or state not in FINISHED or d.status_code != 200:
            lost.append({"job_id": job.job_id, "job": state, "diagnosis_status": d.status_code})
    return {"submitted": len(jobs), "final_states": dict(states), "lost": len(lost), "lost_jobs": lost}


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
    rows.append(f"5xx in all: {summary['server_errors']}; lost jobs: {jobs['lost'] if jobs is not None else 'n/a'}")
    return "\n".join(rows)


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Start the server, prepare, measure the baseline, run the load, drain, check; return the summary."""
    mix = parse_mix(args.mix)
    settings = parse_settings(args.set)
    with (
        tempfile.TemporaryDirectory(prefix="bench-load-") as tmp,
        serve(args.workdir or Path(tmp), settings) as base_url,
        httpx.Client(base_url=base_url, timeout=REQUEST_TIMEOUT) as client,
    ):
        logger.info("preparing: training the pattern set, simulating %d records", len(WIDTHS))
        fixture = prepare(client)
        for record in fixture.records[:2]:  # warm-up: the first identification loads the set
            client.post("/v1/identify", json={"record": record, "channel": "v2", "pattern_set": fixture.pattern_set})
        before = probe_healthz(client, BASELINE_REQUESTS, 0.0)
        recorder = Recorder()
        load = Load(base_url, fixture, mix, args.max_diagnoses, args.poll, recorder)
        start = time.monotonic()
        load.stop_at = start + args.seconds
        load.drain_until = load.stop_at + args.drain
        threads = [threading.Thread(target=load.run_client, args=(i,), name=f"client-{i}") for i in range(args.clients)]
        logger.info("load: %d clients for %g s", args.clients, args.seconds)
        for t in threads:
            t.start()
        under_load = probe_healthz(client, None, args.probe_interval, until=load.stop_at)
        for t in threads:
            t.join()
        drain_seconds = max(0.0, time.monotonic() - load.stop_at)
        logger.info("load done; drained in %.1f s; checking %d jobs", drain_seconds, len(recorder.jobs))
        jobs = final_check(client, recorder.jobs) if fixture.async_diagnoses else None
    b50, b90 = percentiles_ms(before, (50, 90))
    u50, u90 = percentiles_ms(under_load, (50, 90))
    operations = {op: s.summary(args.seconds) for op, s in sorted(recorder.ops.items())}
    return {
        "base_url": base_url,
        "clients": args.clients,
        "seconds": args.seconds,
        "mix": mix,
        "max_diagnoses": args.max_diagnoses,
        "server_settings": settings,
        "note": None
        if fixture.async_diagnoses
        else "the server has no POST /v1/diagnoses: the diagnoses were the synchronous POST /v1/diagnose",
        "operations": operations,
        "server_errors": sum(s["server_errors"] for s in operations.values()),
        "jobs": jobs,
        "drain_seconds": drain_seconds,
        "baseline": {
            "before_n": len(before),
            "before_p50_ms": b50,
            "before_p90_ms": b90,
            "under_load_n": len(under_load),
            "under_load_p50_ms": u50,
            "under_load_p90_ms": u90,
            "ratio_p50": _ratio(u50, b50),
            "ratio_p90": _ratio(u90, b90),
        },
    }


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
    """``simulate=4,identify=4,diagnosis=1`` as a dict of weights."""
    mix = {}
    for part in text.split(","):
        name, _, weight = part.partition("=")
        if name.strip() not in ("simulate", "identify", "diagnosis"):
            raise argparse.ArgumentTypeError(f"unknown operation {name.strip()!r} in --mix")
        mix[name.strip()] = float(weight)
    if not any(w > 0 for w in mix.values()):
        raise argparse.ArgumentTypeError("--mix needs a positive weight")
    return mix


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clients", type=int, default=20, help="concurrent clients (threads)")
    ap.add_argument("--seconds", type=float, default=60.0, help="duration of the load [s]")
    ap.add_argument("--mix", default="simulate=4,identify=4,diagnosis=1", help="weights of the operations")
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
    args = ap.parse_args(argv)
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
