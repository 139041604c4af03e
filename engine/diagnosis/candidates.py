"""Which effect: fit every candidate effect (with the calibration) and rank them by evidence.

For every effect of an :class:`~engine.simulation.EffectLibrary` the
calibration is refitted with the effect's scalar value as one more bounded
parameter (:func:`engine.diagnosis.candidate.fit_candidate`), in three passes:

1. **Seeded fits** (every candidate): least squares on the full record from
   the nominal calibration with the effect at its neutral value, and with the best
   value of a one-dimensional scan of the effect (9 values across its range). Their
   finite-difference step is 1e-5 of the box (:data:`engine.diagnosis.candidate.SEEDED_FITS`): on
   the whole record a true effect's valley can be so narrow in K that differences over 1e-4 point
   the trust region off it and the fit creeps (seed-173 case0228, a sensor gain: chi2/n 2.0 after
   30 evaluations at 1e-4, 1.01 after 100; 0.99 in 17-27 at 1e-5; docs/diagnosis.md 8b, *The
   seeded fits' difference step*).
1b. **Re-seeded fits** (only when no candidate fits to the noise after pass 1): the
   candidates, best seeded BIC first, are fitted again from the nominal calibration's global
   starts, each with the best value of a scan of the effect there
   (:func:`engine.diagnosis.candidate.refit_from_starts`), until one fits to the noise
   (``CandidateSettings.reseed_stop_at_noise``): a strong missing effect can drag the nominal
   fit out of the basin its early-window starts were in, and every seeded fit with it. The
   diagnosis's staged search runs it later (:func:`reseed_candidates`), only when the early
   escalation of the best two seeded candidates did not reach the noise either
   (:attr:`engine.diagnosis.sets.SetSettings.escalate_before_reseed`).
2. **Escalation** (only when no candidate fits to the noise after pass 1b):
   the candidates, best seeded BIC first, get the full global search (256
   Sobol points on the early window, continuation over 10, 20, 40, 80, 200 ms)
   in the joint space, until one fits to the noise; a strong effect can drag
   the nominal calibration out of the true basin, and then no seed lies in it.
3. **Polish**: the best ``n_polish`` candidates (and any other within 10 %
   of the best chi2, up to ``max_polish``) are refined at the final integrator
   step, so that they compete on equal terms with the nominal fit and with
   each other.

The speed quantum is fitted by dense scans instead of least squares
(:mod:`engine.diagnosis.quantisation`); the evidence (BIC and posterior
weights) is described in :mod:`engine.diagnosis.candidate`.

The candidates are independent, so each pass fits them on ``n_jobs`` threads
(:class:`engine.parallel.Runner`), each running its simulations on one core
(:func:`engine.simulation.serial_kernel`): the optimiser's single-point
evaluations would otherwise leave all but one core idle. The escalation keeps
its sequential meaning: its fits are collected in ranking order and the rest
are cancelled once one fits to the noise, so the result does not depend on
``n_jobs`` (beyond rounding).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import replace

from engine.diagnosis.calibration import CalibrationError, CalibrationResult, calibrate
from engine.diagnosis.candidate import (
    Candidate,
    CandidateSettings,
    effect_strength,
    fit_candidate,
    posterior_weights,
    refit_from_starts,
)
from engine.diagnosis.quantisation import is_speed_quantum
from engine.diagnosis.space import ModelSpace
from engine.parallel import Deferred, Runner, Task, single_threaded_blas
from engine.records import Record
from engine.simulation import CATALOGUE, EffectLibrary, serial_kernel

logger = logging.getLogger(__name__)

__all__ = [
    "escalate_candidates",
    "fit_candidates",
    "needs_escalation",
    "needs_reseed",
    "reseed_candidates",
    "to_escalate",
]


def _fitted(c: Candidate) -> CalibrationResult:
    """The joint fit of a candidate that has one."""
    if c.calibration is None:
        raise ValueError(f"the candidate {c.effect} was not fitted")
    return c.calibration


def fit_candidates(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary = CATALOGUE,
    settings: CandidateSettings | None = None,
    escalate: bool = True,
    progress: Callable[[float, str], None] | None = None,
    reseed: bool = True,
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
    settings : CandidateSettings, optional
        Search settings (default ``CandidateSettings()``).
    escalate : bool
        Run pass 2 (the escalation) when no seeded fit reaches the noise; with False the
        caller may escalate later with :func:`escalate_candidates` (the diagnosis first
        tries sets of effects from the seeded fits).
    progress : callable, optional
        ``progress(fraction, stage)`` as the seeded fits come in (fraction of them done).
    reseed : bool
        Run pass 1b (with ``settings.reseed_from_starts``) when no seeded fit reaches the noise;
        with False the caller may run it later with :func:`reseed_candidates` (the staged search
        first escalates the best seeded singles, :attr:`engine.diagnosis.sets.SetSettings.escalate_before_reseed`).

    Returns
    -------
    list of Candidate
        Sorted by BIC; ``delta_bic`` and ``weight`` filled in (weights are
        normalised over the candidates and the nominal model, whose weight is
        ``1 - sum(weights)``).
    """
    settings = CandidateSettings() if settings is None else settings
    runner = Runner(settings.jobs(), thread_context=serial_kernel, thread_name_prefix="candidate")
    with single_threaded_blas(), runner:
        t0 = time.perf_counter()
        # pass 1: seeded fits at the search step
        seeded = [
            runner.submit(fit_candidate, record, nominal, space, e, settings, polish=False) for e in library.values()
        ]
        fitted = []
        for i, f in enumerate(seeded):  # in order: a later fit may be done first, the count is still right
            fitted.append(f.result())
            if progress is not None:
                progress((i + 1) / len(seeded), f"fitted {i + 1} of {len(seeded)} candidate effects")
        cands = _order(fitted)
        logger.info("seeded fits of %d candidates: %.1f s", len(cands), time.perf_counter() - t0)
        if reseed and needs_reseed(nominal, cands, settings):
            cands = _reseed(record, nominal, space, library, cands, settings, runner)
        if escalate:
            cands = _escalate(record, nominal, space, library, cands, settings, runner)
        return _finish(record, nominal, space, library, cands, settings, runner, t0)


