"""The gap diagnosis on any plant of the interface (:mod:`engine.plants.base`): calibrate, where, which, how far.

This module reads a plant only through its interface (channels, calibrated parameters, catalogue,
``measured``, ``simulate``, ``scored``); it is where the diagnosis of real records starts (the
EMPS benchmark). The backlash drive's own diagnosis (:func:`engine.diagnosis.diagnose`) predates the
interface and still works on its cases directly.

Method
------
- **Objective.** The residual of channel c is ``(y_sim,c - y_c) / ||y_c||`` over the plant's scored
  samples, stacked over the channels: its squared norm is the sum over channels of the squared
  relative errors ``(e_c / 100)^2`` of the authors' eq. 11, so every channel weighs by its own
  scale and the fit minimises the very figure the report tables.
- **Calibration** (:func:`calibrate`): bounded least squares (scipy's trf) of the calibrated
  parameters, on a unit box, from their nominal values.
- **Where** (:func:`localise`): the calibrated model's residual energy of every channel split into
  frequency bands (zero-phase Butterworth band-passes) and time windows of :data:`WINDOW`; the
  cells holding the most energy are reported with their share. Where the plant knows its input
  events (a pulse edge), :func:`event_shares` says how much of each channel's residual lies just
  after them, beside the share of samples that lie there.
- **Which** (:func:`rank_effects`): every catalogue effect is fitted with the calibrated parameters
  (refitted with it, or held when a calibration from another record is being scored): a scan of the
  effect over its range first (the best of :data:`N_SCAN` values, beside the calibration held and,
  when it is refitted, beside the nominal values too), then least squares from there. An effect is *named* when it removes at least :data:`MIN_SHARE` of the
  residual's squared norm; a greedy forward set (up to three effects, each addition fitted jointly)
  keeps an addition that removes a further :data:`MIN_SHARE` of the calibrated model's residual.
  Before that, effects the calibrated parameters absorb locally (:func:`absorbed_effects`) are set
  aside when the calibration is refitted: the refit would cancel them, so they could never be
  named, and the answer lists them as ``absorbed_by_calibration``.
- **How far**: the relative error per channel before and after.

Uncertainties are the linearised least-squares ones, scaled by the residual's own RMS and by its
integrated autocorrelation time tau (:func:`correlation_time`): n samples of a residual correlated
over tau samples carry about n / tau independent ones. On white noise tau is 1 and nothing changes;
on a real record the residual is model error, correlated over many samples, and the inflation is
large (DATA_EMPS: see ``docs/real-data.md``). This assumes a stationary residual and columns of the
Jacobian no rougher than it (a scalar inflation, not a full sandwich estimate): a better figure than
the plain least-squares one, still not an interval to bet on; the cross-record check (calibrate on
one record, score the other) is the better measure of what holds.
"""

from __future__ import annotations

import functools
import logging
import math
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np

from engine.constants import Z95
from engine.diagnosis.plant_locus import (
    EXPLAINED_SHARE,
    TIE_BIC,
    PlantLocusReport,
    estimate_plant_locus,
)
from engine.diagnosis.plant_plausibility import check_channels, check_fit, check_interval
from engine.diagnosis.settings import DiagnosisSettings
from engine.parallel import MapLike, thread_map
from engine.plants.base import CalibratedParameter, Plant, difference_step, free_parameters
from engine.plants.noise import NoiseLevel, integrated_time

__all__ = [
    "BANDS",
    "MIN_SHARE",
    "N_SCAN",
    "Cell",
    "EffectFit",
    "Fit",
    "NoiseGate",
    "PlantGapReport",
    "PlantObjective",
    "absorbed_effects",
    "calibrate",
    "change_over_noise",
    "correlation_time",
    "diagnose_plant",
    "effect_strength",
    "event_shares",
    "fit",
    "gap_budget",
    "integrated_time",
    "localise",
    "noise_gate",
    "noise_limits",
    "open_world",
    "rank_effects",
    "relative_errors",
    "solve_unit_box",
]

logger = logging.getLogger(__name__)

#: Share of the residual's squared norm an effect must remove to be named (and an addition to a set).
MIN_SHARE: float = 0.05
#: Values of an effect's scalar scanned across its range before its least-squares fit (a lightly
#: damped mode's basin is narrow: with 9 values a 65 Hz flexibility fell between two of them).
N_SCAN: int = 25
#: Largest share of an effect's residual change left outside the calibration's span for the effect
#: to count as absorbed by the calibration (:func:`absorbed_effects`). Measured on the first 12 s of
#: DATA_EMPS: coulomb_asymmetry and offset_change 0.001, drive_gain 0.13 (absorbed exactly in
#: theory; the finite differences of a chattering simulation leave the rest), viscous_asymmetry
#: 0.45, every other effect above 0.9.
ABSORBED_RATIO: float = 0.25
#: Frequency bands of the localisation [Hz] (the last ends at the measurement chain's 100 Hz).
BANDS: tuple[tuple[float, float], ...] = ((0.0, 2.0), (2.0, 10.0), (10.0, 30.0), (30.0, 100.0))
#: Length of a time window of the localisation [s].
WINDOW: float = 0.1
#: Cells of the localisation reported.
TOP_CELLS: int = 8
#: Largest number of effects in a set.
MAX_SET: int = 3
#: Function evaluations per least-squares fit (the step of its finite differences is the plant's
#: own :attr:`~engine.plants.base.Plant.diff_step`: how rough its simulation is depends on the plant).
MAX_NFEV: int = 60
#: z of the chi-square's sampling scatter a fit "to the noise" may reach on a channel of few
#: independent samples: the thresholds are the backlash drive's (:class:`DiagnosisSettings`:
#: ``max_reduced_chi2``, ``max_channel_chi2``) or 1 + Z sqrt(2 / n_eff), whichever is larger.
CHI2_SCATTER_Z: float = 3.0
#: The catalogue effect that is a play: its fitted value is the width an answer shows (the BRFD's).
WIDTH_EFFECT: str = "backlash"


