"""The sim-to-real gap diagnosis of one record: calibrate, localise, rank candidate effects, decide.

Decision rule (thresholds in :class:`DiagnosisSettings`)
--------------------------------------------------------
Every candidate effect is fitted (with the calibration) and ranked by BIC.
The fit statistic of a calibration is its noise-normalised residual energy
per sample, ``chi2 / n`` (1 when the model reproduces the record to the
noise), in total and per channel. The noise level comes from the record
itself (:func:`~engine.diagnosis.noise.estimate_noise`, relative
standard error about 2.2 % per channel), so the statistic scatters by a few
per cent around 1 even without a gap; the thresholds allow for that. A fit is
"to the noise" when total ``chi2/n <= max_reduced_chi2`` and every channel's
``chi2_j/n_j <= max_channel_chi2``.

* Evidence for an effect: the best candidate lowers the BIC of the nominal
  model by at least ``min_delta_bic`` (a likelihood-ratio test; unlike the
  absolute fit statistic it does not depend on the noise estimate's error).
* With evidence: ``explained`` when the best candidate fits to the noise and
  the fitted effect moves the record clearly beyond the noise (some channel's
  RMS change, fit with the effect minus the same calibration without it, above
  ``min_strength`` = 3 noise standard deviations: the validation's rule);
  ``no_gap`` when it fits but is weaker than that; ``unexplained`` when no
  candidate fits to the noise.
  When no candidate fits to the noise, the verdict is still ``no_gap`` if the
  gap is not clearly beyond the noise by both measures at hand: the nominal
  misfit (RMS beyond the noise, ``sqrt(chi2_j/n_j - 1)``, at most
  ``min_strength`` in every channel) and the best candidate's strength (at
  most ``min_strength``): a statistically significant but weak residue, such
  as a fine speed quantum that no candidate models (added after the seed-31
  blind run, see docs/diagnosis.md section 4).
* Without evidence: ``no_gap`` when the nominal model fits to the noise;
  ``weak_gap`` when its misfit is statistically beyond the noise but weaker
  than the rule above (the nominal misfit at most ``min_strength`` in every
  channel), else ``unexplained``.

Several effects at once (issue 10)
----------------------------------
When no single candidate fits to the noise, sets of two and three effects are
fitted (:mod:`engine.diagnosis.sets`). The model compared with the rules above
is then the most parsimonious of the best single candidate, the best pair and
the best triple: a larger set replaces a smaller model only when it lowers the
BIC by at least ``min_delta_bic`` and every one of its effects is strong
(moves the record by more than ``min_strength`` noise RMS on its own). The
verdict lists the set's effects with their share of the gap (the gap budget,
:func:`engine.diagnosis.sets.gap_budget`), largest first; ``effect`` and
``value`` are the largest share's.

Weak gaps
---------
``weak_gap`` replaces the former ``no_gap`` answers for gaps that are
statistically real but too weak to attribute: the nominal misfit beyond the
noise but at most ``min_strength`` noise RMS in every channel, or an effect
with evidence whose fit moves the record by at most ``min_strength`` while the
nominal model does not fit to the noise itself. ``no_gap`` is kept for records
the nominal model fits to the noise, with or without such a weak effect. The
strengths are in units of the noise the fit used, floored at 60 dB below each
channel's RMS (:data:`engine.diagnosis.noise.NOISE_FLOOR_REL`): a noiseless
(simulated) record is judged against that floor, not against a zero noise.

Locus
-----
Every verdict with a gap names the part of the plant where the missing physics
acts (``verdict.locus``, one of :data:`engine.simulation.LOCI`): the locus of
the named effect with the largest share; for ``unexplained`` and ``weak_gap``
the locus the data point to (:func:`engine.diagnosis.locus.estimate_locus`,
which also estimates the missing term: ``verdict.missing_term``).

Confidence (0..1): for ``no_gap`` and ``unexplained`` a logistic function of
how far the deciding statistic lies from its threshold (in units of the
statistic's scatter on clean records); for ``explained`` the same for the
best candidate's fit, times its posterior weight among all candidates and the
nominal model (BIC weights), so two effects that explain the record equally
well share the confidence.

Twins
-----
Each named effect lists its exact twins (``alternatives``: effects that give the very same
record, :func:`engine.diagnosis.space.indistinguishable`) and its near twins in this record
(``near_twins``: an effect that, in place of the named one, gives a model that explains the
record as well and whose BIC is higher by less than ``min_delta_bic``,
:mod:`engine.diagnosis.ambiguity`).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from scipy.special import expit

from engine.diagnosis.ambiguity import Model, NearTwin, near_twins
from engine.diagnosis.calibration import CalibrationResult, CalibrationSettings, calibrate
from engine.diagnosis.candidate import Candidate, CandidateSettings, effect_strength, posterior_weights
from engine.diagnosis.candidates import escalate_candidates, fit_candidates, needs_escalation
from engine.diagnosis.gap import Gap, closed_fraction, gap_of
from engine.diagnosis.localisation import DEFAULT_WINDOWS_MS, Cell, localise
from engine.diagnosis.sets import CandidateSet, ScreenCache, SetSettings, search_sets
from engine.diagnosis.space import ALIGNMENT, Bounds, ModelSpace, default_space, indistinguishable
from engine.parallel import single_threaded_blas
from engine.records import Record, WindowUse
from engine.simulation import CATALOGUE, EffectLibrary

logger = logging.getLogger(__name__)

__all__ = [
    "DiagnosisResult",
    "DiagnosisSettings",
    "IdentificationHook",
    "Verdict",
    "decide",
    "diagnose",
    "fit_statistic",
]

#: Hook for identification before/after (wired by the service, e.g.
#: :func:`engine.diagnosis.identification.identification_hook`): called as
#: ``hook(record, result)`` once the result is complete (verdict, calibration,
#: ``before``/``after`` simulations); returns a JSON-ready dict stored under
#: ``"identification"``.
IdentificationHook = Callable[[Record, "DiagnosisResult"], dict]


#: A single candidate's fit "moved" during the escalation (so that the pairs built from it are fitted
#: again) when some value changed by more than this fraction (polishing moves values by ~0.1 %).
MOVED_REL_TOL: float = 0.01

#: Search settings of the nominal calibration of a diagnosis: 256 Sobol points, 16 of them screened
#: on the first horizon, 2 continued over six horizons with a scan of every parameter at each
#: extension (a wide backlash seen only in the drive's own channels leaves the early window flat
#: in c; docs/diagnosis.md section 8c).
NOMINAL_CALIBRATION = CalibrationSettings(
    n_global=256, n_starts=2, n_screen=16, horizons_ms=(10.0, 20.0, 40.0, 80.0, 130.0, 200.0), n_extend_scan=17
)


@dataclass(frozen=True)
class DiagnosisSettings:
    """Settings of :func:`diagnose`.

    Parameters
    ----------
    calibration : CalibrationSettings
        Search settings of the nominal calibration.
    candidates : CandidateSettings
        Search settings of the candidate fits.
    max_reduced_chi2 : float
        Largest total chi2/n of a fit "to the noise".
    max_channel_chi2 : float
        Largest chi2_j/n_j of any one channel of a fit "to the noise".
    chi2_scatter : float
        Scatter (standard deviation) of the total chi2/n on clean records; sets
        the width of the confidence's logistic function.
    min_delta_bic : float
        Smallest BIC improvement of the best candidate over the nominal model
        that counts as evidence for an effect.
    min_strength : float
        An explaining effect counts as a gap only when it moves some channel by
        more than this many noise standard deviations (RMS); the blind
        validation's rule for "clearly beyond the noise".
    strength_scatter : float
        Width of the logistic confidence around ``min_strength``.
    n_cells : int or None
        Localisation cells kept in :meth:`DiagnosisResult.to_dict`, largest
        excess first (None: all 5 x 11 x 5 of a five-channel record; the object keeps all).
    sets : SetSettings
        Search settings of the sets of effects (``max_size = 1`` turns the set search off).
    locate : bool
        Estimate the locus and the missing term of an unexplained or weak gap.
    """

    calibration: CalibrationSettings = NOMINAL_CALIBRATION
    candidates: CandidateSettings = field(default_factory=CandidateSettings)
    max_reduced_chi2: float = 1.05
    max_channel_chi2: float = 1.2
    chi2_scatter: float = 0.02
    min_delta_bic: float = 10.0
    min_strength: float = 3.0
    strength_scatter: float = 0.3
    n_cells: int | None = None
    sets: SetSettings = field(default_factory=SetSettings)
    locate: bool = True

    def set_search(self) -> SetSettings:
        """The set search's settings with this diagnosis's decision thresholds (``min_strength``,
        ``max_reduced_chi2``), which the search uses to stop and to drop weak members."""
        return replace(self.sets, min_strength=self.min_strength, max_reduced_chi2=self.max_reduced_chi2)


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
        0..1.
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
    stages : list of dict
        Where the time went: ``{"stage", "seconds"}`` per stage of the work, in order (the nominal
        calibration, the single candidates, the early escalation, the first pairs, the first
        triples, the singles' escalation, the sets of up to three, the decision, the gap after
        the fix or the locus, the identification), each that ran; wall times [s].
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
        event: dict[str, Any] = {"index": rec.event_index, "located": loc is not None}
        if loc is None:
            event.update({"time": rec.event_index * ts, "sigma": 0.0})
        else:
            cal = self.calibration
            offset = cal.values.get(ALIGNMENT)
            sigma = cal.uncertainties.get(ALIGNMENT)
            event.update(loc.to_dict())
            event.update(
                {
                    "offset": offset,
                    "time": rec.event_index * ts + (offset if offset is not None else 0.0),
                    "sigma": sigma if sigma is not None and math.isfinite(sigma) else loc.sigma,
                }
            )
        return {
            "sample_interval": ts,
            "n_samples": rec.n_samples,
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
            "calibration": self.calibration.to_dict(),
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


def fit_statistic(cal: CalibrationResult) -> tuple[float, float]:
    """Total chi2/n and the largest per-channel chi2_j/n_j of a calibration."""
    n_per = cal.n_data / max(len(cal.chi2_per_channel), 1)
    worst = max(c / n_per for c in cal.chi2_per_channel.values())
    return cal.reduced_chi2, worst


def _adequacy(cal: CalibrationResult, s: DiagnosisSettings) -> float:
    """Probability-like score (0..1) that a fit is "to the noise"."""
    total, worst = fit_statistic(cal)
    m_total = (s.max_reduced_chi2 - total) / s.chi2_scatter
    m_ch = (s.max_channel_chi2 - worst) / (2.0 * s.chi2_scatter)
    return float(expit(min(m_total, m_ch)))


def _fits_noise(cal: CalibrationResult, s: DiagnosisSettings) -> bool:
    total, worst = fit_statistic(cal)
    return total <= s.max_reduced_chi2 and worst <= s.max_channel_chi2


def _strength(m: Model) -> float:
    """How far a model's (weakest) effect moves the record [noise RMS]; inf when unknown."""
    st = m.strength
    return float(st) if st is not None and math.isfinite(st) else math.inf


