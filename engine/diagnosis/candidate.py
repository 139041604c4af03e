"""One candidate effect: its joint fit with the calibration, and the evidence for it.

For an effect of an :class:`~engine.simulation.EffectLibrary`, the
calibration is refitted with the effect's scalar value as one more bounded
parameter (:func:`engine.diagnosis.calibration.calibrate` on
``space.with_effect(effect)``, see :func:`fit_candidate`), seeded by the
nominal calibration with the effect at its neutral value and at the best value
of a one-dimensional scan of the effect; the speed quantum, which least
squares cannot fit, is fitted by dense scans instead
(:mod:`engine.diagnosis.quantisation`). An effect that is degenerate with a
calibrated parameter, or invisible in the record's channels, is not fitted.

Evidence: the Bayesian information criterion of a Gaussian likelihood with the
estimated noise, ``BIC = chi2 + k ln(n)`` (k fitted parameters, n residuals),
so an effect must lower chi2 by more than ln(n) (about 9 for five channels)
to beat the nominal model. Posterior weights ``exp(-BIC / 2)``, normalised
over the candidates and the nominal model, give each candidate's probability
(:func:`posterior_weights`). :func:`effect_strength` says how far the fitted
effect moves the record, in noise standard deviations.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numba
import numpy as np

from engine.constants import CHANNELS
from engine.diagnosis.calibration import CalibrationError, CalibrationResult, CalibrationSettings, calibrate
from engine.diagnosis.gap import Gap, gap_of, shrinkage_ratio
from engine.diagnosis.noise import NOISE_FLOOR_REL
from engine.diagnosis.objective import Objective
from engine.diagnosis.quantisation import fit_quantisation, is_speed_quantum
from engine.diagnosis.space import TIME_SHIFT_EFFECTS, ModelSpace, scan_grid
from engine.records import Record
from engine.simulation import Effect, SolverSettings, run_cases

__all__ = [
    "ESCALATED_FITS",
    "SEEDED_FITS",
    "Candidate",
    "CandidateSettings",
    "effect_strength",
    "fit_candidate",
    "posterior_weights",
    "strength_noise",
]


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
        :func:`engine.diagnosis.gap.shrinkage_ratio`).
    strength : float or None
        How far the fitted effect moves the record: the largest channel RMS of
        (fit with the effect - the same calibration without it) in noise
        standard deviations (see :func:`effect_strength`); computed for the
        polished front runners only.
    note : str
        Why an effect was not fitted (e.g. degenerate with a calibrated parameter).
    locus : str or None
        Where in the plant the effect acts (:data:`engine.simulation.LOCI`).
    escalated : bool
        Whether the effect's joint space has had the global search (the escalation), so that
        a later escalation does not search it again.
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
    locus: str | None = None
    escalated: bool = False

    @classmethod
    def from_fit(cls, effect: Effect, cal: CalibrationResult, nominal: CalibrationResult) -> Candidate:
        """The candidate of a joint fit ``cal`` of ``effect``, compared with the ``nominal`` calibration."""
        return cls(
            effect=effect.name,
            value=cal.values[effect.name],
            uncertainty=cal.uncertainties.get(effect.name),
            unit=effect.unit,
            calibration=cal,
            bic=cal.bic,
            gap=gap_of(cal),
            shrinkage=shrinkage_ratio(nominal, cal),
            locus=effect.locus,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the calibration without arrays)."""
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
            "locus": self.locus,
            "calibration": self.calibration.to_dict() if self.calibration else None,
            "note": self.note,
        }


