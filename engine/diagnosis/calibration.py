"""Noise estimation and calibration of the uncertain plant parameters against a record.

The calibration fits the parameters that are uncertain in practice (the
backlash width K, the motor-side inertia J1, the absorber viscosity c, and
the absorber discontinuity c1 unless the record's conditions fix it), and
optionally the scalar value of one unmodelled effect, to a backlash-test
record. The cost is the noise-normalised sum of squared residuals::

    chi2(theta) = sum_j sum_k ((sim_j[k](theta) - rec_j[k]) / sigma_j)^2

over the channels j present in the record and the samples k, where sigma_j
is the channel's white-noise level estimated from the record (see
:func:`estimate_noise`).

Why not plain least squares
---------------------------
``docs/INVERSE-PROBLEM.md`` (shared spec) shows that the cost basin around
the truth is narrow (about +-3 % in K, +-1.5 % in J1): outside it the
sequence of clutch impacts changes and the late part of the record no longer
points towards the optimum. The fit therefore proceeds in two stages:

1. **Global search**: a scrambled Sobol sample of the parameter box is
   simulated in one batch (coarse integrator step) and scored on the *early*
   window of the record only (pre-event samples and the first 20 ms after the
   event), where the cost is smooth because no impact has happened yet.
2. **Continuation over the time horizon**: from the best few, mutually
   distinct, Sobol points, ``scipy.optimize.least_squares`` refines the fit
   on a horizon that grows (20, 50, 100, 200 ms after the event); each stage
   starts from the previous stage's optimum, which keeps it inside the
   narrowing basin. The best full-horizon fit is polished with a finer
   integrator step and gives the uncertainties (Gauss-Newton covariance).

Finite-difference Jacobians are computed as one batch of simulations (the
simulator is parallel over cases), not column by column.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pywt
from scipy.optimize import least_squares
from scipy.stats import qmc

from engine.constants import CHANNEL_WAVELETS, CHANNELS, N_SAMPLES
from engine.parallel import raise_if_cancelled, single_threaded_blas
from engine.records import Record
from engine.simulation import Case, Effect, PlantParameters, SolverSettings, run_cases

logger = logging.getLogger(__name__)

__all__ = [
    "WIDTH_SETTINGS",
    "CalibrationError",
    "CalibrationResult",
    "CalibrationSettings",
    "FreeParameter",
    "ModelSpace",
    "Objective",
    "WidthEstimate",
    "calibrate",
    "default_space",
    "estimate_noise",
    "estimate_width",
]

#: Default search box of the calibrated plant parameters: (low, high, unit).
#: Slightly wider than the validation ranges (K in [0.0025, 0.01] m, J1 in
#: [0.75, 0.93] kg m^2, c in [0.8, 1.5]) so that optima near an edge stay interior.
DEFAULT_BOUNDS: dict[str, tuple[float, float, str]] = {
    "K": (0.0022, 0.0105, "m"),
    "J1": (0.72, 0.96, "kg m^2"),
    "c": (0.75, 1.6, "pu"),
    "c1": (0.0, 0.6, "pu"),
}
#: Plant parameters a record's conditions may fix (MODEL.md; others are nominal).
CALIBRATED: tuple[str, ...] = ("K", "J1", "c", "c1")
#: Effects whose value is best searched on a logarithmic scale.
LOG_SCALED_EFFECTS: frozenset[str] = frozenset({"contact_stiffness", "contact_damping", "sensor_lowpass"})
#: Relative floor of the noise level used as a weight, as a fraction of the channel's RMS
#: (60 dB SNR); keeps noiseless (simulated) records from giving infinite weights.
NOISE_FLOOR_REL: float = 1e-3
#: Residual used for a case the simulator could not run (no event, divergence), per sample.
FAILED_RESIDUAL: float = 1e3


class CalibrationError(RuntimeError):
    """Raised when the calibration cannot produce a fit (e.g. no parameter set can be simulated)."""


# --------------------------------------------------------------------------- noise
def estimate_noise(record: Record) -> dict[str, float]:
    """White-noise standard deviation of every channel of a record.

    Uses the finest detail level (cD1, 1024 coefficients) of the channel's own
    wavelet (MODEL.md section 3, periodization DWT). A first, robust estimate
    is the median absolute deviation, ``sigma0 = median(|cD1|) / 0.6745``
    (Donoho & Johnstone); the result is the RMS of the coefficients within
    ``4 sigma0`` (corrected for the truncation), which keeps the median's
    immunity to the few coefficients at impacts and at the event's torque step
    but has about 1.6 times less scatter (relative standard error about 2.2 %
    instead of 3.6 % for 1024 coefficients). With 5-6 vanishing moments the
    smooth part of the record hardly reaches the finest level.

    Parameters
    ----------
    record : Record
        Any subset of channels.

    Returns
    -------
    dict of str to float
        Noise standard deviation per channel, in the channel's unit.
    """
    out: dict[str, float] = {}
    for name, x in record.channels.items():
        _, cd1 = pywt.dwt(np.array(x, dtype=float), CHANNEL_WAVELETS[name], mode="periodization")
        s0 = float(np.median(np.abs(cd1)) / 0.6744897501960817)
        if s0 > 0:
            kept = cd1[np.abs(cd1) <= _CLIP * s0]
            s0 = float(np.sqrt(np.mean(kept**2) / _CLIP_VARIANCE)) if kept.size else s0
        out[name] = s0
    return out


#: Clipping of the noise estimate [sigma] and the variance of a unit normal truncated there.
_CLIP = 4.0
_CLIP_VARIANCE = 1.0 - 2.0 * _CLIP * math.exp(-(_CLIP**2) / 2.0) / math.sqrt(2.0 * math.pi) / math.erf(
    _CLIP / math.sqrt(2.0)
)


def noise_weights(record: Record, noise: Mapping[str, float]) -> dict[str, float]:
    """Standard deviation used to normalise each channel's residual.

    ``max(noise, NOISE_FLOOR_REL * rms(channel))`` in the channel's unit.
    """
    out = {}
    for name, x in record.channels.items():
        rms = float(np.sqrt(np.mean(np.square(x))))
        floor = NOISE_FLOOR_REL * rms if rms > 0 else 1e-12
        out[name] = max(float(noise[name]), floor, 1e-12)
    return out


# --------------------------------------------------------------------------- parameter space
@dataclass(frozen=True)
class FreeParameter:
    """One fitted parameter and its search interval.

    Parameters
    ----------
    name : str
        Plant field (``K``, ``J1``, ``c``, ``c1``) or effect name.
    lo, hi : float
        Search interval, in the parameter's unit.
    unit : str
        Unit of the value.
    log : bool
        Search on a logarithmic scale (needs ``lo > 0``).
    """

    name: str
    lo: float
    hi: float
    unit: str = ""
    log: bool = False

    def value(self, u: np.ndarray | float) -> np.ndarray | float:
        """Map unit-box coordinate(s) u in [0, 1] to value(s)."""
        u = np.clip(u, 0.0, 1.0)
        if self.log:
            return self.lo * (self.hi / self.lo) ** u
        return self.lo + (self.hi - self.lo) * u

    def unit_coord(self, v: float) -> float:
        """Inverse of :meth:`value`."""
        v = min(max(float(v), self.lo), self.hi)
        if self.log:
            return math.log(v / self.lo) / math.log(self.hi / self.lo)
        return (v - self.lo) / (self.hi - self.lo)

    def dvalue_du(self, u: float) -> float:
        """Derivative of :meth:`value` with respect to u (for uncertainties)."""
        if self.log:
            return float(self.value(u)) * math.log(self.hi / self.lo)
        return self.hi - self.lo


@dataclass(frozen=True)
class ModelSpace:
    """The family of cases a calibration searches.

    Parameters
    ----------
    base : Case
        The plant with every known condition applied (fixed parameters).
    params : tuple of FreeParameter
        Free plant parameters, then (optionally) the effect's value last.
    effect : Effect or None
        The unmodelled effect whose value is the last free parameter.
    """

    base: Case
    params: tuple[FreeParameter, ...]
    effect: Effect | None = None

    @property
    def dim(self) -> int:
        return len(self.params)

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.params]

    def values(self, u: np.ndarray) -> dict[str, float]:
        """Parameter values at unit-box point u."""
        return {p.name: float(p.value(ui)) for p, ui in zip(self.params, u)}

    def unit(self, values: Mapping[str, float]) -> np.ndarray:
        """Unit-box point of parameter values (missing names at the box centre)."""
        return np.array([p.unit_coord(values[p.name]) if p.name in values else 0.5 for p in self.params])

    def case(self, u: np.ndarray) -> Case:
        """The simulation case at unit-box point u."""
        vals = self.values(u)
        plant_changes = {k: v for k, v in vals.items() if self.effect is None or k != self.effect.name}
        case = Case(self.base.plant.replace(**plant_changes), self.base.sensors)
        if self.effect is not None:
            case = self.effect.apply(case, vals[self.effect.name])
        return case

    def with_effect(self, effect: Effect) -> ModelSpace:
        """This space plus one effect's value as an extra free parameter."""
        lo, hi = effect.bounds
        log = effect.name in LOG_SCALED_EFFECTS and lo > 0
        return ModelSpace(self.base, self.params + (FreeParameter(effect.name, lo, hi, effect.unit, log),), effect)


