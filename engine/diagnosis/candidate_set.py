"""A set of effects fitted together with the calibration (:func:`engine.diagnosis.sets.search_sets`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from engine.diagnosis.calibration import CalibrationResult
from engine.diagnosis.gap import Gap, gap_of, shrinkage_ratio
from engine.simulation import Effect

__all__ = ["CandidateSet"]


@dataclass
class CandidateSet:
    """A set of effects fitted together with the calibration.

    Attributes
    ----------
    effects : tuple of str
        Effect names, in the order fitted.
    calibration : CalibrationResult or None
        The joint fit.
    units : dict of str to str
        Unit of each effect's value.
    loci : dict of str to str
        Locus of each effect.
    bic : float
        Bayesian information criterion of the fit.
    gap : Gap or None
        The gap left by the fit.
    shrinkage : float
        Excess energy of the nominal fit over that of this fit.
    strengths : dict of str to float
        Per effect: the largest channel RMS change when that effect alone is set to neutral
        at the fit's operating point [noise standard deviations].
    shares : dict of str to float
        Gap budget: fraction of the nominal excess energy each effect removes
        (:func:`engine.diagnosis.budget.gap_budget`).
    left : float
        Fraction of the nominal excess energy left by the fit.
    delta_bic : float
        BIC minus the best model's BIC.
    weight : float
        Posterior probability among every model fitted (nominal, singles, sets).
    note : str
        Remarks (e.g. why it was not refined).
    searched : bool
        Whether its joint space has had the global search (the escalation), so that a later
        search that reuses it does not pay for it again.
    """

    effects: tuple[str, ...]
    calibration: CalibrationResult | None
    units: dict[str, str]
    loci: dict[str, str]
    bic: float
    gap: Gap | None = None
    shrinkage: float = 1.0
    strengths: dict[str, float] = field(default_factory=dict)
    shares: dict[str, float] = field(default_factory=dict)
    left: float = math.nan
    delta_bic: float = 0.0
    weight: float = 0.0
    note: str = ""
    searched: bool = False

    @property
    def name(self) -> str:
        """The effects joined by ``+``."""
        return "+".join(self.effects)

    @property
    def values(self) -> dict[str, float]:
        """Fitted value of every effect, in its unit."""
        cal = self.calibration
        return {e: cal.values[e] for e in self.effects} if cal is not None else {}

    @property
    def uncertainties(self) -> dict[str, float | None]:
        """One standard deviation of every effect's value."""
        cal = self.calibration
        return {e: cal.uncertainties.get(e) for e in self.effects} if cal is not None else {}

    @property
    def strength(self) -> float:
        """The weakest member's strength (a set is only as credible as its weakest effect)."""
        return min(self.strengths.values()) if self.strengths else math.nan

    @classmethod
    def from_fit(cls, effects: Sequence[Effect], cal: CalibrationResult, nominal: CalibrationResult) -> CandidateSet:
        """The set of a joint fit ``cal`` of ``effects``, compared with the ``nominal`` calibration."""
        return cls(
            effects=tuple(e.name for e in effects),
            calibration=cal,
            units={e.name: e.unit for e in effects},
            loci={e.name: e.locus for e in effects},
            bic=cal.bic,
            gap=gap_of(cal),
            shrinkage=shrinkage_ratio(nominal, cal),
        )

    def effect_rows(self) -> list[dict[str, Any]]:
        """One row per effect, ``{"effect", "value", "uncertainty", "unit", "locus", "share", "strength"}``,
        largest share first."""
        rows = [
            {
                "effect": e,
                "value": self.values.get(e),
                "uncertainty": self.uncertainties.get(e),
                "unit": self.units[e],
                "locus": self.loci[e],
                "share": self.shares.get(e),
                "strength": self.strengths.get(e),
            }
            for e in self.effects
        ]
        return sorted(rows, key=lambda r: -(r["share"] if r["share"] is not None else -math.inf))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the calibration without arrays)."""
        return {
            "kind": "set",
            "effect": self.name,
            "effects": self.effect_rows(),
            "bic": self.bic if math.isfinite(self.bic) else None,
            "delta_bic": self.delta_bic if math.isfinite(self.delta_bic) else None,
            "weight": self.weight,
            "gap_after": self.gap.to_dict() if self.gap else None,
            "shrinkage": self.shrinkage,
            "left": self.left if math.isfinite(self.left) else None,
            "calibration": self.calibration.to_dict() if self.calibration else None,
            "note": self.note,
        }