def _all_strong(s: CandidateSet, settings: DiagnosisSettings) -> bool:
    return bool(s.strengths) and all(math.isfinite(v) and v > settings.min_strength for v in s.strengths.values())


def choose_model(
    candidates: Sequence[Candidate], sets: Sequence[CandidateSet], settings: DiagnosisSettings
) -> Model | None:
    """The most parsimonious of the best single candidate, the best pair and the best triple.

    A larger set replaces the smaller model only when it lowers the BIC by at least
    ``min_delta_bic`` and every one of its effects is strong (moves the record by more
    than ``min_strength`` noise RMS on its own).
    """
    chosen: Model | None = next((c for c in candidates if c.calibration is not None), None)
    for size in (2, 3):
        best = next((x for x in sets if len(x.effects) == size and x.calibration is not None), None)
        if best is None or not _all_strong(best, settings):
            continue
        if chosen is None or best.bic <= chosen.bic - settings.min_delta_bic:
            chosen = best
    return chosen


def _rows(m: Model, nominal: CalibrationResult) -> tuple[tuple[dict[str, Any], ...], float]:
    """The verdict's effect rows (largest share first) and the fraction left."""
    if isinstance(m, CandidateSet):
        return tuple(m.effect_rows()), m.left
    cal = m.calibration
    share = closed_fraction(nominal, cal) if cal is not None else 0.0
    row = {
        "effect": m.effect,
        "value": m.value,
        "uncertainty": m.uncertainty,
        "unit": m.unit,
        "locus": m.locus,
        "share": share,
        "strength": m.strength,
    }
    return (row,), 1.0 - share