@dataclass(frozen=True)
class Fit:
    """A fitted model: values, cost and linearised uncertainties.

    Attributes
    ----------
    values : dict of str to float
        Every fitted name (calibrated parameters and effect scalars) and every held one.
    free : tuple of str
        The names that were fitted.
    cost : float
        Squared norm of the residual (sum over channels of squared relative errors / 100^2).
    uncertainty : dict of str to float
        One standard deviation per fitted name, in its unit (lower bound, module docstring); inf
        where the record does not constrain it (the cost is flat along it, e.g. a command limit
        above every command of the record).
    n_eval : int
        Simulations spent.
    """

    values: dict[str, float]
    free: tuple[str, ...]
    cost: float
    uncertainty: dict[str, float]
    n_eval: int


@dataclass(frozen=True)
class EffectFit:
    """One effect (or set) fitted with the calibration.

    Attributes
    ----------
    effects : tuple of str
        The effects' names.
    fit : Fit
        The joint fit.
    share : float
        Share of the calibrated model's residual squared norm it removes, in [0, 1].
    loci : tuple of str
        The effects' loci.
    path : tuple of float
        For a set built by forward selection, its share after each addition (in the order of
        ``effects``): the gap budget.
    """

    effects: tuple[str, ...]
    fit: Fit
    share: float
    loci: tuple[str, ...]
    path: tuple[float, ...] = ()


@dataclass(frozen=True)
class Cell:
    """Residual energy of one channel in one band and one time window.

    Attributes
    ----------
    channel : str
    band : tuple of float
        [Hz].
    window : tuple of float
        [s], on the record's time axis.
    share : float
        Share of the total residual energy (all channels, weighted as the objective weighs them).
    """

    channel: str
    band: tuple[float, float]
    window: tuple[float, float]
    share: float


@dataclass(frozen=True)
class NoiseGate:
    """A fit's residual against the plant's noise (:meth:`~engine.plants.base.Plant.noise`).

    Attributes
    ----------
    levels : dict of str to NoiseLevel
        Each channel's noise.
    before, after : dict of str to float
        chi2_c / n_c of each channel (mean squared residual over the noise's variance) for the
        calibrated model and for the model the answer ends with (the calibrated one unless the gate
        says ``gap`` and a set is named).
    limits : dict of str to float
        The largest chi2_c / n_c of a fit to the noise, per channel, and ``"total"`` for their mean.
    strength : float or None
        How far the best set moves the record: the largest channel RMS of its change [noise RMS]
        (None when no set removes :data:`MIN_SHARE`); when the gate sets it aside, what it says why.
    status : str
        What the gate decides: ``no_gap``, ``weak_gap``, or ``gap`` (the named model decides).
    reason : str
        Why, in words.
    """

    levels: dict[str, NoiseLevel]
    before: dict[str, float]
    after: dict[str, float]
    limits: dict[str, float]
    strength: float | None
    status: str
    reason: str

    @staticmethod
    def total(chi2: Mapping[str, float]) -> float:
        """The channels' mean chi2/n."""
        return sum(chi2.values()) / max(len(chi2), 1)

    @staticmethod
    def fits(chi2: Mapping[str, float], limits: Mapping[str, float]) -> bool:
        """Whether per-channel chi2/n (``chi2``) fit to the noise: each channel and their mean within ``limits``."""
        return NoiseGate.total(chi2) <= limits["total"] and all(v <= limits[c] for c, v in chi2.items())

    def gap(self, named: bool) -> dict[str, dict[str, float]]:
        """The residual's RMS over the noise's [-] (the root of the channels' mean chi2/n): before, and
        after the named effects when the answer names any (the shape of the backlash drive's ``gap``,
        :class:`engine.diagnosis.gap.Gap`)."""
        pairs = (("before", self.before), ("after", self.after)) if named else (("before", self.before),)
        return {k: {"rms_over_noise": math.sqrt(NoiseGate.total(v))} for k, v in pairs}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "status": self.status,
            "reason": self.reason,
            "levels": {
                c: {"sigma": v.sigma, "correlation_samples": v.tau, "source": v.source} for c, v in self.levels.items()
            },
            "reduced_chi2": {"before": self.before, "after": self.after},
            "limits": self.limits,
            "strength_noise_rms": self.strength,
        }


