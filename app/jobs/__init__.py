"""Background jobs, persisted in the store's SQLite file: :class:`JobManager` runs them, :mod:`app.db.jobs` keeps them."""

from app.db.jobs import FINISHED, UNFINISHED, Job, JobState
from app.jobs.manager import JobCancelled, JobKind, JobManager, JobResult, ProgressFn, Retried

__all__ = [
    "FINISHED",
    "UNFINISHED",
    "Job",
    "JobCancelled",
    "JobKind",
    "JobManager",
    "JobResult",
    "JobState",
    "ProgressFn",
    "Retried",
]