def default_space(record: Record, bounds: Mapping[str, tuple[float, float, str]] | None = None) -> ModelSpace:
    """Parameter space of a record: K, J1, c, c1 are free unless its conditions fix them.

    Parameters
    ----------
    record : Record
        Its ``conditions`` may fix ``K`` [m], ``J1`` [kg m^2], ``c`` [pu], ``c1`` [pu]
        (and any other ``PlantParameters`` field, which is then applied as known).
    bounds : mapping, optional
        Search box per free parameter, ``name -> (low, high, unit)``;
        defaults to :data:`DEFAULT_BOUNDS`.
    """
    bounds = dict(DEFAULT_BOUNDS if bounds is None else bounds)
    plant_fields = set(PlantParameters.__dataclass_fields__)
    known = {k: v for k, v in record.conditions.items() if k in plant_fields}
    base = Case(PlantParameters(**known))
    free = tuple(
        FreeParameter(name, bounds[name][0], bounds[name][1], bounds[name][2])
        for name in CALIBRATED
        if name not in known
    )
    return ModelSpace(base, free)


# --------------------------------------------------------------------------- objective
class Objective:
    """Noise-normalised residual of a record against simulations of a model space.

    Parameters
    ----------
    record : Record
        The measured record.
    space : ModelSpace
        What is fitted.
    sigma : mapping of str to float
        Residual normalisation per channel (see :func:`noise_weights`).
    """

    def __init__(self, record: Record, space: ModelSpace, sigma: Mapping[str, float]):
        self.record = record
        self.space = space
        self.names = list(record.channels)
        self.rows = [CHANNELS.index(n) for n in self.names]
        self.data = np.stack([record.channels[n] for n in self.names])
        self.sigma = np.array([sigma[n] for n in self.names])
        self.n_simulations = 0
        self._cache: dict[tuple, np.ndarray] = {}

    def simulate(self, U: np.ndarray, solver: SolverSettings) -> tuple[np.ndarray, np.ndarray]:
        """Simulate unit-box points U (m, d): the record's channels (m, n_ch, 2048) and ok flags (m,)."""
        raise_if_cancelled()  # a fit made redundant on another thread stops here
        U = np.atleast_2d(np.asarray(U, dtype=float))
        keys = [(solver.max_step, tuple(np.round(u, 14))) for u in U]
        todo = [i for i, k in enumerate(keys) if k not in self._cache]
        if todo:
            cases = [self.space.case(U[i]) for i in todo]
            ch, _, status = run_cases(cases, solver)
            self.n_simulations += len(todo)
            for j, i in enumerate(todo):
                sim = ch[j, self.rows] if status[j] == 0 else None
                if sim is not None and not np.all(np.isfinite(sim)):
                    sim = None
                self._cache[keys[i]] = sim
            if len(self._cache) > 4096:
                for k in list(self._cache)[:2048]:
                    del self._cache[k]
        sims = [self._cache[k] for k in keys]
        ok = np.array([s is not None for s in sims])
        out = np.stack([s if s is not None else np.full((len(self.rows), N_SAMPLES), np.nan) for s in sims])
        return out, ok

    def residuals(self, U: np.ndarray, horizon: int, solver: SolverSettings) -> np.ndarray:
        """Normalised residuals (m, n_ch * horizon) of the first ``horizon`` samples."""
        sims, ok = self.simulate(U, solver)
        r = (sims[:, :, :horizon] - self.data[None, :, :horizon]) / self.sigma[None, :, None]
        r[~ok] = FAILED_RESIDUAL
        return r.reshape(r.shape[0], -1)

    def chi2(self, U: np.ndarray, horizons: Sequence[int], solver: SolverSettings) -> np.ndarray:
        """chi2 (m, len(horizons)) of points U on each horizon (inf where the simulation failed)."""
        sims, ok = self.simulate(U, solver)
        r2 = np.square((sims - self.data[None]) / self.sigma[None, :, None]).sum(axis=1)  # (m, 2048)
        cum = np.cumsum(r2, axis=1)
        out = np.stack([cum[:, h - 1] for h in horizons], axis=1)
        out[~ok] = np.inf
        return out

    def jacobian(
        self,
        u: np.ndarray,
        horizon: int,
        solver: SolverSettings,
        fd_step: float,
        r0: np.ndarray | None = None,
        central: bool = False,
    ) -> np.ndarray:
        """Finite-difference Jacobian (n_res, d) of the residuals in unit-box coordinates, one batch of simulations."""
        d = self.space.dim
        if central:
            lo = np.maximum(u - fd_step, 0.0)
            hi = np.minimum(u + fd_step, 1.0)
            U = np.vstack([u[None, :] + np.diag(hi - u), u[None, :] + np.diag(lo - u)])
            R = self.residuals(U, horizon, solver)
            return ((R[:d] - R[d:]) / (hi - lo)[:, None]).T
        if r0 is None:
            r0 = self.residuals(u[None], horizon, solver)[0]
        steps = np.where(u + fd_step <= 1.0, fd_step, -fd_step)
        R = self.residuals(u[None, :] + np.diag(steps), horizon, solver)
        return ((R - r0[None]) / steps[:, None]).T

    def local_fit(
        self, u0: np.ndarray, horizon: int, solver: SolverSettings, max_nfev: int, fd_step: float
    ) -> tuple[np.ndarray, float, np.ndarray, int]:
        """Bounded least-squares refinement on one horizon.

        Returns the optimum u, its chi2, the Jacobian (n_res, d) in unit-box
        coordinates and the number of residual evaluations.
        """
        d = self.space.dim
        last: dict[str, np.ndarray] = {}

        def fun(u: np.ndarray) -> np.ndarray:
            r = self.residuals(u[None], horizon, solver)[0]
            last["u"], last["r"] = u.copy(), r
            return r

        def jac(u: np.ndarray) -> np.ndarray:
            r0 = last["r"] if "u" in last and np.array_equal(last["u"], u) else fun(u)
            return self.jacobian(u, horizon, solver, fd_step, r0)

        res = least_squares(
            fun,
            np.clip(u0, 0.0, 1.0),
            jac=jac,
            bounds=(np.zeros(d), np.ones(d)),
            method="trf",
            x_scale=np.full(d, 0.05),
            max_nfev=max_nfev,
            xtol=1e-6,
            ftol=1e-6,
        )
        return res.x, float(2.0 * res.cost), res.jac, int(res.nfev)


