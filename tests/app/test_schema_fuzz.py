"""Property-based fuzzing of the whole OpenAPI schema with schemathesis (issue 12, "Contract and load").

Every operation of ``/openapi.json`` gets requests generated from its schema: its documented examples,
the coverage phase's boundary values (valid and invalid) and random ones (hypothesis), against a real
uvicorn server of the application (:class:`servicekit.InProcessServer`: ``create_app(Settings(...))`` with
its lifespan run). Every answer must be no 5xx (``not_a_server_error``), carry a documented status
(``status_code_conformance``) and content type (``content_type_conformance``), and match its documented
schema (``response_schema_conformance``).

Before the fuzzing the server is given a few resources (:func:`seeded`: pattern sets, identifications of an
asset, diagnoses and their records); about half of the generated path parameters are pointed at them
(:func:`use_seeded`), so that the operations on one resource reach their success path, not only 404.

Bounded for CI: at most :data:`MAX_EXAMPLES` random requests per operation (plus the examples and the
coverage cases), derandomized so that a run is reproducible, no example database. The long run of issue 51
(at least 100 per operation) sets the environment: ``FUZZ_EXAMPLES=100 FUZZ_REPORT=docs/service/fuzz.json
.venv/bin/python -m pytest -q tests/app/test_schema_fuzz.py``; the report counts each operation's requests,
their statuses, the 5xx and the failed checks (docs/gen.py prints its table in docs/service-operation.md). The work a request can
start is bounded by the server's settings (:func:`fuzz_settings`: one training thread and one diagnosis
process, at most two pending jobs, small batches, a time limit on synchronous diagnoses) and, for training,
by :func:`bound_training`. No operation is excluded.

A failure names the operation and the request (``curl`` to reproduce it); the server's log is in the test's
captured output.
"""

from __future__ import annotations

import json
import os
import subprocess
import zlib
from collections import Counter, defaultdict
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_schema_conformance,
    status_code_conformance,
)
from servicekit import SMALL_TRAINING, InProcessServer, train

from app.core.config import Settings
from app.main import create_app

#: Random requests per operation (hypothesis ``max_examples``), besides the examples and the coverage cases
#: (``FUZZ_EXAMPLES`` in the environment sets another number, e.g. 100 for the long run).
MAX_EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "15"))
#: Where the run's counts are written as JSON (``FUZZ_REPORT`` in the environment; unset: nowhere).
REPORT = os.environ.get("FUZZ_REPORT")
#: Longest a request may take [s] before the test fails (a bound against hanging, not a timing assumption).
REQUEST_TIMEOUT = 60.0
#: Largest epoch cap per network of the paper kind's training the fuzzer sends: the schema allows 100 000, which
#: with a learning coefficient that never converges keeps the training thread busy for minutes (and, holding the
#: GIL, the server's event loop with it); 500 is the identifier's default. The answer to the POST is decided
#: before the job runs (validation, then 202 or 429), so the bound changes the job's duration, not the contract.
FUZZ_MAX_EPOCHS = 500
#: The repository (the report names its commit).
ROOT = Path(__file__).resolve().parents[2]
#: The asset the seeded identification and diagnoses belong to.
ASSET = "press-7"
#: The checks every answer must pass.
CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance]


def fuzz_settings(db_path: Path) -> Settings:
    """The fuzzed server's settings: its own database, one training thread and one diagnosis process, at most
    two pending jobs (the rest get 429), four cases per batch simulation, one synchronous diagnosis at a time
    stopped after 20 s (504), FMU plants on."""
    return Settings(
        db_path=db_path,
        workers=1,
        diagnosis_workers=1,
        max_pending_jobs=2,
        max_batch_cases=4,
        max_sync_diagnoses=1,
        sync_diagnose_timeout=20.0,
        allow_fmu_plants=True,  # the FMU routes reach their success paths too (tests/app/test_app_fmu_plants.py
        log_level="WARNING",  # has them off)
    )


#: The schema the application publishes, read from an application built with the same settings but never started
#: (building it opens nothing; its database path is a placeholder). Loaded when the module is collected, so that
#: every operation is a test of its own; schemathesis's lazy ``from_fixture`` does not run on pytest 9.
schema = schemathesis.openapi.from_dict(create_app(fuzz_settings(Path("schema-only.sqlite3"))).openapi())


