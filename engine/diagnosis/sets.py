"""Several effects at once: candidate sets of up to three effects, and the gap budget of a fit.

When no single effect brings the residual to the noise, the record may carry
two or three effects at once. :func:`search_sets` fits sets of effects
together with the calibration (one more bounded parameter per effect,
:meth:`engine.diagnosis.space.ModelSpace.with_effects`) by greedy forward
selection:

1. **Pairs**: every pair among the ``pool`` best single candidates (by BIC,
   only those that lower the nominal BIC), and the ``n_forward`` effects of the
   library that the profiled screen (:func:`engine.diagnosis.screening.rank_additions`:
   a scan of each effect's value at the single's fit with the calibration refitted to
   first order) ranks best as the second member of the ``n_base`` best singles
   (forward selection: an effect that is weak beside a strong one, such as a sensor
   gain, ranks low as a single because its single fit cannot absorb the strong effect's
   residual, yet it is what the best single lacks), and the speed quantum
   whenever the record's omega1 values lie on a lattice
   (:func:`engine.diagnosis.quantisation.lattice_quantum`: the screen judges the
   quantum by the model's omega1, which a strong effect beside it distorts), less
   pairs that are the same physics (two pure time shifts, or two effects on the same field). Each
   pair is fitted from seeds built of its members' single fits (the better
   member's calibration with the other effect at its single-fit value and at
   its neutral value, and the best point of a scan of the other effect's value
   over its range at the better member's fit), by least squares at the search
   step: every seed is simulated once and only the ``n_seed_fits`` of lowest chi2 are
   refined.
2. **Triples**: the ``n_extend`` best pairs, the ``n_base`` best of them
   extended by the ``n_forward`` best-screened other effects of the library, the others by every other
   pool member, seeded the same way from the pair's fit and a scan of the new
   member's value at it; only when no pair fits to the noise, the best pair refined at the final
   integrator step first (the search step's integration error alone can lift a
   right pair's chi2/n above the threshold on a quiet record).
3. **Escalation**: when no set fits to the noise after the seeded fits, the
   ``n_escalate`` best pairs and the best triple get the full global search in
   their joint space (strong effects can drag every single fit out of the true
   basin).
4. **Exchange**: when still no set fits to the noise, each member of the best triple in turn
   (the one whose removal costs least first) is replaced by the ``n_exchange`` effects the
   profiled screen ranks best beside the other two (refitted from the triple's fit), each new
   triple with the global search, until one fits to the noise (sequential replacement: a member
   that stands in for a near-equivalent effect, a sensor low-pass for a measurement delay, holds
   the forward selection's triples away from the true one); repeated from the new best triple,
   up to ``n_exchange_rounds`` rounds, while no set fits to the noise and the best triple is one
   no round started from.
5. **Polish**: the best sets are refined at the final integrator step.
6. **Backward elimination**: a polished set that fits to the noise is refitted
   without its weak members (those that move the record by at most
   ``min_strength`` noise RMS on its own), or, when every member is strong,
   without each member in turn, seeded from its own fit: a spurious third
   effect often lets the search reach the basin that the smaller set's seeded
   fit missed, and on a quiet record a spurious member can sit a hair from its
   neutral value yet move the record by several noise RMS at that operating
   point, so only the refitted smaller set shows it is not needed.
7. **Swap**: once the best set fits to the noise, each member in turn is replaced by the
   ``n_swap`` effects the profiled screen ranks best beside the others, fitted from the others'
   fit (seeded, refined at the final step): the search stops at the first set that fits, so
   without it an effect the search never tried in a member's place could neither replace that
   member nor be reported as its near twin (:mod:`engine.diagnosis.ambiguity`). A swapped set
   that fits to the noise with a weak member (the true pair beside a third effect at its
   neutral value) is refitted without its weak members, as in step 6.

Evidence is the same BIC as for single effects (``chi2 + k ln n``): every
added effect must lower chi2 by more than ln(n) (about 9 for five channels) to
pay for its parameter, and the decision (:func:`engine.diagnosis.diagnose.decide`)
asks a larger set to beat the best smaller model by ``min_delta_bic``.

The gap budget of a fit (:func:`~engine.diagnosis.budget.gap_budget`) and each member's strength
are in :mod:`engine.diagnosis.budget`; the set type in :mod:`engine.diagnosis.candidate_set`.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from engine.diagnosis.budget import gap_budget, member_strengths
from engine.diagnosis.calibration import CalibrationResult, CalibrationSettings, calibrate
from engine.diagnosis.candidate import Candidate, CandidateSettings
from engine.diagnosis.candidate_set import CandidateSet
from engine.diagnosis.noise import NoiseModel, noise_weights
from engine.diagnosis.objective import Objective
from engine.diagnosis.quantisation import fit_quantisation, is_speed_quantum, record_lattice
from engine.diagnosis.screening import rank_additions
from engine.diagnosis.space import TIME_SHIFT_EFFECTS, ModelSpace, scan_grid
from engine.parallel import Runner, single_threaded_blas
from engine.records import Record
from engine.simulation import Effect, EffectLibrary, serial_kernel

logger = logging.getLogger(__name__)

__all__ = ["ScreenCache", "SetSettings", "same_physics", "search_sets"]

#: The profiled screens of one diagnosis: ``(group, additions, the group's fit values, n_forward)`` ->
#: the additions to fit beside the group, best first (:func:`search_sets`, ``screens``).
ScreenCache = dict[tuple[Any, ...], list[str]]


@dataclass(frozen=True)
class SetSettings:
    """Settings of the search for sets of effects.

    Parameters
    ----------
    max_size : int
        Largest set (3).
    pool : int
        Best single candidates (by BIC) the sets are built from.
    n_extend : int
        Best pairs extended to triples.
    n_base : int
        Forward selection: every effect of the library is tried as the second member of
        this many best singles, and as the third member of this many best pairs (the other
        extended pairs, and the other pairs, are built of the ``pool`` only; 0: the pool only).
        Two, not one: the best single is often a stand-in (a stator resistance drift for a
        supply voltage change) beside which the true partner screens last, while it screens
        well beside the true member that ranks second (docs/diagnosis.md 8b, *Two bases*).
    n_forward : int or None
        Forward selection fits only this many of the library's effects beside a base model,
        the best ranked by the profiled scan of :func:`engine.diagnosis.screening.rank_additions`
        (None: every effect).
    escalate : bool
        Global search for the best set of each size when no seeded set fits to the noise.
    n_escalate : int
        Best pairs (by BIC) that get the global search when no seeded set fits to the noise
        (with the best triple): a right pair seeded from single fits distorted by each other's
        residual can rank below wrong pairs until it leaves the wrong basin.
    escalate_above : float
        A set "fits to the noise" for the escalation rule when its search-step chi2/n is at most this.
    max_reduced_chi2 : float
        ... and when its chi2/n at the final integrator step (once refined) is at most this: the
        decision's threshold (the diagnosis passes its own), so that a refined set just above it
        goes on to the triples and the escalation instead of ending the search unexplained.
    n_polish : int
        Best sets (by BIC) refined at the final integrator step.
    n_report : int or None
        Sets kept in the result (best BIC first; None: every set fitted).
    min_strength : float
        A member of a set that fits to the noise but moves the record by at most this many
        noise RMS on its own is dropped and the rest refitted (backward elimination); the
        diagnosis passes its own ``min_strength``.
    before_escalation : bool
        The diagnosis tries pairs built from the seeded single fits (no triples; the best
        pair with the global search in its joint space when none fits to the noise) before
        it escalates the single candidates, and escalates them only
        when no such pair explains the record (fits to the noise with every member strong):
        the escalation of every single candidate is the most expensive step of a compound
        record, and a compound record is what it cannot explain (docs/diagnosis.md 8b).
    n_exchange : int
        Exchange: when no set fits to the noise after the escalation, each member of the best
        triple is replaced in turn by this many of the effects the profiled screen ranks best
        beside the other two (not two of the same physics, such as a trigger offset and a
        measurement delay, which fit alike), each such triple with the global search (0: none). A member that
        stands in for a near-equivalent effect (a sensor low-pass for a measurement delay) keeps
        the forward selection from ever fitting the true triple (docs/diagnosis.md 8b, *Exchange*).
    n_exchange_rounds : int
        Most rounds of the exchange: after a round, while no set fits to the noise and the best triple
        is one no round has started from, the exchange starts again from it (sequential replacement
        until the best triple stays the same). One round (the order before 2026-11-25) leaves a triple
        whose global search reached the true basin with one member still wrong as it is.
    first_triples : bool
        With ``before_escalation``, when no first pair explains the record, the triples are fitted
        from the seeded singles and the first pairs (seeded fits only: no global search, no
        exchange) before the singles' escalation, which is skipped when one of them explains the
        record (fits to the noise with every member strong): on a triple record no single and no
        pair can pay off the escalation of the singles, which took a third of a triple's time
        (docs/diagnosis.md 8b, *Cuts for the time budgets*). When none explains, the search after the
        escalation keeps the best of them as the first pairs are kept.
    first_exchange : bool
        With ``before_escalation`` and ``first_triples``, when no first triple explains the record,
        the exchange (``n_exchange``, up to ``n_exchange_rounds`` rounds, each new triple with the
        global search) runs from the best first triple before the singles' escalation, which is
        skipped when it finds a set that explains the record. On the seed-173 triples that went
        through the whole search, the exchange found the answer from a best triple that the first
        triples had already shown (docs/diagnosis.md 8b, *The exchange before the escalation*); the
        escalation of the singles and the second fit of every pair and triple only took it there
        later. When it explains nothing, the search goes on as without it (its best sets are handed
        on as the first triples' are).
    min_escalation_gain, min_set_progress : float or None, float
        With ``before_escalation``, the search of sets of up to three from the escalated singles is
        skipped, and the first search's sets stand, when both the escalation of the singles closed
        less than ``min_escalation_gain`` of every single's excess chi2
        (:func:`engine.diagnosis.staged.escalation_gain`: its sets would start from the basins the
        first search started from) and the best set so far closed less than ``min_set_progress`` of
        the best single's excess (:func:`engine.diagnosis.staged.set_progress`: two or three catalogue
        effects together leave most of the gap that one leaves, so what is missing is not a third
        member). Issue 54: on a record outside the catalogue that search took about 40 % of the
        diagnosis; on a development triple (seed 239 case0139, first pairs at 208 against singles at
        5817) it found the answer though no single improved, hence the second condition.
        ``min_escalation_gain`` None: always search again.
    min_exchange_progress : float or None
        With ``before_escalation``, the exchange from the best first triple (``first_exchange``) runs
        only when the best set so far closed at least this share of the best single's excess chi2
        (:func:`engine.diagnosis.staged.set_progress`); below it, two and three catalogue effects
        together leave almost all of the gap one leaves, and replacing one member of the triple will
        not close it (issue 54). The escalation of the singles runs as before: a single effect its
        seeded fits missed leaves such a record too (seed-229 case0280, a rotor drift at chi2/n 7.0,
        progress 0.12, found by that escalation). 0.25 from development records of seed 223
        (``lab/validation/triple-progress``): out-of-catalogue records at 0.003-0.82 (4 of 6 below
        0.25), the compound records a later stage found right at 0.36-0.98. None: always exchange.
    n_swap : int
        Swap: once the best set fits to the noise, each of its members is replaced by this many of the
        effects the profiled screen ranks best beside the others, each such set fitted from the others'
        fit and refined (no global search); the decision then compares them by BIC like every other
        model, so a better set is named and one as good is reported as a near twin (0: none).
    n_escalate_first : int
        With ``before_escalation``, the single candidates of this many best BICs get the global
        search before the first pairs (best first, stopping at one that fits to the noise): a
        single effect whose seeded fit stayed in the nominal calibration's wrong basin is most
        often among the first few (docs/diagnosis.md 8b, *Early escalation*), and its global
        search costs a few seconds where the pairs it would otherwise wait for cost tens. 0: none.
    escalate_before_reseed : bool
        With ``before_escalation``, the early escalation of the ``n_escalate_first`` best seeded singles
        runs before pass 1b of the single candidates (their refits from the nominal calibration's
        starts, :func:`engine.diagnosis.candidates.reseed_candidates`), which then runs only when
        neither fits to the noise, followed by the early escalation of the best two after it that
        were not escalated yet. Pass 1b refits all sixteen singles: on two seed-223 singles over the
        time budget (case0145, case0044) it took 4.5 and 4.4 s on 2 cores and reached no noise,
        after which the early escalation found the effect in about a second (docs/diagnosis.md 8b,
        *Early escalation before pass 1b*). False: pass 1b first, inside
        :func:`~engine.diagnosis.candidates.fit_candidates`.
    n_escalate_singles : int or None
        With ``before_escalation``, the single candidates of this many best seeded BICs (those escalated
        early included) get the global search once the first pairs explain nothing (None: every
        candidate, the default). On a record that no single effect explains, the escalation of every
        one of the 16 singles took 24-35 % of the time (five development records), but a single effect whose seeded fit
        ranks near last can need it: six cost seed-131 case0077, an absorber discontinuity ranked 15th
        of 16 (docs/diagnosis.md 8b, *Fewer seed refinements*).
    n_seed_fits : int or None
        Of the seeds of a set's joint fit (built from its subsets' fits, up to seven), only this many
        of lowest chi2 on the full record are refined (:attr:`CalibrationSettings.n_seed_fits`;
        None: every seed): two instead of all cut the set search's time by about a third on ten
        development records (docs/diagnosis.md 8b, *Fewer seed refinements*).
    """

    max_size: int = 3
    pool: int = 5
    n_extend: int = 2
    n_base: int = 2
    n_forward: int | None = 6
    escalate: bool = True
    n_escalate: int = 3
    escalate_above: float = 1.1
    max_reduced_chi2: float = 1.05
    n_polish: int = 3
    n_report: int | None = 5
    min_strength: float = 3.0
    before_escalation: bool = True
    n_exchange: int = 2
    n_escalate_first: int = 2
    escalate_before_reseed: bool = True
    n_escalate_singles: int | None = None
    n_seed_fits: int | None = 2
    n_exchange_rounds: int = 3
    n_swap: int = 2
    first_triples: bool = True
    first_exchange: bool = True
    min_escalation_gain: float | None = 0.1
    min_set_progress: float = 0.5
    min_exchange_progress: float | None = 0.25

    def escalation(self, candidates: CandidateSettings, early: bool = False) -> CandidateSettings:
        """The candidate settings of the singles' escalation in the staged order (``before_escalation``).

        Parameters
        ----------
        candidates : CandidateSettings
            The diagnosis's candidate settings (their own ``n_escalate`` caps both escalations too).
        early : bool
            The early escalation (``n_escalate_first`` singles) rather than the one after the first
            pairs (``n_escalate_singles``).

        Returns
        -------
        CandidateSettings
            ``candidates`` with ``n_escalate`` the smaller of its own and this escalation's cap.
        """
        cap = self.n_escalate_first if early else self.n_escalate_singles
        if cap is None:
            return candidates
        own = candidates.n_escalate
        return replace(candidates, n_escalate=cap if own is None else min(cap, own))


def same_physics(a: Effect, b: Effect) -> bool:
    """Whether two effects cannot be told apart in one set (both pure time shifts, or the same field)."""
    if a.name in TIME_SHIFT_EFFECTS and b.name in TIME_SHIFT_EFFECTS:
        return True
    return a.target == b.target and a.field == b.field


def _seeds(
    members: Sequence[Effect], fits: Mapping[tuple[str, ...], CalibrationResult], single_values: Mapping[str, float]
) -> list[dict[str, float]]:
    """Starting points of a set's joint fit from the fits of its subsets."""
    names = tuple(e.name for e in members)
    neutral = {e.name: e.neutral for e in members}
    seeds: list[dict[str, float]] = []
    subs = [s for s in fits if set(s) < set(names)]
    subs.sort(key=lambda s: (-len(s), fits[s].chi2))
    for s in subs[:3]:
        base = dict(fits[s].values)
        for fill in (single_values, neutral):
            seed = dict(base)
            for e in members:
                if e.name not in s:
                    lo, hi = e.bounds
                    seed[e.name] = min(max(fill.get(e.name, e.neutral), lo), hi)
            if seed not in seeds:
                seeds.append(seed)
    return seeds