def needs_escalation(cands: list[Candidate], settings: CandidateSettings) -> bool:
    """Whether no fitted candidate reaches the noise (search-step chi2/n above ``escalate_above``)."""
    fitted = [c for c in cands if c.calibration is not None]
    return bool(fitted) and min(_fitted(c).reduced_chi2 for c in fitted) > settings.escalate_above


def needs_reseed(nominal: CalibrationResult, cands: list[Candidate], settings: CandidateSettings) -> bool:
    """Whether pass 1b is due: it is on, the nominal calibration has global starts, and no fitted
    candidate reaches the noise."""
    return settings.reseed_from_starts and bool(nominal.starts) and needs_escalation(cands, settings)


def to_escalate(cands: list[Candidate], settings: CandidateSettings) -> list[int]:
    """Indices of the candidates, in the given (ranking) order, that an escalation with ``settings``
    would give the global search: fitted, not escalated yet, among the first ``n_escalate``."""
    n_esc = len(cands) if settings.n_escalate is None else settings.n_escalate
    return [i for i, c in enumerate(cands[:n_esc]) if c.calibration is not None and not c.escalated]


def escalate_candidates(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    cands: list[Candidate],
    settings: CandidateSettings | None = None,
) -> list[Candidate]:
    """Pass 2 and 3 for candidates fitted with ``fit_candidates(..., escalate=False)``.

    Parameters
    ----------
    record, nominal, space, library
        As given to :func:`fit_candidates`.
    cands : list of Candidate
        Its result (not modified).
    settings : CandidateSettings, optional
        Search settings (default ``CandidateSettings()``).

    Returns
    -------
    list of Candidate
        Ranked again, with the escalated fits that improved on the seeded ones (refined at
        the final step when among the front runners).
    """
    settings = CandidateSettings() if settings is None else settings
    return _later_pass(_escalate, record, nominal, space, library, cands, settings)