def _named(rows: Sequence[Mapping[str, Any]]) -> str:
    return " and ".join(f"{r['effect']} = {r['value']:.4g} {r['unit']}" for r in rows)


def decide(
    nominal: CalibrationResult,
    candidates: list[Candidate],
    settings: DiagnosisSettings,
    sets: Sequence[CandidateSet] = (),
) -> Verdict:
    """The verdict from the nominal calibration, the ranked candidates and sets (see the module notes)."""
    model = choose_model(candidates, sets, settings)
    total, worst = fit_statistic(nominal)
    gap_rms = math.sqrt(max(worst - 1.0, 0.0))
    dbic = nominal.bic - model.bic if model is not None else -math.inf
    if model is None or model.calibration is None or dbic < settings.min_delta_bic:
        best_name = model.effect if isinstance(model, Candidate) else model.name if model is not None else None
        what = (
            f"no candidate improves the fit significantly (best: {best_name}, BIC lower by {dbic:.1f} < "
            f"{settings.min_delta_bic:g})"
            if model is not None
            else "no candidate could be fitted"
        )
        if _fits_noise(nominal, settings):
            return Verdict.without_effect(
                "no_gap",
                _adequacy(nominal, settings),
                f"the calibrated nominal model fits to the noise (chi2/n = {total:.3f}, worst channel "
                f"{worst:.3f}) and {what}",
            )
        if gap_rms <= settings.min_strength:
            return Verdict.without_effect(
                "weak_gap",
                float(expit((settings.min_strength - gap_rms) / settings.strength_scatter)),
                f"the nominal model leaves a misfit beyond the noise (chi2/n = {total:.3g}, worst channel "
                f"{worst:.3g}) but a weak one ({gap_rms:.2f} noise RMS, <= {settings.min_strength:g}), and {what}",
            )
        return Verdict.without_effect(
            "unexplained",
            1.0 - _adequacy(nominal, settings),
            f"the nominal model leaves a gap (chi2/n = {total:.3g}, worst channel {worst:.3g}) and {what}",
        )
    m_cal = model.calibration
    b_total, b_worst = fit_statistic(m_cal)
    rows, left = _rows(model, nominal)
    strength = _strength(model)
    sure = float(expit((strength - settings.min_strength) / settings.strength_scatter))
    if _fits_noise(m_cal, settings):
        if strength <= settings.min_strength and _fits_noise(nominal, settings):
            # as without a candidate: nothing beyond the noise, and what the best fit adds is too weak to count
            # (a noiseless record, judged against the noise floor, gets here: its BIC favours any refinement)
            return Verdict.without_effect(
                "no_gap",
                _adequacy(nominal, settings),
                f"the calibrated nominal model fits to the noise (chi2/n = {total:.3g}, worst channel {worst:.3g}); "
                f"the best candidate, {_named(rows)}, moves the record by only {strength:.2f} noise RMS "
                f"(<= {settings.min_strength:g})",
            )
        if strength <= settings.min_strength:
            return Verdict.without_effect(
                "weak_gap",
                1.0 - sure,
                f"{_named(rows)} fits the record but moves it by only {strength:.2f} noise RMS "
                f"(<= {settings.min_strength:g}): a gap beyond the noise, too weak to attribute",
            )
        top = rows[0]
        shares = ", ".join(f"{r['effect']} {100 * (r['share'] or 0):.0f} %" for r in rows)
        return Verdict(
            "explained",
            top["effect"],
            top["value"],
            top["uncertainty"],
            top["unit"],
            _adequacy(m_cal, settings) * model.weight * sure,
            f"adding {_named(rows)} brings the fit to the noise (chi2/n {total:.3g} -> {b_total:.3f}, worst "
            f"channel {b_worst:.3f}); gap budget: {shares}, {100 * left:.1f} % left",
            effects=rows,
            locus=top["locus"],
            left=left,
        )
    weakest = max(gap_rms, strength)
    if weakest <= settings.min_strength:
        return Verdict.without_effect(
            "weak_gap",
            float(expit((settings.min_strength - weakest) / settings.strength_scatter)),
            f"no candidate brings the fit to the noise (the best, {_named(rows)}, leaves chi2/n = "
            f"{b_total:.3g}), and the gap is weak: the nominal misfit is {gap_rms:.2f} noise RMS beyond the "
            f"noise and the best candidate moves the record by {strength:.2f} noise RMS (both <= "
            f"{settings.min_strength:g})",
        )
    return Verdict.without_effect(
        "unexplained",
        1.0 - _adequacy(m_cal, settings),
        f"no candidate or set of candidates brings the fit to the noise: the best, {_named(rows)}, leaves "
        f"chi2/n = {b_total:.3g} (worst channel {b_worst:.3g})",
    )


