"""The sim-to-real gap diagnosis (issue 4) as the service sees it: a thin call into the engine."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from engine.diagnosis import DiagnosisResult
from engine.diagnosis import diagnose as engine_diagnose
from engine.diagnosis.identification import identification_hook
from engine.diagnosis.plots import plot_gap_budget, plot_missing_term, plot_overlays, plot_residual_map
from engine.diagnosis.space import Bounds
from engine.records import Record
from engine.simulation import CATALOGUE, EffectLibrary
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription


def run(
    record: Record,
    effects: Sequence[str] | None = None,
    bounds: Bounds | None = None,
    progress: Callable[[float, str], None] | None = None,
    drive: DriveDescription | None = None,
) -> DiagnosisResult:
    """Diagnose ``record`` against the catalogue (or the named subset of it), with identification before/after.

    ``bounds`` narrows or moves the calibration's search box (:func:`engine.diagnosis.space.check_bounds`);
    ``progress(fraction, stage)`` hears of each stage; ``drive`` is the drive the record was measured on (None:
    MODEL.md's reference plant).
    """
    library = CATALOGUE if not effects else EffectLibrary([CATALOGUE[name] for name in effects])
    plant = REFERENCE_DRIVE if drive is None else drive
    return engine_diagnose(
        record,
        library=library,
        identify=identification_hook(drive=plant),
        bounds=bounds,
        progress=progress,
        drive=plant,
    )


def diagnose(record: Record, effects: Sequence[str] | None = None, bounds: Bounds | None = None) -> dict[str, Any]:
    """JSON-ready diagnosis in the response shape of issues 4 and 10."""
    return run(record, effects, bounds).to_dict()


def write_plots(record: Record, result: DiagnosisResult, out_dir: Path) -> list[Path]:
    """Residual maps (before, and after when an effect is named), record-vs-simulation overlays, the gap
    budget of the named effects and, for a gap outside the catalogue, the missing term, as PNG."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [
        plot_residual_map(result, out_dir / "residual_map_before.png"),
        plot_overlays(record, result, out_dir / "overlays.png"),
    ]
    if result.verdict.status == "explained":
        paths.append(plot_residual_map(result, out_dir / "residual_map_after.png", after=True))
    if result.verdict.effects:
        paths.append(plot_gap_budget(result, out_dir / "gap_budget.png"))
    if result.locus and result.locus.get("term"):
        paths.append(plot_missing_term(result, out_dir / "missing_term.png"))
    return paths
