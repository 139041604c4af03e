"""The gap diagnosis of a plant other than the default one (``--plant``, ``"plant"``): a thin call into the engine."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from engine.diagnosis.plant_gap import PlantGapReport, calibrate, diagnose_plant
from engine.diagnosis.plant_plots import plot_plant_overlay
from engine.plants import Plant, get_plant

__all__ = ["PlantDiagnosis", "PlantRecords", "read", "read_file", "run", "write_plots"]


@dataclass(frozen=True)
class PlantDiagnosis:
    """A diagnosis with what it was run on (for the plots)."""

    plant: Plant
    record: Any
    report: PlantGapReport

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready response."""
        return self.report.to_dict(self.plant)


@dataclass(frozen=True)
class PlantRecords:
    """A plant and the record files of one diagnosis, read and checked before any work is done."""

    plant: Plant
    record: Any
    calibrate_on: Any | None = None


def read_file(plant: Plant, path: Path) -> Any:
    """One record file as ``plant`` reads it (its ``read``); raises ``RecordError`` with what to fix."""
    reader = getattr(plant, "read", None)
    if reader is None:
        raise ValueError(f"plant {plant.name!r} reads its records through the default diagnosis, not --plant")
    return reader(path)


def read(plant_name: str, record_path: Path, calibrate_on: Path | None = None) -> PlantRecords:
    """Read the record (and the calibration record) of plant ``plant_name``; raises ``RecordError`` with what to fix."""
    plant = get_plant(plant_name)
    return PlantRecords(plant, read_file(plant, record_path), read_file(plant, calibrate_on) if calibrate_on else None)


def run(records: PlantRecords, hold: bool = False) -> PlantDiagnosis:
    """Diagnose the record: calibrated on itself, or on ``records.calibrate_on`` (the cross-record check).

    Parameters
    ----------
    records : PlantRecords
        What :func:`read` read.
    hold : bool
        Hold the calibration while fitting effects (default: refit it with each effect).
    """
    plant = records.plant
    calibration = calibrate(plant, records.calibrate_on) if records.calibrate_on is not None else None
    report = diagnose_plant(
        plant,
        records.record,
        calibration=calibration,
        refit=not hold,
        calibrated_on=getattr(records.calibrate_on, "name", None),
    )
    return PlantDiagnosis(plant, records.record, report)


def write_plots(result: PlantDiagnosis, out_dir: Path) -> list[Path]:
    """Measured vs simulated, before and after, around the record's events: one PNG per dynamic channel, plus
    the plant's own figures (the BRFD's force-displacement loop)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    names = [c.name for c in result.plant.channels]
    chosen = [c for c in ("acceleration", "force") if c in names] or names[:1]
    return [
        plot_plant_overlay(result.plant, result.record, result.report, out_dir / f"overlay_{c}.png", channel=c)
        for c in chosen
    ] + _plant_figures(result, out_dir)


def _plant_figures(result: PlantDiagnosis, out_dir: Path) -> list[Path]:
    """The plant's own figures, where it has any (``figures(record, before, after, out_dir)``)."""
    figures = getattr(result.plant, "figures", None)
    if figures is None:
        return []
    report = result.report
    after = report.named.fit.values if report.named else None
    return list(figures(result.record, report.calibration.values, after, out_dir))