def _reweight(nominal: CalibrationResult, cands: Sequence[Candidate], sets: Sequence[CandidateSet]) -> None:
    """Posterior weights and delta BIC over every model fitted: the nominal one, single effects and sets."""
    models: list[Model] = [*cands, *sets]
    names = [m.effect if isinstance(m, Candidate) else m.name for m in models]
    w = posterior_weights({"<nominal>": nominal.bic, **dict(zip(names, (m.bic for m in models), strict=True))})
    best = min((m.bic for m in models), default=math.inf)
    for name, m in zip(names, models, strict=True):
        m.weight = w[name]
        m.delta_bic = m.bic - best


def _locate(
    record: Record, nominal: CalibrationResult, verdict: Verdict, space: ModelSpace
) -> tuple[Verdict, dict[str, Any] | None]:
    """The verdict with the locus and missing term the data point to (see :mod:`engine.diagnosis.locus`)."""
    from engine.diagnosis.locus import estimate_locus

    try:
        report = estimate_locus(record, nominal, space=space)
    except (ValueError, RuntimeError) as exc:  # the diagnosis stands without it; say why
        logger.warning("locus estimate failed: %s", exc)
        return replace(verdict, reason=f"{verdict.reason}; the locus could not be estimated ({exc})"), None
    out = report.to_dict()
    term = {k: v for k, v in out.get("term", {}).items() if k not in ("series", "t")} if out.get("term") else None
    return replace(verdict, locus=report.locus, missing_term=term), out


