"""Calibration of the uncertain plant parameters against a record.

The calibration fits the parameters that are uncertain in practice (the
backlash width K, the motor-side inertia J1, the absorber viscosity c, and
the absorber discontinuity c1 unless the record's conditions fix it; see
:mod:`engine.diagnosis.space`), and optionally the scalar value of one
unmodelled effect, to a backlash-test record. The cost is the noise-normalised
sum of squared residuals (:class:`~engine.diagnosis.objective.Objective`)::

    chi2(theta) = sum_j sum_k ((sim_j[k](theta) - rec_j[k]) / sigma_j)^2

over the channels j present in the record and the samples k, where sigma_j
is the channel's white-noise level estimated from the record (see
:func:`engine.diagnosis.noise.estimate_noise`); when the record's noise is
coloured (low-passed), the same sum over the residual's whitened wavelet
coefficients (:mod:`engine.diagnosis.noise`).

Why not plain least squares
---------------------------
``docs/INVERSE-PROBLEM.md`` (shared spec) shows that the cost basin around
the truth is narrow (about +-3 % in K, +-1.5 % in J1): outside it the
sequence of clutch impacts changes and the late part of the record no longer
points towards the optimum. The fit therefore proceeds in two stages:

1. **Global search**: a scrambled Sobol sample of the parameter box is
   simulated in one batch (coarse integrator step) and scored on the *early*
   window of the record only (pre-event samples and the first 20 ms after the
   event), where the cost is smooth because no impact has happened yet. The
   best few distinct points (8 by default, ``n_screen``) are each refined
   briefly on that window and the best of those refined points (``n_starts``)
   continue: in the wide plausible box (issue 10) the lowest sampled points are
   often not the ones that lead into the deepest valley.
2. **Continuation over the time horizon**: from those starts,
   ``scipy.optimize.least_squares`` refines the fit
   on a horizon that grows (20, 50, 100, 200 ms after the event); each stage
   starts from the previous stage's optimum, which keeps it inside the
   narrowing basin. The best full-horizon fit is polished with a finer
   integrator step and gives the uncertainties (Gauss-Newton covariance).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypedDict

import numpy as np

from engine.constants import CHANNELS
from engine.diagnosis.noise import NoiseModel, estimate_noise, noise_weights
from engine.diagnosis.objective import ChannelResidual, Objective
from engine.diagnosis.space import CALIBRATED, ModelSpace, across_switch_off, default_space
from engine.features.wavelet import level_for_interval
from engine.parallel import single_threaded_blas
from engine.records import Record, SampleGrid
from engine.simulation import Case, SolverSettings, run_cases
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription

logger = logging.getLogger(__name__)

__all__ = [
    "CalibrationError",
    "CalibrationResult",
    "CalibrationSettings",
    "Stage",
    "calibrate",
    "correlation",
    "unit_covariance",
]


class CalibrationError(RuntimeError):
    """Raised when the calibration cannot produce a fit (e.g. no parameter set can be simulated)."""


class Stage(TypedDict):
    """One stage of a calibration's trace.

    Attributes
    ----------
    start : {"global", "seed", "polish"}
        Where the refinement started: a point of the global search, a seed, or the polish.
    horizon : int
        Samples of the record fitted.
    chi2 : float
        chi2 at the end of the stage [noise variances].
    step : float
        Integrator step [s].
    nfev : int
        Residual evaluations.
    """

    start: str
    horizon: int
    chi2: float
    step: float
    nfev: int


@dataclass(frozen=True)
class CalibrationSettings:
    """Settings of :func:`calibrate`.

    Parameters
    ----------
    n_global : int
        Sobol points of the global search (rounded up to a power of two; 0 for none).
    n_starts : int
        Distinct starting points refined by continuation.
    horizons_ms : tuple of float
        Continuation horizons after the event [ms]; the last should cover the record.
    search_step : float
        Integrator step of the global search and continuation [s].
    final_step : float
        Integrator step of the final polish and the reported fit [s].
    max_nfev : int
        Cap on residual evaluations per continuation stage.
    polish_nfev : int
        Cap on residual evaluations of the final polish (it usually converges sooner).
    fd_step : float
        Finite-difference step of the optimiser's Jacobian in the global search's
        refinements and the continuation, in unit-box coordinates. The cost's valleys
        are so narrow in K (chi2 rises by thousands for a 0.02 % change) that a step of
        2e-3 (0.5 % of K on the plausible box's log scale; the value until 2026-11-24)
        gives a Jacobian along which the trust region cannot follow a valley where K
        and the other parameters must move together: the fit stalls where it started
        (docs/diagnosis.md section 1, "The optimiser's difference step").
    fd_step_uncertainty : float
        Central-difference step of the Jacobian behind the uncertainties (unit box);
        the polish uses three times this step.
    min_separation : float
        Smallest unit-box distance between two starting points.
    seed : int
        Seed of the Sobol scrambling.
    n_screen : int
        When larger than ``n_starts``: this many of the best distinct Sobol points are
        first refined on the first horizon (at most ``screen_nfev`` evaluations each), and
        the ``n_starts`` best of those refined points (still distinct) are continued. The
        early window's cost is smooth, so a short refinement tells a point that leads into
        a deep valley from one that only happened to be sampled low.
    screen_nfev : int
        Cap on residual evaluations of each screening refinement.
    n_extend_scan : int
        When positive, each time the continuation extends the horizon, every parameter is
        scanned on its own over its whole range (this many values, one batch on the new
        horizon) and the continuation goes on from the best point found (or stays): a
        parameter that the shorter horizon did not pin sits wherever its start put it, and
        when the longer horizon reveals its effect the local fit would only reach the
        nearest of its basins.
    n_seed_fits : int or None
        When more seeds than this are given, all of them are first evaluated on the full record
        (one batch at the search step) and only this many with the lowest chi2 are refined
        (None: every seed; at least 1). The joint fits of a set of effects get up to seven seeds,
        built from the fits of its subsets, and refining each costs as much as a seeded single fit.
    """

    n_global: int = 512
    n_starts: int = 4
    horizons_ms: tuple[float, ...] = (20.0, 50.0, 100.0, 200.0)
    search_step: float = 5e-5
    final_step: float = 2e-5
    max_nfev: int = 12
    polish_nfev: int = 30
    fd_step: float = 1e-4
    fd_step_uncertainty: float = 1e-4
    min_separation: float = 0.08
    seed: int = 0
    n_screen: int = 8
    screen_nfev: int = 6
    n_extend_scan: int = 0
    n_seed_fits: int | None = None

    def horizons(self, record: Record) -> list[int]:
        """Horizons as sample counts from the start of the record (on its own interval)."""
        n = record.n_samples
        hs = sorted({min(n, record.event_index + round(h * 1e-3 / record.sample_interval)) for h in self.horizons_ms})
        if hs[-1] != n:
            hs.append(n)
        return hs


@dataclass
class CalibrationResult:
    """Outcome of a calibration.

    Attributes
    ----------
    values : dict of str to float
        Fitted parameters (plant parameters in their unit, effect value in the effect's unit).
    uncertainties : dict of str to float
        One standard deviation of each fitted value (Gauss-Newton covariance,
        inflated by the reduced chi-square when it exceeds 1), same units.
    fixed : dict of str to float
        Plant parameters fixed by the record's conditions.
    chi2 : float
        Noise-normalised sum of squared residuals over all channels and samples [noise variances].
    chi2_per_channel : dict of str to float
        The same per channel.
    n_data : int
        Number of residuals (channels x samples).
    noise : NoiseModel or mapping of str to float
        Noise per channel: as a mapping, its standard deviation per sample (channel unit);
        a :class:`~engine.diagnosis.noise.NoiseModel` also holds its colour
        (:func:`engine.diagnosis.noise.estimate_noise`).
    sigma : NoiseModel or mapping of str to float
        Normalisation actually used (noise with a floor, see
        :func:`engine.diagnosis.noise.noise_weights`), channel unit.
    effect : str or None
        Effect fitted together with the calibration, if any (a set: names joined by "+").
    n_simulations : int
        Simulations run.
    seconds : float
        Wall time [s].
    stages : list of Stage
        Trace of the best start: kind ("global", "seed", "polish"), horizon
        [samples], chi2, integrator step [s] and residual evaluations.
    case : Case
        The calibrated simulation case (effect applied).
    simulation : ndarray, shape (5, n_samples)
        Its five channels on the record's grid (the test window), model units.
    event_time : float
        Its event time t_e [s].
    step : float
        Integrator step of the reported fit [s].
    drive : DriveDescription
        The drive fitted (its model space's): its ``t_event_max`` [s] bounds every later simulation of the fit
        (:meth:`solver`), and the plausibility checks read its envelopes.
    grid : SampleGrid or None
        The grid calibrated on (the record's test window).
    lowfreq_ratio : dict of str to float
        Per channel, mean squared wavelet coefficient of the normalised residual
        below fs / 16 (levels D4 and coarser; 625 Hz at 0.1 ms) over that of
        levels D1-D2 (fs / 8 to fs / 2): about 1 for a white
        residual whatever the noise estimate's error; a structured (mostly
        low-frequency) gap raises it. Reported as a diagnostic
        (:func:`engine.diagnosis.noise.lowfreq_ratio`; for coloured noise on the whitened
        coefficients, :meth:`engine.diagnosis.noise.ChannelNoise.lowfreq_ratio`).
    starts : list of dict of str to float
        The global search's starting points of the continuation (the early window's best
        distinct points after the screen), in the parameters' units; empty without a global
        search. Where the continuation left them for another basin, a missing effect may
        have dragged the fit there (:func:`engine.diagnosis.candidate.refit_from_starts`).
    """

    values: dict[str, float]
    uncertainties: dict[str, float]
    fixed: dict[str, float]
    chi2: float
    chi2_per_channel: dict[str, float]
    n_data: int
    noise: Mapping[str, float]
    sigma: Mapping[str, float]
    effect: str | None
    n_simulations: int
    seconds: float
    stages: list[Stage] = field(default_factory=list)
    case: Case | None = field(default=None, repr=False)
    simulation: np.ndarray | None = field(default=None, repr=False)
    event_time: float | None = None
    step: float = 2e-5
    lowfreq_ratio: dict[str, float] = field(default_factory=dict)
    grid: SampleGrid | None = None
    starts: list[dict[str, float]] = field(default_factory=list)
    drive: DriveDescription = field(default=REFERENCE_DRIVE, repr=False)

    def solver(self, max_step: float | None = None) -> SolverSettings:
        """Integrator settings for simulations of this fit: steps of at most ``max_step`` [s] (default the fit's
        own :attr:`step`), the event within the drive's ``t_event_max``."""
        return self.drive.solver(self.step if max_step is None else max_step)

    @property
    def n_params(self) -> int:
        """Number of fitted parameters."""
        return len(self.values)

    @property
    def reduced_chi2(self) -> float:
        """chi2 per residual; about 1 when the model fits to the noise."""
        return self.chi2 / max(self.n_data, 1)

    @property
    def bic(self) -> float:
        """Bayesian information criterion chi2 + k ln(n) (Gaussian noise of known sigma)."""
        return self.chi2 + self.n_params * math.log(max(self.n_data, 2))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no arrays)."""
        return {
            "values": dict(self.values),
            "uncertainties": dict(self.uncertainties),
            "fixed": dict(self.fixed),
            "effect": self.effect,
            "chi2": self.chi2,
            "reduced_chi2": self.reduced_chi2,
            "chi2_per_channel": dict(self.chi2_per_channel),
            "n_data": self.n_data,
            "bic": self.bic,
            "noise": dict(self.noise),
            "noise_model": NoiseModel.of(self.noise).describe(),
            "lowfreq_ratio": dict(self.lowfreq_ratio),
            "n_simulations": self.n_simulations,
            "seconds": self.seconds,
            "step": self.step,
        }

    def simulated_record(self, template: Record) -> Record:
        """The calibrated simulation in the record format (all five channels) on ``template``'s grid.

        Its conditions carry the calibrated J1, c, c1 and K (and the template's other
        conditions, e.g. the ``base_torque`` of an m_el in N*m), and it keeps the template's
        units (its :meth:`Record.to_dict` writes them). When the template's grid is the one
        calibrated on, the stored simulation is used; otherwise (e.g. the whole of a record
        longer than the test window) the calibrated case is simulated on it.
        """
        if self.case is None or self.simulation is None:
            raise CalibrationError("this calibration result holds no simulation")
        sim = self.simulation
        if sim.shape[-1] != template.n_samples or self.grid != template.grid:
            ch, _, st = run_cases([self.case], self.solver(), template.grid)
            if st[0] != 0:
                raise CalibrationError(
                    f"the calibrated parameters cannot be simulated on the record's grid (status {int(st[0])})"
                )
            sim = ch[0]
        p = self.case.plant
        return Record(
            channels={n: sim[j] for j, n in enumerate(CHANNELS)},
            sample_interval=template.sample_interval,
            event_index=template.event_index,
            conditions={**template.conditions, "J1": p.J1, "c": p.c, "c1": p.c1, "K": p.K},
            event_time=self.event_time,
            units=template.units,
        )


def _pick_starts(U: np.ndarray, cost: np.ndarray, n: int, min_sep: float) -> list[np.ndarray]:
    """The n lowest-cost points that are at least ``min_sep`` apart (unit-box distance)."""
    starts: list[np.ndarray] = []
    for i in np.argsort(cost):
        if not np.isfinite(cost[i]):
            break
        if all(np.linalg.norm(U[i] - s) >= min_sep for s in starts):
            starts.append(U[i])
            if len(starts) == n:
                break
    return starts


def _best_seeds(
    obj: Objective, seeds: list[np.ndarray], settings: CalibrationSettings, solver: SolverSettings
) -> list[np.ndarray]:
    """The ``settings.n_seed_fits`` seeds (unit box) of lowest chi2 on the full record, in their given order."""
    n = settings.n_seed_fits
    if n is not None and n < 1:
        raise ValueError(f"n_seed_fits must be at least 1 (or None for every seed), got {n}")
    if n is None or len(seeds) <= n:
        return seeds
    c2 = obj.chi2(np.array(seeds), [obj.record.n_samples], solver)[:, 0]
    keep = sorted(np.argsort(c2, kind="stable")[:n])
    logger.debug("seeds: %d of %d kept (chi2 %s)", len(keep), len(seeds), np.round(c2, 1))
    return [seeds[i] for i in keep]


def calibrate(
    record: Record,
    space: ModelSpace | None = None,
    settings: CalibrationSettings = CalibrationSettings(),
    noise: Mapping[str, float] | None = None,
    seeds: Sequence[Mapping[str, float]] = (),
    polish: bool = True,
    residual_of: Mapping[str, ChannelResidual] | None = None,
) -> CalibrationResult:
    """Fit the uncertain parameters (and optionally one effect's value) to a record.

    Parameters
    ----------
    record : Record
        Measured record; any subset of channels.
    space : ModelSpace, optional
        What to fit; default :func:`~engine.diagnosis.space.default_space` (K, J1, c, c1 less those fixed
        by ``record.conditions``). Use ``space.with_effect(effect)`` to fit an
        effect's value too.
    settings : CalibrationSettings
        Search settings; ``n_global = 0`` skips the global search (then
        ``seeds`` must be given).
    noise : mapping of str to float, optional
        Noise per channel: a :class:`~engine.diagnosis.noise.NoiseModel` (e.g. an earlier
        calibration's ``noise``), or standard deviations (channel unit) of white noise;
        estimated with :func:`~engine.diagnosis.noise.estimate_noise` when omitted.
    seeds : sequence of mappings
        Extra starting points (parameter name -> value, e.g. an earlier
        calibration). They are refined on the full horizon directly (no
        continuation), next to the continuation from the global search.
    polish : bool
        Refine the best fit with ``settings.final_step`` and report chi2 and
        uncertainties at that step; otherwise everything is at ``search_step``.
    residual_of : mapping of str to callable, optional
        Per channel, its own normalised residual in place of the noise-normalised difference
        (:class:`~engine.diagnosis.objective.ChannelResidual`); the result's chi-squares are of
        the residuals fitted, its ``simulation`` is without the effects they take (its ``case``
        with them).

    Returns
    -------
    CalibrationResult

    Raises
    ------
    CalibrationError
        When no point of the search box (nor any seed) can be simulated, or the
        fitted parameters cannot be simulated.

    Notes
    -----
    The record's test window (:meth:`engine.records.Record.test_window`) is fitted, on the
    record's own sample grid: the simulations are sampled at its instants.
    """
    record, _ = record.test_window()
    with single_threaded_blas():
        return _calibrate(record, space, settings, noise, seeds, polish, residual_of)


def _calibrate(
    record: Record,
    space: ModelSpace | None,
    settings: CalibrationSettings,
    noise: Mapping[str, float] | None,
    seeds: Sequence[Mapping[str, float]],
    polish: bool,
    residual_of: Mapping[str, ChannelResidual] | None = None,
) -> CalibrationResult:
    t0 = time.perf_counter()
    space = default_space(record) if space is None else space
    noise = estimate_noise(record) if noise is None else NoiseModel.of(noise)
    sigma = noise_weights(record, noise)
    obj = Objective(record, space, sigma, residual_of)
    horizons = settings.horizons(record)
    coarse = space.solver(settings.search_step)
    final = space.solver(settings.final_step) if polish else coarse
    d = space.dim
    fixed = {k: float(getattr(space.base.plant, k)) for k in CALIBRATED if k not in space.names}
    stages: list[Stage] = []
    u_best = np.zeros(0)
    global_starts: list[dict[str, float]] = []

    if d > 0:
        # 1. global search on the early window (Sobol points, one batch)
        starts: list[tuple[np.ndarray, str]] = []
        if settings.n_global > 0:
            m = 1 << max(3, math.ceil(math.log2(settings.n_global)))
            U = sobol(d, scramble=True, seed=settings.seed).random(m)
            C = obj.chi2(U, horizons[:1], coarse)[:, 0]
            picked = _pick_starts(U, C, max(settings.n_starts, settings.n_screen), settings.min_separation)
            if len(picked) > settings.n_starts:  # screen: a short refinement on the first horizon each
                refined = [
                    obj.local_fit(u, horizons[0], coarse, settings.screen_nfev, settings.fd_step)[:2] for u in picked
                ]
                picked = _pick_starts(
                    np.array([r[0] for r in refined]),
                    np.array([r[1] for r in refined]),
                    settings.n_starts,
                    settings.min_separation,
                )
            starts += [(u, "global") for u in picked]
            global_starts = [space.values(u) for u in picked]
            logger.debug("global search: %d points, best early chi2 %.4g", len(U), np.min(C))
        # seeds (already close to a full-horizon optimum) skip the continuation
        starts += [(u, "seed") for u in _best_seeds(obj, [space.unit(s) for s in seeds], settings, coarse)]
        if not starts:
            raise CalibrationError(
                "no parameter set of the search box could be simulated; check the record's conditions"
            )

        # 2. continuation over the horizon, from every start
        best_chi2 = math.inf
        for s, kind in starts:
            u = s
            trace: list[Stage] = []
            for i, h in enumerate(horizons if kind == "global" else [record.n_samples]):
                if i > 0 and settings.n_extend_scan > 1:
                    U, C = obj.axis_scan(u, range(u.size), settings.n_extend_scan, h, coarse)
                    u = U[int(np.argmin(C))] if np.isfinite(C).any() else u
                u, c2, _, nfev = obj.local_fit(u, h, coarse, settings.max_nfev, settings.fd_step)
                trace.append({"start": kind, "horizon": h, "chi2": c2, "step": settings.search_step, "nfev": nfev})
            logger.debug("%s start %s -> %s chi2 %.4g", kind, np.round(s, 3), np.round(u, 3), trace[-1]["chi2"])
            if trace[-1]["chi2"] < best_chi2:
                best_chi2, u_best, stages = trace[-1]["chi2"], u, trace
        if not np.isfinite(best_chi2):
            raise CalibrationError("no start of the calibration reached a parameter set that can be simulated")
        # 2b. a time shift stopped at the edge of the switch-off jump: refit from its other side
        for w in across_switch_off(space, u_best, record):
            u, c2, _, nfev = obj.local_fit(w, record.n_samples, coarse, settings.max_nfev, settings.fd_step)
            logger.debug("across the switch-off jump: chi2 %.4g -> %.4g", best_chi2, c2)
            if c2 < best_chi2:
                best_chi2, u_best = c2, u
                stages = [
                    *stages,
                    {
                        "start": "across",
                        "horizon": record.n_samples,
                        "chi2": c2,
                        "step": settings.search_step,
                        "nfev": nfev,
                    },
                ]

        # 3. polish at the final integrator step, full horizon; small difference steps near the optimum
        if polish:
            u_best, c2, _, nfev = obj.local_fit(
                u_best, record.n_samples, final, settings.polish_nfev, 3 * settings.fd_step_uncertainty
            )
            stages.append(
                {"start": "polish", "horizon": record.n_samples, "chi2": c2, "step": settings.final_step, "nfev": nfev}
            )

    case = space.case(u_best)
    ch_all, t_e, st = run_cases([space.case(u_best, obj.taken)], final, record.grid)
    obj.n_simulations += 1
    if st[0] != 0:
        raise CalibrationError(f"the calibrated parameters cannot be simulated (kernel status {int(st[0])})")
    resid = ch_all[0, obj.rows] - obj.data
    chi2_ch: dict[str, float] = {}
    for j, n in enumerate(obj.names):
        own = obj.own_chi2(n, ch_all[0, obj.rows[j]], u_best)
        chi2_ch[n] = float(sigma.channel(n).chi2(resid[j])) if own is None else own
    chi2 = float(sum(chi2_ch.values()))
    level = level_for_interval(record.sample_interval, record.n_samples)
    lowfreq = {n: sigma.channel(n).lowfreq_ratio(resid[j], level) for j, n in enumerate(obj.names)}
    n_data = int(resid.size)
    unc: dict[str, float] = {}
    if d > 0:
        J = obj.jacobian(u_best, record.n_samples, final, settings.fd_step_uncertainty, central=True)
        unc = _uncertainties(space, u_best, J, chi2, n_data)
    res = CalibrationResult(
        values=space.values(u_best),
        uncertainties=unc,
        fixed=fixed,
        chi2=chi2,
        chi2_per_channel=chi2_ch,
        n_data=n_data,
        noise=noise,
        sigma=sigma,
        effect="+".join(space.effect_names) if space.effects else None,
        n_simulations=obj.n_simulations,
        seconds=time.perf_counter() - t0,
        stages=stages,
        case=case,
        simulation=ch_all[0],
        event_time=float(t_e[0]),
        step=final.max_step,
        lowfreq_ratio=lowfreq,
        grid=record.grid,
        starts=global_starts,
        drive=space.drive,
    )
    logger.info(
        "calibration%s: %s chi2/n %.3f (%d simulations, %.1f s)",
        f" with {res.effect}" if res.effect else "",
        ", ".join(f"{k}={v:.5g}" for k, v in res.values.items()),
        res.reduced_chi2,
        res.n_simulations,
        res.seconds,
    )
    return res


def unit_covariance(J: np.ndarray) -> np.ndarray:
    """Gauss-Newton covariance ``pinv(J^T J)`` of the fitted parameters, in unit-box coordinates.

    Parameters
    ----------
    J : ndarray, shape (n_res, d)
        Jacobian of the whitened residuals with respect to the unit-box coordinates.

    Returns
    -------
    ndarray, shape (d, d)
        The covariance for unit noise variance (scale it by the fit's chi2/dof when that exceeds
        one); all NaN when the pseudo-inverse fails.
    """
    d = J.shape[1]
    try:
        return np.asarray(np.linalg.pinv(J.T @ J))
    except np.linalg.LinAlgError:
        return np.full((d, d), np.nan)


def correlation(cov: np.ndarray) -> np.ndarray:
    """Correlation matrix of a covariance matrix (NaN rows and columns where a variance is not positive)."""
    sd = np.sqrt(np.where(np.diag(cov) > 0, np.diag(cov), np.nan))
    return np.asarray(cov / np.outer(sd, sd))


def _uncertainties(space: ModelSpace, u: np.ndarray, J: np.ndarray, chi2: float, n: int) -> dict[str, float]:
    """One-sigma uncertainties from the Jacobian J (n_res, d) in unit-box coordinates."""
    d = space.dim
    scale = max(1.0, chi2 / max(n - d, 1))
    cov_u = unit_covariance(J) * scale
    out = {}
    for i, p in enumerate(space.params):
        su = math.sqrt(max(cov_u[i, i], 0.0)) if np.isfinite(cov_u[i, i]) else math.nan
        out[p.name] = abs(p.dvalue_du(float(u[i]))) * su
    return out


def sobol(d: int, *, scramble: bool, seed: int | None) -> Any:
    """scipy's Sobol sequence in ``d`` dimensions (``scipy.stats.qmc.Sobol``), for the calibration's global starts and
    the plausibility envelopes (scipy.stats is imported here, not at the top: it adds about 1.5 s to a process
    start)."""
    from scipy.stats import qmc

    return qmc.Sobol(d, scramble=scramble, seed=seed)
