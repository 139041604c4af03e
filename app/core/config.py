"""The service's settings: one validated ``BaseSettings``, read from ``BACKLASH_*`` environment variables.

=========================  =====================================  ==========================
environment variable        meaning                                default
=========================  =====================================  ==========================
``BACKLASH_DB_PATH``        pattern-store SQLite file              the user's data directory
``BACKLASH_API_KEY``        if set, every request but ``/healthz``  unset (no key needed)
                            needs the header ``X-API-Key``
``BACKLASH_ALLOW_NO_KEY``   1: serve on a non-loopback address     0 (refuse to start so)
                            without an API key
``BACKLASH_MAX_BODY_BYTES`` largest request body [bytes] (413)    32 MiB
``BACKLASH_MAX_BATCH_CASES`` most cases in one batch simulation    64
``BACKLASH_WORKERS``        trainings at once                      1
``BACKLASH_TRAINING_RUNS_IN`` process or thread                      process
``BACKLASH_MAX_PENDING_JOBS`` queued + running jobs before 429     16
``BACKLASH_DIAGNOSIS_WORKERS`` worker processes of diagnosis jobs    1
``BACKLASH_MAX_SYNC_DIAGNOSES`` synchronous diagnoses at once (429)  2
``BACKLASH_SYNC_DIAGNOSE_TIMEOUT`` time limit of one [s] (504)       120
``BACKLASH_REQUEST_THREADS`` requests computed at once (the rest  2 per core
                            wait; ``/healthz`` never does)
``BACKLASH_KEEP_ALIVE_TIMEOUT`` idle keep-alive connection [s]     5
``BACKLASH_READ_TIMEOUT``   longest wait for a request's headers,  30
                            or between pieces of its body [s]
``BACKLASH_LOG_LEVEL``      DEBUG, INFO, WARNING, ERROR            INFO
``BACKLASH_RETENTION_DAYS`` age [days] past which a retention run  unset (keep everything)
                            deletes finished jobs, diagnoses,
                            identifications, unreferenced records
``BACKLASH_RETENTION_INTERVAL_HOURS`` hours between the service's   24 (0: never)
                            retention runs (deletion, compaction)
``BACKLASH_MAX_PATTERN_SETS`` stored plus training pattern sets     500
                            before training is refused (507)
``BACKLASH_HISTORY_POINTS`` points of an asset's history per       1000
                            answer (newest first; ``before`` pages)
``BACKLASH_ALLOW_FMU_PLANTS`` 1: accept clients' FMUs (native code  0 (FMU uploads refused)
                            the workers run): trusted clients only
``BACKLASH_MAX_FMU_BYTES``  largest FMU archive [bytes] (413)      32 MiB
``BACKLASH_MAX_FMU_UNPACKED_BYTES`` what one may unpack to [bytes]  256 MiB
``BACKLASH_MAX_PLANTS``     stored plants before more are refused  100
                            (507)
=========================  =====================================  ==========================

Retention (:mod:`app.services.retention`) never deletes pattern sets: they are refused beyond
``BACKLASH_MAX_PATTERN_SETS`` instead, and deleted by a person (``DELETE /v1/pattern-sets/{id}``).
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path
from typing import Annotated, Final, Literal

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from engine.storage import DEFAULT_STORE_PATH

#: Prefix of every environment variable the service reads.
ENV_PREFIX = "BACKLASH_"
#: Path prefix of the versioned API.
API_V1_STR = "/v1"

#: The most cases ``BACKLASH_MAX_BATCH_CASES`` may allow (also the schema's bound on a batch's cases).
MAX_BATCH_CASES_LIMIT = 10_000
#: The most points one answer of an asset's history may hold (the ``limit`` query's bound, and what the trend
#: fits at most: the newest identifications).
MAX_HISTORY_POINTS = 10_000

LogLevel = Literal["DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"]


#: Threads of ``GET /healthz`` (it reads the store), apart from the ``request_threads`` that compute answers.
HEALTH_THREADS: Final[int] = 2


class Settings(BaseSettings):
    """Validated service settings (see the module docstring for the environment variables)."""

    model_config = SettingsConfigDict(
        env_prefix=ENV_PREFIX,
        env_ignore_empty=True,
        extra="ignore",
        frozen=True,
    )

    db_path: Path = Field(
        default=DEFAULT_STORE_PATH,
        description="Pattern-store SQLite file; created with its directory if missing. Must be on a local file system.",
    )
    api_key: SecretStr | None = Field(
        default=None,
        description="If set, every request but /healthz must send it in the X-API-Key header.",
    )
    max_body_bytes: Annotated[int, Field(ge=1024, le=1 << 30)] = Field(
        default=32 << 20,
        description="Largest accepted request body [bytes]; larger bodies get 413. The default holds a 100 kHz "
        "record of 0.8 s with five channels as JSON (about 9 MB) with room to spare.",
    )
    max_batch_cases: Annotated[int, Field(ge=1, le=MAX_BATCH_CASES_LIMIT)] = Field(
        default=64, description="Most cases in one POST /v1/simulate/batch request."
    )
    workers: Annotated[int, Field(ge=1, le=64)] = Field(
        default=1, description="Pattern sets trained at once (worker processes, or threads; see training_runs_in)."
    )
    max_pending_jobs: Annotated[int, Field(ge=1, le=10_000)] = Field(
        default=16, description="Queued plus running jobs (training, diagnosis) before new ones are refused with 429."
    )
    training_runs_in: Literal["process", "thread"] = Field(
        default="process",
        description="Where training jobs run: worker processes (the default; cancelling stops one at once and "
        "a long training does not slow the API) or threads of the service (lighter for tiny sets). With a Dask "
        "scheduler a training is sent there and a thread waits for it.",
    )
    diagnosis_workers: Annotated[int, Field(ge=1, le=64)] = Field(
        default=1,
        description="Worker processes that run diagnosis jobs (POST /v1/diagnoses); one diagnosis uses one core.",
    )
    max_sync_diagnoses: Annotated[int, Field(ge=1, le=64)] = Field(
        default=2, description="Synchronous diagnoses (POST /v1/diagnose) running at once; more get 429."
    )
    sync_diagnose_timeout: Annotated[float, Field(gt=0, le=3600)] = Field(
        default=120.0,
        description="Time limit of a synchronous diagnosis [s]; beyond it the diagnosis is stopped (504). "
        "Diagnosis jobs have no limit.",
    )
    allow_no_key: bool = Field(
        default=False,
        description="Serve on an address other than loopback without an API key (otherwise `backlash serve` "
        "refuses to start so): for a network where every client is trusted.",
    )
    request_threads: Annotated[int, Field(ge=1, le=256)] = Field(
        default_factory=lambda: 2 * (os.cpu_count() or 1),
        description="Threads that compute answers at once (simulations, identifications, figures, parsing of "
        "bodies, the store's reads); further requests wait for one. Few threads keep the event loop, which "
        "answers GET /healthz and accepts connections, from waiting behind many threads for the GIL (Starlette's "
        "default is 40); the load benchmark's committed run and its command are in docs/service-operation.md, "
        "section Load. Default: two per core.",
    )
    keep_alive_timeout: Annotated[int, Field(ge=1, le=300)] = Field(
        default=5, description="Seconds an idle keep-alive connection stays open after an answer."
    )
    read_timeout: Annotated[float, Field(gt=0, le=600)] = Field(
        default=30.0,
        description="Longest wait [s] for a request's headers (from the connection's opening or the previous "
        "answer; the connection is then closed) and between two pieces of its body (408).",
    )
    log_level: LogLevel = Field(default="INFO", description="Log level of the service and the engine.")
    retention_days: Annotated[float | None, Field(ge=0, le=36_500)] = Field(
        default=None,
        description="Age [days] past which a retention run deletes finished jobs, diagnoses (with their figures), "
        "identifications and the records nothing refers to any more (app/services/retention.py has the rules). "
        "Unset or 0: keep everything (the default: no data is lost unless this is set). Pattern sets are never "
        "deleted by age.",
    )
    retention_interval_hours: Annotated[float, Field(ge=0, le=8760)] = Field(
        default=24.0,
        description="Hours between the service's retention runs (the first one when it starts): the deletions of "
        "retention_days, then the compaction that gives freed pages back to the file system. 0: no periodic run "
        "(POST /v1/maintenance/retention and `backlash store prune` still run one).",
    )
    max_pattern_sets: Annotated[int, Field(ge=1, le=100_000)] = Field(
        default=500,
        description="Stored pattern sets plus the ones being trained beyond which a new training is refused (507): "
        "a set is about 0.5 MB, so the default bounds them near 250 MB. Delete unused sets to make room.",
    )
    history_points: Annotated[int, Field(ge=1, le=MAX_HISTORY_POINTS)] = Field(
        default=1000,
        description="Points of an asset's history one answer holds when the request gives no limit (the newest; "
        "the answer says how to read older ones).",
    )
    allow_fmu_plants: bool = Field(
        default=False,
        description="Accept the clients' own simulators as FMUs (POST /v1/fmus, POST /v1/plants) and diagnose "
        "records of them. An FMU is native code that the diagnosis workers load and run with the service's "
        "rights: turn this on only where every client that can reach the service is trusted (docs/fmu-plant.md).",
    )
    max_fmu_bytes: Annotated[int, Field(ge=1024, le=1 << 30)] = Field(
        default=32 << 20, description="Largest FMU archive accepted [bytes]; a larger one gets 413."
    )
    max_fmu_unpacked_bytes: Annotated[int, Field(ge=1024, le=1 << 32)] = Field(
        default=256 << 20,
        description="Most bytes an FMU archive's members may unpack to [bytes]; beyond it the archive is refused "
        "(422) before anything is unpacked.",
    )
    max_plants: Annotated[int, Field(ge=1, le=10_000)] = Field(
        default=100, description="Stored plants beyond which a new one is refused (507): delete one first."
    )
    dask_scheduler: str | None = Field(
        default=None,
        description="Address of a Dask scheduler (tcp://host:port; the same variable as the CLI's, "
        "BACKLASH_DASK_SCHEDULER): training jobs then run on that cluster; the job API is unchanged.",
    )

    @field_validator("dask_scheduler")
    @classmethod
    def _check_dask_scheduler(cls, value: str | None) -> str | None:
        if value is not None and "://" not in value:
            raise ValueError(f"dask_scheduler must be an address such as tcp://host:8786, got {value!r}")
        return value

    @field_validator("retention_days")
    @classmethod
    def _zero_keeps_forever(cls, value: float | None) -> float | None:
        return None if value is not None and value == 0 else value

    @field_validator("log_level", mode="before")
    @classmethod
    def _upper_log_level(cls, value: object) -> object:
        return value.strip().upper() if isinstance(value, str) else value

    @field_validator("api_key")
    @classmethod
    def _check_api_key(cls, value: SecretStr | None) -> SecretStr | None:
        if value is None:
            return None
        key = value.get_secret_value()
        if len(key) < 8 or key != key.strip():
            raise ValueError("api_key must be at least 8 characters without surrounding whitespace")
        return value

    @field_validator("db_path")
    @classmethod
    def _check_db_path(cls, value: Path) -> Path:
        text = str(value)
        if text in ("", ".", ":memory:") or text.startswith("file:"):
            raise ValueError(f"db_path must be a database file path, got {text!r}")
        return value.expanduser()


@lru_cache
def get_settings() -> Settings:
    """The settings from the environment, read once per process."""
    return Settings()
