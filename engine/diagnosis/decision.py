"""The decision on the fitted models of a diagnosis: whether a fit reaches the noise
(:func:`fit_statistic`), which model the verdict names (:func:`choose_model`), the verdict
(:func:`decide`), the posterior weights over every model fitted, and the named effects' exact and
near twins. The rules are described in :mod:`engine.diagnosis.diagnose`.

The verdict's ``score`` is the decision's 0..1 score (a logistic of the deciding statistic's
distance from its threshold, times the BIC weight when explained); its ``confidence`` is that
score recalibrated to the probability that such a verdict is right
(:func:`engine.diagnosis.confidence.calibrated_confidence`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

from scipy.special import expit

from engine.diagnosis.ambiguity import Model, NearTwin, near_twins
from engine.diagnosis.calibration import CalibrationResult
from engine.diagnosis.candidate import Candidate, posterior_weights
from engine.diagnosis.candidate_set import CandidateSet
from engine.diagnosis.confidence import calibrated_confidence
from engine.diagnosis.gap import closed_fraction
from engine.diagnosis.result import Verdict
from engine.diagnosis.settings import DiagnosisSettings
from engine.diagnosis.space import indistinguishable
from engine.simulation import EffectLibrary

__all__ = [
    "choose_model",
    "decide",
    "explains",
    "explains_as_well",
    "explains_single",
    "fit_statistic",
    "fits_noise",
    "model_near_twins",
    "reweight",
    "with_alternatives",
]


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


def fits_noise(cal: CalibrationResult, s: DiagnosisSettings) -> bool:
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
    """The verdict from the nominal calibration, the ranked candidates and sets (see the module notes).

    ``score`` is the decision's score, ``confidence`` its calibrated probability of being right
    (:mod:`engine.diagnosis.confidence`); the status does not depend on either.
    """
    v = _decide(nominal, candidates, settings, sets)
    # an explained verdict's probability also allows for a stand-in (engine.diagnosis.open_world)
    conf = calibrated_confidence(v.status, v.confidence, nominal_chi2=nominal.reduced_chi2)
    return replace(v, confidence=conf, score=v.confidence)


def _decide(
    nominal: CalibrationResult,
    candidates: list[Candidate],
    settings: DiagnosisSettings,
    sets: Sequence[CandidateSet],
) -> Verdict:
    """The verdict with the decision's score as its confidence (:func:`decide` calibrates it)."""
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
        if fits_noise(nominal, settings):
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
    if fits_noise(m_cal, settings):
        if strength <= settings.min_strength and fits_noise(nominal, settings):
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


def reweight(nominal: CalibrationResult, cands: Sequence[Candidate], sets: Sequence[CandidateSet]) -> None:
    """Posterior weights and delta BIC over every model fitted: the nominal one, single effects and sets."""
    models: list[Model] = [*cands, *sets]
    names = [m.effect if isinstance(m, Candidate) else m.name for m in models]
    w = posterior_weights({"<nominal>": nominal.bic, **dict(zip(names, (m.bic for m in models), strict=True))})
    best = min((m.bic for m in models), default=math.inf)
    for name, m in zip(names, models, strict=True):
        m.weight = w[name]
        m.delta_bic = m.bic - best


def explains(s: CandidateSet, settings: DiagnosisSettings) -> bool:
    """Whether a set fits to the noise with every member strong (no single escalation needed)."""
    return s.calibration is not None and fits_noise(s.calibration, settings) and _all_strong(s, settings)


def explains_single(cands: Sequence[Candidate], settings: DiagnosisSettings) -> bool:
    """Whether the best fitted single candidate fits to the noise."""
    best = next((c for c in cands if c.calibration is not None), None)
    return best is not None and best.calibration is not None and fits_noise(best.calibration, settings)


def explains_as_well(m: Model, settings: DiagnosisSettings) -> bool:
    """Whether a model explains the record as a named one must: refined at the final integrator
    step, fits to the noise, every effect strong."""
    cal = m.calibration
    if cal is None or cal.step != settings.candidates.seeded.final_step:
        return False
    if isinstance(m, CandidateSet):
        return explains(m, settings)
    strong = m.strength is not None and math.isfinite(m.strength) and m.strength > settings.min_strength
    return strong and fits_noise(cal, settings)


def model_near_twins(
    verdict: Verdict,
    model: Model | None,
    models: Sequence[Model],
    settings: DiagnosisSettings,
    library: EffectLibrary,
) -> dict[str, tuple[NearTwin, ...]]:
    """Near twins of the named effects of ``model`` (:mod:`engine.diagnosis.ambiguity`); none unless explained."""
    if model is None or verdict.status != "explained":
        return {}
    return near_twins(model, models, lambda m: explains_as_well(m, settings), settings.min_delta_bic, library)


def with_alternatives(
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