def _scan_seed(
    record: Record,
    gspace: ModelSpace,
    noise: Mapping[str, float],
    base: Mapping[str, float],
    name: str,
    n_scan: int,
    step: float,
) -> list[dict[str, float]]:
    """The best point of a 1-D scan of one member's value at a smaller set's fit (``base``).

    The member's single fit was made at an operating point distorted by the other members'
    residual, so its value may lie far from the one it takes beside them; a scan over its
    whole range (``n_scan`` values, more for a time shift: :func:`engine.diagnosis.space.scan_grid`;
    one batch at integrator step ``step`` [s]) finds the
    basin cheaply, as for the single candidates (:func:`engine.diagnosis.candidate._seeds`).
    """
    obj = Objective(record, gspace, noise_weights(record, NoiseModel.of(noise)))
    i = gspace.names.index(name)
    u = gspace.unit(base)
    U, c2 = obj.axis_scan(u, [i], scan_grid(gspace, i, u, record, n_scan), record.n_samples, gspace.solver(step))
    j = int(np.argmin(c2[:-1]))  # the scan's own points (the base, last, is a seed already)
    return [gspace.values(U[j])] if np.isfinite(c2[j]) else []


def _fit_set(
    record: Record,
    space: ModelSpace,
    members: Sequence[Effect],
    settings: CalibrationSettings,
    noise: Mapping[str, float],
    seeds: Sequence[Mapping[str, float]],
    polish: bool,
    scan: tuple[Mapping[str, float], str, int] | None = None,
    n_quantum: int = 4000,
    flip_tolerance: bool = True,
) -> CalibrationResult | None:
    """Joint fit of a set, or None when nothing of it can be simulated.

    ``scan``: ``(base, name, n)``, add the seed of an ``n``-value scan of member ``name`` at
    the smaller set's fit ``base`` (:func:`_scan_seed`). A set holding the speed quantum is
    fitted as :func:`_fit_set_with_quantum` says (``n_quantum`` values per dense scan,
    ``flip_tolerance`` as :attr:`engine.diagnosis.candidate.CandidateSettings.flip_tolerance`).
    """
    from engine.diagnosis.calibration import CalibrationError

    quantum = next((e for e in members if is_speed_quantum(e)), None)
    if quantum is not None:
        return _fit_set_with_quantum(record, space, members, quantum, settings, noise, seeds, n_quantum, flip_tolerance)
    gspace = space.with_effects(members)
    if scan is not None:
        base, name, n = scan
        seeds = [*seeds, *_scan_seed(record, gspace, noise, base, name, n, settings.search_step)]
    try:
        return calibrate(record, gspace, settings, noise=noise, seeds=seeds, polish=polish)
    except CalibrationError as exc:
        logger.info("set %s could not be fitted: %s", "+".join(e.name for e in members), exc)
        return None