def reseed_candidates(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    cands: list[Candidate],
    settings: CandidateSettings | None = None,
) -> list[Candidate]:
    """Pass 1b (and pass 3) for candidates fitted with ``fit_candidates(..., reseed=False)``.

    Runs only when ``settings.reseed_from_starts``, the nominal calibration has global starts and
    no candidate fits to the noise; otherwise the candidates come back ranked as given.

    Parameters
    ----------
    record, nominal, space, library
        As given to :func:`fit_candidates`.
    cands : list of Candidate
        Its result, perhaps escalated since (not modified).
    settings : CandidateSettings, optional
        Search settings (default ``CandidateSettings()``).

    Returns
    -------
    list of Candidate
        Ranked again, with the refits from the starts that improved on the fits given (refined
        at the final step when among the front runners).
    """
    settings = CandidateSettings() if settings is None else settings
    if not needs_reseed(nominal, cands, settings):
        return _order(list(cands))
    return _later_pass(_reseed, record, nominal, space, library, cands, settings)


def _later_pass(
    run: Callable[..., list[Candidate]],
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    cands: list[Candidate],
    settings: CandidateSettings,
) -> list[Candidate]:
    """``run`` (:func:`_escalate` or :func:`_reseed`) on a copy of ``cands`` in ranking order, then pass 3."""
    runner = Runner(settings.jobs(), thread_context=serial_kernel, thread_name_prefix="candidate")
    with single_threaded_blas(), runner:
        t0 = time.perf_counter()
        out = run(record, nominal, space, library, _order(list(cands)), settings, runner)
        return _finish(record, nominal, space, library, out, settings, runner, t0)


def _order(cs: list[Candidate]) -> list[Candidate]:
    return sorted(cs, key=lambda c: c.bic)


def _better(new: Candidate, old: Candidate) -> Candidate:
    """The fit of lower BIC (``old`` on a tie), a copy that counts the simulations and seconds of both."""
    kept, spent = (new, old) if new.bic < old.bic else (old, new)
    cal, other = _fitted(kept), _fitted(spent)
    work = replace(cal, n_simulations=cal.n_simulations + other.n_simulations, seconds=cal.seconds + other.seconds)
    return replace(kept, calibration=work)


def _reseed(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    cands: list[Candidate],
    settings: CandidateSettings,
    runner: Runner,
) -> list[Candidate]:
    """Pass 1b: every fitted candidate (but the speed quantum, fitted by scans) refitted from the
    nominal calibration's starts; a refit replaces the seeded fit when its BIC is lower.

    With ``settings.reseed_stop_at_noise`` the refits are collected in ranking order and the
    rest are cancelled at the first that fits to the noise (they keep their seeded fits, with a
    note), so that the result does not depend on ``n_jobs``.
    """
    t0 = time.perf_counter()
    todo = {
        i: runner.submit(refit_from_starts, record, nominal, space, library[c.effect], settings, _fitted(c))
        for i, c in enumerate(cands)
        if c.calibration is not None and not is_speed_quantum(library[c.effect])
    }
    out = list(cands)
    stopped_by = ""
    for i, task in todo.items():
        c = cands[i]
        if stopped_by:
            task.cancel()  # stops it even if it is running
            note = c.note or f"seeded fit only: the re-seeded fits stopped once {stopped_by} fitted to the noise"
            out[i] = replace(c, note=note)
            continue
        try:
            new = task.result()
        except CalibrationError as exc:  # the seeded fit stands
            logger.info("%s could not be refitted from the nominal starts: %s", c.effect, exc)
            continue
        out[i] = replace(_better(new, c), escalated=c.escalated)  # an escalated fit is not escalated again
        if settings.reseed_stop_at_noise and _fitted(out[i]).reduced_chi2 <= settings.escalate_above:
            stopped_by = c.effect
            logger.info("re-seeded fits: %s (rank %d) fits to the noise, the rest are not refitted", c.effect, i + 1)
    out = _order(out)
    logger.info(
        "re-seeded fits from %d nominal starts: %.1f s, best %s chi2/n %.4g",
        len(nominal.starts),
        time.perf_counter() - t0,
        out[0].effect,
        _fitted(out[0]).reduced_chi2 if out[0].calibration is not None else math.nan,
    )
    return out


