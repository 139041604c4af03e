"""How well the record determines the value of a locus's part term.

The term a locus ends with may hold one of its part's own terms (a Coulomb friction [pu], or a
MODEL.md parameter drifted by a factor); the answer names its value, so it carries a standard
deviation too: Gauss-Newton at the final estimate, the calibrated parameters and the input's
extras free beside it, scaled by the estimate's dispersion (its fit's chi2 per degree of freedom,
at least 1) and by the correlation time of its whitened residual (a residual that is model error
is correlated in time, and ``n`` samples then carry about ``n / tau`` independent ones; the same
rule as the answer's width, :mod:`engine.diagnosis.width`), and by :data:`INFLATION`.
"""

from __future__ import annotations

import math

import numpy as np

from engine.diagnosis.calibration import CalibrationResult, unit_covariance
from engine.diagnosis.locus._cases import is_coulomb, parameter_cases, with_input, with_moves, with_term
from engine.diagnosis.locus._refine import Estimate
from engine.diagnosis.locus._report import LocusSettings
from engine.diagnosis.locus._responses import N_EXTRAS, PROBE, Observed, Responses
from engine.diagnosis.plant_gap import correlation_time
from engine.simulation import Case, run_cases

#: Factor on the Gauss-Newton standard deviation, set on the development family (seed 303, the 20
#: records whose effect is a term of the library: supply frequency, resilient damping, load mass
#: drifts and the wheel's Coulomb friction; ``lab/validation/dev-locus-seed303/``): without it the
#: truth lay within 1.96 sigma in 17 of 20 (the |z| of the misses 2.35, 3.77 and 28; the next 1.23),
#: at the optimum (a Gauss-Newton step from the estimate moves the value by a small part of sigma)
#: and at every integrator step tried, so the fit itself is narrower than the truth's spread; the
#: 95th percentile of |z| there is 3.8, about twice 1.96. Its coverage on records it was not set on
#: is measured in ``lab/validation/dev-locus-seed307/``.
INFLATION: float = 2.0
#: Step of a Coulomb friction's finite difference [pu].
FRICTION_STEP: float = 1e-3
#: Step of a drift's finite difference, relative to its factor (small: the supply frequency's
#: valley is about 1e-3 wide in the factor).
DRIFT_STEP: float = 1e-4


def part_term_sigma(
    cal: CalibrationResult,
    locus: str,
    resp: Responses,
    est: Estimate,
    obs: Observed,
    dispersion: float,
    settings: LocusSettings,
) -> tuple[float, int]:
    """Standard deviation of the part term's value of ``est`` (friction [pu], or drift: factor - 1).

    One batch of simulations at the locus's step: the estimate, the term moved by
    :data:`FRICTION_STEP` or :data:`DRIFT_STEP`, each calibrated parameter by its response column's step and each extra by
    the locus's probe. The covariance of (term, parameters, extras) is ``pinv(J^T J)`` of the
    whitened residual's Jacobian, times ``dispersion * tau`` (``tau``: the integrated
    autocorrelation time of the estimate's whitened residual, per channel, at least 1); the
    standard deviation is its root times :data:`INFLATION`.

    Parameters
    ----------
    cal : CalibrationResult
        The calibration the estimate moves from.
    locus : str
        The estimate's locus.
    resp, est, obs
        The response columns, the final estimate (with ``field`` and ``f``), the record as fitted.
    dispersion : float
        The report's dispersion (chi2 per degree of freedom of the best fit, at least 1).
    settings : LocusSettings
        For the integrator step.

    Returns
    -------
    sigma : float
        In the term's unit (NaN when the estimate has no part term or cannot be simulated).
    n_simulations : int
    """
    assert cal.case is not None
    if not est.field or est.f == 0.0:
        return math.nan, 0
    names = resp.param_names
    base = with_moves(cal.case, names, est.p)

    def at(value: float, e: np.ndarray, case_base: Case = base) -> Case:
        """The estimate with the term at ``value`` and extras ``e``, from ``case_base``."""
        return with_input(with_term(case_base, est.field, value), resp.schedule(locus, est.x, e))

    h_term = FRICTION_STEP if is_coulomb(est.field) else DRIFT_STEP * (1.0 + est.f)
    centre = at(est.f, est.e)
    cases = [centre, at(est.f + h_term, est.e)]
    steps = [h_term]
    pcases, psteps, _ = parameter_cases(base, names)
    cases += [at(est.f, est.e, c) for c in pcases]
    steps += psteps
    for i in range(N_EXTRAS):
        de = np.zeros(N_EXTRAS)
        de[i] = PROBE[locus]
        cases.append(at(est.f, est.e + de))
        steps.append(PROBE[locus])
    ch, _, status = run_cases(cases, cal.solver(settings.step), obs.record.grid)
    if np.any(status != 0):
        return math.nan, len(cases)
    r0 = obs.residual(ch[0])
    J = np.stack([(obs.residual(c) - r0) / h for c, h in zip(ch[1:], steps, strict=True)], axis=1)
    cov = unit_covariance(J)
    var = float(cov[0, 0])
    if not math.isfinite(var) or var < 0.0:
        return math.nan, len(cases)
    n_s = obs.data.shape[1]
    tau = max(1.0, correlation_time([r0[j * n_s : (j + 1) * n_s] for j in range(len(obs.rows))]))
    return INFLATION * math.sqrt(var * max(dispersion, 1.0) * tau), len(cases)