def _fit_set_with_quantum(
    record: Record,
    space: ModelSpace,
    members: Sequence[Effect],
    quantum: Effect,
    settings: CalibrationSettings,
    noise: Mapping[str, float],
    seeds: Sequence[Mapping[str, float]],
    n_quantum: int,
    flip_tolerance: bool = True,
) -> CalibrationResult | None:
    """Joint fit of a set that holds the speed quantum, or None when it cannot be fitted.

    Least squares cannot move a quantum (its cost is piecewise constant in q), so, as for the
    single candidate (:func:`engine.diagnosis.quantisation.fit_quantisation`), the other members
    and the calibration are fitted first (from the seeds, without the quantum), then refitted on
    the unrounded omega1 with the rounding as extra noise, q found by dense scans in between.
    """
    from engine.diagnosis.calibration import CalibrationError

    if "omega1" not in record.channels:
        return None
    others = [e for e in members if e.name != quantum.name]
    ospace = space.with_effects(others)
    oseeds: list[dict[str, float]] = []
    for seed in seeds:
        s = {k: v for k, v in seed.items() if k != quantum.name}
        if s not in oseeds:
            oseeds.append(s)
    try:
        start = calibrate(record, ospace, settings, noise=noise, seeds=oseeds, polish=False)
        # the start had the global search, if any: the refits around it are local
        local = replace(settings, n_global=0)
        return fit_quantisation(record, start, ospace, quantum, n_quantum, local, local, flip_tolerance)
    except CalibrationError as exc:
        logger.info("set %s could not be fitted: %s", "+".join(e.name for e in members), exc)
        return None