@dataclass(frozen=True)
class PlantGapReport:
    """Where, which and how far, for one record of one plant.

    Attributes
    ----------
    plant : str
    record : str
    calibration : Fit
        The calibrated model the gap is measured from.
    relative_error : dict
        ``{"before": {channel: %}, "after": {channel: %}}``: the calibrated model, and the model
        with the named effects.
    where : list of Cell
        The largest residual cells of the calibrated model.
    where_summary : dict
        ``{"channel": {name: share}, "band_hz": {"lo-hi": share}}``: the residual energy summed
        over the other two axes of the localisation.
    event_share : dict
        ``{"before": {channel: share}, "after": {...}, "samples": {"share": s}}``: the share of each
        channel's residual energy near the plant's input events (:meth:`~engine.plants.base.Plant.near_events`), before and
        after, beside the share of samples there (empty dicts without events).
    ranking : list of EffectFit
        Every single effect, best first.
    named : EffectFit or None
        The named set (None when no effect removes :data:`MIN_SHARE`).
    calibration_refitted : bool
        Whether the calibrated parameters were refitted with each effect.
    budget : dict of str to float
        The named set's gap budget (:func:`gap_budget`).
    absorbed : dict of str to float
        Effects the refitted calibration absorbs on this record (:func:`absorbed_effects`), not
        fitted: no record can name them beside a refitted calibration.
    gate : NoiseGate or None
        The residuals against the plant's noise (None: not computed, the share rule alone decides).
    locus : PlantLocusReport or None
        Where the gap the answer's model leaves lies and what the missing term looks like
        (:mod:`engine.diagnosis.plant_locus`), for a gap the catalogue does not take to the noise
        and for a weak gap (the locus of the weak misfit the calibrated model leaves); None when not
        estimated (no gap, a fit to the noise, a plant with no locus signals).
    """

    plant: str
    record: str
    calibration: Fit
    relative_error: dict[str, dict[str, float]]
    where: list[Cell]
    where_summary: dict[str, dict[str, float]]
    event_share: dict[str, dict[str, float]]
    ranking: list[EffectFit]
    named: EffectFit | None
    calibration_refitted: bool
    budget: dict[str, float] = field(default_factory=dict)
    absorbed: dict[str, float] = field(default_factory=dict)
    gate: NoiseGate | None = None
    locus: PlantLocusReport | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def status(self) -> str:
        """``no_gap`` or ``weak_gap`` (the noise gate's, nothing named), ``unexplained`` (no effect
        removes :data:`MIN_SHARE`), ``explained`` (the named set removes at least
        :data:`EXPLAINED_SHARE` of the gap, or its fit reaches the noise) or ``partly_explained``."""
        if self.named is None:
            return self.gate.status if self.gate is not None and self.gate.status != "gap" else "unexplained"
        reaches = self.gate is not None and NoiseGate.fits(self.gate.after, self.gate.limits)
        return "explained" if self.named.share >= EXPLAINED_SHARE or reaches else "partly_explained"

    def width(self, plant: Plant, effect: str = WIDTH_EFFECT) -> dict[str, Any]:
        """The backlash width of the answer (the shape of :class:`engine.diagnosis.width.AnswerWidth`).

        From the model the answer ends with: the named set's fit when it names the play ``effect``;
        otherwise not identifiable, with the reason (the plant's catalogue has no play, or the
        answer's model holds none).
        """
        out: dict[str, Any] = {"K": None, "sigma_K": None, "interval_95": None, "identifiable": False}
        if effect not in plant.catalogue:
            return {**out, "from": "nominal", "reason": f"the {plant.name} model has no backlash width"}
        if self.named is None or effect not in self.named.effects:
            return {
                **out,
                "from": "nominal" if self.named is None else "+".join(self.named.effects),
                "reason": "the answer's model names no play: the record shows no width to measure",
            }
        K = float(self.named.fit.values[effect])
        sigma = _finite(self.named.fit.uncertainty.get(effect))
        return {
            "K": K,
            "sigma_K": sigma,
            "interval_95": [K - Z95 * sigma, K + Z95 * sigma] if sigma is not None else None,
            "from": "+".join(self.named.effects),
            "identifiable": sigma is not None,
            "reason": None if sigma is not None else "the fit gives no finite uncertainty for the play",
        }

    def to_dict(self, plant: Plant) -> dict[str, Any]:
        """JSON-ready form (the CLI's and the API's response); values in the units the plant declares."""
        cat = plant.catalogue
        units = {p.name: p.unit for p in plant.calibrated if p.name in self.calibration.values}
        effects = []
        if self.named is not None:
            for name in sorted(self.named.effects, key=lambda n: -self.budget.get(n, 0.0)):
                effects.append(
                    {
                        "effect": name,
                        "value": self.named.fit.values[name],
                        "uncertainty": _finite(self.named.fit.uncertainty.get(name)),
                        "unit": cat[name].unit,
                        "locus": cat[name].locus,
                        "share": self.budget.get(name, 0.0),
                    }
                )
        return {
            "plant": self.plant,
            "record": self.record,
            "status": self.status,
            "width": self.width(plant),
            "warnings": [w.to_dict() for w in self.extra.get("warnings", ())],
            "verdict": {
                "effects": effects,
                "effect": effects[0]["effect"] if effects else None,
                "value": effects[0]["value"] if effects else None,
                "locus": effects[0]["locus"] if effects else (self.locus.locus if self.locus is not None else None),
                "locus_confidence": (
                    None if effects or self.locus is None or self.locus.locus is None else self.locus.confidence
                ),
                "share": self.named.share if self.named else 0.0,
                "left": 1.0 - self.named.share if self.named else 1.0,
                "reason": self.extra.get("reason") or (self.gate.reason if self.gate is not None else None),
            },
            "locus": self.locus.to_dict() if self.locus is not None else None,
            "calibration": {
                "values": {k: self.calibration.values[k] for k in units if k in self.calibration.values},
                "uncertainty": {k: _finite(v) for k, v in self.calibration.uncertainty.items()},
                "units": units,
                "refitted_with_effects": self.calibration_refitted,
                "from": self.extra.get("calibrated_on", self.record),
            },
            "relative_error": self.relative_error,
            "where": [
                {"channel": c.channel, "band_hz": list(c.band), "window_s": list(c.window), "share": c.share}
                for c in self.where
            ],
            "where_summary": self.where_summary,
            "event_share": self.event_share,
            "candidates": [
                {
                    "effects": list(e.effects),
                    "values": {n: e.fit.values[n] for n in e.effects},
                    "share": e.share,
                    "loci": list(e.loci),
                }
                for e in ([self.named] if self.named and len(self.named.effects) > 1 else []) + self.ranking
            ],
            "absorbed_by_calibration": sorted(self.absorbed),
            "noise": self.gate.to_dict() if self.gate is not None else None,
            "gap": self.gate.gap(named=self.named is not None) if self.gate is not None else None,
            "n_simulations": self.extra.get("n_eval", 0),
        }


def _finite(x: float | None) -> float | None:
    """JSON has no inf: an unconstrained uncertainty is reported as null."""
    return x if x is not None and math.isfinite(x) else None


