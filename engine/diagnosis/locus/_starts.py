"""The starts of the refinement (step 3 of the method).

A scan of simple inputs (a constant or a step at every locus, a Coulomb friction [pu] at every
rotating part) from the calibration and from its global starts, a dense scan of a zone offset
[rad], damped Gauss-Newton steps of each locus's best (:func:`extras_scan`); the joint fits of
every part's Coulomb friction and of each drift of a part's own parameters with the calibrated
parameters (:func:`joint_fits`); and the choice between the scan and the linearised estimate
(:func:`refinement_start`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import cast

import numpy as np

from engine.diagnosis.calibration import CalibrationError, CalibrationResult
from engine.diagnosis.candidate import CandidateSettings, fit_candidate
from engine.diagnosis.locus._cases import (
    MIN_DRIFT,
    current,
    is_coulomb,
    parameter_cases,
    part_terms,
    with_input,
    with_moves,
    with_term,
)
from engine.diagnosis.locus._refine import STEP_LENGTHS, Estimate
from engine.diagnosis.locus._report import LocusSettings
from engine.diagnosis.locus._responses import N_EXTRAS, PROBE, Observed, Responses
from engine.diagnosis.space import ModelSpace
from engine.parallel import Runner
from engine.records import Record
from engine.simulation import DISTURBANCE_LOCI, Case, Effect, Locus, SolverSettings, run_cases, serial_kernel
from engine.simulation.parameters import COULOMB_FIELDS, PART_FIELDS

logger = logging.getLogger(__name__)


#: Constant inputs of the scan, as fractions of the locus's scale :data:`SCAN_SCALE`.
_SCAN_FRACTIONS: tuple[float, ...] = (-1.0, -0.5, -0.25, -0.1, 0.1, 0.25, 0.5, 1.0)
#: Coulomb frictions of the scan (loci of :data:`COULOMB_FIELDS`), as fractions of :data:`SCAN_SCALE`;
#: friction only opposes motion, so none is negative.
_FRICTION_FRACTIONS: tuple[float, ...] = (0.1, 0.25, 0.5, 1.0)
#: Relative step of a drift's finite difference in the polish (of the factor).
_DRIFT_STEP: float = 1e-2
#: Largest constant input of the scan per locus, in the locus's unit: a fifth of the rated
#: torque, a tenth of the voltage, the angle of the smallest backlash's quarter width.
SCAN_SCALE: dict[str, float] = {
    "supply": 0.1,
    "motor_electrical": 0.2,
    "motor_shaft": 0.2,
    "clutch": 0.006,
    "drive_train": 0.2,
    "load": 0.2,
    "clutch_torque": 0.2,
}


def _friction_loci(names: list[str]) -> list[str]:
    """Loci whose Coulomb friction the locus estimate tries: those whose field is not calibrated."""
    return [locus for locus, name in COULOMB_FIELDS.items() if name not in names]


def extras_scan(
    cal: CalibrationResult, resp: Responses, obs: Observed, settings: LocusSettings
) -> tuple[dict[str, _Start], float, int]:
    """chi2 of simple inputs at every locus: a constant, or a step at the switch-off, of several sizes.

    The sizes are :data:`_SCAN_FRACTIONS` of :data:`SCAN_SCALE`. A first batch simulates each
    with the calibrated parameters; a second the same inputs with the calibrated parameters moved
    by the linearised fit of what each first run leaves (the parameters' response columns of the
    calibrated case), so that a term the calibration partly absorbed (e.g. a zone offset taken up
    by the width) is matched with the parameters it needs; then ``extras_iterations`` damped
    Gauss-Newton steps of every locus's best (extras, parameters). Returns the best start per
    locus, the chi2 of the calibrated case, all at the settings' integrator step (the scale of
    every chi2 the refinement compares), and the simulations used.
    """
    assert cal.case is not None
    solver = cal.solver(settings.step)
    names = resp.param_names
    zeros = np.zeros(resp.n_free)
    no_move = np.zeros(len(names))
    cases = [with_input(cal.case, resp.schedule("load", zeros, np.zeros(N_EXTRAS)))]
    bases = _base_points(cal, names) if settings.scan_from_starts else [no_move]
    trials: list[_Trial] = []
    for locus in DISTURBANCE_LOCI:
        for i in range(N_EXTRAS):
            for f in _SCAN_FRACTIONS:
                e = np.zeros(N_EXTRAS)
                e[i] = f * SCAN_SCALE[locus]
                trials += [_Trial(locus, e, base) for base in bases]
    for locus in _friction_loci(names):
        field = COULOMB_FIELDS[locus]
        for f in _FRICTION_FRACTIONS:
            trials += [_Trial(locus, np.zeros(N_EXTRAS), base, f * SCAN_SCALE[locus], field) for base in bases]
    trials += _zone_trials(cal.case, bases[1:], names, settings.n_zone_scan)
    cases += [t.case(cal.case, names, resp, t.p) for t in trials]
    ch, _, status = run_cases(cases, solver, obs.record.grid)
    chi2_base = float(np.sum(obs.residual(ch[0]) ** 2)) if status[0] == 0 else math.inf
    best = {locus: _Start(np.zeros(N_EXTRAS), no_move, math.inf) for locus in DISTURBANCE_LOCI}
    moves = []
    for t, c, st in zip(trials, ch[1:], status[1:], strict=True):
        if st != 0:
            moves.append(t.p)
            continue
        res = obs.residual(c)
        c2 = float(res @ res)
        if c2 < best[t.locus].chi2:
            best[t.locus] = _Start(t.e, t.p, c2, t.f, t.field)
        moves.append(t.p + np.linalg.lstsq(resp.params, res, rcond=None)[0] if names else no_move)
    used = len(cases)
    if names:
        cases = [t.case(cal.case, names, resp, p) for t, p in zip(trials, moves, strict=True)]
        ch, _, status = run_cases(cases, solver, obs.record.grid)
        used += len(cases)
        for t, p, c, st in zip(trials, moves, ch, status, strict=True):
            c2 = float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf
            if c2 < best[t.locus].chi2:
                best[t.locus] = _Start(t.e, p, c2, t.f, t.field)
    for _ in range(settings.extras_iterations):
        best, n = _polish_extras(cal, resp, obs, best, solver)
        used += n
    return best, chi2_base, used


def _friction_effect(case: Case, locus: str) -> Effect:
    """A Coulomb friction against the motion of the part at ``locus``, as an effect on top of ``case``:
    its value is the field's total (neutral: the case's), at most :data:`SCAN_SCALE` more."""
    name = COULOMB_FIELDS[locus]
    now = float(getattr(case.plant, name))
    return Effect(
        f"{locus}_coulomb_friction",
        f"Coulomb friction against the motion of the part at {locus} ({name} * tanh(w / W_SMOOTH))",
        "plant",
        name,
        "set",
        (now, now + SCAN_SCALE[locus]),
        now,
        "pu",
        cast(Locus, locus),
    )


def _drift_effect(locus: str, field: str) -> Effect:
    """A drift of the part parameter ``field`` at ``locus`` by a factor, as an effect on top of the
    calibrated case (neutral 1, within the parameter's plausible range of :data:`PART_FIELDS`)."""
    meaning, bounds = PART_FIELDS[locus][field]
    return Effect(
        f"{field}_drift", f"{meaning} multiplied by value", "plant", field, "multiply", bounds, 1.0,
        "x", cast(Locus, locus),
    )  # fmt: skip


def joint_fits(
    record: Record,
    cal: CalibrationResult,
    space: ModelSpace,
    resp: Responses,
    obs: Observed,
    best: dict[str, _Start],
    settings: LocusSettings,
    known: Mapping[str, Mapping[str, float]] | None = None,
) -> tuple[dict[str, _Start], int]:
    """Every part's own terms fitted jointly with the calibrated parameters, by a global search.

    **Coulomb frictions** (``settings.friction_fits``). The scan's coarse friction sizes and two
    Gauss-Newton steps find a friction only near the calibrated point; one strong enough to stop
    a part moves the impacts, and its valley in (friction, K, J1) is narrower than the scan's
    steps, and the calibration's global starts, searched without the friction, are off too. On
    the record of
    ``tests/test_locus.py::test_a_wheel_friction_that_stops_the_wheel_is_a_coulomb_friction_on_the_drive_wheel``
    (a wheel friction of 0.09 pu at the nominal plant, 40 dB; the test asserts the last is above
    100): the true friction, J1 and c give chi2/n 1.02 with the true K, 159 with K 1 % off and
    547 with K 3 % off.

    **Drifts of a part's own parameters** (``settings.part_drifts``,
    :data:`~engine.simulation.parameters.PART_FIELDS`), each by a factor. A drift that acts
    through the whole run (the supply frequency moves the motor's speed from the switch-on) is
    absorbed by the calibration, which moves K, J1 and c to meet it partly; the drift alone from
    the calibrated point then makes the fit worse (a supply frequency 1.7 % high: chi2/n 57
    calibrated, 1453 with the drift added at the calibrated K, J1 and c, 0.98 refitted), so it
    must be fitted with them, and globally: the valley is narrow, and a seeded fit stops short (a
    frequency 2 % high, nominal plant, 40 dB: seeded fits over three ranges gave 1.0191, 1.0146
    and 1.0066 with chi2/n 22-171; the global search 1.0200 with 0.98 from each). A scan of the
    factors with a linearised move of the calibrated parameters does not rank such a drift either
    (on that record the frequency's scan left the most of the ten parameters). A field in
    ``known`` (the fitted values of a global joint fit already made, e.g. the diagnosis's
    escalated catalogue candidate of the same drift, the factor under the key ``"factor"``) is
    not fitted again.

    Each is a catalogue candidate's fit with the global search
    (:func:`~engine.diagnosis.candidate.fit_candidate`, ``global_search=True``; 1.4-3 s and about
    1000 simulations each), all of them on the candidate fits' threads (one core each,
    :func:`~engine.simulation.serial_kernel`; the same results as one after another). Each point,
    simulated at the locus's step, replaces the locus's start where its chi2 is lower. Returns the
    starts and the simulations used.
    """
    assert cal.case is not None
    names = resp.param_names
    jobs: list[tuple[str, str, Effect]] = []
    fitted: list[_Trial] = []
    if settings.friction_fits:
        jobs += [(locus, COULOMB_FIELDS[locus], _friction_effect(cal.case, locus)) for locus in _friction_loci(names)]
    if settings.part_drifts:
        for locus in DISTURBANCE_LOCI:
            for field in part_terms(locus, names):
                if is_coulomb(field):
                    continue
                if known and field in known:
                    values = known[field]
                    p = np.array([values[n] - current(cal.case, n) if n in values else 0.0 for n in names])
                    fitted.append(_Trial(locus, np.zeros(N_EXTRAS), p, float(values["factor"]) - 1.0, field))
                else:
                    jobs.append((locus, field, _drift_effect(locus, field)))
    used = 0
    runner = Runner(CandidateSettings().jobs(), thread_context=serial_kernel, thread_name_prefix="locus")
    with runner:  # BLAS is single-threaded around the whole estimate (estimate_locus)
        tasks = [runner.submit(_global_fit, record, cal, space, effect, names) for _, _, effect in jobs]
        for (locus, field, effect), task in zip(jobs, tasks, strict=True):
            got = task.result()
            if got is None:
                continue
            p, value, n_sim = got
            used += n_sim
            if is_coulomb(field):
                if value - effect.neutral > 0.0:
                    fitted.append(_Trial(locus, np.zeros(N_EXTRAS), p, value - effect.neutral, field))
            else:  # the effect multiplies the space's base case, whose part parameters are the calibrated case's
                fitted.append(_Trial(locus, np.zeros(N_EXTRAS), p, value - 1.0, field))
    out, n_sim = _keep_better(cal, names, resp, obs, best, fitted, settings)
    return out, used + n_sim


def _global_fit(
    record: Record, cal: CalibrationResult, space: ModelSpace, effect: Effect, names: list[str]
) -> tuple[np.ndarray, float, int] | None:
    """An effect fitted with the calibrated parameters by a global search: (their moves, the effect's
    value, simulations used), or None when it cannot be fitted."""
    assert cal.case is not None
    try:
        cand = fit_candidate(record, cal, space, effect, global_search=True)
    except (CalibrationError, ValueError) as exc:
        logger.info("locus: %s could not be fitted (%s)", effect.name, exc)
        return None
    fit = cand.calibration
    if fit is None:
        return None
    p = np.array([fit.values[n] - current(cal.case, n) if n in fit.values else 0.0 for n in names])
    return p, float(fit.values[effect.name]), fit.n_simulations


def _keep_better(
    cal: CalibrationResult,
    names: list[str],
    resp: Responses,
    obs: Observed,
    best: dict[str, _Start],
    fitted: list[_Trial],
    settings: LocusSettings,
) -> tuple[dict[str, _Start], int]:
    """Each fitted trial, simulated at the locus's step, replaces its locus's start where its chi2 is
    lower; returns the starts and the simulations used."""
    assert cal.case is not None
    if not fitted:
        return best, 0
    ch, _, status = run_cases(
        [t.case(cal.case, names, resp, t.p) for t in fitted], cal.solver(settings.step), obs.record.grid
    )
    out = dict(best)
    for t, c, st in zip(fitted, ch, status, strict=True):
        c2 = float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf
        logger.debug("locus: %s %s %.4g fitted, chi2 %.4g (start %.4g)", t.locus, t.field, t.f, c2, out[t.locus].chi2)
        if c2 < out[t.locus].chi2:
            out[t.locus] = _Start(t.e, t.p, c2, t.f, t.field)
    return out, len(fitted)


def _base_points(cal: CalibrationResult, names: list[str]) -> list[np.ndarray]:
    """Points the scan of simple inputs starts from, as moves of the calibrated parameters: the
    calibration itself, and each of its global starts (the early window's best points).

    A missing term that acts late (after the first impacts) pulls the continuation of the nominal
    calibration away from the early window's points, which were near the truth; an input scanned
    only at the calibrated parameters then has to undo that pull too. Pass 1b of the single
    candidates starts from the same points for the same reason (``refit_from_starts``).
    """
    assert cal.case is not None
    out = [np.zeros(len(names))]
    for start in cal.starts:
        p = np.array([start[n] - current(cal.case, n) if n in start else 0.0 for n in names])
        if np.any(p != 0.0):
            out.append(p)
    return out


def _zone_trials(case: Case, starts: list[np.ndarray], names: list[str], n: int) -> list[_Trial]:
    """A dense scan of a constant offset of the backlash zone from each global start, along the
    widths that keep one side of the zone in place.

    The zone is ``-b + o <= theta_1 - theta_2 <= b + o`` (half-width ``b = K / r``). Where the
    early window closes the clutch on one side only, an offset ``o`` looks like a width ``K + o r``
    (contact on the positive side) or ``K - o r``, and the early window's starts carry that width.
    From such a start the true point lies on the line ``(o, K_start - o r)`` (or ``+ o r``), and
    along it chi2 has a narrow valley in ``o`` (on a synthetic record at K 7.6 mm, o = -3.8 mrad,
    36 dB: chi2/n 1.2 at the true offset, 341 and 265 at -3.0 and -4.5 mrad), which the coarse
    scan of every locus steps over and no Gauss-Newton step from it reaches. So ``n`` offsets
    evenly spread over ``+-SCAN_SCALE["clutch"]`` on both lines from every start (none when the
    width is not calibrated).
    """
    if n <= 0 or "K" not in names or not starts:
        return []
    out = []
    k = names.index("K")
    for o in np.linspace(-1.0, 1.0, n) * SCAN_SCALE["clutch"]:
        e = np.zeros(N_EXTRAS)
        e[0] = o
        for start in starts:
            for side in (1.0, -1.0):
                p = start.copy()
                p[k] -= side * o * case.plant.r
                out.append(_Trial("clutch", e, p))
    return out


@dataclass(frozen=True)
class _Start:
    """A starting point of the refinement: extras (constant, step), parameter moves, its chi2, and
    the part term at the locus: its value ``f`` (Coulomb friction added [pu], or a parameter's
    drift, factor - 1) and its ``field`` ("" for none; see :func:`with_term`)."""

    e: np.ndarray
    p: np.ndarray
    chi2: float
    f: float = 0.0
    field: str = ""


@dataclass(frozen=True)
class _Trial:
    """A simple input of the scan: the locus, its extras, the parameter moves it starts from, and
    a part term at the locus (value ``f``, ``field``; see :func:`with_term`)."""

    locus: str
    e: np.ndarray
    p: np.ndarray
    f: float = 0.0
    field: str = ""

    def case(self, cal_case: Case, names: list[str], resp: Responses, p: np.ndarray) -> Case:
        """The calibrated case with this input, its parameters moved by ``p``."""
        zeros = np.zeros(resp.n_free)
        moved = with_term(with_moves(cal_case, names, p), self.field, self.f)
        return with_input(moved, resp.schedule(self.locus, zeros, self.e))


def _polish_extras(
    cal: CalibrationResult, resp: Responses, obs: Observed, best: dict[str, _Start], solver: SolverSettings
) -> tuple[dict[str, _Start], int]:
    """One damped Gauss-Newton step of every locus's (extras or part term, parameter moves), jointly.

    One batch of finite differences (each extra, or the part term where the start has one, and
    each calibrated parameter, around each locus's current point) and one batch of three step
    lengths; a locus keeps the step if its simulated chi2 falls. A friction stays >= 0, a drift's
    factor >= 1 + MIN_DRIFT.
    """
    assert cal.case is not None
    names = resp.param_names
    zeros = np.zeros(resp.n_free)
    loci = [locus for locus in DISTURBANCE_LOCI if math.isfinite(best[locus].chi2)]
    cases: list[Case] = []
    steps: dict[str, list[float]] = {}
    for locus in loci:
        start = best[locus]
        h = 5.0 * PROBE[locus]
        trial = _Trial(locus, start.e, start.p, start.f, start.field)
        centre = trial.case(cal.case, names, resp, start.p)
        cases.append(centre)
        if start.field:  # a part term is polished with the parameters alone (the extras would trade with it)
            if is_coulomb(start.field):
                cases.append(with_term(centre, start.field, h))
                hs = [h]
            else:  # the factor (1 + f) times (1 + step): a step of f of (1 + f) step
                cases.append(with_term(centre, start.field, _DRIFT_STEP))
                hs = [_DRIFT_STEP * (1.0 + start.f)]
        else:
            for i in range(N_EXTRAS):
                de = np.zeros(N_EXTRAS)
                de[i] = h
                cases.append(with_input(centre, resp.schedule(locus, zeros, start.e + de)))
            hs = [h] * N_EXTRAS
        pcases, psteps, _ = parameter_cases(centre, names)
        cases += pcases
        steps[locus] = hs + psteps
    ch, _, status = run_cases(cases, solver, obs.record.grid)
    used = len(cases)
    trials: list[_Trial] = []
    i = 0
    for locus in loci:
        m = len(steps[locus])
        block, st = ch[i : i + 1 + m], status[i : i + 1 + m]
        i += 1 + m
        start = best[locus]
        n_in = 1 if start.field else N_EXTRAS  # the input's own unknowns, before the parameters
        if np.any(st != 0) or m != n_in + len(names):
            continue
        r0 = obs.residual(block[0])
        J = np.stack([(obs.residual(b) - r0) / h for b, h in zip(block[1:], steps[locus], strict=True)], axis=1)
        delta = -np.linalg.lstsq(J, r0, rcond=None)[0]
        de, df = (0.0 * start.e, float(delta[0])) if start.field else (delta[:N_EXTRAS], 0.0)
        floor = 0.0 if is_coulomb(start.field) else MIN_DRIFT
        trials += [
            _Trial(locus, start.e + a * de, start.p + a * delta[n_in:], max(start.f + a * df, floor), start.field)
            for a in STEP_LENGTHS
        ]
    if not trials:
        return best, used
    tcases = [t.case(cal.case, names, resp, t.p) for t in trials]
    ch, _, status = run_cases(tcases, solver, obs.record.grid)
    used += len(tcases)
    out = dict(best)
    for t, c, st in zip(trials, ch, status, strict=True):
        c2 = float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf
        if c2 < out[t.locus].chi2:
            out[t.locus] = _Start(t.e, t.p, c2, t.f, t.field)
    return out, used


def refinement_start(
    cal: CalibrationResult,
    locus: str,
    resp: Responses,
    est: Estimate,
    obs: Observed,
    chi2_cal: float,
    scan: _Start,
    settings: LocusSettings,
) -> tuple[Estimate, int]:
    """The start of a locus's refinement, simulated: the better of the linearised estimate and the scan.

    The linearised estimate (input and parameter moves) is tried at full, half and quarter length
    from the calibration (one batch of three); the scan's best simple input (``scan``) is already
    simulated. When neither lowers the calibration's chi2 the start is no input at all. Returns
    the start (``refined``, its chi2 simulated) and the simulations used.
    """
    assert cal.case is not None
    names = resp.param_names
    solver = cal.solver(settings.step)
    ln_n = math.log(max(obs.data.size, 2))
    extra = len(names) + N_EXTRAS  # the parameters and the extras
    trials = [
        with_input(with_moves(cal.case, names, a * est.p), resp.schedule(locus, a * est.x, a * est.e))
        for a in STEP_LENGTHS
    ]
    ch, _, status = run_cases(trials, solver, obs.record.grid)
    chi2s = [float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf for c, st in zip(ch, status, strict=True)]
    i = int(np.argmin(chi2s))
    if min(chi2s[i], scan.chi2) >= chi2_cal:  # neither start helps: the linearisation fails here
        zero = Estimate(0.0 * est.x, 0.0 * est.e, 0.0 * est.p, est.fit, chi2_cal, chi2_cal + extra * ln_n, True)
        return zero, len(trials)
    if chi2s[i] <= scan.chi2:
        a0 = STEP_LENGTHS[i]
        out = Estimate(a0 * est.x, a0 * est.e, a0 * est.p, est.fit, chi2s[i], math.nan, True)
    else:
        out = Estimate(0.0 * est.x, scan.e, scan.p, est.fit, scan.chi2, math.nan, True, f=scan.f, field=scan.field)
    out.bic = out.rss + (out.fit.dof + len(names) + out.n_extras) * ln_n
    return out, len(trials)
