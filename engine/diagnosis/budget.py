"""What each effect of a joint fit does to the record: its share of the gap, and its strength.

Gap budget (:func:`gap_budget`)
-------------------------------
How much of the nominal model's excess residual energy ``E0 = chi2_0 - n``
[noise variances] each effect of a fit removes, and what is left: the fit
closes ``E0 - E_S`` (``E_S = max(chi2_S - n, 0)``), and that is split among
its effects in proportion to their Shapley values of the game
``v(T) = chi2(fit with only the effects in T) - chi2(fit with all)``
evaluated at the fit's operating point without refitting (``2^k``
simulations): an order-free attribution that credits interacting effects
fairly. Shares and ``left = E_S / E0`` sum to 1.

Strength (:func:`member_strengths`)
-----------------------------------
Per effect of a fit: the largest channel RMS change when that effect alone is set back to
none at the fit's operating point, in noise standard deviations
(:func:`~engine.diagnosis.candidate.strength_noise`). A set is only as credible as its
weakest member (:attr:`engine.diagnosis.candidate_set.CandidateSet.strength`).

Both evaluate the fit's operating point without refitting, from the simulated channels over the
noise sigma of each channel (white noise; a record's coloured noise model is not used here).
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Mapping, Sequence

import numpy as np

from engine.constants import CHANNELS
from engine.diagnosis.calibration import CalibrationResult
from engine.diagnosis.candidate import strength_noise
from engine.diagnosis.space import ModelSpace
from engine.records import Record
from engine.simulation import Case, Effect, SolverSettings, run_cases

logger = logging.getLogger(__name__)

__all__ = ["case_with", "gap_budget", "member_strengths"]


def case_with(space: ModelSpace, values: Mapping[str, float], effects: Sequence[Effect]) -> Case:
    """The case of ``space``'s plant parameters at ``values`` with only ``effects`` applied.

    Parameters
    ----------
    space : ModelSpace
        The model space whose free plant parameters ``values`` sets (its known conditions stay).
    values : mapping of str to float
        A fit's values: every free plant parameter of ``space`` [its unit] and the value of each of
        ``effects`` [the effect's unit]; other entries are ignored.
    effects : sequence of Effect
        The effects to apply, at their values in ``values``.

    Returns
    -------
    Case
        The case to simulate (:func:`engine.simulation.run_cases`).

    Raises
    ------
    ValueError
        When ``values`` lacks a free parameter of ``space`` (which would otherwise be read as the
        centre of its search interval).
    ParameterError
        When a value lies outside its effect's range.
    """
    missing = [n for n in space.names if n not in values]
    if missing:
        raise ValueError(f"no value for the free parameters {', '.join(missing)} of the model space")
    plain = {k: v for k, v in values.items() if k in space.names}
    case = space.case(space.unit(plain))
    for e in effects:
        case = e.apply(case, values[e.name])
    return case


def _chi2_of_cases(
    record: Record, cases: Sequence[Case], sigma: Mapping[str, float], solver: SolverSettings
) -> np.ndarray:
    """chi2 [noise variances] of each case on the record (inf where it cannot be simulated)."""
    rows = [CHANNELS.index(n) for n in record.channels]
    data = np.stack([record.channels[n] for n in record.channels])
    sig = np.array([sigma[n] for n in record.channels])
    ch, _, status = run_cases(list(cases), solver, record.grid)
    r = (ch[:, rows] - data[None]) / sig[None, :, None]
    out = np.sum(r**2, axis=(1, 2))
    out[status != 0] = np.inf
    return out


def member_strengths(
    record: Record, cal: CalibrationResult, space: ModelSpace, effects: Sequence[Effect], noise: Mapping[str, float]
) -> dict[str, float]:
    """Per effect: the largest channel RMS change (noise sigmas, :func:`~engine.diagnosis.candidate.strength_noise`)
    when it alone is set back to none."""
    if cal.simulation is None:
        return {e.name: math.nan for e in effects}
    sigma = strength_noise(record, cal, noise)
    cases = [case_with(space, cal.values, [f for f in effects if f.name != e.name]) for e in effects]
    ch, _, status = run_cases(cases, cal.solver(), record.grid)
    out = {}
    for i, e in enumerate(effects):
        if status[i] != 0:
            out[e.name] = math.nan
            continue
        worst = 0.0
        for name in record.channels:
            j = CHANNELS.index(name)
            rms = float(np.sqrt(np.mean((cal.simulation[j] - ch[i, j]) ** 2)))
            worst = max(worst, rms / max(sigma[name], 1e-300))
        out[e.name] = worst
    return out


def gap_budget(
    record: Record,
    cal: CalibrationResult,
    space: ModelSpace,
    effects: Sequence[Effect],
    nominal: CalibrationResult,
) -> tuple[dict[str, float], float]:
    """Share of the nominal excess residual energy each effect of a fit removes, and what is left.

    Parameters
    ----------
    record : Record
        The record's test window (the grid calibrated on).
    cal : CalibrationResult
        The joint fit of ``effects``.
    space : ModelSpace
        The nominal model space (its plant parameters are read from ``cal``).
    effects : sequence of Effect
        The fitted effects.
    nominal : CalibrationResult
        The nominal calibration (its excess energy is the whole gap).

    Returns
    -------
    shares : dict of str to float
        Per effect, the fraction [-] of the nominal excess energy it removes.
    left : float
        The fraction left by the fit [-]; ``sum(shares) + left == 1``.

    Notes
    -----
    See the module notes: the closed part ``E0 - E_S`` is split by the Shapley values of
    ``v(T)``, evaluated with ``2^k`` simulations at the fit's operating point.
    """
    n = cal.n_data
    e0 = max(nominal.chi2 - nominal.n_data, 0.0)
    e_s = max(cal.chi2 - n, 0.0)
    if e0 <= 0.0:
        return {e.name: 0.0 for e in effects}, 1.0
    closed = max(min(e0 - e_s, e0), 0.0)
    left = 1.0 - closed / e0
    k = len(effects)
    if k == 1:
        return {effects[0].name: closed / e0}, left
    subsets = [s for r in range(k + 1) for s in itertools.combinations(range(k), r)]
    cases = [case_with(space, cal.values, [effects[i] for i in s]) for s in subsets]
    chi2 = dict(zip(subsets, _chi2_of_cases(record, cases, cal.sigma, cal.solver()), strict=True))
    full = chi2[tuple(range(k))]
    # v(T): how much of the chi2 of "no effect" the effects in T remove (at the fit's operating point)
    v = {s: chi2[()] - chi2[s] for s in subsets}
    phi = np.zeros(k)
    for i in range(k):
        for s in subsets:
            if i in s:
                continue
            with_i = tuple(sorted((*s, i)))
            w = math.factorial(len(s)) * math.factorial(k - len(s) - 1) / math.factorial(k)
            phi[i] += w * (v[with_i] - v[s])
    if not np.all(np.isfinite(phi)) or not math.isfinite(full) or phi.clip(min=0).sum() <= 0:
        logger.warning("gap budget: the effects' contributions could not be evaluated; split evenly")
        phi = np.ones(k)
    phi = phi.clip(min=0)
    shares = phi / phi.sum() * (closed / e0)
    return {e.name: float(s) for e, s in zip(effects, shares, strict=True)}, left
