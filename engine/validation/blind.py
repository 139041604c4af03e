"""The blind step of a protocol-v2 validation: diagnose every case from its record alone, resumably.

Reads ``cases/`` and the run's manifest (the effect library, the same for every
case) and nothing else: never the answer key. Each case's diagnosis is written to
``results/<case_id>.json`` as soon as it is done (atomically), and a case whose
result exists is not diagnosed again, so an interrupted run loses at most the
cases in progress. A diagnosis that raises is recorded as status ``error`` (a
wrong answer for the scorer); an interruption (Ctrl-C) is not recorded.
"""

from __future__ import annotations

import logging
import multiprocessing
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

from engine.diagnosis.diagnose import DiagnosisSettings, diagnose
from engine.records import Record
from engine.simulation import EffectLibrary
from engine.validation.layout import RunLayout

logger = logging.getLogger(__name__)

__all__ = ["DiagnoseFn", "diagnose_cases", "diagnose_record", "library_of_run"]

#: A diagnosis of one record with a library and settings, returning the JSON-ready result
#: (``DiagnosisResult.to_dict()``'s shape). Must be picklable (module-level) for ``workers > 1``.
DiagnoseFn = Callable[[Record, EffectLibrary, DiagnosisSettings], dict[str, Any]]

#: Localisation cells kept per result file (the scorer reads none; they are for a reader).
CELLS_KEPT: int = 10


def diagnose_record(record: Record, library: EffectLibrary, settings: DiagnosisSettings) -> dict[str, Any]:
    """The gap diagnosis of one record as the result file stores it (no simulated records, top cells only)."""
    out = diagnose(record, library, settings).to_dict(include_records=False)
    for k in ("cells", "cells_after"):
        if isinstance(out.get(k), list):
            out[k] = out[k][:CELLS_KEPT]
    return out


def library_of_run(layout: RunLayout, catalogue: EffectLibrary) -> EffectLibrary:
    """The effect library the run hands the diagnosis: the manifest's effects, taken from ``catalogue``.

    Raises
    ------
    FileNotFoundError
        The run's cases are not (completely) written.
    """
    manifest = layout.read_manifest()
    if manifest is None or not manifest.get("complete"):
        raise FileNotFoundError(f"{layout.root} holds no complete set of cases (run.json missing or incomplete)")
    return EffectLibrary([catalogue[n] for n in manifest["library"]])


def _init_worker() -> None:
    import numba

    numba.set_num_threads(1)


def _diagnose_one(
    root: str,
    case_id: str,
    library: EffectLibrary,
    settings: DiagnosisSettings,
    fn: DiagnoseFn,
    version: dict[str, Any],
) -> tuple[str, str, float]:
    layout = RunLayout(Path(root))
    record = layout.read_case(case_id)
    t0 = time.perf_counter()
    try:
        out = fn(record, library, settings)
    except Exception as exc:
        logger.exception("diagnosis of %s failed", case_id)
        out = {
            "verdict": {"status": "error", "effect": None, "value": None, "effects": [], "locus": None},
            "error": repr(exc),
        }
    wall = time.perf_counter() - t0
    out["case_id"] = case_id
    out["wall_seconds"] = wall
    out["code_version"] = version
    layout.write_result(case_id, out)
    return case_id, str(out.get("verdict", {}).get("status")), wall


def diagnose_cases(
    layout: RunLayout,
    library: EffectLibrary,
    workers: int = 1,
    settings: DiagnosisSettings | None = None,
    diagnose_fn: DiagnoseFn | None = None,
    version: dict[str, Any] | None = None,
) -> list[str]:
    """Diagnose every case of ``cases/`` that has no result yet.

    Parameters
    ----------
    layout : RunLayout
        The run's directory (its cases written).
    library : EffectLibrary
        The candidate effects, the same for every case (:func:`library_of_run`).
    workers : int
        Parallel processes (each with one numba thread); 1 diagnoses in this process.
    settings : DiagnosisSettings, optional
        Diagnosis settings (default ``DiagnosisSettings()``).
    diagnose_fn : DiagnoseFn, optional
        The diagnosis (default :func:`diagnose_record`; tests pass a cheap stand-in).
    version : dict, optional
        Code version stored in every result (:func:`engine.validation.provenance.code_version`).

    Returns
    -------
    list of str
        Ids of the cases diagnosed by this call (in the order they finished).
    """
    settings = DiagnosisSettings() if settings is None else settings
    fn = diagnose_record if diagnose_fn is None else diagnose_fn
    version = {} if version is None else version
    ids = layout.case_ids()
    done = layout.done() & set(ids)
    todo = [c for c in ids if c not in done]
    n = len(ids)
    if done:
        logger.info("resuming: %d of %d cases already diagnosed, %d to go", len(done), n, len(todo))
    finished: list[str] = []
    t0 = time.perf_counter()

    def log(case_id: str, status: str, seconds: float) -> None:
        finished.append(case_id)
        logger.info(
            "case %d/%d %s: %s (%.1f s; %.0f s elapsed)",
            len(done) + len(finished),
            n,
            case_id,
            status,
            seconds,
            time.perf_counter() - t0,
        )

    root = str(layout.root)
    if workers <= 1:
        for case_id in todo:
            log(*_diagnose_one(root, case_id, library, settings, fn, version))
        return finished
    ctx = multiprocessing.get_context("spawn")
    ex = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker)
    try:
        pending: set[Future[tuple[str, str, float]]] = {
            ex.submit(_diagnose_one, root, c, library, settings, fn, version) for c in todo
        }
        while pending:
            ready, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in ready:
                log(*fut.result())
    finally:
        ex.shutdown(wait=True, cancel_futures=True)
    return finished