@dataclass
class Seeded:
    """Ids of the resources stored before the fuzzing, by path parameter name.

    ``kept`` serve every method but DELETE; ``deleted`` serve DELETE, so that deleting one does not turn the
    other operations on it into 404s.
    """

    kept: dict[str, list[str]] = field(default_factory=dict)
    deleted: dict[str, list[str]] = field(default_factory=dict)

    def ids(self, method: str, name: str) -> list[str]:
        return (self.deleted if method.upper() == "DELETE" else self.kept).get(name, [])


@pytest.fixture(scope="module")
def fuzz_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InProcessServer]:
    """The application served by uvicorn in a thread of this process, on a fresh database."""
    server = InProcessServer(create_app(fuzz_settings(tmp_path_factory.mktemp("fuzz") / "patterns.sqlite3")))
    server.start()
    try:
        yield server
    finally:
        server.request_stop()
        server.join(timeout=120)


def _diagnosis(client: httpx.Client, record: dict[str, Any], measured_at: str) -> dict[str, Any]:
    """Submit a diagnosis of ``record`` for :data:`ASSET` and cancel its job at once (its record and diagnosis
    stay stored; no core is spent on it)."""
    r = client.post("/v1/diagnoses", json={"record": {**record, "asset": ASSET, "measured_at": measured_at}})
    assert r.status_code == 202, r.text
    accepted = r.json()
    cancel = client.post(f"/v1/jobs/{accepted['job_id']}/cancel")
    assert cancel.status_code in (200, 409), cancel.text  # 409: it finished first
    return accepted


def _plants(client: httpx.Client, fmu: Path, out: Seeded) -> None:
    """Upload the quarter car's FMU and store two plants of it (one kept, one for DELETE)."""
    from fmukit import OCTET, small_description

    up = client.post("/v1/fmus", content=fmu.read_bytes(), headers=OCTET)
    assert up.status_code == 201, up.text
    out.kept["sha256"] = [up.json()["sha256"]]
    ids = []
    for name in ("fuzz_kept", "fuzz_deleted"):
        made = client.post("/v1/plants", json={"description": {**small_description(up.json()["sha256"]), "name": name}})
        assert made.status_code == 201, made.text
        ids.append(made.json()["id"])
    out.kept["plant_id"], out.deleted["plant_id"] = [ids[0]], [ids[1]]


@pytest.fixture(scope="module")
def seeded(fuzz_server: InProcessServer, tmp_path_factory: pytest.TempPathFactory) -> Seeded:
    """Store two small pattern sets, three identifications of :data:`ASSET` over a week, two diagnoses of it
    (cancelled), an FMU and two plants of it."""
    from engine.plants.fmu import EXAMPLES_DIR
    from engine.plants.fmu.build import build_fmu

    fmu = build_fmu(EXAMPLES_DIR / "quarter_car", tmp_path_factory.mktemp("fuzz_fmu"))
    paths = schema.raw_schema["paths"]
    out = Seeded(kept={"asset": [ASSET], "name": ["overlays", "residual_map_before"]})
    with fuzz_server.client() as client:
        client.timeout = httpx.Timeout(REQUEST_TIMEOUT)
        sets = [train(client), train(client, {**SMALL_TRAINING, "J1_values": [0.87]})]
        for s in sets:
            assert s["job"]["state"] == "done", s["job"]
        out.kept["set_id"], out.deleted["set_id"] = [sets[0]["pattern_set_id"]], [sets[1]["pattern_set_id"]]
        out.kept["job_id"] = [sets[0]["job_id"]]
        out.deleted["job_id"] = [sets[1]["job_id"]]  # a finished job nothing needs: DELETE removes it
        for day, K in ((1, 0.005), (5, 0.0055), (9, 0.006)):  # a week of wear: GET .../trend has a line to fit
            r = client.post("/v1/simulate", json={"K": K})
            assert r.status_code == 200, r.text
            record = {k: r.json()[k] for k in ("sample_interval", "event_index", "channels", "conditions")}
            identified = client.post(
                "/v1/identify",
                json={
                    "record": {**record, "asset": ASSET, "measured_at": f"2026-11-{day:02d}T08:00:00Z"},
                    "channel": "v2",
                    "pattern_set": sets[0]["pattern_set_id"],
                },
            )
            assert identified.status_code == 200, identified.text
        if "/v1/diagnoses" in paths:
            kept, deleted = (_diagnosis(client, record, f"2026-11-{day}T08:00:00Z") for day in (12, 14))
            out.kept["job_id"].append(kept["job_id"])
            for ids, accepted in ((out.kept, kept), (out.deleted, deleted)):
                ids["diagnosis_id"], ids["record_id"] = [accepted["diagnosis_id"]], [accepted["record_id"]]
        if "/v1/plants" in paths:
            _plants(client, fmu, out)
    return out


