"""Samples at a speed quantum's cell edges that a fit cannot place: the flip tolerance.

A rounded record says in which cell ``[(k - 1/2) q, (k + 1/2) q)`` the unrounded speed ``x`` lay.
A model whose ``x`` passes within a hair of a cell edge puts a sample in the neighbouring cell
whenever its ``x`` is off by more than that hair, and the chi-square of the rounded model counts
that sample as a whole quantum of misfit: ``(q / sigma)^2``, 900 to 560 000 noise variances at the
catalogue's q / sigma of 30 to 750. The fit cannot place ``x`` that well: its parameters are known
to their uncertainty, q to its own, and the integrator has an error of its own. On the scored
protocol-2 runs (development data) three compound records held their true set at the truth and
missed the noise by one such sample, a thousandth of a quantum from its edge
(seed-173 case0279, seed-191 case0028, seed-223 case0246; docs/diagnosis.md 8b, *Where the
quantum compounds fail*).

The tolerance (:func:`tolerant_levels`): the spread of ``z = x / q`` at each sample is

    s_z^2 = (g_i C g_i^T) / q^2 + (x_i s_q / q^2)^2 + (e_i / q)^2,

``g_i`` the gradient of ``x_i`` in the fit's unit-box coordinates, ``C`` their Gauss-Newton
covariance for the record's noise (:func:`engine.diagnosis.calibration.unit_covariance`, of the
fit's residuals with the rounding as extra white noise of variance ``q^2 / 12`` on omega1, as the
quantum's refits weigh it; not inflated by the fit's chi2/n, which the flips themselves raise),
``s_q`` the quantum's uncertainty and ``e_i`` the integrator's error (``x`` at the fit's step
against ``x`` at half of it). A sample whose record lies in the cell just across the nearer edge
of the model's, with that edge within ``EDGE_TOLERANCE_SIGMAS`` spreads of ``z``, counts at the
record's level; every other sample at the model's rounded level, as before.

Where it fails: each sample is tolerated on its own, while one parameter move must place every
edge at once, so it forgives somewhat more than the model can (a sample is only ever moved to
the level next to the model's, and only within two spreads of an edge; on a record that shows no
lattice nothing is tolerated). The covariance is a local (linear) one: near a bound of the box or
where parameters are barely identified it can be much too wide or narrow.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

import numpy as np

from engine.constants import CHANNELS
from engine.diagnosis.calibration import CalibrationError, CalibrationSettings, unit_covariance
from engine.diagnosis.noise import noise_weights
from engine.diagnosis.objective import Objective
from engine.diagnosis.space import ModelSpace
from engine.records import Record
from engine.simulation import run_cases

__all__ = ["EDGE_TOLERANCE_SIGMAS", "edge_spread", "tolerant_levels"]

logger = logging.getLogger(__name__)

#: A flip is tolerated when its cell edge lies within this many spreads of ``x / q`` [-].
EDGE_TOLERANCE_SIGMAS: float = 2.0


def edge_spread(
    record: Record,
    space: ModelSpace,
    values: Mapping[str, float],
    noise: Mapping[str, float],
    q: float,
    sigma_q: float,
    step: float,
    fd_step: float = CalibrationSettings.fd_step_uncertainty,
) -> tuple[np.ndarray, np.ndarray]:
    """The model's unrounded omega1 and the spread of ``x / q`` at each sample (see the module notes).

    Parameters
    ----------
    record : Record
        The measured record (with an omega1 channel).
    space : ModelSpace
        The fit's model space, without the speed quantum (it rounds after the simulation).
    values : mapping of str to float
        The fitted values of ``space``'s parameters (a quantum among them is ignored).
    noise : mapping of str to float
        The record's noise per channel (standard deviations, channel unit, or a noise model);
        omega1's gets the rounding's ``q / sqrt(12)`` added.
    q : float
        The quantum [rad/s], > 0.
    sigma_q : float
        Its uncertainty [rad/s], >= 0.
    step : float
        The fit's integrator step [s].
    fd_step : float
        Central-difference step of the gradient and covariance [unit box]; by default that of every
        fit's uncertainties (:attr:`CalibrationSettings.fd_step_uncertainty`).

    Returns
    -------
    x : ndarray, shape (n_samples,)
        The unrounded omega1 at the fit [rad/s].
    spread : ndarray, shape (n_samples,)
        The standard deviation of ``x / q`` [quanta].

    Raises
    ------
    ValueError
        ``q`` not positive, ``sigma_q`` negative, or the record has no omega1.
    CalibrationError
        The fit's point cannot be simulated.
    """
    if not (q > 0.0 and sigma_q >= 0.0):
        raise ValueError(f"the edge spread needs q > 0 and sigma_q >= 0, got q = {q}, sigma_q = {sigma_q}")
    if "omega1" not in record.channels:
        raise ValueError("the record has no omega1 channel")
    weights = noise_weights(record, {**dict(noise), "omega1": math.hypot(noise["omega1"], q / math.sqrt(12.0))})
    obj = Objective(record, space, weights)
    u = space.unit(values)
    solver = space.solver(step)
    n = record.n_samples
    j = obj.names.index("omega1")
    sims, ok = obj.simulate(u[None], solver)
    if not ok[0]:
        raise CalibrationError("the fitted parameters cannot be simulated")
    x = sims[0, j]
    var = np.zeros(n)
    if space.dim > 0:
        J = obj.jacobian(u, n, solver, fd_step, central=True)
        cov = unit_covariance(J)
        lo, hi = np.maximum(u - fd_step, 0.0), np.minimum(u + fd_step, 1.0)
        d = space.dim
        U = np.vstack([u[None, :] + np.diag(hi - u), u[None, :] + np.diag(lo - u)])
        pm, ok_pm = obj.simulate(U, solver)  # the jacobian's own simulations, from the cache
        if not ok_pm.all() or not np.all(np.isfinite(cov)):
            raise CalibrationError("the gradient of omega1 at the fit cannot be simulated")
        G = ((pm[:d, j] - pm[d:, j]) / (hi - lo)[:, None]).T  # (n, d)
        var += np.einsum("ij,jk,ik->i", G, cov, G)
    var /= q * q
    var += (x * sigma_q / (q * q)) ** 2
    half, _, status = run_cases([space.case(u)], space.solver(step / 2.0), record.grid)
    if status[0] != 0:
        raise CalibrationError(f"the fit cannot be simulated at half its step (kernel status {int(status[0])})")
    var += ((half[0, CHANNELS.index("omega1")] - x) / q) ** 2
    return x, np.sqrt(var)


def tolerant_levels(
    x: np.ndarray, y: np.ndarray, q: float, spread: np.ndarray, n_sigma: float = EDGE_TOLERANCE_SIGMAS
) -> np.ndarray:
    """The model's rounding levels, a sample at the record's level where the fit cannot place the edge.

    Parameters
    ----------
    x : ndarray, shape (n,)
        The model's unrounded omega1 [rad/s].
    y : ndarray, shape (n,)
        The recorded omega1 [rad/s] (rounded to ``q``, noise small beside it).
    q : float
        The quantum [rad/s], > 0.
    spread : ndarray, shape (n,)
        The spread of ``x / q`` [quanta] (:func:`edge_spread`).
    n_sigma : float
        Spreads within which an edge is tolerated.

    Returns
    -------
    ndarray, shape (n,)
        Integer levels ``k`` (as floats): the model's omega1 is ``q k``.
    """
    if not q > 0.0:
        raise ValueError(f"the levels need q > 0, got {q}")
    k = np.round(x / q)
    z = x / q - k  # in [-1/2, 1/2]: the nearer edge is on the side of z's sign
    across = k + np.where(z >= 0.0, 1.0, -1.0)
    flip = (np.round(np.asarray(y) / q) == across) & (0.5 - np.abs(z) <= n_sigma * spread)
    if flip.any():
        logger.debug(
            "%d samples in the cell across an edge within %.3g spreads: at the record's level", flip.sum(), n_sigma
        )
    return np.where(flip, across, k)
