"""The search of a diagnosis beyond its single candidates: the staged search of sets of effects
(:func:`staged_search`) and the singles refitted from a set that fits to the noise with them as its
only strong member (:func:`singles_of_sets`)."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace

from engine.diagnosis.calibration import CalibrationResult, calibrate
from engine.diagnosis.candidate import Candidate, effect_strength
from engine.diagnosis.candidate_set import CandidateSet
from engine.diagnosis.candidates import (
    escalate_candidates,
    needs_escalation,
    needs_reseed,
    reseed_candidates,
    to_escalate,
)
from engine.diagnosis.decision import explains, explains_single, fits_noise
from engine.diagnosis.sets import ScreenCache, search_sets
from engine.diagnosis.settings import DiagnosisSettings
from engine.diagnosis.space import ModelSpace
from engine.records import Record
from engine.simulation import EffectLibrary

logger = logging.getLogger(__name__)

__all__ = ["MOVED_REL_TOL", "escalation_gain", "left_basin", "set_progress", "singles_of_sets", "staged_search"]

#: A single candidate's fit "moved" during the escalation (so that the pairs built from it are fitted
#: again) when some value changed by more than this fraction (polishing moves values by ~0.1 %).
MOVED_REL_TOL: float = 0.01


def left_basin(before: Mapping[str, Mapping[str, float]], c: Candidate) -> bool:
    """Whether a candidate's fit left its earlier fit's basin (a value changed by more than ``MOVED_REL_TOL``)."""
    old = before.get(c.effect)
    if old is None or c.calibration is None:
        return True
    new = c.calibration.values
    return any(not math.isclose(v, old.get(k, math.nan), rel_tol=MOVED_REL_TOL, abs_tol=1e-6) for k, v in new.items())


def singles_of_sets(
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
        if st.calibration is None or not fits_noise(st.calibration, settings):
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


def staged_search(
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
    often among them, and found in seconds); with ``escalate_before_reseed``, pass 1b of the
    singles (their refits from the nominal calibration's starts, which ``cands`` then must not
    have had: ``fit_candidates(..., reseed=False)``) and the early escalation of the best two
    after it that were not escalated yet; the first pairs from the seeded singles, the best with
    a global search in their joint space; the first triples (``first_triples``: seeded fits only);
    the exchange from the best first triple (``first_exchange``, unless the sets so far closed less
    than ``min_exchange_progress`` of the best single's excess); the escalation of the singles
    (``n_escalate_singles``); the search of sets of up to three from the escalated singles. The
    first triples start from every first pair as fitted, the exchange from every set so far; the
    last search keeps the ``n_report`` best sets so far unless the escalation moved a member's
    single fit, and fits the rest again; the decision sees each search's ``n_report`` best.

    Parameters
    ----------
    record, nominal, space, library
        As in :func:`~engine.diagnosis.diagnose.diagnose` (``record`` is the test window).
    cands : list of Candidate
        The seeded single candidates (``fit_candidates(..., escalate=False)``; with
        ``reseed=False`` too when ``SetSettings.escalate_before_reseed``).
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
    if ss.escalate_before_reseed and needs_reseed(nominal, cands, cs):
        cands = reseed_candidates(record, nominal, space, library, cands, cs)
        stage("re-seeded singles")
        early = ss.escalation(cs, early=True)
        if to_escalate(cands, early) and needs_escalation(cands, cs):
            # the best after pass 1b that were not escalated yet
            cands = escalate_candidates(record, nominal, space, library, cands, early)
            stage("early escalation of the best re-seeded singles")
    if explains_single(cands, settings):
        return cands, sets
    everything = replace(ss, n_report=None)  # every set fitted, for the later stages
    screens: ScreenCache = {}  # the staged searches screen the same best singles
    fitted = search_sets(record, nominal, space, library, cands, cs, replace(everything, max_size=2), (), screens)
    sets = fitted[: ss.n_report]
    stage("first pairs")
    progress: float | None = None  # the share of the best single's excess the sets closed, after the first triples
    if ss.first_triples and ss.max_size >= 3 and not any(explains(s, settings) for s in sets):
        seeded_only = replace(everything, escalate=False, n_exchange=0)
        triples = search_sets(record, nominal, space, library, cands, cs, seeded_only, fitted, screens)
        fitted = _merge_sets(fitted, triples)
        sets = fitted[: ss.n_report]
        stage("first triples")
        progress = set_progress(cands, sets)
        logger.info(
            "after the first triples: best set %s at chi2/n %.4g, best single at %.4g; progress %.3g",
            "+".join(sets[0].effects) if sets else "-",
            sets[0].calibration.reduced_chi2 if sets and sets[0].calibration is not None else math.nan,
            min((c.calibration.reduced_chi2 for c in cands if c.calibration is not None), default=math.nan),
            progress,
        )
    triples_so_far = any(len(s.effects) == 3 for s in fitted)
    exchange = (
        ss.first_exchange and ss.n_exchange > 0 and triples_so_far and not any(explains(s, settings) for s in sets)
    )
    if exchange and ss.min_exchange_progress is not None:
        progress = set_progress(cands, sets) if progress is None else progress
        if progress < ss.min_exchange_progress:
            logger.info("no exchange: the sets so far closed %.3g of the best single's excess", progress)
            exchange = False
    if exchange:
        # the sets fitted so far are kept as they are (n_extend 0: no triple is built or fitted
        # again); only the exchange from the best triple, and the finish of the best sets, run
        exchange_only = replace(everything, escalate=False, n_extend=0)
        exchanged = search_sets(record, nominal, space, library, cands, cs, exchange_only, fitted, screens)
        fitted = _merge_sets(fitted, exchanged)
        sets = fitted[: ss.n_report]
        stage("first exchange")
    if any(explains(s, settings) for s in sets):
        return cands, sets
    before = {c.effect: c.calibration for c in cands if c.calibration is not None}
    if needs_escalation(cands, cs):
        cands = escalate_candidates(record, nominal, space, library, cands, ss.escalation(cs))
        stage("escalation of the singles")
    if not explains_single(cands, settings):
        gain, progress = escalation_gain(before, cands), set_progress(cands, sets)
        logger.info(
            "the escalation of the singles closed up to %.3g of a single's excess chi2; the best set so far "
            "closed %.3g of the best single's",
            gain,
            progress,
        )
        if ss.min_escalation_gain is not None and gain < ss.min_escalation_gain and progress < ss.min_set_progress:
            # the second search would start from the basins the first one started from, and the sets of
            # up to three found so far left most of the best single's gap: the catalogue lacks what is missing
            logger.info("the first search's sets stand (no second search of sets)")
            return cands, sets
        # the best sets so far stand as fitted unless the escalation moved a single they came from; the
        # others are fitted again from the escalated singles (keeping every unmoved set lost seed-151
        # case0168: its true triple was found from a pair refitted there, docs/diagnosis.md 8b)
        moved = {
            c.effect
            for c in cands
            if c.calibration is not None and left_basin({n: cal.values for n, cal in before.items()}, c)
        }
        keep = [s for s in sets if not moved & set(s.effects)]
        again = search_sets(record, nominal, space, library, cands, cs, ss, keep, screens)
        sets = _merge_sets(sets, again)
        stage("sets of up to three")
    return cands, sets


def escalation_gain(before: Mapping[str, CalibrationResult], cands: Sequence[Candidate]) -> float:
    """The largest share of a single candidate's excess chi2 that its escalation closed.

    A single's excess is its seeded fit's chi2 above what noise alone leaves (:func:`_excess`); the
    share closed is ``(chi2_before - chi2_after) / excess``, 0 for a fit the escalation did not improve
    and 1 for one it brought to the noise.

    Parameters
    ----------
    before : mapping of str to CalibrationResult
        Each single's fit before the escalation, by effect name.
    cands : sequence of Candidate
        The candidates after it.

    Returns
    -------
    float
        The largest share over the candidates (0 when none was fitted before and after).
    """
    best = 0.0
    for c in cands:
        old, new = before.get(c.effect), c.calibration
        if old is None or new is None:
            continue
        excess = _excess(old)
        if excess > 0:
            best = max(best, (old.chi2 - new.chi2) / excess)
    return best


def set_progress(cands: Sequence[Candidate], sets: Sequence[CandidateSet]) -> float:
    """The share of the best single candidate's excess chi2 that the best set so far closed.

    The excess of a fit is its chi2 above what noise alone leaves (:func:`_excess`); the share closed is
    ``1 - excess(best set) / excess(best single)``: 0 when no set fits better than the best single,
    near 1 when a set comes close to the noise that no single approaches.

    Parameters
    ----------
    cands : sequence of Candidate
        The single candidates.
    sets : sequence of CandidateSet
        The sets fitted so far.

    Returns
    -------
    float
        The share, in [0, 1] (0 without a fitted single or set, or when the best single is at the noise).
    """
    single = min((_excess(c.calibration) for c in cands if c.calibration is not None), default=math.nan)
    best = min((_excess(s.calibration) for s in sets if s.calibration is not None), default=math.nan)
    if not (math.isfinite(single) and math.isfinite(best)) or single <= 0.0:
        return 0.0
    return float(min(max(1.0 - max(best, 0.0) / single, 0.0), 1.0))


def _excess(cal: CalibrationResult) -> float:
    """A fit's chi2 above what noise alone leaves, its number of data (reduced chi2 1) [noise variances]."""
    return cal.chi2 - cal.n_data


def _merge_sets(first: Sequence[CandidateSet], second: Sequence[CandidateSet]) -> list[CandidateSet]:
    """The sets of two searches, the better fit of each group of effects, best BIC first."""
    best: dict[frozenset[str], CandidateSet] = {}
    for s in (*first, *second):
        key = frozenset(s.effects)
        if key not in best or s.bic < best[key].bic:
            best[key] = s
    return sorted(best.values(), key=lambda s: s.bic)
