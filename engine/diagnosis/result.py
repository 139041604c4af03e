"""What the diagnosis of one record answers: the verdict (:class:`Verdict`, one of :data:`STATUSES`)
and everything the diagnosis found (:class:`DiagnosisResult`), with their JSON-ready copies."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from engine.diagnosis.calibration import CalibrationResult
from engine.diagnosis.candidate import Candidate
from engine.diagnosis.candidate_set import CandidateSet
from engine.diagnosis.gap import Gap
from engine.diagnosis.localisation import Cell
from engine.diagnosis.space import ALIGNMENT
from engine.diagnosis.width import AnswerWidth
from engine.records import Record, WindowUse

__all__ = ["STATUSES", "DiagnosisResult", "Verdict"]

#: Verdict statuses.
STATUSES: tuple[str, ...] = ("explained", "unexplained", "weak_gap", "no_gap")


@dataclass(frozen=True)
class Verdict:
    """Answer of the diagnosis.

    Attributes
    ----------
    status : {"explained", "unexplained", "weak_gap", "no_gap"}
        Outcome.
    effect : str or None
        Named effect with the largest share of the gap (``explained`` only).
    value : float or None
        Its fitted value, in ``unit``.
    uncertainty : float or None
        One standard deviation of the value.
    unit : str or None
        Unit of the value.
    confidence : float
        Probability that the verdict is right, 0..1: the decision's ``score`` recalibrated on blind
        validation runs (:mod:`engine.diagnosis.confidence`); for ``unexplained``, that nothing in
        the catalogue explains the record.
    reason : str
        One sentence on why.
    effects : list of dict
        Every named effect, ``{"effect", "value", "uncertainty", "unit", "locus", "share",
        "strength", "alternatives", "near_twins"}``, largest share of the gap first (empty unless
        ``explained``); ``alternatives`` lists the library's effects that give the very same
        record at that value (:func:`~engine.diagnosis.space.indistinguishable`: a measurement
        delay and a trigger offset), which no record can tell from the named one;
        ``near_twins`` the effects that this record cannot tell from it
        (``{"effect", "value", "unit", "delta_bic"}``, :mod:`engine.diagnosis.ambiguity`).
    locus : str or None
        Where in the plant the missing physics acts (None for ``no_gap``).
    missing_term : dict or None
        For ``unexplained`` and ``weak_gap``: what the missing term looks like (kind, unit,
        rms, dominant frequency, what it follows, a description); the time series is in
        :attr:`DiagnosisResult.locus`.
    left : float or None
        Fraction of the nominal excess residual energy the named effects leave [-].
    score : float or None
        The decision's uncalibrated score 0..1 behind ``confidence`` (what the map is refitted on).
    locus_confidence : float or None
        For a locus from the locus estimate (``unexplained``, ``weak_gap``): probability that the
        missing physics acts in ``locus_group`` (:func:`engine.diagnosis.confidence.locus_confidence`).
    locus_group : tuple of str
        With a locus from the locus estimate: the loci the record cannot tell from ``locus``,
        ``locus`` first (:data:`engine.simulation.parameters.LOCUS_GROUPS`): the part of the plant
        the answer names; ``(locus,)`` when it is in no group, empty without a locus estimate.
    """

    status: str
    effect: str | None
    value: float | None
    uncertainty: float | None
    unit: str | None
    confidence: float
    reason: str
    effects: tuple[dict[str, Any], ...] = ()
    locus: str | None = None
    missing_term: dict[str, Any] | None = None
    left: float | None = None
    score: float | None = None
    locus_confidence: float | None = None
    locus_group: tuple[str, ...] = ()

    @classmethod
    def without_effect(cls, status: str, confidence: float, reason: str) -> Verdict:
        """A verdict that names no effect (``no_gap``, ``weak_gap`` or ``unexplained``)."""
        return cls(status, None, None, None, None, confidence, reason)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {
            "status": self.status,
            "effect": self.effect,
            "value": self.value,
            "uncertainty": self.uncertainty,
            "unit": self.unit,
            "confidence": self.confidence,
            "reason": self.reason,
            "effects": [dict(e) for e in self.effects],
            "locus": self.locus,
            "missing_term": self.missing_term,
            "left": self.left,
            "score": self.score,
            "locus_confidence": self.locus_confidence,
            "locus_group": list(self.locus_group),
        }


@dataclass
class DiagnosisResult:
    """Everything the diagnosis found about one record.

    Attributes
    ----------
    calibration : CalibrationResult
        Calibration of the nominal model.
    cells : list of Cell
        Localisation of the nominal residual, largest excess first.
    candidates : list of Candidate
        Candidate effects, best (lowest BIC) first.
    sets : list of CandidateSet
        The best sets of two or three effects (empty when one effect fits to the noise).
    verdict : Verdict
        The answer.
    gap_before, gap_after : Gap, Gap or None
        Gap of the nominal calibration and of the named effects' fit.
    before, after : Record, Record or None
        Calibrated simulations without and with the named effects, on the record's own
        grid (all its samples) and in its units, to overlay on it directly.
    cells_after : list of Cell
        Localisation of the residual left by the named effect's fit (empty if none).
    identification : dict or None
        Filled by an :data:`IdentificationHook`, if one is given.
    n_simulations : int
        Simulations run in total.
    seconds : float
        Wall time [s].
    window : WindowUse or None
        Which of the record's samples were analysed (the test window).
    record : Record or None
        The diagnosed record (for its grid, units and event location in :meth:`to_dict`).
    locus : dict or None
        The locus estimate of an unexplained or weak gap (scores per locus, the missing
        term's time series on the record's grid), JSON-ready.
    shrinkage : float or None
        Excess energy before over after the named effects' fit.
    answer_calibration : CalibrationResult or None
        The fit of the model the answer ends with (:func:`engine.diagnosis.width.answer_calibration`:
        the named effect's or set's when explained, the best fit when unexplained, else the nominal
        one); the width, the event instant and the identification's c group come from it. None
        means the nominal calibration.
    width : AnswerWidth or None
        The backlash width of the answer, from that model, with its 95 % interval
        (:mod:`engine.diagnosis.width`).
    warnings : list of dict
        What makes the record doubtful for this plant (``{"code", "message", "channel"}``,
        :mod:`engine.diagnosis.plausibility`); empty when nothing is.
    stages : list of dict
        Where the time went: ``{"stage", "seconds"}`` per stage of the work, in order (the nominal
        calibration, the single candidates, the early escalation, the first pairs, the first
        triples, the first exchange, the singles' escalation, the sets of up to three, the
        decision, the plausibility checks, the gap after the fix or the locus, the identification), each that ran; wall
        times [s].
    """

    calibration: CalibrationResult
    cells: list[Cell]
    candidates: list[Candidate]
    verdict: Verdict
    gap_before: Gap
    gap_after: Gap | None
    before: Record
    after: Record | None
    cells_after: list[Cell] = field(default_factory=list)
    identification: dict | None = None
    n_simulations: int = 0
    seconds: float = 0.0
    n_cells: int | None = None
    window: WindowUse | None = None
    record: Record | None = None
    sets: list[CandidateSet] = field(default_factory=list)
    locus: dict[str, Any] | None = None
    shrinkage: float | None = None
    stages: list[dict[str, Any]] = field(default_factory=list)
    answer_calibration: CalibrationResult | None = None
    width: AnswerWidth | None = None
    warnings: list[dict[str, Any]] = field(default_factory=list)

    @property
    def final(self) -> CalibrationResult:
        """The calibration of the model the answer ends with (the nominal one when none is set)."""
        return self.answer_calibration if self.answer_calibration is not None else self.calibration

    def record_summary(self) -> dict[str, Any] | None:
        """How the record was read: its grid, units, the samples analysed and where the event is.

        ``event.time`` is the event instant in seconds from the record's first sample. For a
        located event the calibration places it within the located interval (``event.offset``
        [s] = the fitted ``trigger_offset`` relative to sample ``event.index``; ``event.sigma``
        its uncertainty); a given event is the labelled sample.
        """
        rec = self.record
        if rec is None:
            return None
        ts = rec.sample_interval
        loc = rec.event_location
        index = rec.origin.first + rec.event_index  # in the record as read (an excerpt's differs)
        event: dict[str, Any] = {"index": index, "located": loc is not None}
        if loc is None:
            event.update({"time": index * ts, "sigma": 0.0})
        else:
            cal = self.final  # the event instant of the model the answer ends with
            offset = cal.values.get(ALIGNMENT)
            sigma = cal.uncertainties.get(ALIGNMENT)
            event.update(loc.to_dict())
            event.update(
                {
                    "offset": offset,
                    "time": index * ts + (offset if offset is not None else 0.0),
                    "sigma": sigma if sigma is not None and math.isfinite(sigma) else loc.sigma,
                }
            )
        return {
            "sample_interval": ts,
            "n_samples": rec.origin.n_samples,
            "units": {c: rec.unit(c) for c in rec.channels},
            "event": event,
            "window": self.window.to_dict() if self.window is not None else None,
        }

    def _ranked_candidates(self) -> list[dict[str, Any]]:
        """Single effects and sets in one list, best BIC first (``kind``: "single" or "set")."""
        rows = [{"kind": "single", **c.to_dict()} for c in self.candidates] + [s.to_dict() for s in self.sets]
        return sorted(rows, key=lambda r: r["bic"] if r["bic"] is not None else math.inf)

    def _budget(self) -> dict[str, Any] | None:
        """The gap budget of the named effects: each one's share of the gap, and what is left."""
        if not self.verdict.effects:
            return None
        return {"shares": {e["effect"]: e["share"] for e in self.verdict.effects}, "left": self.verdict.left}

    def candidate(self, name: str) -> Candidate:
        """The candidate of one effect (KeyError when it was not in the library)."""
        for c in self.candidates:
            if c.effect == name:
                return c
        raise KeyError(f"effect {name!r} was not among the candidates: {', '.join(c.effect for c in self.candidates)}")

    def rank(self, name: str) -> int | None:
        """1-based rank of an effect among the candidates (None when absent)."""
        for i, c in enumerate(self.candidates):
            if c.effect == name:
                return i + 1
        return None

    def to_dict(self, include_records: bool = True) -> dict[str, Any]:
        """JSON-ready result in the shape of issue 4."""
        out = {
            "width": self.width.to_dict() if self.width is not None else None,
            "warnings": [dict(w) for w in self.warnings],
            "calibration": self.calibration.to_dict(),
            "answer_calibration": self.final.to_dict(),
            "cells": [c.to_dict() for c in self.cells[: self.n_cells]],
            "record": self.record_summary(),
            "candidates": self._ranked_candidates(),
            "verdict": self.verdict.to_dict(),
            "gap": {
                "before": self.gap_before.to_dict(),
                "after": self.gap_after.to_dict() if self.gap_after else None,
                "shrinkage": self.shrinkage,
                "budget": self._budget(),
            },
            "locus": self.locus,
            "cells_after": [c.to_dict() for c in self.cells_after[: self.n_cells]],
            "identification": self.identification,
            "n_simulations": self.n_simulations,
            "seconds": self.seconds,
            "stages": [dict(s) for s in self.stages],
        }
        if include_records:
            out["records"] = {
                "before": self.before.to_dict(),
                "after": self.after.to_dict() if self.after is not None else None,
            }
        return out