def search_sets(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    singles: Sequence[Candidate],
    candidate_settings: CandidateSettings | None = None,
    settings: SetSettings | None = None,
    previous: Sequence[CandidateSet] = (),
    screens: ScreenCache | None = None,
) -> list[CandidateSet]:
    """Fit sets of two and three effects (see the module notes), best BIC first.

    Parameters
    ----------
    record : Record
        The record's test window.
    nominal : CalibrationResult
        The nominal calibration.
    space : ModelSpace
        The nominal model space.
    library : EffectLibrary
        The candidate effects.
    singles : sequence of Candidate
        The single-effect candidates, fitted (:func:`engine.diagnosis.candidates.fit_candidates`).
    candidate_settings : CandidateSettings, optional
        Search settings of the fits (seeded, escalated; threads).
    settings : SetSettings, optional
        Settings of the set search.
    previous : sequence of CandidateSet
        Sets already fitted from the same single candidates (the diagnosis's first pairs, and
        its best first sets whose members' single fits the escalation did not move): kept as
        they are, not fitted again.
    screens : ScreenCache, optional
        The profiled screens of earlier searches of the same diagnosis (same record, noise and
        settings), filled in by this one: a screen of the same additions beside the same fit is
        not simulated again (the diagnosis's staged searches screen the same best singles).

    Returns
    -------
    list of CandidateSet
        At most ``settings.n_report`` (every set when None), best BIC first, with strengths and gap budgets for
        the polished ones; empty when fewer than two single candidates lower the nominal BIC.
    """
    cs = CandidateSettings() if candidate_settings is None else candidate_settings
    ss = SetSettings() if settings is None else settings
    runner = Runner(cs.jobs(), thread_context=serial_kernel, thread_name_prefix="set")
    with single_threaded_blas(), runner:
        return _search(record, nominal, space, library, singles, cs, ss, runner, previous, screens)


