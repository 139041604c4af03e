"""One locus's estimate and its refinement (step 4 of the method).

:class:`Estimate` holds a locus's input (free hats, extras), the calibrated parameters' moves, the
fit and its chi2; :func:`refine` runs damped Gauss-Newton iterations of the input re-linearised
around the current estimate, each kept only if its *simulated* chi2 falls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from engine.diagnosis.calibration import CalibrationResult
from engine.diagnosis.locus._cases import with_input, with_moves, with_term
from engine.diagnosis.locus._linear import Fit, orth, penalised_fit, project
from engine.diagnosis.locus._report import LocusSettings
from engine.diagnosis.locus._responses import N_EXTRAS, PROBE, Observed, Responses
from engine.simulation import Case, run_cases

#: Step lengths tried by every Gauss-Newton iteration of :func:`refine`.
STEP_LENGTHS: tuple[float, ...] = (1.0, 0.5, 0.25)


@dataclass
class Estimate:
    """One locus's estimate: free hats, extras (constant, step), calibrated-parameter moves, fit, evidence."""

    x: np.ndarray
    e: np.ndarray
    p: np.ndarray
    fit: Fit
    rss: float  # chi2 of the estimate: linearised, or simulated once refined
    bic: float
    refined: bool
    f: float = 0.0  # the part term's value: Coulomb friction added [pu], or a parameter's drift (factor - 1)
    field: str = ""  # the part term's field (COULOMB_FIELDS or PART_FIELDS), "" for none

    @property
    def n_extras(self) -> int:
        """Unpenalised parameters of the input: the constant, the step, and the part term if used."""
        return N_EXTRAS + bool(self.field and self.f != 0.0)


def refine(
    cal: CalibrationResult,
    locus: str,
    resp: Responses,
    est: Estimate,
    obs: Observed,
    iterations: int,
    settings: LocusSettings,
) -> tuple[Estimate, int]:
    """Damped Gauss-Newton iterations of one locus's input, re-linearised around the current estimate.

    The calibrated parameters stay where the start (:func:`refinement_start`) put them: freeing them again
    at every iteration lets the input and the backlash width trade large, opposite moves whose
    effects on the impact times are far from linear (measured: the chi2 rose 65-fold). Every
    iteration simulates the current estimate with a probe on every free hat and extra (one
    batch), refits the penalised input on its residual, and tries the step at full, half and
    quarter length (one batch of three); the best is kept if its *simulated* chi2 is lower, else
    the iterations stop. Returns the refined estimate, with its BIC from the simulated chi2, and
    the simulations used.
    """
    assert cal.case is not None
    names = resp.param_names
    solver = cal.solver(settings.step)
    ln_n = math.log(max(obs.data.size, 2))

    def case_of(base: Case, x: np.ndarray, e: np.ndarray) -> Case:
        return with_input(base, resp.schedule(locus, x, e))

    x, e, p, fit, chi2_cur = est.x, est.e, est.p, est.fit, est.rss
    used = 0
    base = with_term(with_moves(cal.case, names, p), est.field, est.f)
    for _ in range(iterations):
        cases = [case_of(base, x, e)]
        cases += [with_input(base, d) for d in resp.probes(locus, x, e)]
        ch, _, status = run_cases(cases, solver, obs.record.grid)
        used += len(cases)
        if status[0] != 0:
            break
        r_cur = obs.residual(ch[0])
        diff = ch[:, obs.rows] - ch[0][None, obs.rows]
        diff[status != 0] = 0.0
        cols = (diff[1:] / obs.sigma[None, :, None]).reshape(len(cases) - 1, -1).T / PROBE[locus]
        A, U = cols[:, :-N_EXTRAS], cols[:, -N_EXTRAS:]
        Qc = orth(U, U.shape[0])
        # the fit is for the new input as a whole (its roughness is penalised, not the step's)
        r_eff = r_cur + A @ x
        new_fit = penalised_fit(project(Qc, A), project(Qc, r_eff[:, None])[:, 0], Qc.shape[1], settings)
        dx = np.nan_to_num(new_fit.x) - x
        de = np.linalg.lstsq(U, r_cur - A @ dx, rcond=None)[0]
        trials = [case_of(base, x + a * dx, e + a * de) for a in STEP_LENGTHS]
        ch, _, status = run_cases(trials, solver, obs.record.grid)
        used += len(trials)
        chi2s = [float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf for c, st in zip(ch, status, strict=True)]
        i = int(np.argmin(chi2s))
        if not chi2s[i] < chi2_cur:
            break
        a = STEP_LENGTHS[i]
        x, e, fit, chi2_cur = x + a * dx, e + a * de, new_fit, chi2s[i]
    out = Estimate(x, e, p, fit, chi2_cur, math.nan, refined=True, f=est.f, field=est.field)
    out.bic = chi2_cur + (fit.dof + len(names) + out.n_extras) * ln_n
    return out, used
