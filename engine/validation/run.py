"""A protocol-v2 validation run, end to end and resumable: generate, diagnose blind, then score.

1. :func:`prepare_cases` draws the cases (:func:`engine.validation.cases.generate_cases`) and
   writes ``cases/``, ``key/answer_key.json`` apart, and ``run.json`` last. Run again on the same
   directory with the same settings, it keeps them (the generator is deterministic, so an
   interrupted generation is simply redone); with other settings it refuses. A run on a described
   drive (not MODEL.md's reference plant) holds the drive's fingerprint in its fingerprint and its
   description (:meth:`~engine.simulation.drive.DriveDescription.provenance`) in ``run.json`` and the
   key, so it is resumed only on the same drive; a run on the reference drive holds neither (its
   manifests are those written before drives were described).
2. :func:`engine.validation.blind.diagnose_cases` diagnoses, from ``cases/`` alone, every case
   without a result.
3. Only then is the key read: :func:`engine.validation.score.score_cases`, and the report is
   written (:mod:`engine.validation.report`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from engine.diagnosis.diagnose import DiagnosisSettings
from engine.run_manifest import fingerprint as run_fingerprint
from engine.run_manifest import must_draw_cases
from engine.simulation import CATALOGUE, HELD_BACK, EffectLibrary
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.validation.blind import DiagnoseFn, diagnose_cases, drive_of_run, library_of_run
from engine.validation.cases import case_counts, generate_cases
from engine.validation.layout import RunLayout
from engine.validation.protocol import GENERATOR_RULES, PROTOCOL_VERSION, operating_box
from engine.validation.provenance import code_version
from engine.validation.reliability import reliability_section, run_outcomes
from engine.validation.report import build_report, metric_lines, write_report
from engine.validation.score import score_cases

logger = logging.getLogger(__name__)

__all__ = ["prepare_cases", "run_validation", "score_run"]


def _rules(absorption: bool) -> list[str]:
    """The generator rules of a run (:data:`~engine.validation.protocol.GENERATOR_RULES`)."""
    return [r for r in GENERATOR_RULES if absorption or r != "absorption"]


def _fingerprint(
    n_cases: int,
    seed: int,
    counts: Mapping[str, int],
    catalogue: EffectLibrary,
    held_back: EffectLibrary,
    absorption: bool = True,
    drive: DriveDescription | None = None,
) -> str:
    """Hash of everything the cases depend on (the held-back family enters only through it).

    A described drive's fingerprint enters as ``drive``; the reference drive (or None) adds nothing, so a
    run on it keeps the fingerprint it had before drives were described.
    """
    spec: dict[str, Any] = {
        "protocol": PROTOCOL_VERSION,
        "rules": _rules(absorption),
        "n_cases": n_cases,
        "seed": seed,
        "counts": dict(counts),
        "catalogue": [(e.name, e.field, e.bounds) for e in catalogue.values()],
        "held_back": [(e.name, e.field, e.bounds) for e in held_back.values()],
    }
    if drive is not None and not drive.is_reference:
        spec["drive"] = drive.fingerprint
    return run_fingerprint(spec)


def _drive_label(provenance: Mapping[str, Any] | None) -> str:
    """A drive for people, from a stored :meth:`~engine.simulation.drive.DriveDescription.provenance`:
    its name and the first 12 hex digits of its fingerprint (MODEL.md's reference plant when None)."""
    if provenance is None:
        return f"{REFERENCE_DRIVE.name!r} ({REFERENCE_DRIVE.fingerprint[:12]})"
    name = (provenance.get("description") or {}).get("name")
    return f"{name!r} ({str(provenance.get('fingerprint'))[:12]})"


def _same_drive(layout: RunLayout, held: Mapping[str, Any] | None, drive: DriveDescription | None) -> None:
    """Refuse a directory whose run was drawn on another drive, naming both (before the generic refusal)."""
    if held is None:
        return
    mine = None if drive is None or drive.is_reference else drive.provenance()
    theirs = held.get("drive")
    if DriveDescription.fingerprint_of(theirs) != DriveDescription.fingerprint_of(mine):
        raise FileExistsError(
            f"{layout.root} holds a validation run on drive {_drive_label(theirs)}, not on {_drive_label(mine)}; "
            "to resume it give the same drive (--drive), else choose a new output directory"
        )


def prepare_cases(
    layout: RunLayout,
    n_cases: int,
    seed: int,
    mix: Mapping[str, float] | None = None,
    catalogue: EffectLibrary = CATALOGUE,
    held_back: EffectLibrary = HELD_BACK,
    absorption: bool = True,
    drive: DriveDescription | None = None,
) -> bool:
    """Write the run's cases, key and manifest, unless the directory already holds this very run.

    Parameters
    ----------
    layout : RunLayout
        The run's directory.
    n_cases, seed, mix, catalogue, held_back, absorption, drive
        As :func:`engine.validation.cases.generate_cases` (``drive`` None: MODEL.md's reference plant).

    Returns
    -------
    bool
        True when the cases were generated now, False when the existing ones were kept.

    Raises
    ------
    FileExistsError
        The directory holds another run (other settings, another drive, protocol 1), or cases or results
        without a manifest.
    """
    counts = case_counts(n_cases, mix)
    fingerprint = _fingerprint(n_cases, seed, counts, catalogue, held_back, absorption, drive)
    has_files = bool(layout.done()) or any(layout.cases.glob("*.json"))
    held = layout.read_manifest()
    _same_drive(layout, held, drive)
    if not must_draw_cases(layout.root, held, fingerprint, has_files):
        return False
    header: dict[str, Any] = {
        "protocol": PROTOCOL_VERSION,
        "rules": _rules(absorption),
        "seed": seed,
        "n_cases": n_cases,
        "counts": counts,
        "library": list(catalogue),
        "fingerprint": fingerprint,
    }
    if drive is not None and not drive.is_reference:
        header["drive"] = drive.provenance()
    layout.write_manifest({**header, "complete": False})
    cases, key = generate_cases(n_cases, seed, catalogue, held_back, mix, absorption, drive)
    layout.write_cases((c.case_id, c.record) for c in cases)
    layout.write_key(key, {**header, "held_back": list(held_back)})
    layout.write_manifest({**header, "complete": True})
    logger.info("wrote %d cases to %s, the key to %s", n_cases, layout.cases, layout.key)
    return True


def score_run(layout: RunLayout, version: dict[str, Any] | None = None) -> dict[str, Any]:
    """Score a finished run and write ``report.json`` and ``report.md``; returns the report document.

    The answer key is read here, and only once every case has a result.

    Raises
    ------
    RuntimeError
        Some case has no result yet.
    """
    ids = layout.case_ids()
    missing = sorted(set(ids) - layout.done())
    if missing:
        raise RuntimeError(f"{len(missing)} of {len(ids)} cases have no result yet (e.g. {missing[0]}): run them first")
    results = {cid: layout.read_result(cid) for cid in ids}
    header, key = layout.read_key()
    scores = score_cases(key, results)
    seen = sorted({str((r.get("code_version") or {}).get("describe")) for r in results.values()})
    ran_with: list[dict[str, Any]] = []  # distinct, in case order (a resumed run may have run otherwise)
    for r in results.values():
        if r.get("ran_with") and r["ran_with"] not in ran_with:
            ran_with.append(r["ran_with"])
    if len(seen) > 1:
        logger.warning("the diagnoses of this run ran on %d code versions: %s", len(seen), ", ".join(seen))
    provenance: dict[str, Any] = {
        "protocol": header["protocol"],
        "seed": header["seed"],
        "n_cases": header["n_cases"],
        "counts": header["counts"],
        "library": header["library"],
        "held_back": header["held_back"],
        "code_version": code_version() if version is None else version,
        "result_code_versions": seen,
        "ran_with": ran_with,
    }
    if header.get("drive") is not None:  # a described drive (a run on the reference holds none)
        drive = drive_of_run(layout)
        provenance["drive"] = {
            "name": drive.name,
            "fingerprint": drive.fingerprint,
            "operating_box": {k: list(v) for k, v in operating_box(drive).items()},
            "description": drive.to_dict(),
        }
    doc = build_report(scores, provenance)
    # how often the verdicts stated at each confidence were right (engine.validation.reliability)
    doc["reliability"] = reliability_section(run_outcomes(layout.root.name, doc, results)[0])
    write_report(layout, doc)
    for line in metric_lines(scores.metrics):
        logger.info("%s", line)
    return doc


def run_validation(
    n_cases: int,
    seed: int,
    out_dir: str | Path,
    workers: int | None = 0,
    settings: DiagnosisSettings | None = None,
    mix: Mapping[str, float] | None = None,
    catalogue: EffectLibrary = CATALOGUE,
    held_back: EffectLibrary = HELD_BACK,
    diagnose_fn: DiagnoseFn | None = None,
    absorption: bool = True,
    scheduler: str | None = None,
    drive: DriveDescription | None = None,
) -> dict[str, Any]:
    """Run (or resume) a protocol-v2 validation and write its report (see the module notes).

    Parameters
    ----------
    n_cases : int
        Number of cases.
    seed : int
        Seed of the case generator.
    out_dir : path
        The run's directory (``run.json``, ``cases/``, ``key/``, ``results/``, ``report.*``).
    workers : int or None
        Single-threaded workers of a local Dask cluster (None: one per core; 0, the default: in this
        process).
    settings : DiagnosisSettings, optional
        Diagnosis settings (default ``DiagnosisSettings()``).
    mix : mapping of str to float, optional
        Share of each case kind (default :data:`engine.validation.protocol.DEFAULT_MIX`).
    catalogue : EffectLibrary
        The library given to the diagnosis of every case (default the full catalogue).
    held_back : EffectLibrary
        The held-back family (default :data:`engine.simulation.HELD_BACK`).
    diagnose_fn : DiagnoseFn, optional
        The diagnosis (default :func:`engine.validation.blind.diagnose_record`).
    absorption : bool
        The generator's absorption rule (:func:`engine.validation.cases.generate_cases`; off only
        in tests of the run's machinery).
    scheduler : str, optional
        An existing Dask scheduler (``tcp://host:port``; default ``$BACKLASH_DASK_SCHEDULER``, else a
        local cluster of ``workers``).
    drive : DriveDescription, optional
        The drive the cases are simulated and diagnosed on (default None: MODEL.md's reference plant);
        recorded in the manifest and the report, and a run is resumed only on the same drive.

    Returns
    -------
    dict
        The report document (as ``report.json``).

    Raises
    ------
    FileExistsError
        ``out_dir`` holds another run (other settings or another drive).
    """
    layout = RunLayout(Path(out_dir))
    version = code_version()
    prepare_cases(layout, n_cases, seed, mix, catalogue, held_back, absorption, drive)
    library = library_of_run(layout, catalogue)
    diagnose_cases(layout, library, workers, settings, diagnose_fn, version, scheduler, drive_of_run(layout))
    return score_run(layout, version)