class PlantObjective:
    """Stacked, channel-normalised residual of a plant on a record (module docstring, Objective).

    Parameters
    ----------
    plant : Plant
    record
        One of the plant's records; its measured channels are computed once.
    workers : map-like, optional
        Runs independent simulations (a Jacobian's columns, a scan) on threads
        (:func:`simulation_pool`); default one after another.

    Attributes
    ----------
    n_eval : int
        Simulations run so far.
    """

    def __init__(self, plant: Plant, record: Any, workers: MapLike | None = None) -> None:
        self.plant = plant
        self.record = record
        self.workers = workers
        self._lock = threading.Lock()
        self.window = plant.scored(record)
        meas = plant.measured(record)
        self.channels = [c.name for c in plant.channels]
        self.y = {c: meas[c][self.window] for c in self.channels}
        self.scale = {c: 1.0 / float(np.linalg.norm(self.y[c])) for c in self.channels}
        self.n_eval = 0
        self._recent: dict[tuple[tuple[str, float], ...], dict[str, np.ndarray]] = {}

    def residuals(self, values: Mapping[str, float]) -> dict[str, np.ndarray]:
        """Per-channel residual (simulated - measured) over the scored samples, in channel units.

        The last few points are kept: a report asks for the calibrated and the named model's
        residuals several times (localisation, event shares, relative errors).
        """
        key = tuple(sorted(values.items()))
        with self._lock:  # the workers' threads share the count and the cache
            hit = self._recent.get(key)
            if hit is not None:
                return hit
            self.n_eval += 1
        sim = self.plant.simulate(self.record, values)
        out = {c: sim[c][self.window] - self.y[c] for c in self.channels}
        with self._lock:
            self._recent[key] = out
            while len(self._recent) > 4:
                del self._recent[next(iter(self._recent))]
        return out

    def relative_errors(self, values: Mapping[str, float]) -> dict[str, float]:
        """Relative error [%] per channel at ``values`` (authors' eq. 11, on the scored samples)."""
        res = self.residuals(values)
        return {c: 100.0 * float(np.linalg.norm(res[c])) * self.scale[c] for c in self.channels}

    def vector(self, values: Mapping[str, float]) -> np.ndarray:
        """The scaled residuals of every channel at ``values``, end to end (the least squares' vector)."""
        r = self.residuals(values)
        return np.concatenate([r[c] * self.scale[c] for c in self.channels])

    def vectors(self, points: Sequence[Mapping[str, float]]) -> list[np.ndarray]:
        """:meth:`vector` at each of ``points``, in their order (on the workers' threads when given)."""
        return list((self.workers or map)(self.vector, points))


@contextmanager
def simulation_pool(plant: Plant, jobs: int | None = None) -> Iterator[MapLike | None]:
    """Threads for a diagnosis's independent simulations, when the plant's may run on them.

    ``jobs`` threads (default numba's thread count, as the backlash drive's candidate fits) when the
    plant is :attr:`~engine.plants.base.Plant.concurrent`; None (one after another) otherwise or for
    one job. The threads change no result: every evaluation is the same, in the same order.

    Raises
    ------
    ValueError
        For ``jobs`` below 1.
    """
    n = int(numba.get_num_threads()) if jobs is None else int(jobs)
    if n < 1:
        raise ValueError(f"jobs must be at least 1 (threads for the diagnosis's simulations), got {jobs}")
    with thread_map(n if plant.concurrent else 1, thread_name_prefix=f"{plant.name}-sim") as workers:
        yield workers


def relative_errors(
    plant: Plant, record: Any, values: Mapping[str, float], objective: PlantObjective | None = None
) -> dict[str, float]:
    """Relative error [%] per channel of the model at ``values`` (authors' eq. 11, on the scored samples)."""
    return (objective or PlantObjective(plant, record)).relative_errors(values)


def fit(
    plant: Plant,
    record: Any,
    free: Sequence[CalibratedParameter],
    held: Mapping[str, float] | None = None,
    start: Mapping[str, float] | None = None,
    objective: PlantObjective | None = None,
) -> Fit:
    """Bounded least squares of ``free`` with ``held`` fixed (module docstring).

    Parameters
    ----------
    plant, record
        The plant and one of its records.
    free : sequence of CalibratedParameter
        The fitted names with their intervals.
    held : mapping, optional
        Values held fixed (names not given and not free keep the plant's nominal or neutral value).
    start : mapping, optional
        Start values of free names (default: each one's nominal, clipped into its interval).

    Raises
    ------
    RuntimeError
        When the solver fails.
    """
    obj = objective or PlantObjective(plant, record)
    held = dict(held or {})
    start = dict(start or {})
    n0 = obj.n_eval

    # the solver works on z = 1 + u in [1, 2]: its relative difference step is then the same share
    # of every interval wherever the point lies
    def values(z: np.ndarray) -> dict[str, float]:
        return {**held, **{p.name: float(p.value(zi - 1.0)) for p, zi in zip(free, z, strict=True)}}

    u0 = np.array([p.unit_coord(start.get(p.name, p.nominal)) for p in free])
    if not free:
        r = obj.vector(held)
        return Fit(dict(held), (), float(r @ r), {}, obj.n_eval - n0)
    res = solve_unit_box(
        lambda z: obj.vector(values(z)), u0, plant.diff_step, [p.name for p in free], workers=obj.workers
    )
    cost = float(res.fun @ res.fun)
    dof = max(res.fun.size - len(free), 1)
    # correlated residuals carry fewer independent samples than they have: inflate by tau
    s2 = cost / dof * correlation_time(np.split(res.fun, len(obj.channels)))
    jac = np.asarray(res.jac)
    scale = np.linalg.norm(jac, axis=0)
    flat = scale <= 1e-9 * max(float(scale.max()), 1e-300)  # the record does not move the cost along it
    sd_u = np.full(len(free), math.inf)
    if np.any(~flat):
        j = jac[:, ~flat]
        try:
            sd_u[~flat] = np.sqrt(np.clip(np.diag(np.linalg.pinv(j.T @ j)) * s2, 0.0, None))
        except np.linalg.LinAlgError:
            sd_u[~flat] = math.nan
    unc = {}
    for p, zi, su in zip(free, res.x, sd_u, strict=True):
        ui = float(zi) - 1.0
        unc[p.name] = float(abs(p.dvalue_du(ui)) * su)
    return Fit(values(res.x), tuple(p.name for p in free), cost, unc, obj.n_eval - n0)