def use_seeded(case: Any, seeded: Seeded) -> None:
    """Point about half of the path parameters at seeded resources (in place; the choice depends only on the
    generated value, so a derandomized run makes the same choices)."""
    for name, value in (case.path_parameters or {}).items():
        ids = seeded.ids(case.method, name)
        digest = zlib.crc32(repr(value).encode())
        if ids and digest % 2 == 0:
            case.path_parameters[name] = ids[(digest // 2) % len(ids)]


def bound_training(case: Any) -> None:
    """Cap a training request's epoch cap (field or ``params``) at :data:`FUZZ_MAX_EPOCHS`, in place."""
    if case.method.upper() != "POST" or case.path != "/v1/pattern-sets" or not isinstance(case.body, dict):
        return
    for holder in (case.body, case.body.get("params")):
        if not isinstance(holder, dict):
            continue
        epochs = holder.get("max_epochs")
        if isinstance(epochs, int) and not isinstance(epochs, bool) and epochs > FUZZ_MAX_EPOCHS:
            holder["max_epochs"] = FUZZ_MAX_EPOCHS


@dataclass
class Tally:
    """Requests sent per operation, by answer status, and the failed checks (for :data:`REPORT`)."""

    statuses: defaultdict[str, Counter[str]] = field(default_factory=lambda: defaultdict(Counter))
    failures: Counter[str] = field(default_factory=Counter)

    def summary(self) -> dict[str, Any]:
        ops = {
            op: {
                "requests": sum(c.values()),
                "statuses": dict(sorted(c.items())),
                "server_errors": sum(v for k, v in c.items() if k.startswith("5")),
                "failed": self.failures[op],
            }
            for op, c in sorted(self.statuses.items())
        }
        described = subprocess.run(
            ["git", "describe", "--always", "--dirty", "--abbrev=7"], capture_output=True, text=True, cwd=ROOT
        )
        return {
            "code": described.stdout.strip() or "unknown",
            "max_examples": MAX_EXAMPLES,
            "checks": [check.__name__ for check in CHECKS],
            "operations": ops,
            "requests": sum(o["requests"] for o in ops.values()),
            "server_errors": sum(o["server_errors"] for o in ops.values()),
            "failed": sum(self.failures.values()),
        }


@pytest.fixture(scope="module")
def tally() -> Iterator[Tally]:
    """Counts of the module's requests, written to :data:`REPORT` at its end when that is set."""
    out = Tally()
    yield out
    if REPORT:
        Path(REPORT).parent.mkdir(parents=True, exist_ok=True)
        Path(REPORT).write_text(json.dumps(out.summary(), indent=1) + "\n")


@schema.parametrize()
@settings(
    max_examples=MAX_EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large],
)
def test_every_operation_keeps_its_contract(
    case: Any, fuzz_server: InProcessServer, seeded: Seeded, tally: Tally
) -> None:
    use_seeded(case, seeded)
    bound_training(case)
    op = f"{case.operation.method.upper()} {case.operation.path}"  # the documented operation (its coverage phase
    # also sends methods it does not allow: counted here, answered 405)
    response = case.call(base_url=fuzz_server.base_url, timeout=REQUEST_TIMEOUT)
    tally.statuses[op][str(response.status_code)] += 1
    try:
        case.validate_response(response, checks=CHECKS)
    except Exception:
        tally.failures[op] += 1
        raise
