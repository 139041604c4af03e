"""The cost a calibration minimises: noise-normalised residuals of a record against simulations.

For the channels j present in the record and the samples k, with white noise::

    chi2(theta) = sum_j sum_k ((sim_j[k](theta) - rec_j[k]) / sigma_j)^2

where sigma_j is the channel's noise level (:func:`engine.diagnosis.noise.noise_weights`).
With coloured noise (a :class:`~engine.diagnosis.noise.NoiseModel` whose channels have
per-level noise levels) the residual of each channel is whitened instead: its orthogonal
DWT coefficients, each divided by its level's noise standard deviation
(:meth:`engine.diagnosis.noise.ChannelNoise.normalise`); the residual of the first samples
only is zero-padded to the record's length first.
:class:`Objective` evaluates it on points of a
:class:`~engine.diagnosis.space.ModelSpace`'s unit box, over the first samples
of the record only if asked (the calibration's continuation over the time
horizon). The simulations are sampled on the record's own grid
(:attr:`engine.records.Record.grid`), so no record is ever resampled here. A simulation renders
only the samples its horizon holds (the kernel stops after the last of them; the samples are
those of the whole record's simulation, bit for bit), so a fit on the first 20 ms after the event
costs about a quarter of one on the whole record. Simulations are cached per (integrator step,
point) with the number of samples rendered, and every batch of points, finite-difference
Jacobians included, is simulated in one call to the batch-parallel simulator rather than column
by column.

A channel may have its own residual (``residual_of``, a :class:`ChannelResidual`): a function
of its simulated and recorded samples that replaces the noise-normalised difference, for a
reading the difference describes badly (the rounded speed while its quantum is fitted,
:class:`engine.diagnosis.quantisation.CellResidual`). Such a channel is never whitened. A
channel residual may take one effect of the space as its own parameter (``takes``): the
simulations are then run without that effect, their cache ignores its coordinate (its column
of a Jacobian costs no simulation), and the residual gets its value.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

import numpy as np

from engine.constants import CHANNELS
from engine.diagnosis.noise import ChannelNoise, NoiseModel
from engine.diagnosis.space import ModelSpace
from engine.parallel import raise_if_cancelled
from engine.records import Record
from engine.simulation import SolverSettings, run_cases

__all__ = ["FAILED_RESIDUAL", "ChannelResidual", "Objective"]

#: Residual used for a case the simulator could not run (no event, divergence), per sample.
FAILED_RESIDUAL: float = 1e3
#: The cache of simulations is halved when it exceeds this many points.
_CACHE_SIZE = 4096


def _covers(entry: tuple[int, np.ndarray | None], n: int) -> bool:
    """Whether a cached simulation (its sample count, its channels) serves a horizon of ``n`` samples.

    A simulation that failed over fewer samples fails over more too; one that failed over more
    samples may have failed after the first ``n``, so it is run again.
    """
    length, sim = entry
    return length <= n if sim is None else length >= n


class ChannelResidual(Protocol):
    """A channel's own normalised residual (see the module notes).

    Attributes
    ----------
    takes : str or None
        Name of the space's effect whose value the residual applies (the simulations leave it
        out), or None.
    """

    @property
    def takes(self) -> str | None:
        """The effect the residual applies, or None."""
        ...

    def __call__(self, sim: np.ndarray, data: np.ndarray, value: np.ndarray | None) -> np.ndarray:
        """Residuals (m, k) [-] of simulated samples ``sim`` (m, k) against the record's ``data`` (k,);
        ``value`` (m,) holds the taken effect's value per simulation (None when it takes none)."""
        ...


