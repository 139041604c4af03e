"""Diagnoses as stored jobs: submit one (record stored, job queued), run it in a worker process, read it back.

A submitted diagnosis is three rows written in one transaction before the answer (202), once the
queue has room: the record as sent (:mod:`app.db.records`), the diagnosis without a result
(:mod:`app.db.diagnoses`) and its job (:mod:`app.db.jobs`). The job runs :func:`run_job` in a worker process, which stores the result
and the figures in the transaction that marks the job ``done`` (:class:`app.jobs.JobResult`). A diagnosis
is therefore either complete with a done job or has none of its result; a retried job computes it again
from the stored record, unless the result is already stored (:func:`stored_result`: the retry is done at once).
"""

from __future__ import annotations

import logging
import sqlite3
import uuid
from pathlib import Path
from typing import Any

from app.db.codec import now
from app.db.diagnoses import DiagnosisRepository, StoredDiagnosis
from app.db.jobs import JobState
from app.db.records import NewRecord, RecordRepository, StoredRecord
from app.jobs import Job, JobKind, JobManager, JobResult, ProgressFn
from app.jobs.manager import RowsFn
from app.services.assets import check_asset_drive, machine_key
from app.services.diagnosis_requests import DiagnosisRequest, compute, n_samples, parse
from app.services.errors import NotFoundError
from engine.storage import PatternStore

logger = logging.getLogger(__name__)

__all__ = ["DIAGNOSE_JOB", "JOB_KIND", "delete", "get", "run_job", "submit"]

#: The diagnosis job's kind.
DIAGNOSE_JOB = "diagnose"


def run_job(db_path: Path, spec: dict[str, Any], progress: ProgressFn) -> JobResult:
    """A diagnosis job, in a worker process: read the stored record, diagnose it; the result and figures are stored
    with the job's move to ``done``, in one transaction."""
    store = PatternStore(db_path)
    progress(0.02, "reading the stored record")
    stored = RecordRepository(store).get(spec["record_id"])
    if stored is None:
        raise NotFoundError(f"record {spec['record_id']} was deleted before its diagnosis ran")
    # the store is given: a record of an uploaded plant was accepted while FMU plants were on, and reads so again
    parsed = parse(DiagnosisRequest(stored.media, stored.body or b"", stored.params, store=str(db_path)))
    progress(0.05, f"diagnosing {stored.n_samples} samples")

    def stage(fraction: float, what: str) -> None:  # the diagnosis's stages between 5 % and 95 %
        progress(0.05 + 0.9 * fraction, what)

    outcome = compute(parsed, figures=True, progress=stage)
    progress(0.95, f"storing the result and {len(outcome.figures)} figures")

    def write(conn: sqlite3.Connection) -> None:
        kept = DiagnosisRepository(store).complete(
            spec["diagnosis_id"],
            outcome.result,
            status=outcome.status,
            effect=outcome.effect,
            width=outcome.width,
            width_sigma=outcome.width_sigma,
            figures=outcome.figures,
            conn=conn,
        )
        if not kept:
            logger.info("diagnosis %s was deleted while it ran; its result is dropped", spec["diagnosis_id"])

    return JobResult({"diagnosis_id": spec["diagnosis_id"]}, write=write)


def stored_result(conn: sqlite3.Connection, spec: dict[str, Any]) -> dict[str, Any] | None:
    """The job's meta if the diagnosis of the job's ``spec`` already has its result (its retry then runs nothing)."""
    diagnosis_id = spec.get("diagnosis_id")
    if diagnosis_id is None or not DiagnosisRepository.has_result(conn, diagnosis_id):
        return None
    return {"diagnosis_id": diagnosis_id}


#: The process pool of diagnosis jobs (``Settings.diagnosis_workers`` processes).
POOL = "diagnosis"
#: Diagnosis as a job kind: in a worker process, so that cancelling it frees its core at once.
JOB_KIND = JobKind(DIAGNOSE_JOB, "process", run_job, pool=POOL, stored=stored_result)


def new_record(store: PatternStore, request: DiagnosisRequest) -> NewRecord:
    """Read and check the request (raises with what to fix); its record as it will be stored, not stored yet."""
    parsed = parse(request)
    drive = None if parsed.drive is None else parsed.drive.fingerprint
    check_asset_drive(store, parsed.asset, machine_key(parsed.plant, drive))  # an asset's history is one machine's
    return RecordRepository.new(
        request.body,
        media=request.media,
        params=request.params,
        plant=parsed.plant,
        name=parsed.name,
        asset=parsed.asset,
        measured_at=parsed.measured_at or now(),
        n_samples=n_samples(parsed.record),
    )


def submit(store: PatternStore, jobs: JobManager, request: DiagnosisRequest) -> tuple[Job, str, StoredRecord]:
    """Check and store the record, create the diagnosis and queue its job; return (job, diagnosis id, record).

    The record, the diagnosis and the job are stored in one transaction, once the queue has room: nothing is
    left behind when the queue is full (``QueueFullError``) or the request is invalid.
    """
    new = new_record(store, request)

    def store_record(conn: sqlite3.Connection, job: Job) -> None:
        RecordRepository.insert(conn, new)

    job, diagnosis_id = _queue(store, jobs, new.record, store_record)
    return job, diagnosis_id, new.record


def submit_stored(store: PatternStore, jobs: JobManager, record: StoredRecord) -> tuple[Job, str]:
    """Diagnose a stored record: create the diagnosis and queue its job (one transaction); return (job, diagnosis id)."""
    return _queue(store, jobs, record, None)


def _queue(store: PatternStore, jobs: JobManager, record: StoredRecord, rows: RowsFn | None) -> tuple[Job, str]:
    """Queue the diagnosis job of ``record``; its diagnosis row (and ``rows``) in the job's transaction."""
    diagnosis_id = uuid.uuid4().hex

    def add_rows(conn: sqlite3.Connection, job: Job) -> None:
        if rows is not None:
            rows(conn, job)
        DiagnosisRepository(store).create(
            job_id=job.id,
            record_id=record.id,
            plant=record.plant,
            asset=record.asset,
            measured_at=record.measured_at,
            diagnosis_id=diagnosis_id,
            conn=conn,
        )

    ids = {"diagnosis_id": diagnosis_id, "record_id": record.id}
    job = jobs.submit(DIAGNOSE_JOB, ids, meta=dict(ids), with_rows=add_rows)
    return job, diagnosis_id


def get(store: PatternStore, diagnosis_id: str, *, with_result: bool = True) -> StoredDiagnosis:
    found = DiagnosisRepository(store).get(diagnosis_id, with_result=with_result)
    if found is None:
        raise NotFoundError(f"no diagnosis with id {diagnosis_id!r}; GET /v1/diagnoses lists the stored ones")
    return found


def job_state(jobs: JobManager, diagnosis: StoredDiagnosis) -> str:
    """The state of the diagnosis's job (``done`` for a stored result whose job is gone)."""
    job = jobs.repo.get(diagnosis.job_id) if diagnosis.job_id else None
    if job is not None:
        return job.state.value
    return JobState.done.value if diagnosis.status is not None else JobState.queued.value


def delete(store: PatternStore, jobs: JobManager, diagnosis_id: str) -> None:
    """Cancel the diagnosis's job if it is still queued or running, then delete the diagnosis and its figures."""
    found = get(store, diagnosis_id, with_result=False)
    job = jobs.repo.get(found.job_id) if found.job_id else None
    if job is not None and not job.finished:
        jobs.cancel(job.id)
    DiagnosisRepository(store).delete(diagnosis_id)