def _explains(s: CandidateSet, settings: DiagnosisSettings) -> bool:
    """Whether a set fits to the noise with every member strong (no single escalation needed)."""
    return s.calibration is not None and _fits_noise(s.calibration, settings) and _all_strong(s, settings)


def _explains_single(cands: Sequence[Candidate], settings: DiagnosisSettings) -> bool:
    """Whether the best fitted single candidate fits to the noise."""
    best = next((c for c in cands if c.calibration is not None), None)
    return best is not None and best.calibration is not None and _fits_noise(best.calibration, settings)


def _moved(before: Mapping[str, Mapping[str, float]], c: Candidate) -> bool:
    """Whether a candidate's fit left its earlier fit's basin (a value changed by more than ``MOVED_REL_TOL``)."""
    old = before.get(c.effect)
    if old is None or c.calibration is None:
        return True
    new = c.calibration.values
    return any(not math.isclose(v, old.get(k, math.nan), rel_tol=MOVED_REL_TOL, abs_tol=1e-6) for k, v in new.items())


def _explains_as_well(m: Model, settings: DiagnosisSettings) -> bool:
    """Whether a model explains the record as a named one must: refined at the final integrator
    step, fits to the noise, every effect strong."""
    cal = m.calibration
    if cal is None or cal.step != settings.candidates.seeded.final_step:
        return False
    if isinstance(m, CandidateSet):
        return _explains(m, settings)
    strong = m.strength is not None and math.isfinite(m.strength) and m.strength > settings.min_strength
    return strong and _fits_noise(cal, settings)


def _near_twins(
    verdict: Verdict,
    model: Model | None,
    models: Sequence[Model],
    settings: DiagnosisSettings,
    library: EffectLibrary,
) -> dict[str, tuple[NearTwin, ...]]:
    """Near twins of the named effects of ``model`` (:mod:`engine.diagnosis.ambiguity`); none unless explained."""
    if model is None or verdict.status != "explained":
        return {}
    return near_twins(model, models, lambda m: _explains_as_well(m, settings), settings.min_delta_bic, library)


def _with_alternatives(
    verdict: Verdict, library: EffectLibrary, near: Mapping[str, Sequence[NearTwin]] | None = None
) -> Verdict:
    """The verdict with every named effect's indistinguishable twins (``alternatives``), its near twins
    in this record (``near_twins``, :mod:`engine.diagnosis.ambiguity`) and a word on each."""
    if not verdict.effects:
        return verdict
    near = {} if near is None else near
    rows = []
    notes = []
    for r in verdict.effects:
        value = r.get("value")
        alts = indistinguishable(r["effect"], float(value), library) if value is not None else ()
        twins = tuple(near.get(r["effect"], ()))
        rows.append({**r, "alternatives": list(alts), "near_twins": [t.to_dict() for t in twins]})
        if alts:
            notes.append(f"{r['effect']} cannot be told from {' or '.join(alts)} (the same shift of every channel)")
        if twins:
            others = " or ".join(
                f"{t.effect}" + (f" = {t.value:.4g} {t.unit}" if t.value is not None else "") for t in twins
            )
            margins = ", ".join(f"{t.delta_bic:.1f}" for t in twins)
            notes.append(
                f"this record cannot tell {r['effect']} from {others}: the fit with it in its place explains the "
                f"record as well (BIC higher by only {margins})"
            )
    reason = f"{verdict.reason}; {'; '.join(notes)}" if notes else verdict.reason
    return replace(verdict, effects=tuple(rows), reason=reason)