class Objective:
    """Noise-normalised residual of a record against simulations of a model space.

    Parameters
    ----------
    record : Record
        The measured record.
    space : ModelSpace
        What is fitted.
    sigma : mapping of str to float
        Residual normalisation per channel: a :class:`~engine.diagnosis.noise.NoiseModel`
        (see :func:`engine.diagnosis.noise.noise_weights`), or standard deviations of white
        noise in the channel's unit.
    residual_of : mapping of str to ChannelResidual, optional
        Per channel, its own normalised residual in place of ``(sim - data) / sigma``.

    Attributes
    ----------
    n_simulations : int
        Simulations run so far, however many samples each rendered (cache hits not counted).
    """

    def __init__(
        self,
        record: Record,
        space: ModelSpace,
        sigma: Mapping[str, float],
        residual_of: Mapping[str, ChannelResidual] | None = None,
    ):
        self.record = record
        self.space = space
        self.grid = record.grid
        self.names = list(record.channels)
        self.rows = [CHANNELS.index(n) for n in self.names]
        self.data = np.stack([record.channels[n] for n in self.names])
        self.sigma = np.array([sigma[n] for n in self.names])
        self.noise = NoiseModel.of(sigma)
        #: per channel, its noise model when the residual is whitened per level (None: white, r / sigma)
        unknown = set(residual_of or {}) - set(self.names)
        if unknown:
            raise ValueError(f"residual_of names channels the record does not hold: {sorted(unknown)}")
        #: per channel, its own residual function (None: the noise-normalised difference)
        self._own = [(residual_of or {}).get(n) for n in self.names]
        taken = [f.takes for f in self._own if f is not None and f.takes is not None]
        missing = set(taken) - set(space.effect_names)
        if missing:
            raise ValueError(f"a channel residual takes effects the space does not fit: {sorted(missing)}")
        #: the effects the channel residuals apply, and their coordinates (left out of the simulations)
        self._taken = tuple(taken)
        self._taken_axes = [space.names.index(t) for t in taken]
        self._coloured = [
            None if self.noise.channel(n).white or f is not None else self.noise.channel(n)
            for n, f in zip(self.names, self._own, strict=True)
        ]
        self.white = all(c is None for c in self._coloured)
        self.n_simulations = 0
        #: per (integrator step, unit-box point): the samples simulated and the channels over them
        #: (None where the simulation failed)
        self._cache: dict[tuple[float, tuple[float, ...]], tuple[int, np.ndarray | None]] = {}

    def simulate(
        self, U: np.ndarray, solver: SolverSettings, horizon: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Simulate unit-box points, over the record's first ``horizon`` samples.

        Parameters
        ----------
        U : ndarray, shape (m, d)
            Points of the unit box.
        solver : SolverSettings
            Integrator settings.
        horizon : int, optional
            Samples from the start of the record (None: all). The kernel integrates only as
            far as the last of them (:func:`engine.simulation.run_cases`, ``first``), and the
            samples are those of the whole record's simulation.

        Returns
        -------
        sims : ndarray, shape (m, n_ch, horizon)
            The record's channels on its grid, in model units (NaN where the simulation failed).
        ok : ndarray of bool, shape (m,)
            Which simulations succeeded.

        Raises
        ------
        engine.parallel.Cancelled
            When this thread's work has been cancelled (:func:`engine.parallel.cancel_scope`).
        """
        raise_if_cancelled()  # a fit made redundant on another thread stops here
        n = self.grid.n_samples if horizon is None else int(horizon)
        U = np.atleast_2d(np.asarray(U, dtype=float))
        V = U.copy()
        V[:, self._taken_axes] = 0.0  # a taken effect does not change the simulation
        keys = [(solver.max_step, tuple(np.round(v, 14))) for v in V]
        # a cached simulation serves every horizon up to its own length
        todo = [i for i, k in enumerate(keys) if not (k in self._cache and _covers(self._cache[k], n))]
        if todo:
            cases = [self.space.case(U[i], self._taken) for i in todo]
            ch, _, status = run_cases(cases, solver, self.grid, first=n)
            self.n_simulations += len(todo)
            for j, i in enumerate(todo):
                sim: np.ndarray | None = ch[j, self.rows] if status[j] == 0 else None
                if sim is not None and not np.all(np.isfinite(sim)):
                    sim = None
                self._cache[keys[i]] = (n, sim)
            if len(self._cache) > _CACHE_SIZE:
                for k in list(self._cache)[: _CACHE_SIZE // 2]:
                    del self._cache[k]
        sims = [self._cache[k][1] for k in keys]
        ok = np.array([s is not None for s in sims])
        out = np.stack([s[:, :n] if s is not None else np.full((len(self.rows), n), np.nan) for s in sims])
        return out, ok

    def residuals(self, U: np.ndarray, horizon: int, solver: SolverSettings) -> np.ndarray:
        """Normalised residuals (m, n_res) [noise sigmas] of the first ``horizon`` samples.

        White noise: n_res = n_ch * horizon, the residuals over sigma. Coloured noise: the
        whitened DWT coefficients of the residuals zero-padded to the record's length
        (n_res fixed, whatever the horizon). A failed simulation gives
        :data:`FAILED_RESIDUAL` at every residual.
        """
        U = np.atleast_2d(np.asarray(U, dtype=float))
        sims, ok = self.simulate(U, solver, horizon)
        if self.white:
            r = self._normalised(sims, U, horizon)
            r[~ok] = FAILED_RESIDUAL
            return r.reshape(r.shape[0], -1)
        return self._whitened(sims, ok, U, horizon)

    def _normalised(self, sims: np.ndarray, U: np.ndarray, horizon: int) -> np.ndarray:
        """Residuals (m, n_ch, horizon) [-] of white channels at points U: over sigma, or the channel's own."""
        r = (sims[:, :, :horizon] - self.data[None, :, :horizon]) / self.sigma[None, :, None]
        for j, f in enumerate(self._own):
            if f is not None:
                r[:, j] = f(sims[:, j, :horizon], self.data[j, :horizon], self._taken_value(f, U))
        return r

    @property
    def taken(self) -> tuple[str, ...]:
        """The effects the channel residuals apply (the simulations leave them out)."""
        return self._taken

    def own_chi2(self, name: str, sim: np.ndarray, u: np.ndarray) -> float | None:
        """chi2 [-] of channel ``name``'s own residual for its simulated samples ``sim`` (n_samples,)
        at point ``u`` (simulated without the taken effects); None for a channel without one."""
        j = self.names.index(name)
        f = self._own[j]
        if f is None:
            return None
        return float(np.sum(f(sim[None], self.data[j], self._taken_value(f, np.atleast_2d(u))) ** 2))

    def _taken_value(self, f: ChannelResidual, U: np.ndarray) -> np.ndarray | None:
        """The values (m,) of the effect ``f`` takes at points U (None if it takes none)."""
        if f.takes is None:
            return None
        i = self.space.names.index(f.takes)
        return np.array([self.space.params[i].value(u) for u in U[:, i]])

    def _whitened(self, sims: np.ndarray, ok: np.ndarray, U: np.ndarray, horizon: int) -> np.ndarray:
        """Whitened residuals (m, n_res) of the first ``horizon`` samples (zero-padded to the record)."""
        d = sims[:, :, :horizon] - self.data[None, :, :horizon]
        d[~ok] = 0.0
        n = self.data.shape[1]
        parts = [self._part(sims, d, U, j, ch, horizon, n) for j, ch in enumerate(self._coloured)]
        r = np.concatenate(parts, axis=1)
        r[~ok] = FAILED_RESIDUAL
        return r

    def _part(
        self, sims: np.ndarray, d: np.ndarray, U: np.ndarray, j: int, ch: ChannelNoise | None, horizon: int, n: int
    ) -> np.ndarray:
        """Channel ``j``'s part (m, k) of the whitened residuals (see :meth:`_whitened`)."""
        own = self._own[j]
        if own is not None:
            r = np.zeros((sims.shape[0], n))
            r[:, :horizon] = own(sims[:, j, :horizon], self.data[j, :horizon], self._taken_value(own, U))
            return r
        if ch is None:
            out: np.ndarray = d[:, j] / self.sigma[j]
            return out
        return ch.normalise(d[:, j], n)

    def chi2(self, U: np.ndarray, horizons: Sequence[int], solver: SolverSettings) -> np.ndarray:
        """chi2 (m, len(horizons)) [noise variances] of points U on each horizon (inf where the simulation failed).

        ``horizons`` are sample counts from the start of the record. With coloured noise, the
        chi2 of the whitened residual of the first samples, without the levels left out of it
        (a constant).
        """
        U = np.atleast_2d(np.asarray(U, dtype=float))
        sims, ok = self.simulate(U, solver, max(horizons))
        if not self.white:
            out = np.stack([np.sum(self._whitened(sims, ok, U, h) ** 2, axis=1) for h in horizons], axis=1)
            out[~ok] = np.inf
            return out
        r = self._normalised(sims, U, sims.shape[2])
        r[~ok] = 0.0
        r2 = np.square(r).sum(axis=1)  # (m, n_samples)
        cum = np.cumsum(r2, axis=1)
        out = np.stack([cum[:, h - 1] for h in horizons], axis=1)
        out[~ok] = np.inf
        return out

    def axis_scan(
        self,
        u: np.ndarray,
        axes: Sequence[int],
        n: int | np.ndarray,
        horizon: int,
        solver: SolverSettings,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Scan of each of ``axes`` alone over its whole range around ``u``, one batch of simulations.

        Parameters
        ----------
        u : ndarray, shape (d,)
            The point the other coordinates keep.
        axes : sequence of int
            Coordinates scanned, one after the other.
        n : int or ndarray
            Values of each scan, evenly spaced over [0, 1] in unit-box coordinates, or the
            unit-box coordinates of the scan themselves (:func:`engine.diagnosis.space.scan_grid`).
        horizon : int
            Samples of the chi2.
        solver : SolverSettings
            Integrator settings.

        Returns
        -------
        U : ndarray, shape (len(axes) * m + 1, d)
            (``m`` values per scan)
            The scan's points, axis after axis, then ``u`` itself (last row).
        chi2 : ndarray, shape (len(axes) * n + 1,)
            Their chi2 [noise variances] on ``horizon`` (inf where the simulation failed).
        """
        grid = np.linspace(0.0, 1.0, int(n)) if np.ndim(n) == 0 else np.asarray(n, dtype=float)
        n = grid.size
        U = np.repeat(np.asarray(u, dtype=float)[None], len(axes) * n + 1, axis=0)
        for k, j in enumerate(axes):
            U[k * n : (k + 1) * n, j] = grid
        return U, self.chi2(U, [horizon], solver)[:, 0]

    def jacobian(
        self,
        u: np.ndarray,
        horizon: int,
        solver: SolverSettings,
        fd_step: float,
        r0: np.ndarray | None = None,
        central: bool = False,
    ) -> np.ndarray:
        """Finite-difference Jacobian (n_res, d) of the residuals in unit-box coordinates, one batch of simulations.

        Parameters
        ----------
        u : ndarray, shape (d,)
            The point.
        horizon : int
            Samples of the residual.
        solver : SolverSettings
            Integrator settings.
        fd_step : float
            Difference step, in unit-box coordinates (reversed at the upper edge).
        r0 : ndarray, optional
            Residual at ``u`` when already known (forward differences only).
        central : bool
            Central differences (clipped to the box) instead of forward ones.
        """
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
        """Bounded least-squares refinement on one horizon (``scipy.optimize.least_squares``, trf).

        Parameters
        ----------
        u0 : ndarray, shape (d,)
            Starting point in the unit box.
        horizon : int
            Samples of the residual.
        solver : SolverSettings
            Integrator settings.
        max_nfev : int
            Cap on residual evaluations.
        fd_step : float
            Finite-difference step of the Jacobian, in unit-box coordinates.

        Returns
        -------
        u : ndarray, shape (d,)
            The optimum.
        chi2 : float
            Its chi2 [noise variances].
        jac : ndarray, shape (n_res, d)
            The Jacobian there, in unit-box coordinates.
        nfev : int
            Residual evaluations.
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

        from scipy.optimize import least_squares  # here: scipy.optimize adds about 0.7 s to a service start

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