#: Search settings of the seeded fits (no global search; seeds refined on the full record). Their
#: difference step is 1e-5 of the box, a tenth of the nominal calibration's: on the whole record a
#: true effect's valley can be narrower than 1e-4 in K, and a fit with the coarser step creeps along
#: it (docs/diagnosis.md 8b, *The seeded fits' difference step*; 2026-11-27).
SEEDED_FITS = CalibrationSettings(n_global=0, max_nfev=30, fd_step=1e-5)
#: Search settings of the escalated fits (global search, 16 of its points screened on the first
#: horizon, continuation of the best 2 over 10-200 ms; the screening was added for the plausible
#: box of issue 10, docs/diagnosis.md section 8c).
ESCALATED_FITS = CalibrationSettings(n_global=256, n_starts=2, n_screen=16, horizons_ms=(10.0, 20.0, 40.0, 80.0, 200.0))


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
    reseed_from_starts : bool
        When no seeded fit reaches the noise, refit every candidate from the nominal
        calibration's global starts (pass 1b, :func:`refit_from_starts`) before any escalation.
    reseed_seed_fits : int or None
        Seeds of a pass-1b refit refined (:attr:`CalibrationSettings.n_seed_fits`): its up to
        five seeds (each start with the effect at its scanned best, and the seeded fit) are
        simulated once on the full record and only this many of lowest chi2 are refined
        (None: every seed).
    seed_fits : int or None
        Of the seeds of a seeded fit (pass 1: the nominal calibration with the effect at its
        neutral value and at the best value of the scan, and any extra seed), only this many of
        lowest chi2 on the full record are refined (:attr:`CalibrationSettings.n_seed_fits`;
        None: every seed, the default). One was tried and not kept: it made the seeded fits of
        the seed-151 singles about 10 % faster, but a single effect whose refined neutral seed
        reaches the noise went on to the set search (docs/diagnosis.md 8b, *Cuts for the time budgets*).
    reseed_stop_at_noise : bool
        Pass 1b collects its refits in ranking order (best seeded BIC first) and stops at the
        first that fits to the noise (``escalate_above``), as the escalation does: the rest keep
        their seeded fits (cancelled even when running). False refits every candidate.
    flip_tolerance : bool
        The chi-square of a fit holding the speed quantum, on a record that shows a lattice,
        counts a sample across a cell edge that the fit cannot place at the record's level
        (:mod:`engine.diagnosis.cell_edges`; single candidates and sets alike). False: the plain
        rounding, as before 2026-11-27.
    """

    seeded: CalibrationSettings = SEEDED_FITS
    escalated: CalibrationSettings = ESCALATED_FITS
    n_scan: int = 9
    n_escalate: int | None = None
    escalate_above: float = 1.1
    n_polish: int = 3
    polish_within: float = 0.1
    max_polish: int = 6
    n_quantum: int = 4000
    n_jobs: int | None = None
    reseed_from_starts: bool = True
    reseed_seed_fits: int | None = 2
    reseed_stop_at_noise: bool = True
    seed_fits: int | None = None
    flip_tolerance: bool = True

    def jobs(self) -> int:
        """Resolved ``n_jobs`` (at least 1)."""
        if self.n_jobs is not None:
            return max(1, int(self.n_jobs))
        return max(1, int(numba.get_num_threads()))


def _identifiable(effect: Effect, space: ModelSpace, record: Record) -> str:
    """Empty string, or why the effect cannot be told apart from the calibration."""
    if effect.target == "plant" and effect.field in space.names:
        return (
            f"{effect.field} is calibrated (not fixed by the record's conditions), so this effect is degenerate with it"
        )
    if space.aligned and effect.name in TIME_SHIFT_EFFECTS:
        return (
            "the record's event was located from the data, which absorbs any shift of every channel in time "
            "(give event_index to diagnose a trigger offset or a measurement delay)"
        )
    if is_speed_quantum(effect) and "omega1" not in record.channels:
        return "the record has no omega1 channel, which is the only channel this effect changes"
    return ""


def _effect_scan(
    obj: Objective, values: Mapping[str, float], n_scan: int, step: SolverSettings
) -> tuple[np.ndarray, np.ndarray]:
    """The one-dimensional scan of the effect (the last parameter of ``obj.space``) at ``values``.

    The base point is ``values`` with the effect at its neutral value (nearest bound when outside
    the range); returns the scanned unit-box points and their chi2 on the full record, the base
    point last (:meth:`~engine.diagnosis.objective.Objective.axis_scan`).
    """
    space = obj.space
    assert space.effect is not None  # the callers' spaces have an effect
    base = space.unit(values)
    base[-1] = space.params[-1].unit_coord(space.effect.neutral)
    grid = scan_grid(space, space.dim - 1, base, obj.record, n_scan)
    return obj.axis_scan(base, [space.dim - 1], grid, obj.record.n_samples, step)


def _seeds(
    record: Record, nominal: CalibrationResult, space: ModelSpace, settings: CandidateSettings, search_step: float
) -> list[dict[str, float]]:
    """Seeds of a joint fit in ``space`` (which has an effect).

    The nominal calibration with the effect at its neutral value (nearest bound
    when the neutral value is outside the range), and with the best value of a
    1-D scan of the effect (``settings.n_scan`` values at ``search_step`` [s]; more for a time
    shift, :func:`engine.diagnosis.space.scan_grid`).
    """
    if space.effect is None:
        raise ValueError("the seeds of a joint fit need a space with an effect")
    obj = Objective(record, space, nominal.sigma)
    U, c2 = _effect_scan(obj, nominal.values, settings.n_scan, space.solver(search_step))
    seeds = [space.values(U[-1])]
    i = int(np.argmin(c2[:-1]))
    if np.isfinite(c2[i]) and abs(U[i, -1] - U[-1, -1]) > 1e-9:
        seeds.append(space.values(U[i]))
    return seeds


def refit_from_starts(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    effect: Effect,
    settings: CandidateSettings = CandidateSettings(),
    previous: CalibrationResult | None = None,
) -> Candidate:
    """Refit a candidate from the nominal calibration's global starts (and from its earlier fit).

    A strong effect missing from the nominal model can drag the nominal calibration's
    continuation out of the true basin: its early-window starts were near the truth, its
    fit is not (seed-137 case0004: a Coulomb friction of 0.09 pu, the starts at K 14.6 mm, the
    nominal fit at 3.5 mm). Seeded from that fit, the candidate's own fit stays in the wrong
    basin. Here each start, with the effect at the best value of a one-dimensional scan
    (``settings.n_scan`` values at the search step; the neutral value included), seeds a local
    fit on the full record, next to the earlier fit when given; the best is kept (search step, no
    polish). Pass 1b of :func:`engine.diagnosis.candidates.fit_candidates` gives the seeded fit:
    without it one seed-137 triple of nine compound development records lost its answer (a
    marginal record, docs/diagnosis.md 8b, *Re-seeded fits*).

    Parameters
    ----------
    record, nominal, space, effect, settings
        As :func:`fit_candidate`; ``nominal.starts`` must not be empty.
    previous : CalibrationResult, optional
        The candidate's earlier fit, one more seed.

    Returns
    -------
    Candidate

    Raises
    ------
    ValueError
        The nominal calibration has no starts (it ran without a global search).
    CalibrationError
        No start can be simulated with the effect.
    """
    if not nominal.starts:
        raise ValueError("the nominal calibration has no global starts to refit from (it had no global search)")
    espace = space.with_effect(effect)
    obj = Objective(record, espace, nominal.sigma)
    step = espace.solver(settings.seeded.search_step)
    seeds: list[Mapping[str, float]] = []
    for start in nominal.starts:
        U, c2 = _effect_scan(obj, start, settings.n_scan, step)
        if np.isfinite(c2).any():
            seeds.append(espace.values(U[int(np.argmin(c2))]))
    if not seeds:
        raise CalibrationError(f"no start of the nominal calibration can be simulated with {effect.name}")
    if previous is not None:
        seeds.append(previous.values)
    fits = replace(settings.seeded, n_seed_fits=settings.reseed_seed_fits)
    cal = calibrate(record, espace, fits, noise=nominal.noise, seeds=seeds, polish=False)
    return Candidate.from_fit(effect, cal, nominal)


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
        Refine at the final integrator step (see :func:`~engine.diagnosis.calibration.calibrate`).
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
        return Candidate(effect.name, None, None, effect.unit, None, math.inf, note=why, locus=effect.locus)
    if is_speed_quantum(effect):
        first = settings.escalated if global_search else settings.seeded
        cal = fit_quantisation(
            record, nominal, space, effect, settings.n_quantum, first, settings.seeded, settings.flip_tolerance
        )
        return Candidate.from_fit(effect, cal, nominal)
    espace = space.with_effect(effect)
    cs = settings.escalated if global_search else replace(settings.seeded, n_seed_fits=settings.seed_fits)
    seeds = _seeds(record, nominal, espace, settings, cs.search_step) + list(extra_seeds)
    cal = calibrate(record, espace, cs, noise=nominal.noise, seeds=seeds, polish=polish)
    return Candidate.from_fit(effect, cal, nominal)


def strength_noise(record: Record, cal: CalibrationResult, noise: Mapping[str, float]) -> dict[str, float]:
    """Per channel, the noise level [channel unit] a fit's strengths are measured in.

    The estimated noise standard deviation, or the RMS of the residual the fit leaves where
    that is smaller, floored at ``NOISE_FLOOR_REL`` of the channel's RMS as the calibration's
    noise is (:func:`engine.diagnosis.noise.noise_weights`). A fit that reaches the noise
    leaves the noise itself; the estimate from the record alone can be larger, for example
    where it counts the rounding of a quantised speed as noise (seed-151 development records:
    a speed quantum of true strength 3.3 measured at 2.8 against the estimate, 3.2 against the
    fit's residual).

    Parameters
    ----------
    record : Record
        The record's test window (the grid of ``cal``).
    cal : CalibrationResult
        The fit, with its simulation.
    noise : mapping of str to float
        Estimated noise standard deviation per channel [channel unit].

    Returns
    -------
    dict of str to float
        Per recorded channel, the smaller of the two [channel unit].
    """
    out = {name: float(noise[name]) for name in record.channels}
    sim = cal.simulation
    if sim is None or sim.shape[-1] != record.n_samples:
        return out
    for name in record.channels:
        x = np.asarray(record[name], dtype=float)
        left = float(np.sqrt(np.mean((x - sim[CHANNELS.index(name)]) ** 2)))
        floor = max(NOISE_FLOOR_REL * float(np.sqrt(np.mean(x * x))), 1e-12)
        out[name] = min(out[name], max(left, floor))
    return out


def effect_strength(cand: Candidate, space: ModelSpace, record: Record, noise: Mapping[str, float]) -> float:
    """Largest channel RMS change the fitted effect causes, in noise standard deviations
    (the smaller of the estimate and the fit's residual RMS, :func:`strength_noise`).

    The fitted calibration is simulated once more without the effect and
    compared with the fit (noiseless, record channels only). This is the
    quantity of the blind validation's strength rule, evaluated at the fitted
    operating point instead of the (unknown) true one.

    Parameters
    ----------
    cand : Candidate
        A fitted candidate.
    space : ModelSpace
        The nominal model space (its free parameters are taken from the fit).
    record : Record
        The record (its channels are compared).
    noise : mapping of str to float
        Noise standard deviation per channel, in the channel's unit.

    Returns
    -------
    float
        The largest RMS change [noise standard deviations]; NaN when the
        candidate was not fitted or cannot be simulated without the effect.
    """
    cal = cand.calibration
    if cal is None or cal.simulation is None:
        return math.nan
    plain = {k: v for k, v in cal.values.items() if k in space.names}
    ch, _, status = run_cases([space.case(space.unit(plain))], cal.solver(), record.grid)
    if status[0] != 0:
        return math.nan
    sigma = strength_noise(record, cal, noise)
    out = 0.0
    for name in record.channels:
        j = CHANNELS.index(name)
        rms = float(np.sqrt(np.mean((cal.simulation[j] - ch[0, j]) ** 2)))
        out = max(out, rms / max(sigma[name], 1e-300))
    return out


def posterior_weights(bics: Mapping[str, float]) -> dict[str, float]:
    """Normalised ``exp(-BIC / 2)`` weights (infinite BIC gets weight 0).

    Parameters
    ----------
    bics : mapping of str to float
        BIC per model.

    Returns
    -------
    dict of str to float
        Weight per model, summing to 1 (all 0 when no BIC is finite).
    """
    finite = {k: v for k, v in bics.items() if math.isfinite(v)}
    if not finite:
        return {k: 0.0 for k in bics}
    b0 = min(finite.values())
    w = {k: math.exp(-0.5 * (v - b0)) if math.isfinite(v) else 0.0 for k, v in bics.items()}
    s = sum(w.values())
    return {k: v / s for k, v in w.items()}
