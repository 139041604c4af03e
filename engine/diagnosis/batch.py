"""One diagnosis of a batch, as a task a Dask worker runs, and the summary row of its answer.

The batch command (``backlash diagnose-batch``) reads the record files in its own process and
submits :func:`diagnose_one` per record (:mod:`engine.distributed`); the answer is the same JSON a
single ``backlash diagnose`` gives.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from engine.simulation.drive import DriveDescription

__all__ = ["SUMMARY_COLUMNS", "diagnose_one", "summary_row"]

#: Columns of the batch's summary table, in order.
SUMMARY_COLUMNS: tuple[str, ...] = ("record", "status", "effect", "value", "locus", "share", "detail")


def diagnose_one(plant_name: str, record: Any, drive: DriveDescription | None = None) -> dict[str, Any]:
    """The diagnosis of one record of plant ``plant_name`` (the default plant's own diagnosis, or the generic one).

    ``drive``: the backlash drive the record was measured on (None: MODEL.md's reference plant); its provenance is
    kept with the answer.
    """
    from engine.plants import DEFAULT_PLANT, get_plant

    if plant_name == DEFAULT_PLANT:
        from engine.diagnosis.diagnose import diagnose

        if drive is None:
            return diagnose(record).to_dict(include_records=False)
        return diagnose(record, drive=drive).to_dict(include_records=False) | {"drive": drive.provenance()}
    from engine.diagnosis.plant_gap import diagnose_plant

    plant = get_plant(plant_name)
    return diagnose_plant(plant, record).to_dict(plant)


def summary_row(name: str, answer: dict[str, Any]) -> dict[str, Any]:
    """One row of the summary table from an answer of :func:`diagnose_one` (either shape)."""
    verdict = answer.get("verdict", {})
    status = answer.get("status") or verdict.get("status")
    share = verdict.get("share")
    detail = verdict.get("reason") or ""
    if "relative_error" in answer:  # a plant of the interface: errors before -> after per channel
        before, after = answer["relative_error"]["before"], answer["relative_error"]["after"]
        detail = "; ".join(f"{c} {before[c]:.3g} -> {after[c]:.3g} %" for c in before)
    return {
        "record": name,
        "status": status,
        "effect": verdict.get("effect"),
        "value": verdict.get("value"),
        "locus": verdict.get("locus"),
        "share": share,
        "detail": detail,
    }
