"""The FastAPI application: ``create_app(settings)`` and the module-level ``app`` for uvicorn.

Run it with ``backlash serve`` (or ``uvicorn app.main:app``); settings come from
``BACKLASH_*`` environment variables (:mod:`app.core.config`).
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import ExitStack, asynccontextmanager
from typing import IO

import anyio
import anyio.to_thread
from fastapi import FastAPI
from fastapi.routing import APIRoute

from app import web
from app.api.errors import register_exception_handlers
from app.api.main import api_router
from app.api.middleware import (
    ApiKeyMiddleware,
    BodyReadTimeoutMiddleware,
    BodySizeLimitMiddleware,
    HeadAsGetMiddleware,
)
from app.api.openapi import install_openapi
from app.api.routes import health
from app.api.routes.health import package_version
from app.core.config import API_V1_STR, HEALTH_THREADS, Settings, get_settings
from app.core.instance import hold_database
from app.core.logging import setup_logging
from app.jobs import JobManager
from app.services import diagnoses, training
from app.services.diagnoses import DIAGNOSE_JOB
from app.services.retention import RetentionScheduler
from app.services.sync_diagnosis import SyncDiagnoses
from app.services.training import TRAIN_JOB
from app.web.docs import install_docs
from engine.constants import MODEL_VERSION
from engine.storage import PatternStore

logger = logging.getLogger(__name__)

DESCRIPTION = f"""
Diagnostic service for mechanical backlash in electric drives (reference model {MODEL_VERSION}).

* **simulate** the backlash test of a case (`POST {API_V1_STR}/simulate`),
* **train** a pattern set in the background (`POST {API_V1_STR}/pattern-sets`, then `GET {API_V1_STR}/jobs/{{id}}`),
* **identify** the backlash width of a record (`POST {API_V1_STR}/identify`).

Records are JSON (`{{"sample_interval", "event_index", "channels", "conditions"}}`) or CSV (a header row of
channel names, one row per sample). When the service has an API key, every request but `/healthz`
needs the header `X-API-Key`.
"""


def _operation_id(route: APIRoute) -> str:
    return f"{route.tags[0]}-{route.name}" if route.tags else route.name


def create_app(settings: Settings | None = None, *, database_lock: IO[bytes] | None = None) -> FastAPI:
    """Build the application; the pattern store is opened and the job threads started on startup.

    Parameters
    ----------
    settings : Settings, optional
        Default: from the environment.
    database_lock : file, optional
        The service lock of ``settings.db_path`` (:func:`app.core.instance.hold_database`) when the caller has
        taken it (``backlash serve`` does, before it checks the store) and keeps it; otherwise the start takes
        it, before opening the store, and gives it back at shutdown.
    """
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        setup_logging(settings.log_level)
        # One pool of threads for every sync route and run_in_threadpool call, as small as the setting says.
        anyio.to_thread.current_default_thread_limiter().total_tokens = settings.request_threads
        # ... and two of its own for GET /healthz, which reads the store: it never waits behind those.
        app.state.health_threads = anyio.CapacityLimiter(HEALTH_THREADS)
        # Whatever the start took is given back in reverse order at shutdown, and also when a later
        # step of the start fails (the service lock, above all: a retry in this process must get it).
        with ExitStack() as taken:
            if database_lock is None:  # first: a refused start never opens (or migrates) the file
                taken.callback(hold_database(settings.db_path).close)  # ServiceAlreadyRunning: another has it
            app.state.store = store = PatternStore(settings.db_path)
            app.state.dask = None
            if settings.dask_scheduler is not None:
                from engine.distributed import connect

                app.state.dask = connect(settings.dask_scheduler)  # SchedulerUnreachable stops the start
                taken.callback(lambda: app.state.dask.close())
                logger.info("training jobs run on the Dask cluster at %s", settings.dask_scheduler)
            kinds = {
                TRAIN_JOB: training.job_kind(store, app.state.dask, settings.training_runs_in),
                DIAGNOSE_JOB: diagnoses.JOB_KIND,
            }
            app.state.sync_diagnoses = SyncDiagnoses(settings.max_sync_diagnoses, settings.sync_diagnose_timeout)
            taken.callback(lambda: app.state.sync_diagnoses.close())
            app.state.jobs = JobManager(
                store,
                kinds,
                workers=settings.workers,
                pools={"training": settings.workers, diagnoses.POOL: settings.diagnosis_workers},
                max_pending=settings.max_pending_jobs,
            )
            taken.callback(lambda: app.state.jobs.shutdown(wait=True))  # first at shutdown: the jobs stop
            app.state.jobs.recover()
            app.state.retention = RetentionScheduler(store, settings.retention_days, settings.retention_interval_hours)
            taken.callback(app.state.retention.stop)  # before the jobs stop: a run under way finishes first
            app.state.retention.start()  # after recover(): a run sees the interrupted jobs as finished
            logger.info(
                "store %s (%d pattern sets); %d training %s(es), %d diagnosis process(es); API key %s",
                app.state.store.path,
                len(app.state.store),
                settings.workers,
                "process" if kinds[TRAIN_JOB].runs_in == "process" else "thread",
                settings.diagnosis_workers,
                "required" if settings.api_key else "not required",
            )
            yield

    app = FastAPI(
        title="backlash",
        version=package_version(),
        description=DESCRIPTION,
        lifespan=lifespan,
        generate_unique_id_function=_operation_id,
        docs_url=None,  # served from local assets instead of a CDN (app/web/docs.py)
        redoc_url=None,
    )
    app.state.settings = settings
    register_exception_handlers(app)
    app.add_middleware(HeadAsGetMiddleware)
    app.add_middleware(BodyReadTimeoutMiddleware, timeout=settings.read_timeout)
    app.add_middleware(BodySizeLimitMiddleware, max_body_bytes=settings.max_body_bytes)
    if settings.api_key is not None:  # outermost: refuse before reading any body
        app.add_middleware(ApiKeyMiddleware, api_key=settings.api_key.get_secret_value())
    install_docs(app)  # before the report page's /static mount
    app.include_router(health.router)
    app.include_router(api_router, prefix=API_V1_STR)
    app.include_router(web.router)
    install_openapi(app)
    return app


app = create_app()