def _singles_of_sets(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    cands: Sequence[Candidate],
    sets: Sequence[CandidateSet],
    settings: DiagnosisSettings,
) -> list[Candidate]:
    """The candidates, each refitted from a set that fits to the noise with it as its only strong member.

    The set search's backward elimination stops at pairs; a pair's global search can reach the basin
    of a single effect that its own seeded and escalated fits missed, the other member weak at its
    neutral value (seed-137 case0055: a stator drift of 1.45 fitted at 1.05 alone, at 1.451 beside a
    neutral rotor drift). That single is refitted from the pair's fit (seeded, refined at the final
    step) and replaces its candidate when its BIC is lower; best BIC first.
    """
    from engine.diagnosis.calibration import CalibrationError

    out = list(cands)
    index = {c.effect: i for i, c in enumerate(out)}
    source: dict[str, CandidateSet] = {}  # per single, the best set it is the only strong member of
    for st in sets:
        if st.calibration is None or not _fits_noise(st.calibration, settings):
            continue
        strong = [e for e, v in st.strengths.items() if math.isfinite(v) and v > settings.min_strength]
        if len(strong) == 1 and strong[0] in index and (strong[0] not in source or st.bic < source[strong[0]].bic):
            source[strong[0]] = st
    for name, st in source.items():
        cal = st.calibration
        assert cal is not None  # kept above
        seed = {k: v for k, v in cal.values.items() if k not in st.effects or k == name}
        try:
            fit = calibrate(
                record,
                space.with_effect(library[name]),
                settings.candidates.seeded,
                noise=nominal.noise,
                seeds=[seed],
                polish=True,
            )
        except CalibrationError as exc:
            logger.info("single %s from the set %s could not be fitted: %s", name, st.name, exc)
            continue
        old = out[index[name]]
        if old.calibration is not None and fit.bic >= old.bic:
            continue
        new = Candidate.from_fit(library[name], fit, nominal)
        new.strength = effect_strength(new, space, record, nominal.sigma)
        logger.info("single %s refitted from the set %s: chi2/n %.4g", name, st.name, fit.reduced_chi2)
        out[index[name]] = replace(new, escalated=old.escalated)
    return sorted(out, key=lambda c: c.bic)


def _staged_search(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    cands: list[Candidate],
    settings: DiagnosisSettings,
    stage: Callable[[str], None],
) -> tuple[list[Candidate], list[CandidateSet]]:
    """The staged search of :attr:`SetSettings.before_escalation`, from the seeded single fits.

    In order, each stage only while nothing explains the record: the early escalation of the best
    singles (a single effect whose seeded fit stayed in the nominal calibration's basin is most
    often among them, and found in seconds); the first pairs from the seeded singles, the best with
    a global search in their joint space; the first triples (``first_triples``: seeded fits only);
    the escalation of the singles (``n_escalate_singles``); the search of sets of up to three from
    the escalated singles. The first triples start from every first pair as fitted; the last
    search keeps the ``n_report`` best sets so far unless the escalation moved a member's single
    fit, and fits the rest again; the decision sees each search's ``n_report`` best.

    Parameters
    ----------
    record, nominal, space, library
        As in :func:`diagnose` (``record`` is the test window).
    cands : list of Candidate
        The seeded single candidates (``fit_candidates(..., escalate=False)``).
    settings : DiagnosisSettings
        The diagnosis's settings.
    stage : callable
        ``stage(name)`` closes a stage of the work (its wall time goes to ``DiagnosisResult.stages``).

    Returns
    -------
    cands : list of Candidate
        The single candidates, escalated where a stage escalated them.
    sets : list of CandidateSet
        The sets for the decision, best BIC first.
    """
    cs = settings.candidates
    ss = settings.set_search()
    sets: list[CandidateSet] = []
    if ss.n_escalate_first > 0 and needs_escalation(cands, cs):
        cands = escalate_candidates(record, nominal, space, library, cands, ss.escalation(cs, early=True))
        stage("early escalation of the best singles")
    if _explains_single(cands, settings):
        return cands, sets
    everything = replace(ss, n_report=None)  # every set fitted, for the later stages
    screens: ScreenCache = {}  # the staged searches screen the same best singles
    fitted = search_sets(record, nominal, space, library, cands, cs, replace(everything, max_size=2), (), screens)
    sets = fitted[: ss.n_report]
    stage("first pairs")
    if ss.first_triples and ss.max_size >= 3 and not any(_explains(s, settings) for s in sets):
        seeded_only = replace(everything, escalate=False, n_exchange=0)
        triples = search_sets(record, nominal, space, library, cands, cs, seeded_only, fitted, screens)
        fitted = _merge_sets(fitted, triples)
        sets = fitted[: ss.n_report]
        stage("first triples")
    if any(_explains(s, settings) for s in sets):
        return cands, sets
    seeded = {c.effect: c.calibration.values for c in cands if c.calibration is not None}
    if needs_escalation(cands, cs):
        cands = escalate_candidates(record, nominal, space, library, cands, ss.escalation(cs))
        stage("escalation of the singles")
    if not _explains_single(cands, settings):
        # the best sets so far stand as fitted unless the escalation moved a single they came from; the
        # others are fitted again from the escalated singles (keeping every unmoved set lost seed-151
        # case0168: its true triple was found from a pair refitted there, docs/diagnosis.md 8b)
        moved = {c.effect for c in cands if c.calibration is not None and _moved(seeded, c)}
        keep = [s for s in sets if not moved & set(s.effects)]
        again = search_sets(record, nominal, space, library, cands, cs, ss, keep, screens)
        sets = _merge_sets(sets, again)
        stage("sets of up to three")
    return cands, sets