def _search(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    library: EffectLibrary,
    singles: Sequence[Candidate],
    cs: CandidateSettings,
    ss: SetSettings,
    runner: Runner,
    previous: Sequence[CandidateSet] = (),
    screens: ScreenCache | None = None,
) -> list[CandidateSet]:
    t0 = time.perf_counter()
    screens = {} if screens is None else screens
    fitted = sorted((c for c in singles if c.calibration is not None), key=lambda c: c.bic)
    pool = [c for c in fitted if c.bic < nominal.bic][: ss.pool]
    if len(pool) < (1 if ss.n_base > 0 else 2) or ss.max_size < 2:
        return []
    # forward selection reaches every fitted single; without it the pool is all there is
    reach = fitted if ss.n_base > 0 else pool
    fits: dict[tuple[str, ...], CalibrationResult] = {
        (c.effect,): c.calibration for c in reach if c.calibration is not None
    }
    single_values = {c.effect: float(c.value) for c in reach if c.value is not None}
    effects = {c.effect: library[c.effect] for c in reach}
    sets: dict[tuple[str, ...], CandidateSet] = {}
    names = [c.effect for c in reach]
    base = [c.effect for c in pool[: ss.n_base]]
    for prev in previous:
        if prev.calibration is not None and set(prev.effects) <= set(names):
            g = tuple(sorted(prev.effects, key=names.index))
            fits[g], sets[g] = prev.calibration, prev

    def fit_all(
        groups: list[tuple[str, ...]],
        settings: CalibrationSettings,
        polish: bool,
        given: Mapping[tuple[str, ...], Mapping[str, float]] | None = None,
    ) -> None:
        tasks = {}
        seeding = settings if ss.n_seed_fits is None else replace(settings, n_seed_fits=ss.n_seed_fits)
        for g in groups:
            members = [effects[n] for n in g]
            scan = None
            if given is not None and g in given:
                seeds = [dict(given[g])]
            elif polish and g in fits:
                seeds = [dict(fits[g].values)]
            else:
                seeds = _seeds(members, fits, single_values)
                if g in fits:
                    seeds.insert(0, dict(fits[g].values))
                elif cs.n_scan > 1:  # the newest member scanned at the best fit of the others
                    subs = [s for s in itertools.combinations(g, len(g) - 1) if s in fits]
                    if subs:
                        sub = min(subs, key=lambda s: fits[s].chi2)
                        new = next(n for n in g if n not in sub)
                        scan = ({**fits[sub].values, new: effects[new].neutral}, new, cs.n_scan)
            tasks[g] = runner.submit(
                _fit_set,
                record,
                space,
                members,
                seeding,
                nominal.noise,
                seeds,
                polish,
                scan,
                cs.n_quantum,
                cs.flip_tolerance,
            )
        for g, task in tasks.items():
            cal = task.result()
            if cal is None:
                continue
            old = fits.get(g)
            if old is not None:
                cal.n_simulations += old.n_simulations
                cal.seconds += old.seconds
            if old is None or cal.chi2 < old.chi2 or (polish and old.step != cs.seeded.final_step):
                fits[g] = cal
                sets[g] = CandidateSet.from_fit([effects[n] for n in g], cal, nominal)

    def fits_noise(g: tuple[str, ...]) -> bool:
        if g not in fits:
            return False
        refined = fits[g].step == cs.seeded.final_step
        return fits[g].reduced_chi2 <= (ss.max_reduced_chi2 if refined else ss.escalate_above)

    def group(*members: str) -> tuple[str, ...]:
        return tuple(sorted(members, key=names.index))

    def compatible(n: str, g: Sequence[str]) -> bool:
        return n not in g and not any(same_physics(effects[n], effects[m]) for m in g)

    # a speed quantum the record's own lattice of omega1 values shows is tried beside every base model:
    # the profiled screen ranks it by the model's omega1, which a strong effect beside it distorts
    lattice = [
        n
        for n in names
        if is_speed_quantum(effects[n])
        and "omega1" in record.channels
        and record_lattice(np.asarray(record["omega1"]), effects[n].bounds) is not None
    ]

    def screened(g: tuple[str, ...]) -> list[str]:
        """The effects to try beside ``g``'s fit: the ``n_forward`` best of the profiled screen, and a
        speed quantum the record's lattice shows."""
        todo = [n for n in names if compatible(n, g)]
        if ss.n_forward is None or len(todo) <= ss.n_forward:
            return todo
        shown = [n for n in lattice if n in todo]
        return shown + [n for n in _screen(g, [n for n in todo if n not in shown]) if n not in shown]

    def _screen(g: tuple[str, ...], todo: list[str]) -> list[str]:
        if ss.n_forward is None or len(todo) <= ss.n_forward:
            return todo
        key = (g, tuple(todo), tuple(sorted(fits[g].values.items())), ss.n_forward)
        if key not in screens:
            screens[key] = _ranked(g, todo)
        return screens[key]

    def _ranked(g: tuple[str, ...], todo: list[str]) -> list[str]:
        assert ss.n_forward is not None  # _screen returns every addition otherwise
        try:
            order = rank_additions(
                record,
                space,
                fits[g].values,
                [effects[m] for m in g],
                [effects[n] for n in todo],
                nominal.noise,
                max(cs.n_scan, 2),
                cs.seeded.search_step,
                cs.seeded.fd_step,
            )
        except RuntimeError as exc:  # the screen is an economy: without it, every effect is fitted
            logger.warning("screen of the additions to %s failed (%s); fitting all", "+".join(g), exc)
            return todo
        return [name for name, _, _ in order[: ss.n_forward]]

    pairs: list[tuple[str, ...]] = []
    forward = ((m, n) for m in base for n in screened((m,)))  # the best-screened effects beside each base
    for a, b in [*itertools.combinations([c.effect for c in pool], 2), *forward]:
        if compatible(b, (a,)) and group(a, b) not in pairs:
            pairs.append(group(a, b))
    fit_all([p for p in pairs if p not in sets], cs.seeded, polish=False)
    logger.info("set search: %d pairs fitted, %.1f s", len(pairs), time.perf_counter() - t0)

    def best_of(size: int) -> list[tuple[str, ...]]:
        return sorted((g for g in sets if len(g) == size), key=lambda g: sets[g].bic)

    if ss.max_size >= 3 and not any(fits_noise(g) for g in best_of(2)) and best_of(2):
        # the search step's integration error alone can keep a right pair above the threshold:
        # refine the best pair at the final step before paying for the triples
        g = best_of(2)[0]
        if fits[g].step != cs.seeded.final_step:  # not when refined already (a previous search's pair)
            fit_all([g], cs.seeded, polish=True)
    if ss.max_size >= 3 and not any(fits_noise(g) for g in best_of(2)):
        triples: list[tuple[str, ...]] = []
        for i, p in enumerate(best_of(2)[: ss.n_extend]):
            for n in screened(p) if i < ss.n_base else [c.effect for c in pool]:
                if compatible(n, p) and group(*p, n) not in triples:
                    triples.append(group(*p, n))
        fit_all(triples, cs.seeded, polish=False)
        logger.info("set search: %d triples fitted, %.1f s", len(triples), time.perf_counter() - t0)

    def _exchange(triple: tuple[str, ...]) -> None:
        """Sequential replacement: each member of ``triple`` in turn (the one whose removal costs least
        first) replaced by the ``n_exchange`` best-screened effects beside the other two, with the
        global search; stops at a triple that fits to the noise."""
        subs = [tuple(n for n in triple if n != m) for m in triple]
        # the pairs refitted from the triple's fit: its basin is theirs too
        fit_all(subs, cs.seeded, polish=True, given={sub: fits[triple].values for sub in subs})
        subs = sorted((s for s in subs if s in fits), key=lambda s: fits[s].chi2)
        for sub in subs:
            (gone,) = set(triple) - set(sub)
            added: list[str] = []
            for n in screened(sub):
                if n == gone or (group(*sub, n) in sets and sets[group(*sub, n)].searched):
                    continue
                # twins (a trigger offset and a measurement delay) fit alike: the next addition instead
                if not any(same_physics(effects[n], effects[m]) for m in added):
                    added.append(n)
                if len(added) == ss.n_exchange:
                    break
            todo = [group(*sub, n) for n in added]
            if not todo:
                continue
            logger.info("exchange: %s for %s", ", ".join("+".join(g) for g in todo), "+".join(triple))
            fit_all(todo, cs.escalated, polish=True)
            for g in todo:
                if g in sets:
                    sets[g].searched = True
            if any(fits_noise(g) for g in todo):
                return

    if ss.escalate and sets and not any(fits_noise(g) for g in sets):
        best = [g for g in best_of(2)[: ss.n_escalate] + best_of(3)[:1] if not sets[g].searched]
        if best:
            logger.info("no set fits to the noise; global search for %s", ", ".join("+".join(g) for g in best))
            # refined at the final step, so that it is compared like for like with refined fits
            fit_all(best, cs.escalated, polish=True)
            for g in best:
                sets[g].searched = True

    if ss.n_exchange > 0 and best_of(3):
        top = best_of(3)[0]
        if fits[top].step != cs.seeded.final_step and any(fits_noise(g) for g in sets):
            # a triple just under the search step's threshold may not fit to the noise once refined
            fit_all([top], cs.seeded, polish=True)
        exchanged: list[tuple[str, ...]] = []
        # sequential replacement repeated from the best triple while it is a new one: a round's
        # global searches can reach the true basin with one member still wrong (a resilient stiffness
        # for a sensor offset), and only a round from that triple replaces it
        while len(exchanged) < ss.n_exchange_rounds and not any(fits_noise(g) for g in sets):
            top = best_of(3)[0]
            if top in exchanged:
                break
            if exchanged:
                logger.info("exchange: round %d from %s", len(exchanged) + 1, "+".join(top))
            exchanged.append(top)
            _exchange(top)

    def finish(groups: list[tuple[str, ...]]) -> None:
        """Refine at the final step, then the strengths and the gap budget."""
        fit_all([g for g in groups if fits[g].step != cs.seeded.final_step], cs.seeded, polish=True)
        for g in groups:
            st, cal = sets[g], fits[g]
            members = [effects[n] for n in g]
            st.strengths = member_strengths(record, cal, space, members, nominal.sigma)  # the floored noise of the fit
            st.shares, st.left = gap_budget(record, cal, space, members, nominal)

    def _swap(best: tuple[str, ...] | None) -> list[tuple[str, ...]]:
        """Each member of the best set, once it explains the record, replaced by the ``n_swap`` effects
        the profiled screen ranks best beside the others, fitted from the others' fit (seeded, refined at
        the final step): the search stops at the first set that fits to the noise, and a member may be
        a near twin of an effect it never tried in its place (a rotor drift of a supply change)."""
        if best is None or len(best) < 2 or fits[best].step != cs.seeded.final_step or not fits_noise(best):
            return []
        todo: list[tuple[str, ...]] = []
        for m in best:
            sub = tuple(n for n in best if n != m)
            if sub not in fits:
                continue
            added: list[str] = []
            for n in screened(sub):
                g = group(*sub, n)
                done = g in fits and fits[g].step == cs.seeded.final_step  # already compared like for like
                if n == m or done or any(same_physics(effects[n], effects[a]) for a in added):
                    continue
                added.append(n)
                if len(added) == ss.n_swap:
                    break
            todo += [group(*sub, n) for n in added if group(*sub, n) not in todo]
        if not todo:
            return []
        logger.info("swap: %s for %s, from its fit", ", ".join("+".join(g) for g in todo), "+".join(best))
        fit_all(todo, cs.seeded, polish=True)
        swapped = [g for g in todo if g in fits]
        finish(swapped)
        now = min(sets, key=lambda g: sets[g].bic)
        logger.info(
            "swap: best set %s (dBIC %.1f against %s)", "+".join(now), sets[now].bic - sets[best].bic, "+".join(best)
        )
        return swapped

    def eliminate(groups: list[tuple[str, ...]], weak_only: bool = False) -> None:
        """Backward elimination: each set that fits to the noise is refitted without its weak members (all
        at once) or, when every member is strong and not ``weak_only``, without each member in turn, from
        its own fit (its basin is that of the smaller set too); the decision then prefers the smaller set
        when it pays."""
        for g in groups:
            st = sets[g]
            if fits[g].reduced_chi2 > ss.escalate_above:
                continue
            weak = [n for n, v in st.strengths.items() if not (math.isfinite(v) and v > ss.min_strength)]
            if weak_only and not weak:
                continue
            subs = [tuple(n for n in g if n not in weak)] if weak else [tuple(n for n in g if n != m) for m in g]
            todo = [
                sub
                for sub in subs
                if len(sub) >= 2
                and not (
                    sub in fits and fits[sub].step == cs.seeded.final_step and fits[sub].chi2 <= fits[g].chi2 * 1.01
                )
            ]
            if not todo:
                continue
            logger.info(
                "set %s fits to the noise; refitting %s from its fit", st.name, ", ".join("+".join(t) for t in todo)
            )
            fit_all(todo, cs.seeded, polish=True, given={sub: fits[g].values for sub in todo})
            finish(todo)

    finish(sorted(sets, key=lambda g: sets[g].bic)[: ss.n_polish])
    eliminate(sorted(sets, key=lambda g: sets[g].bic)[: ss.n_polish])
    if ss.n_swap > 0:
        # a swapped set can fit to the noise with a member at its neutral value (a rotor drift of 0.9999
        # beside the true stator drift): its strong members are then refitted without it, as above, or
        # the decision, which names only the best set of each size, sees a weak member and no pair
        # (seed-191 case0082, docs/diagnosis.md 8b, *Elimination after the swap*)
        eliminate(_swap(sorted(sets, key=lambda g: sets[g].bic)[0] if sets else None), weak_only=True)
    ranked = sorted(sets, key=lambda g: sets[g].bic)[: ss.n_report]
    out = [sets[g] for g in ranked]
    for s in out:
        if not s.strengths:
            s.note = s.note or "not refined at the final step (not among the best sets)"
    logger.info("set search done in %.1f s (%d sets fitted)", time.perf_counter() - t0, len(sets))
    return out
