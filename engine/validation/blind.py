"""The blind step of a protocol-v2 validation: diagnose every case from its record alone, resumably.

Reads ``cases/`` and the run's manifest (the effect library, the same for every
case, and the drive the cases were simulated on) and nothing else: never the answer
key. Each case's diagnosis is written to ``results/<case_id>.json`` as soon as it is
done (atomically), and a case whose result exists is not diagnosed again, so an
interrupted run loses at most the cases in progress. A diagnosis that raises is
recorded as status ``error`` (a wrong answer for the scorer); an interruption
(Ctrl-C) is not recorded.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from typing import Any

from engine.diagnosis.diagnose import DiagnosisSettings, diagnose
from engine.records import Record
from engine.simulation import EffectLibrary, ParameterError
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.validation.layout import RunLayout

logger = logging.getLogger(__name__)

__all__ = ["DiagnoseFn", "concurrency", "diagnose_cases", "diagnose_record", "drive_of_run", "library_of_run"]

#: A diagnosis of one record with a library and settings, returning the JSON-ready result
#: (``DiagnosisResult.to_dict()``'s shape). Must be picklable (module-level): it runs on Dask workers.
#: In a run on a described drive (not the reference) it is also given ``drive=`` (the
#: :class:`~engine.simulation.drive.DriveDescription`), so it must then take that keyword.
DiagnoseFn = Callable[[Record, EffectLibrary, DiagnosisSettings], dict[str, Any]]

#: Localisation cells kept per result file (the scorer reads none; they are for a reader).
CELLS_KEPT: int = 10


def diagnose_record(
    record: Record, library: EffectLibrary, settings: DiagnosisSettings, drive: DriveDescription = REFERENCE_DRIVE
) -> dict[str, Any]:
    """The gap diagnosis of one record as the result file stores it (no simulated records, top cells only).

    Parameters
    ----------
    record : Record
        The case's record.
    library : EffectLibrary
        The candidate effects.
    settings : DiagnosisSettings
        Diagnosis settings.
    drive : DriveDescription
        The drive the record was simulated on (default MODEL.md's reference plant;
        :func:`engine.diagnosis.diagnose.diagnose`'s ``drive``).

    Returns
    -------
    dict
        ``DiagnosisResult.to_dict(include_records=False)`` with at most :data:`CELLS_KEPT` cells.
    """
    out = diagnose(record, library, settings, drive=drive).to_dict(include_records=False)
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


def drive_of_run(layout: RunLayout) -> DriveDescription:
    """The drive a run's cases were simulated on, from its manifest's ``drive`` (the reference when absent).

    Manifests of runs on the reference drive hold no ``drive`` (as before drives were described).

    Raises
    ------
    FileNotFoundError
        The run's cases are not (completely) written.
    ValueError
        The manifest's description does not give its stated fingerprint (an edited manifest).
    """
    manifest = layout.read_manifest()
    if manifest is None or not manifest.get("complete"):
        raise FileNotFoundError(f"{layout.root} holds no complete set of cases (run.json missing or incomplete)")
    stated = manifest.get("drive")
    if stated is None:
        return REFERENCE_DRIVE
    try:
        return DriveDescription.from_provenance(stated)
    except (KeyError, TypeError, ParameterError) as exc:
        raise ValueError(f"{layout.manifest}: unreadable drive description ({exc})") from None


def concurrency(client: Any) -> dict[str, int | None]:
    """How the diagnoses of a run share the machine, stored with each result (its time depends on it).

    Returns
    -------
    dict
        ``at_once``: diagnoses running at the same time (the cluster's workers; 1 in this process);
        ``threads_each``: threads of each (a worker's threads; in this process, every core);
        ``host_cores``: cores of the machine that ran them (None for a remote scheduler's cluster,
        whose machines this process cannot see).
    """
    cores = os.cpu_count()
    if client is None:
        return {"at_once": 1, "threads_each": cores, "host_cores": cores}
    workers = client.scheduler_info().get("workers", {})  # those connected when the run starts
    threads = max((int(w.get("nthreads", 1)) for w in workers.values()), default=1)
    local = getattr(client, "cluster", None) is not None  # a client of a remote scheduler has none
    return {"at_once": len(workers), "threads_each": threads, "host_cores": cores if local else None}


def _diagnose_one(
    case_id: str,
    record: Record,
    library: EffectLibrary,
    settings: DiagnosisSettings,
    fn: DiagnoseFn,
    version: dict[str, Any],
    drive: DriveDescription | None = None,
) -> dict[str, Any]:
    """One case's result as its file stores it (a failure is recorded as status ``error``).

    ``fn`` is given ``drive=drive`` when ``drive`` is not None (a run on a described drive).
    """
    t0 = time.perf_counter()
    call: Callable[..., dict[str, Any]] = fn
    try:
        out = call(record, library, settings) if drive is None else call(record, library, settings, drive=drive)
    except Exception as exc:
        logger.exception("diagnosis of %s failed", case_id)
        out = {
            "verdict": {"status": "error", "effect": None, "value": None, "effects": [], "locus": None},
            "error": repr(exc),
        }
    out["case_id"] = case_id
    out["wall_seconds"] = time.perf_counter() - t0
    out["code_version"] = version
    return out


def diagnose_cases(
    layout: RunLayout,
    library: EffectLibrary,
    workers: int | None = 0,
    settings: DiagnosisSettings | None = None,
    diagnose_fn: DiagnoseFn | None = None,
    version: dict[str, Any] | None = None,
    scheduler: str | None = None,
    drive: DriveDescription | None = None,
) -> list[str]:
    """Diagnose every case of ``cases/`` that has no result yet, on Dask (:mod:`engine.distributed`).

    This process reads each case's record and writes each result as soon as it arrives; the
    diagnoses run on the cluster's workers (no shared file system needed).

    Parameters
    ----------
    layout : RunLayout
        The run's directory (its cases written).
    library : EffectLibrary
        The candidate effects, the same for every case (:func:`library_of_run`).
    workers : int or None
        Single-threaded worker processes of a local Dask cluster (None: one per core); 0 (the
        default) diagnoses in this process. Ignored when a scheduler is given.
    settings : DiagnosisSettings, optional
        Diagnosis settings (default ``DiagnosisSettings()``).
    diagnose_fn : DiagnoseFn, optional
        The diagnosis (default :func:`diagnose_record`; tests pass a cheap stand-in; must be
        importable by the workers, i.e. module-level).
    version : dict, optional
        Code version stored in every result (:func:`engine.validation.provenance.code_version`).
    scheduler : str, optional
        Address of an existing Dask scheduler (default ``$BACKLASH_DASK_SCHEDULER``, else a local cluster).
    drive : DriveDescription, optional
        The drive the cases were simulated on (:func:`drive_of_run`), sent to the workers with each case and
        given to the diagnosis as ``drive=``; None or the reference drive: MODEL.md's reference plant, and the
        diagnosis is called without it (as before drives were described).

    Returns
    -------
    list of str
        Ids of the cases diagnosed by this call (in the order they finished).
    """
    from engine.distributed import dask_client, map_cases

    settings = DiagnosisSettings() if settings is None else settings
    fn = diagnose_record if diagnose_fn is None else diagnose_fn
    version = {} if version is None else version
    if drive is not None and drive.is_reference:
        drive = None
    ids = layout.case_ids()
    done = layout.done() & set(ids)
    todo = [c for c in ids if c not in done]
    if done:
        logger.info("resuming: %d of %d cases already diagnosed, %d to go", len(done), len(ids), len(todo))
    finished: list[str] = []
    if not todo:
        return finished
    inputs = {c: (c, layout.read_case(c), library, settings, fn, version, drive) for c in todo}
    with dask_client(scheduler, workers) as client:
        ran_with = concurrency(client)
        for case_id, out in map_cases(client, _diagnose_one, inputs, "case", len(done), len(ids)):
            out["ran_with"] = ran_with
            layout.write_result(case_id, out)
            finished.append(case_id)
    return finished