def _merge_sets(first: Sequence[CandidateSet], second: Sequence[CandidateSet]) -> list[CandidateSet]:
    """The sets of two searches, the better fit of each group of effects, best BIC first."""
    best: dict[frozenset[str], CandidateSet] = {}
    for s in (*first, *second):
        key = frozenset(s.effects)
        if key not in best or s.bic < best[key].bic:
            best[key] = s
    return sorted(best.values(), key=lambda s: s.bic)


def diagnose(
    record: Record,
    library: EffectLibrary = CATALOGUE,
    settings: DiagnosisSettings = DiagnosisSettings(),
    identify: IdentificationHook | None = None,
    noise: Mapping[str, float] | None = None,
    bounds: Bounds | None = None,
    progress: Callable[[float, str], None] | None = None,
) -> DiagnosisResult:
    """Diagnose the sim-to-real gap of one record.

    Parameters
    ----------
    record : Record
        The measured record (any subset of channels; conditions may fix K [m],
        J1 [kg m^2], c [pu], c1 [pu]).
    library : EffectLibrary
        Candidate effects (default: the full catalogue of issue 4).
    settings : DiagnosisSettings
        Search settings and decision thresholds.
    identify : IdentificationHook, optional
        Identification before/after the fix (stored under ``identification``).
    noise : mapping of str to float, optional
        Known noise standard deviation per channel (channel unit); estimated when omitted.
    bounds : mapping, optional
        Search box of the calibrated parameters, ``name -> (low, high)`` in the parameter's
        unit (K [m], J1 [kg m^2], c [pu], c1 [pu]); parameters not given keep
        :data:`~engine.diagnosis.space.DEFAULT_BOUNDS`, the plausible box (see
        :func:`~engine.diagnosis.space.check_bounds`).
    progress : callable, optional
        ``progress(fraction, stage)`` at each stage (calibration, candidates, sets, verdict,
        identification), fraction 0..1 of the stages (not of the time, which the candidates dominate).

    Returns
    -------
    DiagnosisResult

    Raises
    ------
    CalibrationError
        When the record cannot be fitted at all (no simulable parameter set).
    BoundsError
        When ``bounds`` is invalid (unknown name, low >= high, outside the physical limits).

    Notes
    -----
    The record's test window (4.8 ms before to 200 ms after the event) is analysed on the
    record's own grid; ``records.before``/``records.after`` cover all its samples. When the
    record's event was located from the data, its instant within the located interval is
    calibrated too, and pure time shifts (trigger offset, measurement delay) cannot be
    diagnosed (their candidates say so).
    """
    with single_threaded_blas():
        return _diagnose(record, library, settings, identify, noise, bounds, progress or _no_progress)


def _no_progress(fraction: float, stage: str) -> None:
    """Default progress callback: ignore."""


