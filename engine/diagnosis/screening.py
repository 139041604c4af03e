"""Screening of the effects to add to a fitted model: a profiled scan with a linearised refit.

Forward selection of a set of effects (:mod:`engine.diagnosis.sets`) asks, at the fit of a
smaller model (the best single effect, the best pair), which effect of the library to add.
Fitting every addition jointly with the calibration costs a few hundred simulations each;
this screen costs ``2 (n_scan + 1)`` per addition and ranks them so that only the most promising
are fitted.

Method
------
At the smaller model's fit ``u0`` (unit box of its space, ``d`` free parameters) take the
noise-normalised residual ``r0`` and its finite-difference Jacobian ``J`` (``d`` simulations,
the same whitening as the fit, :class:`~engine.diagnosis.objective.Objective`), and an
orthonormal basis ``Q`` of the columns of ``J``. For each addition ``e``, simulate the record
at ``u0`` with ``e`` at its neutral value and at ``n_scan`` values evenly spaced over its search
interval, each also one finite-difference step further in ``e``: the residual ``r_k`` and its
derivative ``j_k`` with respect to ``e``'s value at each point. A refit of the smaller model's
parameters to first order removes the part that ``J`` spans (``P = I - Q Q^T``), and a step of
``e``'s value to first order removes the part of what is left along ``P j_k``, so the screen's
statistic is

    chi2_e = min_k ( ||P r_k||^2 - (P j_k . P r_k)^2 / ||P j_k||^2 )        [noise variances]

the chi2 the addition reaches near its best point once the calibration has absorbed what it
can of its signature. At the neutral value this is the Lagrange-multiplier (score) test of the
addition; the scan adds the points a first-order step from neutral cannot reach (large values,
and effects that are not smooth at neutral, such as a Coulomb friction or a speed quantum).
Additions are ranked by ``chi2_e``, lowest first. Cost: ``2 (n_scan + 1)`` simulations per
addition and ``d + 1`` for the smaller model.

Where it fails: the refit is linear, so an addition whose benefit appears only once the
calibration moves far (into another basin of c, say) ranks lower than it deserves; the
scan has ``n_scan`` values, so a narrow basin of the value can fall between them. The set
search therefore fits the ``n_forward`` best-ranked additions, not only the first
(:class:`engine.diagnosis.sets.SetSettings`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import numpy as np

from engine.diagnosis.noise import NoiseModel, noise_weights
from engine.diagnosis.objective import Objective
from engine.diagnosis.space import ModelSpace, scan_grid
from engine.records import Record
from engine.simulation import Effect

logger = logging.getLogger(__name__)

__all__ = ["rank_additions"]


def rank_additions(
    record: Record,
    space: ModelSpace,
    values: Mapping[str, float],
    members: Sequence[Effect],
    additions: Sequence[Effect],
    noise: Mapping[str, float],
    n_scan: int,
    step: float,
    fd_step: float,
) -> list[tuple[str, float, float]]:
    """Rank effects to add to a fitted model by the chi2 of a profiled scan (see the module notes).

    Parameters
    ----------
    record : Record
        The record's test window (the grid fitted on).
    space : ModelSpace
        The nominal model space (free plant parameters, no effect).
    values : mapping of str to float
        The smaller model's fit: every free parameter of ``space`` and every member's value,
        each in its unit.
    members : sequence of Effect
        The smaller model's effects (may be empty: the nominal model).
    additions : sequence of Effect
        The effects to rank (none of them a member).
    noise : mapping of str to float
        Noise standard deviation per channel, or a :class:`~engine.diagnosis.noise.NoiseModel`.
    n_scan : int
        Values of each addition scanned over its search interval (at least 2; more for a time
        shift, :func:`engine.diagnosis.space.scan_grid`).
    step : float
        Integrator step of the simulations [s].
    fd_step : float
        Finite-difference step of the Jacobian, in unit-box coordinates.

    Returns
    -------
    list of (str, float, float)
        ``(name, chi2, value)`` per addition, lowest ``chi2`` [noise variances] first; ``value`` is
        the best scanned value in the effect's unit. An addition none of whose scanned values can
        be simulated gets ``chi2 = inf``.

    Raises
    ------
    ValueError
        When an addition is already a member, ``values`` lacks a free parameter of the smaller
        model, or ``n_scan < 2``.
    RuntimeError
        When the smaller model's fit itself cannot be simulated.
    """
    if n_scan < 2:
        raise ValueError(f"n_scan must be at least 2, got {n_scan}")
    names = {m.name for m in members}
    clash = [e.name for e in additions if e.name in names]
    if clash:
        raise ValueError(f"already members of the model: {', '.join(clash)}")
    missing = [k for k in space.with_effects(members).names if k not in values]
    if missing:  # the screen would run at the box centre instead of the fit
        raise ValueError(f"the fit to be extended lacks {', '.join(missing)}")
    weights = noise_weights(record, NoiseModel.of(noise))
    solver = space.solver(step)
    n = record.n_samples
    s0 = space.with_effects(members)
    obj0 = Objective(record, s0, weights)
    u0 = s0.unit(values)
    _, ok = obj0.simulate(u0[None], solver)
    if not ok[0]:
        raise RuntimeError("the fit to be extended cannot be simulated")
    r0 = obj0.residuals(u0[None], n, solver)[0]
    q, _ = np.linalg.qr(obj0.jacobian(u0, n, solver, fd_step, r0))
    out: list[tuple[str, float, float]] = []
    for e in additions:
        se = s0.with_effect(e)
        obj = Objective(record, se, weights)
        # the neutral value first (the score test's point), then the scan; each with a forward step
        ue = np.append(u0, se.params[-1].unit_coord(e.neutral))
        grid = np.append(ue[-1], scan_grid(se, se.dim - 1, ue, record, n_scan))
        steps = np.where(grid + fd_step <= 1.0, fd_step, -fd_step)
        U = np.repeat(np.append(u0, 0.0)[None], 2 * grid.size, axis=0)
        U[: grid.size, -1] = grid
        U[grid.size :, -1] = grid + steps
        R = obj.residuals(U, n, solver)
        _, ok = obj.simulate(U, solver)  # cached: which points could be simulated
        rp = R - (R @ q) @ q.T  # what a first-order refit of the smaller model leaves
        r, j = rp[: grid.size], (rp[grid.size :] - rp[: grid.size]) / steps[:, None]
        jj = np.sum(j * j, axis=1)
        gain = np.where(jj > 0.0, np.sum(j * r, axis=1) ** 2 / np.where(jj > 0.0, jj, 1.0), 0.0)
        chi2 = np.where(ok[: grid.size] & ok[grid.size :], np.sum(r * r, axis=1) - gain, np.inf)
        k = int(np.argmin(chi2))
        out.append((e.name, float(chi2[k]), float(se.params[-1].value(grid[k]))))
    out.sort(key=lambda x: x[1])
    base = float(np.sum((r0 - q @ (q.T @ r0)) ** 2))
    logger.info(
        "screen of %d additions to %s (profiled chi2/n %.3g without): %s",
        len(out),
        "+".join(m.name for m in members) or "the nominal model",
        base / r0.size,
        ", ".join(f"{name} {c / r0.size:.3g}" for name, c, _ in out),
    )
    return out