# --------------------------------------------------------------------------- calibration
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
        Finite-difference step of the optimiser's Jacobian, in unit-box coordinates.
    fd_step_uncertainty : float
        Central-difference step of the Jacobian behind the uncertainties (unit box).
        The cost is very sharp at the optimum (chi2 rises by thousands for a
        0.02 % change of K), so this must be much smaller than ``fd_step``.
    min_separation : float
        Smallest unit-box distance between two starting points.
    seed : int
        Seed of the Sobol scrambling.
    """

    n_global: int = 512
    n_starts: int = 4
    horizons_ms: tuple[float, ...] = (20.0, 50.0, 100.0, 200.0)
    search_step: float = 5e-5
    final_step: float = 2e-5
    max_nfev: int = 12
    polish_nfev: int = 30
    fd_step: float = 2e-3
    fd_step_uncertainty: float = 1e-4
    min_separation: float = 0.08
    seed: int = 0

    def horizons(self, record: Record) -> list[int]:
        """Horizons as sample counts from the start of the record."""
        hs = sorted(
            {
                min(N_SAMPLES, record.event_index + int(round(h * 1e-3 / record.sample_interval)))
                for h in self.horizons_ms
            }
        )
        if hs[-1] != N_SAMPLES:
            hs.append(N_SAMPLES)
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
        Noise-normalised sum of squared residuals over all channels and samples.
    chi2_per_channel : dict of str to float
        The same per channel.
    n_data : int
        Number of residuals (channels x samples).
    noise : dict of str to float
        Estimated white-noise standard deviation per channel (channel unit).
    sigma : dict of str to float
        Normalisation actually used (noise with a floor, see :func:`noise_weights`).
    effect : str or None
        Effect fitted together with the calibration, if any.
    n_simulations : int
        Simulations run.
    seconds : float
        Wall time [s].
    stages : list of dict
        Trace of the best start: kind ("global", "seed", "polish"), horizon
        [samples], chi2, integrator step [s] and residual evaluations.
    case : Case
        The calibrated simulation case (effect applied).
    simulation : ndarray, shape (5, 2048)
        Its five channels.
    event_time : float
        Its event time t_e [s].
    step : float
        Integrator step of the reported fit [s].
    lowfreq_ratio : dict of str to float
        Per channel, mean squared wavelet coefficient of the normalised residual
        below 625 Hz (levels D4..D10 and A10, 256 coefficients) over that of
        levels D1-D2 (1250-5000 Hz, 1536 coefficients): about 1 for a white
        residual whatever the noise estimate's error; a structured (mostly
        low-frequency) gap raises it. Reported as a diagnostic.
    """

    values: dict[str, float]
    uncertainties: dict[str, float]
    fixed: dict[str, float]
    chi2: float
    chi2_per_channel: dict[str, float]
    n_data: int
    noise: dict[str, float]
    sigma: dict[str, float]
    effect: str | None
    n_simulations: int
    seconds: float
    stages: list[dict] = field(default_factory=list)
    case: Case | None = field(default=None, repr=False)
    simulation: np.ndarray | None = field(default=None, repr=False)
    event_time: float | None = None
    step: float = 2e-5
    lowfreq_ratio: dict[str, float] = field(default_factory=dict)

    @property
    def n_params(self) -> int:
        return len(self.values)

    @property
    def reduced_chi2(self) -> float:
        """chi2 per residual; about 1 when the model fits to the noise."""
        return self.chi2 / max(self.n_data, 1)

    @property
    def bic(self) -> float:
        """Bayesian information criterion chi2 + k ln(n) (Gaussian noise of known sigma)."""
        return self.chi2 + self.n_params * math.log(max(self.n_data, 2))

    def to_dict(self) -> dict:
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
            "lowfreq_ratio": dict(self.lowfreq_ratio),
            "n_simulations": self.n_simulations,
            "seconds": self.seconds,
        }

    def simulated_record(self, template: Record) -> Record:
        """The calibrated simulation in the record format (all five channels).

        Its conditions carry the calibrated J1, c, c1 and K.
        """
        if self.case is None or self.simulation is None:
            raise CalibrationError("this calibration result holds no simulation")
        p = self.case.plant
        return Record(
            channels={n: self.simulation[j] for j, n in enumerate(CHANNELS)},
            sample_interval=template.sample_interval,
            event_index=template.event_index,
            conditions={"J1": p.J1, "c": p.c, "c1": p.c1, "K": p.K},
            event_time=self.event_time,
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


def calibrate(
    record: Record,
    space: ModelSpace | None = None,
    settings: CalibrationSettings = CalibrationSettings(),
    noise: Mapping[str, float] | None = None,
    seeds: Sequence[Mapping[str, float]] = (),
    polish: bool = True,
) -> CalibrationResult:
    """Fit the uncertain parameters (and optionally one effect's value) to a record.

    Parameters
    ----------
    record : Record
        Measured record; any subset of channels.
    space : ModelSpace, optional
        What to fit; default :func:`default_space` (K, J1, c, c1 less those fixed
        by ``record.conditions``). Use ``space.with_effect(effect)`` to fit an
        effect's value too.
    settings : CalibrationSettings
        Search settings; ``n_global = 0`` skips the global search (then
        ``seeds`` must be given).
    noise : mapping of str to float, optional
        Noise standard deviation per channel (channel unit); estimated with
        :func:`estimate_noise` when omitted.
    seeds : sequence of mappings
        Extra starting points (parameter name -> value, e.g. an earlier
        calibration). They are refined on the full horizon directly (no
        continuation), next to the continuation from the global search.
    polish : bool
        Refine the best fit with ``settings.final_step`` and report chi2 and
        uncertainties at that step; otherwise everything is at ``search_step``.

    Returns
    -------
    CalibrationResult

    Raises
    ------
    CalibrationError
        When no point of the search box (nor any seed) can be simulated, or the
        fitted parameters cannot be simulated.
    """
    with single_threaded_blas():
        return _calibrate(record, space, settings, noise, seeds, polish)


def _calibrate(
    record: Record,
    space: ModelSpace | None,
    settings: CalibrationSettings,
    noise: Mapping[str, float] | None,
    seeds: Sequence[Mapping[str, float]],
    polish: bool,
) -> CalibrationResult:
    t0 = time.perf_counter()
    space = default_space(record) if space is None else space
    noise = estimate_noise(record) if noise is None else dict(noise)
    sigma = noise_weights(record, noise)
    obj = Objective(record, space, sigma)
    horizons = settings.horizons(record)
    coarse = SolverSettings(max_step=settings.search_step)
    final = SolverSettings(max_step=settings.final_step) if polish else coarse
    d = space.dim
    fixed = {k: float(getattr(space.base.plant, k)) for k in CALIBRATED if k not in space.names}
    stages: list[dict] = []
    u_best = np.zeros(0)

    if d > 0:
        # 1. global search on the early window (Sobol points, one batch)
        starts: list[tuple[np.ndarray, str]] = []
        if settings.n_global > 0:
            m = 1 << max(3, math.ceil(math.log2(settings.n_global)))
            U = qmc.Sobol(d, scramble=True, seed=settings.seed).random(m)
            C = obj.chi2(U, horizons[:1], coarse)[:, 0]
            starts += [(u, "global") for u in _pick_starts(U, C, settings.n_starts, settings.min_separation)]
            logger.debug("global search: %d points, best early chi2 %.4g", len(U), np.min(C))
        # seeds (already close to a full-horizon optimum) skip the continuation
        starts += [(space.unit(s), "seed") for s in seeds]
        if not starts:
            raise CalibrationError(
                "no parameter set of the search box could be simulated; check the record's conditions"
            )

        # 2. continuation over the horizon, from every start
        best_chi2 = np.inf
        for s, kind in starts:
            u = s
            trace = []
            for h in horizons if kind == "global" else [N_SAMPLES]:
                u, c2, _, nfev = obj.local_fit(u, h, coarse, settings.max_nfev, settings.fd_step)
                trace.append({"start": kind, "horizon": h, "chi2": c2, "step": settings.search_step, "nfev": nfev})
            logger.debug("%s start %s -> %s chi2 %.4g", kind, np.round(s, 3), np.round(u, 3), trace[-1]["chi2"])
            if trace[-1]["chi2"] < best_chi2:
                best_chi2, u_best, stages = trace[-1]["chi2"], u, trace
        if not np.isfinite(best_chi2):
            raise CalibrationError("no start of the calibration reached a parameter set that can be simulated")

        # 3. polish at the final integrator step, full horizon; small difference steps near the optimum
        if polish:
            u_best, c2, _, nfev = obj.local_fit(
                u_best, N_SAMPLES, final, settings.polish_nfev, 3 * settings.fd_step_uncertainty
            )
            stages.append(
                {"start": "polish", "horizon": N_SAMPLES, "chi2": c2, "step": settings.final_step, "nfev": nfev}
            )

    case = space.case(u_best)
    ch_all, t_e, st = run_cases([case], final)
    obj.n_simulations += 1
    if st[0] != 0:
        raise CalibrationError(f"the calibrated parameters cannot be simulated (kernel status {int(st[0])})")
    r = (ch_all[0, obj.rows] - obj.data) / obj.sigma[:, None]
    chi2_ch = {n: float(np.sum(r[j] ** 2)) for j, n in enumerate(obj.names)}
    chi2 = float(sum(chi2_ch.values()))
    lowfreq = {n: lowfreq_ratio(r[j], CHANNEL_WAVELETS[n]) for j, n in enumerate(obj.names)}
    n_data = int(r.size)
    unc: dict[str, float] = {}
    if d > 0:
        J = obj.jacobian(u_best, N_SAMPLES, final, settings.fd_step_uncertainty, central=True)
        unc = _uncertainties(space, u_best, J, chi2, n_data)
    res = CalibrationResult(
        values=space.values(u_best),
        uncertainties=unc,
        fixed=fixed,
        chi2=chi2,
        chi2_per_channel=chi2_ch,
        n_data=n_data,
        noise=noise,
        sigma=dict(sigma),
        effect=space.effect.name if space.effect else None,
        n_simulations=obj.n_simulations,
        seconds=time.perf_counter() - t0,
        stages=stages,
        case=case,
        simulation=ch_all[0],
        event_time=float(t_e[0]),
        step=final.max_step,
        lowfreq_ratio=lowfreq,
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


def lowfreq_ratio(r: np.ndarray, wavelet: str, level: int = 10) -> float:
    """Mean squared coefficient of levels D4..D<level>, A<level> over that of D1, D2 (periodization DWT)."""
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"Level value of \d+ is too high", category=UserWarning)
        coeffs = pywt.wavedec(np.array(r, dtype=float), wavelet, mode="periodization", level=level)
    low = np.concatenate(coeffs[: level - 2])
    high = np.concatenate(coeffs[-2:])
    return float(np.mean(low**2) / max(np.mean(high**2), 1e-300))


def _uncertainties(space: ModelSpace, u: np.ndarray, J: np.ndarray, chi2: float, n: int) -> dict[str, float]:
    """One-sigma uncertainties from the Jacobian J (n_res, d) in unit-box coordinates."""
    d = space.dim
    scale = max(1.0, chi2 / max(n - d, 1))
    try:
        cov_u = np.linalg.pinv(J.T @ J) * scale
    except np.linalg.LinAlgError:
        cov_u = np.full((d, d), np.nan)
    out = {}
    for i, p in enumerate(space.params):
        su = math.sqrt(max(cov_u[i, i], 0.0)) if np.isfinite(cov_u[i, i]) else math.nan
        out[p.name] = abs(p.dvalue_du(float(u[i]))) * su
    return out


#: Search settings of the continuous width estimate (two or three free parameters): the ones
#: README's "calibrated K as a continuous width" table was measured with.
WIDTH_SETTINGS = CalibrationSettings(n_global=128, n_starts=2)


@dataclass(frozen=True)
class WidthEstimate:
    """The calibrated K offered as a continuous backlash-width estimate.

    Attributes
    ----------
    K : float
        Estimated backlash zone width [m].
    sigma_K : float
        One standard deviation of K [m] (Gauss-Newton, measurement noise only;
        too small on a1 under noise, see docs/diagnosis.md section 8).
    calibration : CalibrationResult
        The fit behind it (every fitted parameter, chi2, noise).
    """

    K: float
    sigma_K: float
    calibration: CalibrationResult = field(repr=False)

    def to_dict(self) -> dict:
        """JSON-ready summary (the calibration without arrays)."""
        return {"K": self.K, "sigma_K": self.sigma_K, "calibration": self.calibration.to_dict()}


def estimate_width(record: Record, settings: CalibrationSettings = WIDTH_SETTINGS) -> WidthEstimate:
    """Continuous backlash-width estimate: the calibrated K and its one-sigma uncertainty.

    The record's other conditions (J1, c, c1) are used as known; a ``K``
    condition is ignored (K is what is estimated). Works on any subset of
    channels, a single channel included.

    Parameters
    ----------
    record : Record
        The measured record.
    settings : CalibrationSettings
        Search settings (default :data:`WIDTH_SETTINGS`).

    Returns
    -------
    WidthEstimate

    Raises
    ------
    CalibrationError
        When the record cannot be fitted.
    """
    if "K" in record.conditions:
        record = Record(
            record.channels,
            record.sample_interval,
            record.event_index,
            {k: v for k, v in record.conditions.items() if k != "K"},
            record.event_time,
        )
    cal = calibrate(record, settings=settings)
    return WidthEstimate(cal.values["K"], cal.uncertainties["K"], cal)
