"""Which effect: fit every candidate effect (with the calibration) and rank them by evidence.

For every effect of an :class:`~engine.simulation.EffectLibrary` the
calibration is refitted with the effect's scalar value as one more bounded
parameter (:func:`engine.diagnosis.calibration.calibrate` on
``space.with_effect(effect)``), in three passes:

1. **Seeded fits** (every candidate): least squares on the full record from
   the nominal calibration with the effect at its neutral value, and from the
   nominal calibration with the best value of a one-dimensional scan of the
   effect (9 values across its range).
2. **Escalation** (only when no candidate fits to the noise after pass 1):
   the candidates, best seeded BIC first, get the full global search (256
   Sobol points on the early window, continuation over 10, 20, 40, 80, 200 ms)
   in the joint space, until one fits to the noise; a strong effect can drag
   the nominal calibration out of the true basin, and then no seed lies in it.
3. **Polish**: the best ``n_polish`` candidates (and any other within 10 %
   of the best chi2, up to ``max_polish``) are refined at the final integrator
   step, so that they compete on equal terms with the nominal fit and with
   each other.

``speed_quantization`` (omega1 rounded to multiples of q) has a jagged cost in
q (every q moves the rounding thresholds of thousands of samples), so least
squares cannot fit q. Rounding is applied after the simulation, so q is found
by a dense scan (4000 values) of the rounded calibrated omega1; the
calibration is refitted on the unrounded omega1 with the rounding treated as
extra white noise (variance q^2/12), and q is scanned again (two rounds). Its
uncertainty is the half-width of the interval where chi2 rises by 1.

The candidates are independent, so each pass fits them on ``n_jobs`` threads,
each running its simulations on one core (:func:`engine.simulation.serial_kernel`):
the optimiser's single-point evaluations would otherwise leave all but one
core idle. The escalation keeps its sequential meaning: its fits are
collected in ranking order and the rest are cancelled once one fits to the
noise, so the result does not depend on ``n_jobs`` (beyond rounding).

Evidence: the Bayesian information criterion of a Gaussian likelihood with the
estimated noise, ``BIC = chi2 + k ln(n)`` (k fitted parameters, n residuals),
so an effect must lower chi2 by more than ln(n) (about 9 for five channels)
to beat the nominal model. Posterior weights ``exp(-BIC / 2)``, normalised
over the candidates and the nominal model, give each candidate's probability.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from engine.constants import N_SAMPLES
from engine.diagnosis.calibration import (
    CalibrationResult,
    CalibrationSettings,
    ModelSpace,
    Objective,
    calibrate,
)
from engine.parallel import cancel_scope, single_threaded_blas
from engine.records import Record
from engine.simulation import CATALOGUE, Case, Effect, EffectLibrary, SolverSettings, run_cases, serial_kernel

logger = logging.getLogger(__name__)

__all__ = [
    "Candidate",
    "CandidateSettings",
    "Gap",
    "effect_strength",
    "fit_candidate",
    "fit_candidates",
    "gap_of",
    "posterior_weights",
    "shrinkage_ratio",
]


@dataclass(frozen=True)
class Gap:
    """Size of the sim-to-real gap left by a fitted model.

    Attributes
    ----------
    rms_over_noise : float
        Residual RMS divided by the noise level (1 when the model fits to the noise).
    excess_energy : float
        Residual energy beyond the noise, ``max(chi2 - n, 0)`` [noise variances].
    excess_fraction : float
        ``excess_energy`` over the residual energy expected from noise alone, n
        (0 when the model fits to the noise).
    per_channel : dict
        The same three numbers per channel.
    """

    rms_over_noise: float
    excess_energy: float
    excess_fraction: float
    per_channel: dict[str, dict[str, float]]

    def to_dict(self) -> dict:
        return {
            "rms_over_noise": self.rms_over_noise,
            "excess_energy": self.excess_energy,
            "excess_fraction": self.excess_fraction,
            "per_channel": {k: dict(v) for k, v in self.per_channel.items()},
        }


def gap_of(cal: CalibrationResult) -> Gap:
    """The gap a calibration leaves, total and per channel."""
    n_ch = len(cal.chi2_per_channel)
    n_per = cal.n_data // max(n_ch, 1)
    per = {}
    for ch, c2 in cal.chi2_per_channel.items():
        per[ch] = {
            "rms_over_noise": math.sqrt(c2 / n_per),
            "excess_energy": max(c2 - n_per, 0.0),
            "excess_fraction": max(c2 - n_per, 0.0) / n_per,
        }
    ex = max(cal.chi2 - cal.n_data, 0.0)
    return Gap(math.sqrt(cal.chi2 / cal.n_data), ex, ex / cal.n_data, per)


@dataclass
class Candidate:
    """One candidate effect fitted together with the calibration.

    Attributes
    ----------
    effect : str
        Effect name.
    value : float or None
        Fitted value, in ``unit`` (None when the effect was not fitted).
    uncertainty : float or None
        One standard deviation of the value, same unit.
    unit : str
        Unit of the value.
    calibration : CalibrationResult or None
        The joint fit (calibration plus effect value).
    bic : float
        Bayesian information criterion of the fit.
    delta_bic : float
        BIC minus the best candidate's BIC (0 for the best).
    weight : float
        Posterior probability among the nominal model and all candidates.
    gap : Gap or None
        The gap left by the fit.
    shrinkage : float
        Excess energy of the nominal fit over that of this fit (see
        :func:`shrinkage_ratio`).
    strength : float or None
        How far the fitted effect moves the record: the largest channel RMS of
        (fit with the effect - the same calibration without it) in noise
        standard deviations (see :func:`effect_strength`); computed for the
        polished front runners only.
    note : str
        Why an effect was not fitted (e.g. degenerate with a calibrated parameter).
    """

    effect: str
    value: float | None
    uncertainty: float | None
    unit: str
    calibration: CalibrationResult | None
    bic: float
    delta_bic: float = 0.0
    weight: float = 0.0
    gap: Gap | None = None
    shrinkage: float = 1.0
    strength: float | None = None
    note: str = ""

    def to_dict(self) -> dict:
        return {
            "effect": self.effect,
            "value": self.value,
            "uncertainty": self.uncertainty,
            "unit": self.unit,
            "bic": self.bic if math.isfinite(self.bic) else None,
            "delta_bic": self.delta_bic if math.isfinite(self.delta_bic) else None,
            "weight": self.weight,
            "gap_after": self.gap.to_dict() if self.gap else None,
            "shrinkage": self.shrinkage,
            "strength": self.strength,
            "calibration": self.calibration.to_dict() if self.calibration else None,
            "note": self.note,
        }


@dataclass(frozen=True)
class CandidateSettings:
    """Settings of the candidate fits.

    Parameters
    ----------
    seeded : CalibrationSettings
        Settings of the seeded fits (pass 1; ``n_global`` is ignored).
    escalated : CalibrationSettings
        Settings of the escalated fits with a global search (pass 2).
    n_scan : int
        Values of the one-dimensional scan of the effect's value at the nominal calibration.
    n_escalate : int or None
        Best candidates refitted with a global search when none fits to the
        noise (None: all; the BIC ranking of fits that all missed the true basin
        says little, so the true effect may be anywhere in it).
    escalate_above : float
        A candidate "fits to the noise" for the escalation rule when its
        search-step total chi2/n is at most this.
    n_polish : int
        Candidates (best BIC first) always refined at the final integrator step;
        the others keep their search-step fit.
    polish_within : float
        Also refine every candidate whose search-step chi2 is within this
        fraction of the best one (the search step's integration error can
        reorder near-equivalent candidates), up to ``max_polish`` in all.
    max_polish : int
        Most candidates refined.
    n_quantum : int
        Values of the dense scan of a speed quantum.
    n_jobs : int or None
        Candidates fitted at once, on threads with one core each (None: numba's
        thread count, i.e. the cores numba may use; 1 fits them one by one with
        the batch-parallel simulator).
    """

    seeded: CalibrationSettings = CalibrationSettings(n_global=0, max_nfev=30)
    escalated: CalibrationSettings = CalibrationSettings(
        n_global=256, n_starts=2, horizons_ms=(10.0, 20.0, 40.0, 80.0, 200.0)
    )
    n_scan: int = 9
    n_escalate: int | None = None
    escalate_above: float = 1.1
    n_polish: int = 3
    polish_within: float = 0.1
    max_polish: int = 6
    n_quantum: int = 4000
    n_jobs: int | None = None

    def jobs(self) -> int:
        """Resolved ``n_jobs`` (at least 1)."""
        if self.n_jobs is not None:
            return max(1, int(self.n_jobs))
        import numba

        return max(1, int(numba.get_num_threads()))


def shrinkage_ratio(before: CalibrationResult, after: CalibrationResult) -> float:
    """How many times the gap shrinks: excess energy before over excess energy after.

    Both excesses (``chi2 - n``, in noise variances) are floored at their
    resolution, ``3 sqrt(2 n)`` (three standard deviations of a chi-square of
    n degrees of freedom), so a fit to the noise gives a large but finite
    ratio, and a gap below the resolution gives 1.
    """
    floor = 3.0 * math.sqrt(2.0 * after.n_data)
    ex_before = max(before.chi2 - before.n_data, floor)
    ex_after = max(after.chi2 - after.n_data, floor)
    return ex_before / ex_after


def _identifiable(effect: Effect, space: ModelSpace, record: Record) -> str:
    """Empty string, or why the effect cannot be told apart from the calibration."""
    if effect.target == "plant" and effect.field in space.names:
        return (
            f"{effect.field} is calibrated (not fixed by the record's conditions), so this effect is degenerate with it"
        )
    if _is_quantisation(effect) and "omega1" not in record.channels:
        return "the record has no omega1 channel, which is the only channel this effect changes"
    return ""


def _is_quantisation(effect: Effect) -> bool:
    return effect.target == "sensors" and effect.field == "speed_quantum"


def _seeds(
    record: Record, nominal: CalibrationResult, space: ModelSpace, settings: CandidateSettings, search_step: float
) -> list[dict[str, float]]:
    """Seeds of a joint fit: the nominal calibration with the effect at its neutral value
    (nearest bound when the neutral value is outside the range) and with the best value
    of a 1-D scan of the effect."""
    obj = Objective(record, space, nominal.sigma)
    base = space.unit(nominal.values)
    U = np.repeat(base[None], settings.n_scan + 1, axis=0)
    U[:-1, -1] = np.linspace(0.0, 1.0, settings.n_scan)
    U[-1, -1] = space.params[-1].unit_coord(space.effect.neutral)
    c2 = obj.chi2(U, [N_SAMPLES], SolverSettings(max_step=search_step))[:, 0]
    seeds = [space.values(U[-1])]
    i = int(np.argmin(c2[:-1]))
    if np.isfinite(c2[i]) and abs(U[i, -1] - U[-1, -1]) > 1e-9:
        seeds.append(space.values(U[i]))
    return seeds


def _candidate(effect: Effect, cal: CalibrationResult, nominal: CalibrationResult) -> Candidate:
    return Candidate(
        effect=effect.name,
        value=cal.values[effect.name],
        uncertainty=cal.uncertainties.get(effect.name),
        unit=effect.unit,
        calibration=cal,
        bic=cal.bic,
        gap=gap_of(cal),
        shrinkage=shrinkage_ratio(nominal, cal),
    )


def _quantum_scan(omega: np.ndarray, data: np.ndarray, sigma: float, q: np.ndarray) -> np.ndarray:
    """chi2 of omega1 rounded to each quantum in q (0 means no rounding), as the simulator rounds it."""
    out = np.empty(q.size)
    for i, qi in enumerate(q):
        sim = qi * np.round(omega / qi) if qi > 0 else omega
        out[i] = np.sum(((sim - data) / sigma) ** 2)
    return out


def _fit_quantisation(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    effect: Effect,
    settings: CandidateSettings,
    global_search: bool = False,
) -> Candidate:
    """Fit a speed quantum by dense scans around refits of the calibration (see module notes).

    Rounding makes the cost jagged in the plant parameters too, so the
    calibration is refitted on the *unrounded* simulated omega1 with the
    quantisation treated as extra white noise (variance q^2 / 12 added to the
    channel's); q is then scanned on the refitted omega1. Two rounds.
    """
    from engine.constants import CHANNELS

    lo, hi = effect.bounds
    q = np.linspace(lo, hi, settings.n_quantum)
    data = np.asarray(record["omega1"])
    sig = nominal.sigma["omega1"]
    j = CHANNELS.index("omega1")
    omega = nominal.simulation[j]
    values = nominal.values
    n_sim = 0
    cal = nominal
    for rnd in range(2):
        q_best = float(q[int(np.argmin(_quantum_scan(omega, data, sig, q)))])
        noise = {**nominal.noise, "omega1": math.hypot(nominal.noise["omega1"], q_best / math.sqrt(12.0))}
        cs = settings.escalated if (global_search and rnd == 0) else settings.seeded
        cal = calibrate(record, space, cs, noise=noise, seeds=[values], polish=True)
        n_sim += cal.n_simulations
        values, omega = cal.values, cal.simulation[j]
    c2 = _quantum_scan(omega, data, sig, q)
    q_best = float(q[int(np.argmin(c2))])
    # report the fit with the record's own noise and the rounded omega1
    cal.noise, cal.sigma = dict(nominal.noise), dict(nominal.sigma)
    rounded = q_best * np.round(omega / q_best) if q_best > 0 else omega
    cal.simulation = cal.simulation.copy()
    cal.simulation[j] = rounded
    others = {
        n: float(np.sum(((cal.simulation[CHANNELS.index(n)] - record[n]) / nominal.sigma[n]) ** 2))
        for n in record.channels
    }
    cal.chi2_per_channel = others
    cal.chi2 = float(sum(others.values()))
    cal.case = Case(cal.case.plant, cal.case.sensors.replace(speed_quantum=q_best))
    inside = q[c2 <= c2.min() + 1.0]
    unc = max(float(inside.max() - inside.min()) / 2.0, float(q[1] - q[0]))
    cal.values = {**cal.values, effect.name: q_best}
    cal.uncertainties = {**cal.uncertainties, effect.name: unc}
    cal.effect = effect.name
    cal.n_simulations = n_sim
    return _candidate(effect, cal, nominal)


def fit_candidate(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    effect: Effect,
    settings: CandidateSettings = CandidateSettings(),
    polish: bool = True,
    global_search: bool = False,
    extra_seeds: Sequence[Mapping[str, float]] = (),
) -> Candidate:
    """Refit the calibration together with one effect's value.

    Parameters
    ----------
    record : Record
        The measured record.
    nominal : CalibrationResult
        Calibration of the nominal model (seeds the search; supplies the noise levels).
    space : ModelSpace
        The nominal model space (free plant parameters).
    effect : Effect
        The candidate.
    settings : CandidateSettings
        Search settings.
    polish : bool
        Refine at the final integrator step (see :func:`calibrate`).
    global_search : bool
        Add the global search with continuation (``settings.escalated``).
    extra_seeds : sequence of mappings
        More starting points (e.g. an earlier fit of the same candidate).

    Returns
    -------
    Candidate
        With ``calibration`` None and an explanatory ``note`` when the effect is
        degenerate with a calibrated parameter or invisible in the record.
    """
    why = _identifiable(effect, space, record)
    if why:
        return Candidate(effect.name, None, None, effect.unit, None, math.inf, note=why)
    if _is_quantisation(effect):
        return _fit_quantisation(record, nominal, space, effect, settings, global_search)
    espace = space.with_effect(effect)
    cs = settings.escalated if global_search else settings.seeded
    seeds = _seeds(record, nominal, espace, settings, cs.search_step) + list(extra_seeds)
    cal = calibrate(record, espace, cs, noise=nominal.noise, seeds=seeds, polish=polish)
    return _candidate(effect, cal, nominal)


def effect_strength(cand: Candidate, space: ModelSpace, record: Record, noise: Mapping[str, float]) -> float:
    """Largest channel RMS change the fitted effect causes, in noise standard deviations.

    The fitted calibration is simulated once more without the effect and
    compared with the fit (noiseless, record channels only). This is the
    quantity of the blind validation's strength rule, evaluated at the fitted
    operating point instead of the (unknown) true one.
    """
    cal = cand.calibration
    if cal is None or cal.simulation is None:
        return math.nan
    from engine.constants import CHANNELS

    plain = {k: v for k, v in cal.values.items() if k in space.names}
    ch, _, status = run_cases([space.case(space.unit(plain))], SolverSettings(max_step=cal.step))
    if status[0] != 0:
        return math.nan
    out = 0.0
    for name in record.channels:
        j = CHANNELS.index(name)
        rms = float(np.sqrt(np.mean((cal.simulation[j] - ch[0, j]) ** 2)))
        out = max(out, rms / max(float(noise[name]), 1e-300))
    return out


_T = TypeVar("_T")


def _on_one_core(event: threading.Event, fn: Callable[..., _T], *args, **kwargs) -> _T:
    with serial_kernel(), cancel_scope(event):
        return fn(*args, **kwargs)


class _Task:
    """A fit running on a thread; ``cancel()`` also stops it if it has started (:mod:`engine.parallel`)."""

    def __init__(self, executor: ThreadPoolExecutor, fn: Callable[..., _T], *args, **kwargs):
        self._event = threading.Event()
        self._future: Future = executor.submit(_on_one_core, self._event, fn, *args, **kwargs)

    def result(self) -> _T:
        return self._future.result()

    def cancel(self) -> bool:
        self._event.set()
        return self._future.cancel()


class _Deferred:
    """The inline stand-in of a future: computed on the first ``result()``, never if cancelled first."""

    def __init__(self, thunk: Callable[[], _T]):
        self._thunk: Callable[[], _T] | None = thunk
        self._value: _T | None = None

    def result(self) -> _T:
        if self._thunk is not None:
            self._value, self._thunk = self._thunk(), None
        return self._value  # type: ignore[return-value]

    def cancel(self) -> bool:
        self._thunk = None
        return True


class _Runner:
    """Runs independent fits on ``n_jobs`` threads (each on one core), or inline when ``n_jobs == 1``."""

    def __init__(self, n_jobs: int):
        self.n_jobs = n_jobs
        self._ex = ThreadPoolExecutor(n_jobs, thread_name_prefix="candidate") if n_jobs > 1 else None
        self._tasks: list[_Task] = []

    def submit(self, fn: Callable[..., _T], *args, **kwargs) -> _Task | _Deferred:
        """A handle on ``fn(*args, **kwargs)`` (``result()``, ``cancel()``); inline, the call runs
        when its result is first asked for."""
        if self._ex is not None:
            task = _Task(self._ex, fn, *args, **kwargs)
            self._tasks.append(task)
            return task
        return _Deferred(lambda: fn(*args, **kwargs))

    def __enter__(self) -> _Runner:
        return self

    def __exit__(self, *exc) -> None:
        if self._ex is not None:
            for task in self._tasks:  # whatever is still running is no longer wanted (e.g. after an error)
                task.cancel()
            self._ex.shutdown(wait=True, cancel_futures=True)


def posterior_weights(bics: Mapping[str, float]) -> dict[str, float]:
    """Normalised ``exp(-BIC / 2)`` weights (infinite BIC gets weight 0)."""
    finite = {k: v for k, v in bics.items() if math.isfinite(v)}
    if not finite:
        return {k: 0.0 for k in bics}
    b0 = min(finite.values())
    w = {k: math.exp(-0.5 * (v - b0)) if math.isfinite(v) else 0.0 for k, v in bics.items()}
    s = sum(w.values())
    return {k: v / s for k, v in w.items()}


def fit_candidates(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary = CATALOGUE,
    settings: CandidateSettings = CandidateSettings(),
) -> list[Candidate]:
    """Fit every effect of a library and rank them by BIC (best first).

    Parameters
    ----------
    record : Record
        The measured record.
    nominal : CalibrationResult
        Calibration of the nominal model.
    space : ModelSpace
        The nominal model space.
    library : EffectLibrary
        Candidate effects.
    settings : CandidateSettings
        Search settings.

    Returns
    -------
    list of Candidate
        Sorted by BIC; ``delta_bic`` and ``weight`` filled in (weights are
        normalised over the candidates and the nominal model, whose weight is
        ``1 - sum(weights)``).
    """

    with single_threaded_blas(), _Runner(settings.jobs()) as runner:
        return _fit_candidates(record, nominal, space, library, settings, runner)


def _fit_candidates(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    settings: CandidateSettings,
    runner: _Runner,
) -> list[Candidate]:
    def order(cs: list[Candidate]) -> list[Candidate]:
        return sorted(cs, key=lambda c: c.bic)

    t0 = time.perf_counter()
    # pass 1: seeded fits at the search step
    futs = [runner.submit(fit_candidate, record, nominal, space, e, settings, polish=False) for e in library.values()]
    cands = order([f.result() for f in futs])
    logger.info("seeded fits of %d candidates: %.1f s", len(cands), time.perf_counter() - t0)
    fitted = [c for c in cands if c.calibration is not None]

    # pass 2: escalate (best seeded BIC first) when none fits to the noise, until one does
    if fitted and min(c.calibration.reduced_chi2 for c in fitted) > settings.escalate_above:
        n_esc = len(cands) if settings.n_escalate is None else settings.n_escalate
        logger.info("no candidate fits to the noise after the seeded fits; global search for up to %d", n_esc)

        def escalate(i: int):
            return runner.submit(
                fit_candidate,
                record,
                nominal,
                space,
                library[cands[i].effect],
                settings,
                polish=False,
                global_search=True,
                extra_seeds=[cands[i].calibration.values],
            )

        idx = [i for i, c in enumerate(cands[:n_esc]) if c.calibration is not None]
        tasks = {}
        for k, i in enumerate(idx):
            if k == 1:  # the best seeded candidate ran alone (on every core); the rest run side by side
                tasks = {j: escalate(j) for j in idx[1:]}
            c = cands[i]
            new = (tasks[i] if i in tasks else escalate(i)).result()
            new.calibration.n_simulations += c.calibration.n_simulations
            new.calibration.seconds += c.calibration.seconds
            cands[i] = new if new.bic < c.bic else c
            if cands[i].calibration.reduced_chi2 <= settings.escalate_above:
                # one effect explains the record: the others keep their seeded fits
                for j, rest in enumerate(cands[i + 1 : n_esc], start=i + 1):
                    rest.note = (
                        rest.note or f"seeded fit only: the escalation stopped once {c.effect} fitted to the noise"
                    )
                    if j in tasks:
                        tasks[j].cancel()  # stops it even if it is running
                break
        cands = order(cands)
        logger.info("escalation done, %.1f s into the candidate fits", time.perf_counter() - t0)

    # pass 3: refine the front runners at the final integrator step, from their search-step optimum
    fitted = [c for c in cands if c.calibration is not None]
    best_chi2 = fitted[0].calibration.chi2 if fitted else math.inf
    n_pol = sum(
        1
        for i, c in enumerate(fitted[: settings.max_polish])
        if i < settings.n_polish or c.calibration.chi2 <= (1 + settings.polish_within) * best_chi2
    )
    futs = {
        i: runner.submit(
            calibrate,
            record,
            space.with_effect(library[c.effect]),
            settings.seeded,
            noise=nominal.noise,
            seeds=[c.calibration.values],
            polish=True,
        )
        for i, c in enumerate(cands[:n_pol])
        if c.calibration is not None and c.calibration.step != settings.seeded.final_step
    }
    for i, f in futs.items():
        c, cal = cands[i], f.result()
        cal.n_simulations += c.calibration.n_simulations
        cal.seconds += c.calibration.seconds
        cands[i] = _candidate(library[c.effect], cal, nominal)
    cands = order(cands)
    futs = {
        i: runner.submit(effect_strength, c, space, record, nominal.noise)
        for i, c in enumerate(cands[:n_pol])
        if c.calibration is not None
    }
    for i, f in futs.items():
        cands[i].strength = f.result()
    logger.info("candidate fits done in %.1f s (%d refined at the final step)", time.perf_counter() - t0, n_pol)
    w = posterior_weights({"<nominal>": nominal.bic, **{c.effect: c.bic for c in cands}})
    best = cands[0].bic if cands else math.inf
    for c in cands:
        c.delta_bic = c.bic - best
        c.weight = w[c.effect]
        logger.debug(
            "candidate %s: value %s, chi2/n %s, dBIC %.1f",
            c.effect,
            c.value,
            c.calibration.reduced_chi2 if c.calibration else None,
            c.delta_bic,
        )
    return cands