def solve_unit_box(
    residual: Callable[[np.ndarray], np.ndarray],
    u0: np.ndarray,
    diff_step: float,
    names: Sequence[str],
    max_nfev: int = MAX_NFEV,
    workers: MapLike | None = None,
) -> Any:
    """Bounded least squares (scipy's trf) on z = 1 + u in [1, 2]^n, from the unit-box point ``u0``.

    Working on z rather than u makes the solver's relative difference step the same share
    (``diff_step``) of every interval wherever the point lies. ``workers`` evaluates the
    finite-difference Jacobian's columns (scipy's ``workers``; default one after another, the same
    result). Returns scipy's result.

    Raises
    ------
    RuntimeError
        When the solver fails or the residual is not finite (naming the parameters ``names``).
    """
    from scipy.optimize import least_squares  # here: scipy.optimize adds about 0.7 s to a service start

    res = least_squares(
        residual,
        1.0 + np.asarray(u0, dtype=float),
        bounds=(1.0, 2.0),
        method="trf",
        diff_step=diff_step,
        x_scale=1.0,
        max_nfev=max_nfev,
        workers=workers,
    )
    if res.status < 0 or not np.all(np.isfinite(res.fun)):
        raise RuntimeError(f"least squares failed on {list(names)}: {res.message}")
    return res


def correlation_time(residuals: Sequence[np.ndarray]) -> float:
    """:func:`integrated_time` of several channels' residuals, weighted by their squared norms."""
    weights = np.array([float(r @ r) for r in residuals])
    if weights.sum() == 0.0:
        return 1.0
    taus = np.array([integrated_time(r) for r in residuals])
    return float(weights @ taus / weights.sum())


def calibrate(plant: Plant, record: Any, objective: PlantObjective | None = None) -> Fit:
    """Fit the plant's calibrated parameters to a record, from where the plant says
    (:meth:`~engine.plants.base.Plant.calibration_start`: a global search's result, or the nominal values)."""
    free = free_parameters(plant, record)
    start = plant.calibration_start(record)
    if start is not None:
        names = {p.name for p in free}
        start = {n: float(v) for n, v in start.items() if n in names}
    out = fit(plant, record, free, start=start, objective=objective)
    logger.info("calibrated %s on %s: %s (cost %.4g)", plant.name, getattr(record, "name", ""), out.values, out.cost)
    return out


def _fit_effects(
    plant: Plant,
    record: Any,
    names: Sequence[str],
    calibration: Fit,
    refit: bool,
    obj: PlantObjective,
    start: Mapping[str, float] | None = None,
) -> Fit:
    """Joint fit of effects ``names`` (the last one scanned first) with the calibration refitted or held.

    With the calibration refitted, the last effect is scanned twice: beside the calibrated
    parameters and beside their nominal values; the fit starts from the better of the two. A strong
    effect drives a calibration without it far from the plant's nominal values (a 3 ms actuator
    delay, a command limit that saturates much of the record), and scanning beside that distorted
    calibration can miss the effect's basin (synthetic check, seeds 4 and 5).
    """
    effects = [plant.catalogue[n].as_parameter() for n in names]
    calibrated = free_parameters(plant, record)
    start = dict(start or {})
    last = effects[-1]
    bases = [{**calibration.values, **start}]
    if refit:
        bases.append({**{p.name: p.nominal for p in calibrated}, **start})
    best_v, best_c, best_base = last.nominal, math.inf, bases[0]
    scan = [(base, float(last.value(float(u)))) for base in bases for u in np.linspace(0.0, 1.0, N_SCAN)]
    for (base, v), r in zip(scan, obj.vectors([{**base, last.name: v} for base, v in scan]), strict=True):
        c = float(r @ r)
        if c < best_c:
            best_v, best_c, best_base = v, c, base
    free = [*effects, *(calibrated if refit else ())]
    held = {} if refit else dict(calibration.values)
    return fit(plant, record, free, held=held, start={**best_base, last.name: best_v}, objective=obj)


def absorbed_effects(plant: Plant, calibration: Fit, objective: PlantObjective) -> dict[str, float]:
    """Effects the calibrated parameters absorb locally: their residual change lies in the calibration's span.

    At the calibrated point, the residual's Jacobian J with respect to the calibrated parameters
    (forward differences of the plant's ``diff_step`` of each interval) and, per effect, the change j
    of the residual when the effect steps ``diff_step`` of its interval away from its neutral
    value. The effect is absorbed when ``||j - P j|| <= ABSORBED_RATIO ||j||``, P the projector on
    the columns of J: a refit of the calibration then cancels it, so no record can name it beside a
    refitted calibration (e.g. an EMPS drive gain error: scaling M, Fv, Fc and the offset by
    1 / (1 + eps) gives the very same loop). Effects whose neutral value lies outside their range,
    or whose step changes nothing, are not tested.

    Returns
    -------
    dict of str to float
        Absorbed effect -> its ratio ``||j - P j|| / ||j||``.
    """
    base = dict(calibration.values)
    h = plant.diff_step
    r0 = objective.vector(base)
    free = free_parameters(plant, objective.record)
    if not free:
        return {}  # the record fixes every calibrated parameter: nothing can absorb an effect
    points, steps = [], []
    for p in free:
        u, step = difference_step(p, base[p.name], h)
        points.append({**base, p.name: float(p.value(u + step))})
        steps.append(step)
    tested = [(name, e) for name, e in plant.catalogue.items() if e.bounds[0] <= e.neutral <= e.bounds[1]]
    for name, e in tested:
        q = e.as_parameter()
        u, step = difference_step(q, e.neutral, h)
        points.append({**base, name: float(q.value(u + step))})
    moved = objective.vectors(points)  # the calibration's columns and every effect's step, on the workers
    J = np.column_stack([(r - r0) / step for r, step in zip(moved[: len(free)], steps, strict=True)])
    Q, _ = np.linalg.qr(J)
    out = {}
    for (name, _), r in zip(tested, moved[len(free) :], strict=True):
        j = r - r0
        norm = float(np.linalg.norm(j))
        if norm == 0.0:
            continue
        ratio = float(np.linalg.norm(j - Q @ (Q.T @ j))) / norm
        if ratio <= ABSORBED_RATIO:
            out[name] = ratio
    return out