def _escalate(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    cands: list[Candidate],
    settings: CandidateSettings,
    runner: Runner,
) -> list[Candidate]:
    """Pass 2: escalate (best BIC first) when none fits to the noise, until one does."""
    if not needs_escalation(cands, settings):
        return cands
    t0 = time.perf_counter()
    n_esc = len(cands) if settings.n_escalate is None else settings.n_escalate
    logger.info("no candidate fits to the noise after the seeded fits; global search for up to %d", n_esc)

    def escalate(i: int) -> Task[Candidate] | Deferred[Candidate]:
        return runner.submit(
            fit_candidate,
            record,
            nominal,
            space,
            library[cands[i].effect],
            settings,
            polish=False,
            global_search=True,
            extra_seeds=[_fitted(cands[i]).values],
        )

    idx = to_escalate(cands, settings)
    tasks: dict[int, Task[Candidate] | Deferred[Candidate]] = {}
    for k, i in enumerate(idx):
        if k == 1:  # the best seeded candidate ran alone (on every core); the rest run side by side
            tasks = {j: escalate(j) for j in idx[1:]}
        c = cands[i]
        new = (tasks[i] if i in tasks else escalate(i)).result()
        cands[i] = replace(_better(new, c), escalated=True)  # the caller's candidates stay as given
        if _fitted(cands[i]).reduced_chi2 <= settings.escalate_above:
            logger.info("escalation: %s (rank %d before it) fits to the noise", c.effect, i + 1)
            # one effect explains the record: the others keep their seeded fits
            for j, rest in enumerate(cands[i + 1 : n_esc], start=i + 1):
                note = rest.note or f"seeded fit only: the escalation stopped once {c.effect} fitted to the noise"
                cands[j] = replace(rest, note=note)
                if j in tasks:
                    tasks[j].cancel()  # stops it even if it is running
            break
    logger.info("escalation done in %.1f s", time.perf_counter() - t0)
    return _order(cands)


def _finish(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    cands: list[Candidate],
    settings: CandidateSettings,
    runner: Runner,
    t0: float,
) -> list[Candidate]:
    """Pass 3 (refine the front runners at the final integrator step), strengths and weights."""
    fitted = [c for c in cands if c.calibration is not None]
    best_chi2 = _fitted(fitted[0]).chi2 if fitted else math.inf
    n_pol = len(
        [
            c
            for i, c in enumerate(fitted[: settings.max_polish])
            if i < settings.n_polish or _fitted(c).chi2 <= (1 + settings.polish_within) * best_chi2
        ]
    )
    polished = {
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
    for i, fit in polished.items():
        c, cal = cands[i], fit.result()
        cal.n_simulations += _fitted(c).n_simulations
        cal.seconds += _fitted(c).seconds
        cands[i] = replace(Candidate.from_fit(library[c.effect], cal, nominal), escalated=c.escalated)
    cands = _order(cands)
    strengths = {
        i: runner.submit(effect_strength, c, space, record, nominal.sigma)  # the floored noise of the fit
        for i, c in enumerate(cands[:n_pol])
        if c.calibration is not None and c.strength is None
    }
    for i, strength in strengths.items():
        cands[i].strength = strength.result()
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
