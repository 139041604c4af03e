"""The backlash width of a record of another plant than the default (``identify --plant``): a thin call into the engine."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from app.services.plant_diagnosis import read_file
from engine.identification.plant_width import fit_width
from engine.plants import get_plant

__all__ = ["identify_records", "identify_width"]

#: The catalogue effect that is the backlash width, on every plant that has one.
WIDTH_EFFECT: str = "backlash"


def identify_width(plant_name: str, record: Path, joint: list[Path] | None = None) -> dict[str, Any]:
    """Read ``record`` (and the ``joint`` records of the same device) as plant ``plant_name`` reads them; fit the width.

    Raises
    ------
    RecordError
        A file that cannot be read correctly (the message says what to fix).
    ValueError
        For a plant whose catalogue has no backlash width.
    """
    plant = get_plant(plant_name)
    if WIDTH_EFFECT not in plant.catalogue:
        raise ValueError(f"plant {plant_name!r} has no backlash width in its catalogue; identify applies to brfd")
    records = [read_file(plant, record), *(read_file(plant, p) for p in joint or ())]
    return identify_records(plant_name, records)


def identify_records(plant_name: str, records: list[Any]) -> dict[str, Any]:
    """The width of ``records`` (already read) of plant ``plant_name``: continuous, and the seed's method beside it.

    Raises
    ------
    ValueError
        For a plant whose catalogue has no backlash width.
    """
    plant = get_plant(plant_name)
    if WIDTH_EFFECT not in plant.catalogue:
        raise ValueError(f"plant {plant_name!r} has no backlash width in its catalogue; identify applies to brfd")
    width = fit_width(plant, records, WIDTH_EFFECT)
    out: dict[str, Any] = {
        "plant": plant.name,
        "records": width.records,
        "unit": plant.catalogue[WIDTH_EFFECT].unit,
        "continuous": width.to_dict(),
        # the answer's doubts, in the shape every identify and diagnose answer has ({code, message, channel})
        "warnings": [
            {"code": "not_identifiable", "message": f"the width is not identifiable: {reason}", "channel": None}
            for reason in width.reasons
        ],
    }
    if plant_name == "brfd":
        out["paper"] = [_paper(plant, r) for r in records]
    return out


def _paper(plant: Any, record: Any) -> dict[str, Any]:
    """The seed's method (W3 patterns, D vector, argmin) on one record, or why it cannot run."""
    from engine.diagnosis.plant_gap import calibrate
    from engine.plants.brfd.patterns import paper_width

    try:
        res = paper_width(plant, record, calibrate(plant, record).values)
    except ValueError as exc:
        return {"record": record.name, "width": None, "reason": str(exc)}
    return {
        "record": record.name,
        "width": res.width,
        "index": res.index,
        "D": res.D,
        "widths": list(res.widths),
        "window_s": list(res.window),
    }