def rank_effects(
    plant: Plant,
    record: Any,
    calibration: Fit,
    refit: bool = True,
    objective: PlantObjective | None = None,
    absorbed: Mapping[str, float] | None = None,
) -> tuple[list[EffectFit], EffectFit | None]:
    """Fit every catalogue effect; name the best set (module docstring).

    With the calibration refitted, the effects in ``absorbed`` (:func:`absorbed_effects`) are not
    fitted: the refit would cancel them.

    Returns
    -------
    ranking : list of EffectFit
        Single effects, best first.
    named : EffectFit or None
        The named set, or None when no effect removes :data:`MIN_SHARE` of the gap.
    """
    obj = objective or PlantObjective(plant, record)
    c0 = calibration.cost
    skip = set(absorbed or ()) if refit else set()
    singles = []
    run = obj.workers or map  # the candidates' fits are independent: on the workers when given

    def fit_set(effects: tuple[str, ...], start: Mapping[str, float] | None, name: str) -> Fit:
        return _fit_effects(plant, record, [*effects, name], calibration, refit, obj, start=start)

    names = [name for name in plant.catalogue if name not in skip]
    for name, f in zip(names, run(functools.partial(fit_set, (), None), names), strict=True):
        share = max(0.0, 1.0 - f.cost / c0)
        singles.append(EffectFit((name,), f, share, (plant.catalogue[name].locus,), (share,)))
        logger.info("effect %s: share %.3f, value %.4g", name, singles[-1].share, f.values[name])
    singles.sort(key=lambda e: -e.share)
    if not singles or singles[0].share < MIN_SHARE:
        return singles, None
    named = singles[0]
    for _ in range(MAX_SET - 1):
        best: EffectFit | None = None
        start = {n: named.fit.values[n] for n in named.effects}
        added = [c.effects[0] for c in singles if c.effects[0] not in named.effects and c.share >= MIN_SHARE]
        for name, f in zip(added, run(functools.partial(fit_set, named.effects, start), added), strict=True):
            if best is None or f.cost < best.fit.cost:
                loci = tuple(plant.catalogue[n].locus for n in (*named.effects, name))
                share = max(0.0, 1.0 - f.cost / c0)
                best = EffectFit((*named.effects, name), f, share, loci, (*named.path, share))
        # an addition must close MIN_SHARE of the calibrated model's gap, not of what is left: once a
        # set has closed nearly all of it, what is left is the measurement's own (seed-2 synthetic
        # check: an encoder-quantum remainder let a second effect in beside a true one, twice in 23)
        if best is None or named.fit.cost - best.fit.cost < MIN_SHARE * c0:
            break
        named = best
    return singles, named


def gap_budget(named: EffectFit) -> dict[str, float]:
    """Share of the gap each effect of a set closes, in the order forward selection added them.

    The first effect's share is what it closes alone (with the calibration); each later one's is
    what its addition closed beyond the set before it. The shares add up to the set's share; what
    is left is ``1 - named.share``. (The order matters where effects overlap: the share of a later
    effect is what it adds, not what it would close alone.)
    """
    out = {}
    before = 0.0
    for name, cumulative in zip(named.effects, named.path or (named.share,), strict=False):
        out[name] = max(0.0, cumulative - before)
        before = cumulative
    return out


def localise(
    plant: Plant,
    record: Any,
    values: Mapping[str, float],
    top: int | None = TOP_CELLS,
    objective: PlantObjective | None = None,
) -> list[Cell]:
    """The largest cells of residual energy: channel x band x time window (module docstring); all with ``top=None``."""
    obj = objective or PlantObjective(plant, record)
    res = obj.residuals(values)
    t = np.asarray(plant.time(record), dtype=float)[obj.window]
    nyq = 0.5 / float(t[1] - t[0])
    from scipy.signal import butter, sosfiltfilt  # here, not at the top: see integrated_time

    cells: list[tuple[str, tuple[float, float], tuple[float, float], float]] = []
    edges = np.arange(t[0], t[-1] + WINDOW, WINDOW)
    which = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, edges.size - 2)
    for c in obj.channels:
        r = res[c] * obj.scale[c]
        for lo, hi in BANDS:
            if lo <= 0.0:
                sos = butter(4, hi / nyq, btype="low", output="sos")
            else:
                sos = butter(4, [lo / nyq, min(hi / nyq, 0.99)], btype="band", output="sos")
            energy = np.bincount(which, weights=sosfiltfilt(sos, r) ** 2, minlength=edges.size - 1)
            cells.extend((c, (lo, hi), (float(edges[i]), float(edges[i + 1])), float(e)) for i, e in enumerate(energy))
    total = sum(e for *_, e in cells) or 1.0
    cells.sort(key=lambda x: -x[3])
    return [Cell(c, band, win, e / total) for c, band, win, e in (cells if top is None else cells[:top])]


def event_shares(
    plant: Plant, record: Any, values: Mapping[str, float], objective: PlantObjective | None = None
) -> tuple[dict[str, float], float]:
    """Share of each channel's residual energy near the plant's input events, and the share of samples there.

    Returns
    -------
    shares : dict of str to float
        Per channel, the share of its residual energy in the samples the plant counts as near its
        input events (:meth:`~engine.plants.base.Plant.near_events`; empty when there are none).
    samples : float
        The share of the scored samples within those spans (what the energy share would be if
        the residual ignored the events).
    """
    obj = objective or PlantObjective(plant, record)
    near = np.asarray(plant.near_events(record), dtype=bool)[obj.window]
    if not near.any():
        return {}, 0.0
    res = obj.residuals(values)
    shares = {c: float(res[c][near] @ res[c][near] / max(res[c] @ res[c], 1e-300)) for c in obj.channels}
    return shares, float(near.mean())


def _reduced_chi2(
    obj: PlantObjective, values: Mapping[str, float], levels: Mapping[str, NoiseLevel]
) -> dict[str, float]:
    """chi2_c / n_c of each channel at ``values``: the mean squared residual over the noise's variance."""
    res = obj.residuals(values)
    return {c: float(np.mean(res[c] ** 2)) / levels[c].sigma ** 2 for c in obj.channels}


def noise_limits(
    obj: PlantObjective, levels: Mapping[str, NoiseLevel], settings: DiagnosisSettings
) -> dict[str, float]:
    """The largest chi2/n of a fit to the noise, per channel and (``"total"``) for the channels' mean.

    The backlash drive's thresholds, or 1 + :data:`CHI2_SCATTER_Z` standard deviations of chi2/n over
    the channel's n / tau independent samples, whichever is larger (a correlated channel scatters more).
    """
    n = {c: max(obj.y[c].size / levels[c].tau, 1.0) for c in obj.channels}
    out = {c: max(settings.max_channel_chi2, 1.0 + CHI2_SCATTER_Z * math.sqrt(2.0 / n[c])) for c in obj.channels}
    sd_total = math.sqrt(sum(2.0 / v for v in n.values())) / len(n)
    out["total"] = max(settings.max_reduced_chi2, 1.0 + CHI2_SCATTER_Z * sd_total)
    return out


