"""The calibrated K as a continuous backlash-width identifier, with a profile-likelihood interval.

The other identifiers of :mod:`engine.identification` pick one of the paper's
six widths from trained patterns. :func:`estimate_width` instead fits the
plant to the record (the gap diagnosis's calibration,
:func:`engine.diagnosis.calibration.calibrate`) with K free and the record's
other conditions known, and reports the calibrated K with a 95 % interval;
:func:`nearest_grid_width` gives the paper's width class it falls in. It needs
no training, works on any subset of channels (a single channel included), and
costs a calibration (hundreds of simulations) plus a profile of K (one to two
hundred more, about as much time again) per record.

Interval
--------
The Gauss-Newton standard deviation of the calibration is not used: on a1 the
residual is rough at the micrometre scale while chi2 is smooth, so the
finite-difference curvature changes tenfold with the difference step and the
true K lay within 2 sd in only half the noisy records (docs/diagnosis.md,
section 9). The interval is read from chi2 itself instead:

- **Profile.** ``chi2_p(K)``: chi2 with K held and every other free parameter
  (J1, and c, c1 or the event alignment when the record leaves them free)
  refitted, by the same calibration run with a ``K`` condition, from the
  neighbouring profile point (:data:`PROFILE_NFEV` evaluations at most).
- **Threshold.** The 95 % interval holds the K whose profile is within
  ``chi2_1(0.95) * scale`` of the minimum, ``scale = max(1, chi2/dof) * tau``.
  For a Gaussian residual of known variance, ``chi2_p(K) - chi2_min`` is the
  likelihood-ratio statistic of K, chi-square with one degree of freedom
  (Wilks), so ``chi2_1(0.95)`` gives a 95 % interval without the cost being
  quadratic. When the fit leaves more than the noise (``chi2/dof > 1``) the
  residual variance is that many noise variances, and the statistic is divided
  by it (the quasi-likelihood / Birge scaling, as the Gauss-Newton covariance
  already did). When the residual is correlated in time (model error, not
  noise) with integrated autocorrelation time ``tau`` samples, the chi2
  computed as if white counts each independent piece of information ``tau``
  times: for a residual whose correlation is short against the change a
  parameter makes, the true log-likelihood difference is the white one over
  ``tau`` (the sandwich variance ``tau / (J^T J)``), hence the factor ``tau``.
  ``tau`` is that of the calibration's whitened residual
  (:func:`engine.diagnosis.correlation.residual_correlation_time`, built on
  :func:`engine.diagnosis.plant_gap.correlation_time`'s estimator; about 1 for
  a fit to the noise). The same rule gives the BRFD's interval
  (:mod:`engine.identification.plant_width`). Limitation: on a1 chi2 also
  jumps by several units where a model impact crosses a sample instant (the
  sampled acceleration is discontinuous in the parameters), and on the
  development records the statistic at the truth ran about 1.4 times
  chi2_1's quantiles there (docs/identification.md, "The calibrated K as a continuous width
  estimate").
- **Edges.** From the optimum, K steps outwards on each side (first by the
  Gauss-Newton half-width 1.96 sd, at least :data:`MIN_STEP_REL` of K; the
  second side by the first side's half-width), growing as the profile's rise
  predicts for a quadratic, until the profile crosses the threshold or the
  search box's edge is reached; the bracket is then refined :data:`N_REFINE`
  times by interpolation in ``sqrt(chi2_p - chi2_min)`` (linear in K for a
  quadratic profile). About 8-16 profile points per record.
- **Optimum.** A profile point below the calibration's chi2 by more than
  :data:`RECENTRE_TOL` of the threshold means the calibration stopped short of
  the minimum (it happens on a1): the calibration is refitted from that point
  and the profile redone about it (at most :data:`MAX_RECENTRE` times).

``sigma_K`` is half the interval's width over 1.96 (:data:`engine.constants.Z95`),
so that a "within 2 sd" statement agrees with the interval (the interval itself
may be asymmetric about K).

Identifiable
------------
The width is reported as not identifiable (``identifiable = False`` with the
reason) when the interval reaches an edge of the calibration's search box (the
record does not bound K there). A fit whose residual is far above the noise
(chi2 per residual above :data:`MISFIT_WARN`) carries a ``misfit`` warning: its
interval is widened by the scale above, but it rests on a model that does not
reproduce the record.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from scipy.special import chdtri  # the chi-square quantile (scipy.stats costs a service start about 1 s)

from engine.constants import K_GRID, Z95
from engine.diagnosis.calibration import CalibrationError, CalibrationResult, CalibrationSettings, calibrate
from engine.diagnosis.correlation import residual_correlation_time
from engine.diagnosis.plausibility import PlausibilityWarning
from engine.diagnosis.space import default_space
from engine.records import Record
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription

__all__ = [
    "CONFIDENCE",
    "MISFIT_WARN",
    "WIDTH_SETTINGS",
    "WidthEstimate",
    "estimate_width",
    "nearest_grid_width",
]

logger = logging.getLogger(__name__)

#: Search settings of the continuous width estimate (two or three free parameters): the ones
#: docs/identification.md's "calibrated K as a continuous width" table was measured with (with the optimiser's
#: difference step of that time, 2e-3; the diagnosis's default is smaller since 2026-11-24).
WIDTH_SETTINGS = CalibrationSettings(n_global=128, n_starts=2, fd_step=2e-3)
#: Confidence of the interval.
CONFIDENCE: float = 0.95
#: Cap on residual evaluations of each profile point's refit, at the search step and again in the
#: polish: a profile point starts from its neighbour's fit, a few microns away in K, and converges
#: in 3-6 evaluations (about 15 simulations per point on the benchmark's records); the cap bounds
#: the cost of a point whose neighbour is far.
PROFILE_NFEV: int = 10
#: Refinements of each edge's bracket (:func:`_crossing`): on a quadratic profile the first lands
#: on the edge; the second corrects for the profile's curvature and its roughness on a1 (its
#: chi2 jitters by about 0.5 at the micrometre scale), a few % of the half-width.
N_REFINE: int = 2
#: A refinement stays this fraction of the bracket away from its ends (a rough profile can put the
#: interpolated crossing on an end, which would not shrink the bracket).
SAFEGUARD: float = 0.1
#: Smallest first step of the outward search, relative to K: the Gauss-Newton sd of a noiseless
#: record can be near zero; growing by :data:`MAX_GROWTH` from 1e-5 K reaches the box edge in
#: under 10 steps.
MIN_STEP_REL: float = 1e-5
#: A profile point whose rise is below this fraction of the threshold is within the profile's
#: roughness and predicts nothing: the search grows by :data:`MAX_GROWTH` from it.
ROUGH: float = 0.25
#: Beyond a rise that does predict, the next step goes this factor past the quadratic's crossing, so
#: that it brackets the edge (the refinement then comes back to it).
OVERSHOOT: float = 1.2
#: Bounds of the growth of the outward step (a rough profile can predict a step of nothing or of
#: the whole box).
MIN_GROWTH: float = 1.25
MAX_GROWTH: float = 4.0
#: A profile point this fraction of the threshold below the calibration's chi2 moves the optimum
#: there (smaller improvements are the profile's roughness and would only move K within it).
RECENTRE_TOL: float = 0.1
#: Most refits of the optimum from a better profile point.
MAX_RECENTRE: int = 2
#: chi2 per residual above which the fit is said to be far above the noise: a fit to the noise
#: gives 1 +- sqrt(2/n) (0.03 for 2048 samples) with the noise estimate's error of some 10-20 %;
#: at 2 the model leaves as much unexplained as the noise itself, so the residual is mostly model
#: error and the width rests on a model that does not reproduce the record.
MISFIT_WARN: float = 2.0


@dataclass(frozen=True)
class WidthEstimate:
    """The calibrated K offered as a continuous backlash-width estimate.

    Attributes
    ----------
    K : float
        Estimated backlash zone width [m] (the calibration's K).
    sigma_K : float
        Half the width of :attr:`interval_95` over 1.96 [m]: a one-sigma figure consistent with
        the interval (module docstring), not the Gauss-Newton one.
    calibration : CalibrationResult
        The fit behind it (every fitted parameter, chi2, noise).
    interval_95 : tuple of float
        95 % profile-likelihood interval of K [m] (module docstring); contains ``K``.
    identifiable : bool
        False when the interval reaches an edge of the search box (the record does not bound K).
    reason : str or None
        Why not identifiable (None when it is).
    warnings : list of PlausibilityWarning
        Suspicions about the fit (``misfit``: chi2 per residual above :data:`MISFIT_WARN`).
    tau : float
        Integrated autocorrelation time of the fit's whitened residual [samples].
    scale : float
        ``max(1, chi2/dof) * tau``: the factor of the interval's chi2 threshold [-].
    profile : list of tuple of float
        ``(K [m], chi2 - chi2 of the fit [noise variances])`` of every profile point, by K.
    """

    K: float
    sigma_K: float
    calibration: CalibrationResult = field(repr=False)
    interval_95: tuple[float, float]
    identifiable: bool
    reason: str | None = None
    warnings: list[PlausibilityWarning] = field(default_factory=list)
    tau: float = 1.0
    scale: float = 1.0
    profile: list[tuple[float, float]] = field(default_factory=list, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the calibration without arrays)."""
        return {
            "K": self.K,
            "sigma_K": self.sigma_K,
            "interval_95": list(self.interval_95),
            "identifiable": self.identifiable,
            "reason": self.reason,
            "warnings": [w.to_dict() for w in self.warnings],
            "residual_correlation_time": self.tau,
            "interval_scale": self.scale,
            "calibration": self.calibration.to_dict(),
        }


class _Profile:
    """chi2 of a record with K held, every other free parameter refitted (cached per K)."""

    def __init__(
        self,
        record: Record,
        settings: CalibrationSettings,
        noise: Mapping[str, float],
        drive: DriveDescription = REFERENCE_DRIVE,
    ) -> None:
        self.record = record
        self.drive = drive
        self.settings = replace(settings, n_global=0, n_seed_fits=None, max_nfev=PROFILE_NFEV, polish_nfev=PROFILE_NFEV)
        self.noise = noise
        #: K [m] -> (chi2, the other parameters' fitted values)
        self.points: dict[float, tuple[float, dict[str, float]]] = {}
        self.n_simulations = 0

    def add(self, K: float, chi2: float, values: Mapping[str, float]) -> None:
        """Record a point known otherwise (the calibration's optimum)."""
        self.points[K] = (chi2, {k: v for k, v in values.items() if k != "K"})

    def __call__(self, K: float) -> float:
        """Profile chi2 at ``K`` [m] (inf when no refit can be simulated)."""
        if K in self.points:
            return self.points[K][0]
        near = min(self.points, key=lambda k: abs(k - K))
        record = self.record.replace(conditions={**self.record.conditions, "K": K})
        try:
            cal = calibrate(
                record,
                default_space(record, drive=self.drive),
                settings=self.settings,
                noise=self.noise,
                seeds=[self.points[near][1]],
            )
        except CalibrationError:
            self.points[K] = (math.inf, self.points[near][1])
            return math.inf
        self.n_simulations += cal.n_simulations
        self.points[K] = (cal.chi2, dict(cal.values))
        return cal.chi2


def _crossing(
    inside: tuple[float, float], outside: tuple[float, float], threshold: float, margin: float = 0.0
) -> float:
    """K [m] between two profile points ``(K, chi2 - chi2_min)`` where the profile reaches ``threshold``.

    Interpolated linearly in ``sqrt(chi2 - chi2_min)``, which is linear in K for a quadratic
    profile (a point at the optimum, 0, gives the quadratic's crossing in one step); the midpoint
    when the outer point could not be simulated. The result is kept ``margin`` (a fraction of the
    bracket) away from either point.
    """
    (k_in, d_in), (k_out, d_out) = inside, outside
    if math.isfinite(d_out):
        s_in, s_out = math.sqrt(max(d_in, 0.0)), math.sqrt(d_out)
        frac = (math.sqrt(threshold) - s_in) / (s_out - s_in)
    else:
        frac = 0.5
    return k_in + min(max(frac, margin), 1.0 - margin) * (k_out - k_in)


def _edge(
    profile: Callable[[float], float], K0: float, c0: float, step: float, bound: float, threshold: float
) -> tuple[float, bool]:
    """The K [m] beyond ``K0`` towards ``bound`` where the profile rises ``threshold`` above ``c0``.

    Steps outwards from ``K0`` (first ``step`` [m]; then by the growth the profile's rise so far
    predicts for a quadratic, :data:`OVERSHOOT` beyond it, between :data:`MIN_GROWTH` and
    :data:`MAX_GROWTH`) until the profile is above the threshold, then refines the bracket
    :data:`N_REFINE` times (:func:`_crossing`, kept :data:`SAFEGUARD` of the bracket away from its
    ends). Returns the edge and whether the box's edge ``bound`` was reached with the profile
    still inside.
    """
    direction = 1.0 if bound > K0 else -1.0
    inside = (K0, 0.0)
    h = step
    while True:
        K = K0 + direction * h
        if (K - bound) * direction >= 0.0:
            K = bound
        d = profile(K) - c0
        if d > threshold:
            outside = (K, d)
            break
        inside = (K, max(d, 0.0))
        if bound == K:
            return bound, True
        rose = d > ROUGH * threshold  # a rise above the profile's roughness predicts the crossing
        h *= min(max(OVERSHOOT * math.sqrt(threshold / d), MIN_GROWTH), MAX_GROWTH) if rose else MAX_GROWTH
    for _ in range(N_REFINE):
        K = _crossing(inside, outside, threshold, SAFEGUARD)
        d = profile(K) - c0
        if d > threshold:
            outside = (K, d)
        else:
            inside = (K, max(d, 0.0))
    return _crossing(inside, outside, threshold), False


def estimate_width(
    record: Record, settings: CalibrationSettings = WIDTH_SETTINGS, drive: DriveDescription = REFERENCE_DRIVE
) -> WidthEstimate:
    """Continuous backlash-width estimate: the calibrated K and its 95 % profile-likelihood interval.

    The record's other conditions (J1, c, c1) are used as known; a ``K``
    condition is ignored (K is what is estimated). Works on any subset of
    channels, a single channel included. See the module docstring for the
    interval and when the width is not identifiable.

    Parameters
    ----------
    record : Record
        The measured record, on any grid (its test window is fitted on its own instants; a
        located event's instant is fitted too).
    settings : CalibrationSettings
        Search settings of the calibration (default :data:`WIDTH_SETTINGS`); the profile's refits
        use them without the global search.
    drive : DriveDescription
        The drive the record was measured on (default MODEL.md's reference plant): its nominal plant and search
        box (:func:`engine.diagnosis.space.default_space`). The interval's widening rule was set on the reference
        plant's records.

    Returns
    -------
    WidthEstimate

    Raises
    ------
    engine.diagnosis.calibration.CalibrationError
        When the record cannot be fitted.
    """
    t0 = time.perf_counter()
    if "K" in record.conditions:
        record = record.replace(conditions={k: v for k, v in record.conditions.items() if k != "K"})
    cal = calibrate(record, default_space(record, drive=drive), settings=settings)
    window, _ = record.test_window()
    k_param = next(p for p in default_space(window, drive=drive).params if p.name == "K")
    profile = _Profile(record, settings, cal.noise, drive)
    q = float(chdtri(1, 1.0 - CONFIDENCE))  # chi2.ppf(CONFIDENCE, 1)
    previous: tuple[float, float] | None = None  # the edges about the previous optimum
    for attempt in range(MAX_RECENTRE + 1):
        K = cal.values["K"]
        dof = max(cal.n_data - cal.n_params, 1)
        tau = residual_correlation_time(window, cal)
        scale = max(1.0, cal.chi2 / dof) * tau
        threshold = q * scale
        profile.add(K, cal.chi2, cal.values)
        floor = MIN_STEP_REL * K
        # first steps: the edges found about the previous optimum; else the Gauss-Newton
        # half-width (right for a quadratic profile), then the other side's half-width
        if previous is None:
            sd = cal.uncertainties.get("K", math.nan)
            lo, lo_edge = _edge(profile, K, cal.chi2, max(Z95 * sd, floor) if sd > 0 else floor, k_param.lo, threshold)
            hi_step = K - lo
        else:
            lo, lo_edge = _edge(profile, K, cal.chi2, max(K - previous[0], floor), k_param.lo, threshold)
            hi_step = previous[1] - K
        hi, hi_edge = _edge(profile, K, cal.chi2, max(hi_step, floor), k_param.hi, threshold)
        previous = (lo, hi)
        K_best = min(profile.points, key=lambda k: profile.points[k][0])
        c_best, v_best = profile.points[K_best]
        if c_best >= cal.chi2 - RECENTRE_TOL * threshold or attempt == MAX_RECENTRE:
            break
        logger.debug("profile point K=%.6g m is %.3g below the fit: refitting from it", K_best, cal.chi2 - c_best)
        refit = calibrate(
            record,
            default_space(record, drive=drive),
            settings=replace(settings, n_global=0, n_seed_fits=None),
            noise=cal.noise,
            seeds=[{**v_best, "K": K_best}, cal.values],
        )
        if refit.chi2 >= cal.chi2:
            break
        cal = refit
    K = cal.values["K"]
    interval = (min(lo, K), max(hi, K))
    sigma = (interval[1] - interval[0]) / (2.0 * Z95)
    reason = None
    if lo_edge or hi_edge:
        edge = k_param.lo if lo_edge else k_param.hi
        reason = (
            f"the 95 % interval of K reaches the search box's edge at {edge * 1e3:.3g} mm: "
            "the record does not bound the width"
        )
    warnings = []
    per_residual = cal.chi2 / max(cal.n_data, 1)
    if per_residual > MISFIT_WARN:
        n_ch = cal.n_data / max(len(cal.chi2_per_channel), 1)
        worst = max(cal.chi2_per_channel, key=lambda n: cal.chi2_per_channel[n])
        warnings.append(
            PlausibilityWarning(
                "misfit",
                f"the fit leaves {per_residual:.3g} noise variances per sample (noise alone gives about 1; "
                f"{worst}: {cal.chi2_per_channel[worst] / n_ch:.3g}): the record holds something the plant "
                f"model does not; the interval of K is widened for it ({math.sqrt(scale):.3g} x), but the "
                "width rests on a model that does not reproduce the record",
                worst,
            )
        )
    points = sorted((k, c - cal.chi2) for k, (c, _) in profile.points.items())
    logger.info(
        "continuous width: K=%.6g m, 95 %% interval [%.6g, %.6g] m (scale %.3g, tau %.3g), %d profile points "
        "(%d simulations), %.2f s",
        K,
        interval[0],
        interval[1],
        scale,
        tau,
        len(points),
        profile.n_simulations,
        time.perf_counter() - t0,
    )
    return WidthEstimate(
        K=K,
        sigma_K=sigma,
        calibration=cal,
        interval_95=interval,
        identifiable=reason is None,
        reason=reason,
        warnings=warnings,
        tau=tau,
        scale=scale,
        profile=points,
    )


def nearest_grid_width(K: float, grid: Sequence[float] = K_GRID) -> float:
    """The width of ``grid`` (default the paper's K_GRID; a described drive's
    :meth:`~engine.simulation.drive.DriveDescription.k_grid`) nearest to ``K`` [m]: the class a continuous width
    belongs to, in m."""
    return float(min(grid, key=lambda w: abs(w - K)))
