"""The backlash width of a plant of the interface as a continuous, fitted parameter, and whether it is identifiable.

For a plant whose catalogue holds a play (``backlash``, a width in metres; the BRFD), the width
is fitted jointly with the plant's calibrated parameters, on one record or on several records of
the same device at once (one width shared, the calibrated parameters per record: a band tension
or a temperature may differ between tests, the play of the linkage does not).

Method
------
- **Fit**: bounded least squares of the width and every record's calibrated parameters on the
  channel-normalised residual of :class:`~engine.diagnosis.plant_gap.PlantObjective` (stacked
  over the records), from the best of a scan of the width (:data:`N_PROFILE` values) with each
  record's calibration refitted at it.
- **Interval**: the profile of the cost along the width (every record's calibration refitted at
  each value). With ``s2`` the residual variance per degree of freedom and ``tau`` the residual's
  integrated autocorrelation time (:func:`~engine.diagnosis.plant_gap.correlation_time`: the
  residual is model error, correlated in time), the 95 % interval holds the widths whose cost is
  within ``chi2_1(0.95) s2 tau`` of the minimum (a likelihood-ratio interval for a correlated
  Gaussian residual; it does not need the cost to be quadratic, which a play's cost is not).
- **Correlation** of the width with every other fitted parameter, from the Gauss-Newton
  covariance at the optimum.
- **Identifiable** when the profile interval lies inside the searched range (neither reaching zero
  width, where the data cannot tell a play from none, nor the largest width) and is no wider than
  :data:`MAX_INTERVAL` and the width's correlation with no other parameter exceeds
  :data:`MAX_CORRELATION` in magnitude; otherwise the answer says which of these failed, and the
  width is reported as not identifiable rather than as a number.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import chdtri  # the chi-square quantile (scipy.stats costs a service start about 1 s)

from engine.diagnosis.plant_gap import PlantObjective, calibrate, correlation_time, fit, solve_unit_box
from engine.plants.base import FreeParameter, Plant, free_parameters

__all__ = ["MAX_CORRELATION", "MAX_INTERVAL", "N_PROFILE", "WidthFit", "fit_width"]

logger = logging.getLogger(__name__)

#: Values of the width in its profile (and in the scan that starts the fit).
N_PROFILE: int = 25
#: Values per coarse profile step in the refined profile around the interval.
N_REFINE: int = 5
#: Widest 95 % interval [m] of a width reported as identifiable (a third of the BRFD catalogue's
#: 12 mm range: a wider interval says little about the play).
MAX_INTERVAL: float = 0.004
#: Largest magnitude of the width's correlation with another fitted parameter for the width to be
#: reported as identifiable (beyond it the two trade off along a ridge: a soft spring taking up the play).
MAX_CORRELATION: float = 0.95
#: Confidence of the profile interval.
CONFIDENCE: float = 0.95


@dataclass(frozen=True)
class WidthFit:
    """A width fitted on one or several records of a plant.

    Attributes
    ----------
    K : float
        Fitted width [m].
    sigma_K : float
        Its linearised standard deviation [m] (scaled for the residual's correlation time).
    interval : tuple of float
        95 % profile interval [m].
    identifiable : bool
        Whether the width is determined by the data (module docstring).
    reasons : list of str
        Why not, when it is not (empty otherwise).
    records : list of str
        The records fitted.
    fitted : list of dict
        Per record, the calibrated parameters fitted with the width (name -> value, plant units).
    correlation : dict of str to float
        Correlation of the width with every other fitted parameter (``name`` for one record,
        ``name[i]`` with several).
    profile : list of tuple of float
        ``(width [m], cost)`` along the profile.
    relative_error : list of dict
        Per record, the relative error [%] per channel with the width and without (width 0).
    tau : float
        Integrated autocorrelation time of the residual [samples].
    """

    K: float
    sigma_K: float
    interval: tuple[float, float]
    identifiable: bool
    reasons: list[str]
    records: list[str]
    fitted: list[dict[str, float]]
    correlation: dict[str, float]
    profile: list[tuple[float, float]]
    relative_error: list[dict[str, dict[str, float]]] = field(default_factory=list)
    tau: float = 1.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (``continuous`` of ``backlash identify --plant``)."""
        return {
            "K": self.K if self.identifiable else None,
            "sigma_K": self.sigma_K if self.identifiable else None,
            "interval_95": list(self.interval),
            "identifiable": self.identifiable,
            "reasons": self.reasons,
            "best_fit_K": self.K,
            "records": self.records,
            "fitted": self.fitted,
            "correlation_with_K": self.correlation,
            "relative_error": self.relative_error,
            "residual_correlation_time": self.tau,
            "profile": [{"K": k, "cost": c} for k, c in self.profile],
        }


class _Joint:
    """Stacked residual of several records: one width, calibrated parameters per record."""

    def __init__(self, plant: Plant, records: Sequence[Any], width: str) -> None:
        self.plant = plant
        self.width = width
        self.objectives = [PlantObjective(plant, r) for r in records]
        self.free = [free_parameters(plant, r) for r in records]

    def values(self, i: int, K: float, cal: Sequence[float]) -> dict[str, float]:
        return {self.width: K, **{p.name: v for p, v in zip(self.free[i], cal, strict=True)}}

    def vector(self, K: float, cals: Sequence[Sequence[float]]) -> np.ndarray:
        return np.concatenate(
            [o.vector(self.values(i, K, c)) for i, (o, c) in enumerate(zip(self.objectives, cals, strict=True))]
        )


def _calibrated_at(plant: Plant, objective: PlantObjective, width: str, K: float, start: Mapping[str, float]) -> Any:
    """The record's calibration refitted with the width held at ``K``."""
    return fit(
        plant,
        objective.record,
        free_parameters(plant, objective.record),
        held={width: K},
        start=start,
        objective=objective,
    )


def fit_width(plant: Plant, records: Sequence[Any], width: str = "backlash") -> WidthFit:
    """Fit the width ``width`` (a catalogue effect in metres) on ``records`` (module docstring).

    Raises
    ------
    KeyError
        When the plant's catalogue has no effect ``width``.
    ValueError
        For no records.
    RuntimeError
        When the solver fails.
    """
    if width not in plant.catalogue:
        raise KeyError(f"plant {plant.name!r} has no effect {width!r} in its catalogue")
    if not records:
        raise ValueError("give at least one record")
    effect = plant.catalogue[width]
    q = effect.as_parameter()
    joint = _Joint(plant, records, width)
    cals = [calibrate(plant, o.record, objective=o).values for o in joint.objectives]

    # profile: the calibration of every record refitted at each width
    grid = np.linspace(q.lo, q.hi, N_PROFILE)
    profile: list[tuple[float, float]] = []
    starts = [dict(c) for c in cals]
    for K in grid:
        fits = [_calibrated_at(plant, o, width, float(K), s) for o, s in zip(joint.objectives, starts, strict=True)]
        starts = [f.values for f in fits]
        profile.append((float(K), float(sum(f.cost for f in fits))))
    k0 = int(np.argmin([c for _, c in profile]))
    K0 = profile[k0][0]
    start_cals = [_calibrated_at(plant, o, width, K0, c).values for o, c in zip(joint.objectives, cals, strict=True)]

    # joint least squares on the unit box (engine.diagnosis.plant_gap.solve_unit_box)
    params: list[FreeParameter] = [q, *(p for free in joint.free for p in free)]
    sizes = [len(f) for f in joint.free]

    def unpack(z: np.ndarray) -> tuple[float, list[list[float]]]:
        vals = [float(p.value(zi - 1.0)) for p, zi in zip(params, z, strict=True)]
        out, i = [], 1
        for n in sizes:
            out.append(vals[i : i + n])
            i += n
        return vals[0], out

    u0 = [q.unit_coord(K0)] + [p.unit_coord(start_cals[r][p.name]) for r, free in enumerate(joint.free) for p in free]
    res = solve_unit_box(lambda z: joint.vector(*unpack(z)), np.asarray(u0), plant.diff_step, [p.name for p in params])
    K, cal_values = unpack(res.x)
    cost = float(res.fun @ res.fun)
    if cost > profile[k0][1]:  # the profile's point is better: keep it (the cost of a play is rough)
        K, cal_values, cost = (
            K0,
            [[c[p.name] for p in free] for c, free in zip(start_cals, joint.free, strict=True)],
            profile[k0][1],
        )
        res_fun = joint.vector(K, cal_values)
    else:
        res_fun = res.fun
    n_per = [o.vector(joint.values(i, K, cal_values[i])).size for i, o in enumerate(joint.objectives)]
    channel_parts = []
    offset = 0
    for i, o in enumerate(joint.objectives):
        part = res_fun[offset : offset + n_per[i]]
        channel_parts += np.split(part, len(o.channels))
        offset += n_per[i]
    tau = correlation_time(channel_parts)
    dof = max(res_fun.size - len(params), 1)
    s2 = cost / dof * tau

    # covariance and correlations (unit box; the width's standard deviation in metres)
    jac = np.asarray(res.jac)
    cov_u = np.linalg.pinv(jac.T @ jac) * s2
    sd_u = np.sqrt(np.clip(np.diag(cov_u), 0.0, None))
    u_K = q.unit_coord(K)
    sigma_K = float(abs(q.dvalue_du(u_K)) * sd_u[0])
    names = [p.name if len(records) == 1 else f"{p.name}[{r}]" for r, free in enumerate(joint.free) for p in free]
    corr = {}
    for j, name in enumerate(names, start=1):
        denom = sd_u[0] * sd_u[j]
        corr[name] = float(cov_u[0, j] / denom) if denom > 0 else math.nan

    # profile interval: the coarse profile, refined at N_REFINE values per coarse step around it
    threshold = cost + float(chdtri(1, 1.0 - CONFIDENCE)) * s2
    step = (q.hi - q.lo) / (N_PROFILE - 1)
    inside = [k for k, c in profile if c <= threshold] + [K]
    lo, hi = max(q.lo, min(inside) - step), min(q.hi, max(inside) + step)
    fine = np.linspace(lo, hi, max(2, round((hi - lo) / step * N_REFINE) + 1))
    starts = [dict(zip((p.name for p in free), c, strict=True)) for free, c in zip(joint.free, cal_values, strict=True)]
    for Kf in fine:
        fits = [_calibrated_at(plant, o, width, float(Kf), s) for o, s in zip(joint.objectives, starts, strict=True)]
        profile.append((float(Kf), float(sum(f.cost for f in fits))))
    profile.sort()
    K_best, cost_best = min(profile, key=lambda kc: kc[1])
    if cost_best < cost:  # the cost of a play is rough: a profile point can beat the local solver
        fits = [_calibrated_at(plant, o, width, K_best, s) for o, s in zip(joint.objectives, starts, strict=True)]
        K, cost = K_best, float(sum(f.cost for f in fits))
        cal_values = [[f.values[p.name] for p in free] for f, free in zip(fits, joint.free, strict=True)]
    inside = [k for k, c in profile if c <= threshold] + [K]
    interval = (min(inside), max(inside))
    reasons = []
    if interval[1] >= q.hi - 0.5 * step:
        reasons.append(f"the 95 % interval reaches the largest width searched ({q.hi * 1e3:g} mm)")
    if interval[0] <= q.lo + 0.5 * step:
        reasons.append(
            f"the 95 % interval reaches zero width: the data do not tell a play from none "
            f"(at most {interval[1] * 1e3:.2f} mm)"
        )
    if interval[1] - interval[0] > MAX_INTERVAL:
        reasons.append(
            f"the profile is flat: widths from {interval[0] * 1e3:.2f} to {interval[1] * 1e3:.2f} mm fit within the "
            f"noise of the model error (interval wider than {MAX_INTERVAL * 1e3:g} mm)"
        )
    strong = {n: c for n, c in corr.items() if math.isfinite(c) and abs(c) > MAX_CORRELATION}
    if strong:
        reasons.append(
            "the width trades off against "
            + ", ".join(f"{n} (correlation {c:+.2f})" for n, c in strong.items())
            + ": the element's stiffness can take up the play"
        )
    errors = []
    for i, o in enumerate(joint.objectives):
        with_w = o.relative_errors(joint.values(i, K, cal_values[i]))
        without = o.relative_errors(cals[i])
        errors.append({"with_width": with_w, "without": without})
    fitted = [{p.name: v for p, v in zip(free, c, strict=True)} for free, c in zip(joint.free, cal_values, strict=True)]
    out = WidthFit(
        K=float(K),
        sigma_K=sigma_K,
        interval=(float(interval[0]), float(interval[1])),
        identifiable=not reasons,
        reasons=reasons,
        records=[getattr(r, "name", "") for r in records],
        fitted=fitted,
        correlation=corr,
        profile=profile,
        relative_error=errors,
        tau=float(tau),
    )
    logger.info(
        "width on %s: %.4g m +- %.2g (%s)",
        out.records,
        out.K,
        out.sigma_K,
        "identifiable" if out.identifiable else "; ".join(reasons),
    )
    return out