def change_over_noise(
    a: Mapping[str, np.ndarray], b: Mapping[str, np.ndarray], levels: Mapping[str, NoiseLevel]
) -> float:
    """The largest channel RMS of ``b - a`` [noise RMS] (channels ``name -> samples``, the same samples each)."""
    return max(float(np.sqrt(np.mean((b[c] - a[c]) ** 2))) / levels[c].sigma for c in a)


def effect_strength(
    plant: Plant, record: Any, named: EffectFit, levels: Mapping[str, NoiseLevel], objective: PlantObjective
) -> float:
    """How far the named effects move the record at their fitted values: the largest channel RMS of
    the change [noise RMS], against the same model with the effects at their neutral values."""
    neutral = {**named.fit.values, **{n: plant.catalogue[n].neutral for n in named.effects}}
    return change_over_noise(objective.residuals(neutral), objective.residuals(named.fit.values), levels)


def noise_gate(
    plant: Plant,
    record: Any,
    calibration: Fit,
    named: EffectFit | None,
    objective: PlantObjective,
    settings: DiagnosisSettings | None = None,
) -> NoiseGate:
    """The calibrated and the named model's residuals against the plant's noise, and what they decide.

    The backlash drive's rule (:mod:`engine.diagnosis.decision`) on the plant's noise model:

    - the calibrated model fits to the noise and nothing strong is named: ``no_gap``;
    - a misfit beyond the noise, but weak (its worst channel's excess at most ``min_strength`` noise
      RMS) with nothing named, or the named effects move the record by at most ``min_strength`` noise
      RMS: ``weak_gap``;
    - otherwise ``gap``: the share rule names the answer (:func:`rank_effects`).

    A real record's residual is mostly model error, far above the sensors' noise: there the gate says
    ``gap`` and the answer is the share rule's, as before the gate existed.
    """
    s = settings or DiagnosisSettings()
    levels = dict(plant.noise(record))
    missing = [c for c in objective.channels if c not in levels]
    if missing:
        raise ValueError(f"plant {plant.name!r} gives no noise level for channel(s) {missing}")
    limits = noise_limits(objective, levels, s)
    before = _reduced_chi2(objective, calibration.values, levels)
    fits = NoiseGate.fits(before, limits)
    worst = max(before, key=lambda c: before[c])
    gap_rms = math.sqrt(max(before[worst] - 1.0, 0.0))
    strength = effect_strength(plant, record, named, levels, objective) if named is not None else None
    fit_text = f"chi2/n {NoiseGate.total(before):.3g}, worst channel {worst} {before[worst]:.3g}"
    if named is not None and strength is not None and strength > s.min_strength:
        status, reason = "gap", f"{'+'.join(named.effects)} moves the record by {strength:.3g} noise RMS"
    elif named is not None and strength is not None:
        what = f"the best set, {'+'.join(named.effects)}, moves the record by only {strength:.2f} noise RMS"
        if fits:
            status, reason = "no_gap", f"the calibrated model fits to the noise ({fit_text}) and {what}"
        else:
            status, reason = "weak_gap", f"a misfit beyond the noise ({fit_text}), and {what}: too weak to attribute"
    elif fits:
        status, reason = "no_gap", f"the calibrated model fits to the noise ({fit_text})"
    elif gap_rms <= s.min_strength:
        status, reason = (
            "weak_gap",
            f"a misfit beyond the noise ({fit_text}) but a weak one ({gap_rms:.2f} noise RMS, "
            f"<= {s.min_strength:g}), and no effect removes {100 * MIN_SHARE:.0f} % of it",
        )
    else:
        status, reason = "gap", f"a misfit of {gap_rms:.3g} noise RMS ({fit_text})"
    # the model the answer ends with: the named set's only when the gate leaves it named
    after = _reduced_chi2(objective, named.fit.values, levels) if named is not None and status == "gap" else before
    return NoiseGate(levels, before, dict(after), limits, strength, status, reason)


def open_world(
    plant: Plant, record: Any, calibration: Fit, named: EffectFit | None, gate: NoiseGate, objective: PlantObjective
) -> tuple[PlantLocusReport | None, str | None, dict[str, float | str | None]]:
    """The locus of a gap the catalogue does not take to the noise, and whether the named set is a stand-in.

    The locus estimate (:func:`~engine.diagnosis.plant_locus.estimate_plant_locus`) reads the
    calibrated model's residual. When its term reproduces the record
    (:attr:`~engine.diagnosis.plant_locus.PlantLocusReport.reproduces`) and fits it better than the named
    set by :data:`~engine.diagnosis.plant_locus.TIE_BIC` (BIC with the term's effective dof against
    the set's one per effect, on the plant's noise), the record holds evidence against the
    catalogue's answer: the set is a stand-in for something the catalogue lacks, and the answer is
    ``unexplained`` with that locus. Otherwise the set stays named, and the locus reported is that
    of the gap the set leaves (a second estimate from the set's fit). A real record's residual is
    mostly model error, which no one term reproduces: there the catalogue's answer stands.

    Returns the report (None when the estimate fails), the reason to set the named set aside (None to
    keep it), and the stand-in test's figures (the calibrated residual's locus, the share of the gap
    its term explains, its dispersion and its advantage over the named set; empty without a set).
    """
    try:
        locus = estimate_plant_locus(plant, record, calibration.values, gate.levels, objective.workers)
        if named is None:
            return locus, None, {}
        # the named set's whitened chi2: the gate's chi2/n per channel at the set's fit, times n
        chi2_named = sum(gate.after[c] * objective.y[c].size for c in objective.channels)
        advantage = locus.advantage(chi2_named, len(named.effects))
        test: dict[str, float | str | None] = {
            "locus": locus.locus,
            "explained": locus.scores[locus.locus].explained if locus.locus is not None else None,
            "dispersion": locus.dispersion,
            "advantage": advantage,
        }
        if locus.locus is not None and locus.reproduces and advantage >= TIE_BIC:
            return (
                locus,
                f"{'+'.join(named.effects)} removes {100 * named.share:.0f} % of the gap, but a term at the "
                f"{locus.locus} ({locus.term.get('description', '')}) fits the record better by {advantage:.3g} "
                "(scaled BIC): the catalogue's set is a stand-in for something it lacks",
                test,
            )
        left = estimate_plant_locus(plant, record, named.fit.values, gate.levels, objective.workers)
        left.n_simulations += locus.n_simulations  # the stand-in test's estimate is part of this answer's cost
        return left, None, test
    except (RuntimeError, ValueError, FloatingPointError) as exc:
        logger.warning("locus estimate failed on %s: %s", getattr(record, "name", ""), exc)
        return None, None, {}