def _diagnose(
    record: Record,
    library: EffectLibrary,
    settings: DiagnosisSettings,
    identify: IdentificationHook | None,
    noise: Mapping[str, float] | None,
    bounds: Bounds | None = None,
    progress: Callable[[float, str], None] = _no_progress,
) -> DiagnosisResult:
    t0 = time.perf_counter()
    stages: list[dict[str, Any]] = []
    mark = t0

    def stage(name: str) -> None:
        """Close a stage of the work: its name and wall time [s] go to ``DiagnosisResult.stages``."""
        nonlocal mark
        now = time.perf_counter()
        stages.append({"stage": name, "seconds": now - mark})
        mark = now

    whole = record
    record, window = whole.test_window()
    space = default_space(record, bounds)
    progress(0.0, "calibrating the nominal model")
    nominal = calibrate(record, space, settings.calibration, noise=noise)
    cells = localise(record, nominal.simulated_record(record), nominal.sigma, DEFAULT_WINDOWS_MS)
    gap_before = gap_of(nominal)
    n_sim = nominal.n_simulations
    stage("nominal calibration")

    cs = settings.candidates
    set_settings = settings.set_search()
    use_sets = set_settings.max_size >= 2 and not _fits_noise(nominal, settings)
    staged = use_sets and set_settings.before_escalation
    progress(0.15, f"fitting {len(library)} candidate effects")
    cands = fit_candidates(
        record,
        nominal,
        space,
        library,
        cs,
        escalate=not staged,
        progress=lambda f, what: progress(0.15 + 0.35 * f, what),
    )
    stage("single candidates" if staged else "single candidates, escalation included")
    if use_sets and not _explains_single(cands, settings):
        progress(0.55, "no single effect explains the record: searching sets of effects")
    sets: list[CandidateSet] = []
    if staged:
        cands, sets = _staged_search(record, nominal, space, library, cands, settings, stage)
    elif use_sets and not _explains_single(cands, settings):
        sets = search_sets(record, nominal, space, library, cands, cs, set_settings)
        stage("sets of up to three")
    if sets:
        cands = _singles_of_sets(record, nominal, space, library, cands, sets, settings)
        stage("singles from the sets")
    n_sim += sum(c.calibration.n_simulations for c in cands if c.calibration)
    n_sim += sum(s.calibration.n_simulations for s in sets if s.calibration)
    if sets:
        _reweight(nominal, cands, sets)
    progress(0.85, "deciding the verdict")
    verdict = decide(nominal, cands, settings, sets)
    model = choose_model(cands, sets, settings)  # the model the verdict names, when explained
    verdict = _with_alternatives(verdict, library, _near_twins(verdict, model, [*cands, *sets], settings, library))
    stage("decision")

    after = None
    gap_after = None
    shrinkage = None
    cells_after: list[Cell] = []
    locus: dict[str, Any] | None = None
    if verdict.status == "explained":
        best_cal = model.calibration if model is not None else None
        if model is None or best_cal is None:  # an explained verdict names a fitted model
            raise RuntimeError(f"the named effect {verdict.effect} has no fit")
        after = best_cal.simulated_record(whole)
        gap_after = gap_of(best_cal)
        shrinkage = model.shrinkage
        cells_after = localise(record, best_cal.simulated_record(record), nominal.sigma, DEFAULT_WINDOWS_MS)
        stage("gap after the fix")
    elif verdict.status in ("unexplained", "weak_gap") and settings.locate:
        verdict, locus = _locate(record, nominal, verdict, space)
        stage("locus and missing term")
    result = DiagnosisResult(
        calibration=nominal,
        cells=cells,
        candidates=cands,
        verdict=verdict,
        gap_before=gap_before,
        gap_after=gap_after,
        before=nominal.simulated_record(whole),
        after=after,
        cells_after=cells_after,
        n_simulations=n_sim,
        n_cells=settings.n_cells,
        window=window,
        record=whole,
        sets=sets,
        locus=locus,
        shrinkage=shrinkage,
        stages=stages,
    )
    if identify is not None:
        progress(0.9, "identifying the width before and after")
        result.identification = identify(whole, result)
        stage("identification")
    result.seconds = time.perf_counter() - t0
    logger.info(
        "diagnosis: %s %s (confidence %.2f), %d simulations, %.1f s",
        verdict.status,
        verdict.effect or "",
        verdict.confidence,
        n_sim,
        result.seconds,
    )
    return result