def diagnose_plant(
    plant: Plant,
    record: Any,
    calibration: Fit | None = None,
    refit: bool = True,
    calibrated_on: str | None = None,
    jobs: int | None = None,
) -> PlantGapReport:
    """Diagnose one record: calibrate (unless given), localise, rank effects, errors before and after.

    Parameters
    ----------
    plant, record
        The plant and one of its records.
    calibration : Fit, optional
        A calibration (e.g. from another record); default: calibrate on this record.
    refit : bool
        Refit the calibrated parameters with every effect (True), or hold them (the cross-record
        check).
    calibrated_on : str, optional
        Name of the record ``calibration`` came from (reported).
    jobs : int, optional
        Threads for the independent simulations of the fits (:func:`simulation_pool`; default numba's
        thread count). The answer is the same for any number.
    """
    with simulation_pool(plant, jobs) as workers:
        return _diagnose(plant, record, PlantObjective(plant, record, workers), calibration, refit, calibrated_on)


def _diagnose(
    plant: Plant, record: Any, obj: PlantObjective, calibration: Fit | None, refit: bool, calibrated_on: str | None
) -> PlantGapReport:
    """:func:`diagnose_plant` on the objective ``obj`` (whose workers run the simulations)."""
    check_channels(plant, record)
    if calibration is None:
        calibration = calibrate(plant, record, objective=obj)
    else:
        r = obj.vector(calibration.values)
        calibration = Fit(dict(calibration.values), calibration.free, float(r @ r), calibration.uncertainty, 1)
    cells = localise(plant, record, calibration.values, top=None, objective=obj)
    where = cells[:TOP_CELLS]
    summary: dict[str, dict[str, float]] = {"channel": {}, "band_hz": {}}
    for cell in cells:
        band = f"{cell.band[0]:g}-{cell.band[1]:g}"
        summary["channel"][cell.channel] = summary["channel"].get(cell.channel, 0.0) + cell.share
        summary["band_hz"][band] = summary["band_hz"].get(band, 0.0) + cell.share
    absorbed = absorbed_effects(plant, calibration, obj) if refit else {}
    ranking, named = rank_effects(plant, record, calibration, refit=refit, objective=obj, absorbed=absorbed)
    gate = noise_gate(plant, record, calibration, named, obj)
    set_aside = None
    if gate.status in ("no_gap", "weak_gap") and named is not None:
        set_aside, named = named, None  # too weak to attribute: the answer ends with the calibrated model
    locus: PlantLocusReport | None = None
    reason: str | None = None
    stand_in_test: dict[str, float | str | None] = {}
    # the open world: a gap the answer's model leaves beyond the noise, and a weak gap too (its locus,
    # as the backlash drive's weak gaps carry one: an effect the calibration absorbs down to a weak
    # misfit still says where it acts)
    misfit = gate.status == "weak_gap" or (gate.status == "gap" and not NoiseGate.fits(gate.after, gate.limits))
    if refit and plant.entries and misfit:
        locus, stand_in, stand_in_test = open_world(plant, record, calibration, named, gate, obj)
        if stand_in is not None:
            set_aside, named, reason = named, None, stand_in
            gate = noise_gate(plant, record, calibration, None, obj)
    after_values = named.fit.values if named else calibration.values
    levels = plant.noise(record)
    warnings = check_fit(
        plant,
        obj.residuals(after_values),
        obj.residuals({}),  # the nominal model: a scale read from a fit to a mis-scaled channel is distorted
        obj.y,
        levels,
        f"the model with {'+'.join(named.effects)}" if named else "the calibrated model",
    )
    if warnings:  # a poor fit: is it the sample interval? (not on the channels a unit mistake explains)
        scale = [w for w in warnings if w.code == "channel_scale"]
        compared = [c.name for c in plant.channels if c.name not in {w.channel for w in scale}]
        timing = check_interval(plant, record, [after_values, {}], levels, compared) if compared else []
        warnings = [*scale, *timing, *(w for w in warnings if w.code != "channel_scale")]
    budget = gap_budget(named) if named else {}
    before_share, samples = event_shares(plant, record, calibration.values, objective=obj)
    after_share, _ = event_shares(plant, record, after_values, objective=obj)
    return PlantGapReport(
        plant=plant.name,
        record=getattr(record, "name", ""),
        calibration=calibration,
        relative_error={
            "before": obj.relative_errors(calibration.values),
            "after": obj.relative_errors(after_values),
        },
        where=where,
        where_summary=summary,
        event_share={
            "before": before_share,
            "after": after_share,
            "samples": {"share": samples} if before_share else {},
        },
        ranking=ranking,
        named=named,
        calibration_refitted=refit,
        budget=budget,
        absorbed=absorbed,
        gate=gate,
        locus=locus,
        extra={
            "n_eval": obj.n_eval + (locus.n_simulations if locus is not None else 0),
            **({"reason": reason} if reason else {}),
            **({"stand_in_test": stand_in_test} if stand_in_test else {}),
            **({"calibrated_on": calibrated_on} if calibrated_on else {}),
            **({"set_aside": set_aside} if set_aside is not None else {}),
            "warnings": warnings,
        },
    )
