"""Batch simulation of the backlash test (MODEL.md section 2).

``simulate_batch`` runs many cases in one call through the numba kernel
(:mod:`engine.simulation._kernel`), in parallel over cases, and returns a
:class:`SimulationResult`. Records are rendered on any
:class:`~engine.records.SampleGrid` (default: MODEL.md's, ``PROTOCOL_GRID``).

The measurement chain (:class:`~engine.simulation.parameters.SensorParameters`)
is applied in the order of the measurement: the delay and trigger offset shift
the sample instants and the low-pass filters the channels (both in the kernel);
the gain, the offset and the quantisation of omega1 act on the sampled values
(:func:`apply_sensor_readout`, vectorised numpy).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Final

import numpy as np

from engine.constants import CHANNELS
from engine.records import PROTOCOL_GRID, Record, SampleGrid
from engine.simulation import _kernel as kern
from engine.simulation.effects import CATALOGUE, EffectLibrary, apply_effects
from engine.simulation.parameters import Case, ParameterError, PlantParameters, SolverSettings

logger = logging.getLogger(__name__)

#: Kernel code of each locus of an unknown input (``Disturbance.locus``).
DISTURBANCE_CODES: Final[dict[str, int]] = {
    "supply": kern.DIST_SUPPLY,
    "motor_electrical": kern.DIST_MOTOR_ELECTRICAL,
    "motor_shaft": kern.DIST_MOTOR_SHAFT,
    "clutch": kern.DIST_CLUTCH,
    "drive_train": kern.DIST_DRIVE_TRAIN,
    "clutch_torque": kern.DIST_CLUTCH_TORQUE,
    "load": kern.DIST_LOAD,
}

#: Integrator settings used when a caller gives none (immutable, so one shared instance).
DEFAULT_SOLVER: Final[SolverSettings] = SolverSettings()

_STATUS_TEXT = {
    kern.NO_EVENT: "no backlash event (re-entry into the zone after first contact) within {t_max} s of simulated time",
    kern.NON_FINITE: "the integration diverged (non-finite or absurd state); check the parameters",
    kern.HISTORY_TOO_SHORT: "the pre-event window reaches further back than the integrator keeps history",
}


#: numba's default "workqueue" threading layer aborts the process when a parallel
#: kernel is launched from two threads at once; batches are short, so launches are
#: serialised here and every caller (request threads, training jobs) is safe.
_KERNEL_LOCK = threading.Lock()
_THREAD = threading.local()
_SERIAL_LOCK = threading.Lock()
_n_serial = 0  # threads inside serial_kernel()


@contextmanager
def serial_kernel() -> Iterator[None]:
    """Run this thread's simulations on one core while other threads do the same.

    Inside the context, :func:`run_cases` (and everything built on it) uses the
    serial kernel, which releases the GIL and needs neither numba's threading
    layer nor the launch lock, as long as another thread is inside the context
    too; a thread found alone there uses the parallel kernel for its batches.
    For callers that parallelise over threads themselves, e.g. the candidate
    fits of the diagnosis: n threads each inside ``serial_kernel()`` keep n
    cores busy even when every call simulates one case, and the last one
    running still gets every core. Results are identical either way.
    """
    global _n_serial
    prev = getattr(_THREAD, "serial", False)
    _THREAD.serial = True
    if not prev:  # a thread counts once, however deeply nested
        with _SERIAL_LOCK:
            _n_serial += 1
    try:
        yield
    finally:
        if not prev:
            with _SERIAL_LOCK:
                _n_serial -= 1
        _THREAD.serial = prev


class SimulationError(RuntimeError):
    """Raised when a case cannot be simulated; ``failures`` maps case index to reason."""

    def __init__(self, failures: Mapping[int, str]):
        self.failures = dict(failures)
        first = ", ".join(f"case {i}: {msg}" for i, msg in list(self.failures.items())[:3])
        more = "" if len(self.failures) <= 3 else f" (and {len(self.failures) - 3} more)"
        super().__init__(f"{len(self.failures)} case(s) failed: {first}{more}")

    def __reduce__(self) -> tuple[type[SimulationError], tuple[dict[int, str]]]:
        """Pickled by its failures (it crosses process boundaries: worker pools, Dask)."""
        return (SimulationError, (self.failures,))


@dataclass(frozen=True)
class SimulationResult:
    """Records of a batch of cases.

    Attributes
    ----------
    cases : list of Case
        The simulated cases (effects already applied).
    channels : ndarray, shape (n_cases, 5, grid.n_samples)
        a1 [m/s^2], m_el [pu], omega1 [rad/s], a2 [m/s^2], v2 [m/s].
    event_times : ndarray, shape (n_cases,)
        t_e [s] since switch-on.
    grid : SampleGrid
        The sample grid of every record (default: MODEL.md's, 2048 samples of 0.1 ms, the event at 48).
    """

    cases: list[Case]
    channels: np.ndarray
    event_times: np.ndarray
    grid: SampleGrid = PROTOCOL_GRID

    def __len__(self) -> int:
        return len(self.cases)

    def channel(self, name: str) -> np.ndarray:
        """All cases' samples of one channel, shape (n_cases, grid.n_samples)."""
        return self.channels[:, CHANNELS.index(name), :]

    def record(self, i: int) -> Record:
        """Case ``i`` as a :class:`Record` on :attr:`grid` whose conditions carry its J1, c, c1 and K.

        Raises
        ------
        ProtocolError
            The grid does not cover the test window (4.8 ms before to 200 ms after the event).
        """
        p = self.cases[i].plant
        return Record(
            channels={name: self.channels[i, j] for j, name in enumerate(CHANNELS)},
            sample_interval=self.grid.sample_interval,
            event_index=self.grid.event_index,
            conditions={"J1": p.J1, "c": p.c, "c1": p.c1, "K": p.K},
            event_time=float(self.event_times[i]),
        )

    @property
    def records(self) -> list[Record]:
        return [self.record(i) for i in range(len(self))]


def parameter_vector(
    case: Case, solver: SolverSettings = DEFAULT_SOLVER, grid: SampleGrid = PROTOCOL_GRID
) -> np.ndarray:
    """Kernel parameter vector of one case on ``grid`` (see the ``P_*`` layout in the kernel).

    Parameters
    ----------
    case : Case
        Plant (with its model-1.1 to 1.7 terms and unknown input, if any) and measurement
        chain; only the chain's delay, trigger offset, low-pass, (model 1.2) encoder eccentricity,
        (model 1.3) accelerometer cross-talk, (model 1.4) omega1's sample-and-hold, (model 1.5)
        the accelerometers' mains hum, (model 1.6) the torque estimate's current sensor and (model 1.7)
        a1's saturation enter the kernel (gain, offset and quantisation act afterwards: :func:`apply_sensor_readout`). Model
        1.3's higher leakage reactances (``x_leak``) enter as ``x_s + x_leak`` and ``x_r + x_leak``,
        with no term of their own.
    solver : SolverSettings
        RK4 step [s] and the longest time to the event [s].
    grid : SampleGrid
        Sample interval [s] and event index of the record (its length is the output array's).

    Returns
    -------
    ndarray, shape (N_PARAMS,)
    """
    p, s = case.plant, case.sensors
    P = np.empty(kern.N_PARAMS)
    P[kern.P_R_S], P[kern.P_R_R] = p.r_s, p.r_r
    P[kern.P_X_S], P[kern.P_X_R], P[kern.P_X_M] = p.x_s + p.x_leak, p.x_r + p.x_leak, p.x_m  # 1.3: leakages
    P[kern.P_U], P[kern.P_F] = p.u, p.f
    P[kern.P_T1], P[kern.P_T2], P[kern.P_T3] = p.T1, p.T2, p.T3
    P[kern.P_B], P[kern.P_K12], P[kern.P_D12] = p.b, p.k12, p.d12
    P[kern.P_K2], P[kern.P_D2], P[kern.P_C], P[kern.P_C1] = p.k2, p.d2, p.c, p.c1
    P[kern.P_TAU_C1], P[kern.P_B_1], P[kern.P_RADIUS] = p.tau_C1, p.b_1, p.r
    P[kern.P_DELAY], P[kern.P_LOWPASS] = s.delay, s.lowpass_hz
    P[kern.P_STEP], P[kern.P_T_MAX] = solver.max_step, solver.t_event_max
    P[kern.P_TS], P[kern.P_EVENT_INDEX] = grid.sample_interval, float(grid.event_index)
    P[kern.P_TRIGGER_OFFSET] = s.trigger_offset
    P[kern.P_TAU_RIPPLE3], P[kern.P_CLUTCH_OFFSET], P[kern.P_TAU_COG] = p.tau_ripple3, p.clutch_offset, p.tau_cog
    P[kern.P_TAU_C2], P[kern.P_M_OFF] = p.tau_C2, p.m_off
    P[kern.P_DIST_LOCUS : kern.N_PARAMS] = 0.0  # no unknown input; the switch-off instant is the kernel's
    P[kern.P_DIST_DT] = 1.0
    dist = p.disturbance
    if dist is not None:
        n = len(dist.values)
        P[kern.P_DIST_LOCUS] = DISTURBANCE_CODES[dist.locus]
        P[kern.P_DIST_T0], P[kern.P_DIST_DT], P[kern.P_DIST_N] = dist.t0, dist.dt, n
        P[kern.P_DIST_STEP] = dist.step
        P[kern.P_DIST_VALUES : kern.P_DIST_VALUES + n] = dist.values
    # model 1.2 (appended after the switch-off slot, which the zeroing above cleared)
    P[kern.P_U_NEG], P[kern.P_SAT], P[kern.P_B_2] = p.u_neg, p.sat, p.b_2
    P[kern.P_K_PRE], P[kern.P_HARD2], P[kern.P_K_3] = p.k_pre, p.hard2, p.k_3
    P[kern.P_ECC1] = s.ecc1
    # model 1.3 (appended after 1.2's)
    P[kern.P_FLICKER], P[kern.P_TAU_S1], P[kern.P_PROG12] = p.u_flicker, p.tau_S1, p.prog12
    P[kern.P_TAU_DRY2], P[kern.P_B_3], P[kern.P_XTALK2] = p.tau_dry2, p.b_3, s.xtalk2
    # base values of the per-unit system (after the zeroing above): the plant's (MODEL.md's by default)
    P[kern.P_W_B], P[kern.P_OMEGA_B] = p.w_b, p.omega_b
    # model 1.4 (appended after the base values)
    P[kern.P_U_DC], P[kern.P_R_M], P[kern.P_MU1] = p.u_dc, p.r_m, p.mu_1
    P[kern.P_SQ12], P[kern.P_PLAY2], P[kern.P_BUMP3] = p.sq12, p.play2, p.bump3
    P[kern.P_HOLD1] = s.hold1
    # model 1.5 (appended after model 1.4's)
    P[kern.P_R_CON], P[kern.P_R_BAR], P[kern.P_TAU_BRAKE] = p.r_con, p.r_bar, p.tau_brake
    P[kern.P_HYST12], P[kern.P_MESH2], P[kern.P_EDDY3] = p.hyst12, p.mesh2, p.eddy3
    P[kern.P_HUM] = s.hum
    # model 1.6 (appended after model 1.5's)
    P[kern.P_T_POLE], P[kern.P_BYPASS_A], P[kern.P_TAU_RUB] = p.t_pole, p.bypass_a, p.tau_rub
    P[kern.P_SEAL12], P[kern.P_GEAR2], P[kern.P_BIND3] = p.seal12, p.gear2, p.bind3
    P[kern.P_IGAIN_A] = s.igain_a
    # model 1.7 (appended after model 1.6's)
    P[kern.P_U_H57], P[kern.P_PSI_R0], P[kern.P_TAU_MIS1] = p.u_h57, p.psi_r0, p.tau_mis1
    P[kern.P_ECC12], P[kern.P_TAU_UNB2], P[kern.P_BUF3] = p.ecc12, p.tau_unb2, p.buf3
    P[kern.P_SAT_A1] = s.sat_a1
    extended = (
        dist is not None
        or any(P[kern.P_TAU_RIPPLE3 : kern.P_M_OFF + 1] != 0.0)
        or any(P[kern.P_U_NEG : kern.P_XTALK2 + 1] != 0.0)
        or p.x_leak != 0.0  # no kernel term (folded into x_s, x_r above); switched on as every 1.3 term is
        or any(P[kern.P_U_DC : kern.P_HOLD1 + 1] != 0.0)
        or any(P[kern.P_R_CON : kern.P_HUM + 1] != 0.0)
        or any(P[kern.P_T_POLE : kern.P_IGAIN_A + 1] != 0.0)
        or any(P[kern.P_U_H57 : kern.P_SAT_A1 + 1] != 0.0)
    )
    P[kern.P_EXTENDED] = 1.0 if extended else 0.0
    return P


#: Largest |lambda h| of a first-order sensor filter (lambda = 2 pi f_c) for which the fixed-step
#: RK4 is used: the method's real-axis stability limit is 2.785; 2.0 keeps a margin.
LOWPASS_STEP_LIMIT: float = 2.0


def check_step(case: Case, solver: SolverSettings) -> None:
    """Raise :class:`ParameterError` when the integrator step cannot resolve the case's sensor low-pass.

    Parameters
    ----------
    case : Case
        Its ``sensors.lowpass_hz`` [Hz] (0 = none) is checked.
    solver : SolverSettings
        Its ``max_step`` [s] is the RK4 step.

    Raises
    ------
    ParameterError
        When ``2 pi lowpass_hz max_step > LOWPASS_STEP_LIMIT``: the filter state would be
        integrated unstably (the record would be garbage, not an answer).
    """
    f_c = case.sensors.lowpass_hz
    if f_c > 0 and 2.0 * math.pi * f_c * solver.max_step > LOWPASS_STEP_LIMIT:
        f_max = LOWPASS_STEP_LIMIT / (2.0 * math.pi * solver.max_step)
        raise ParameterError(
            f"lowpass_hz = {f_c:g} Hz is too fast for the integrator step {solver.max_step:.3g} s: "
            f"at most {f_max:.0f} Hz (or a smaller max_step)"
        )


def apply_sensor_readout(channels: np.ndarray, cases: Sequence[Case], grid: SampleGrid = PROTOCOL_GRID) -> None:
    """Gain, offset and omega1 quantisation of the sampled records, in place (in that order).

    Parameters
    ----------
    channels : ndarray, shape (n_cases, 5, grid.n_samples)
        The kernel's records (delay, trigger offset and low-pass already applied), model units.
    cases : sequence of Case
        One per record; their ``sensors.gain`` [x], ``sensors.offset_rms`` [x RMS] and
        ``sensors.speed_quantum`` [rad/s] are applied.
    grid : SampleGrid
        The records' grid; the offset's RMS is taken over its test window (:meth:`SampleGrid.window`),
        so it does not depend on how long a record is.

    Notes
    -----
    Each step touches only the records whose value differs from neutral, so a neutral chain
    leaves the samples bit for bit as the kernel produced them.

    Raises
    ------
    GridError
        A case has an offset and ``grid`` does not cover the test window.
    """
    if not len(cases):
        return
    gain = np.array([c.sensors.gain for c in cases], dtype=float)
    scaled = np.flatnonzero(gain != 1.0)
    if scaled.size:
        channels[scaled] *= gain[scaled, None, None]
    offset = np.array([c.sensors.offset_rms for c in cases], dtype=float)
    shifted = np.flatnonzero(offset != 0.0)
    if shifted.size:
        window = channels[shifted][:, :, grid.window()]
        rms = np.sqrt(np.mean(window**2, axis=2))  # (n, 5)
        channels[shifted] += (offset[shifted, None] * rms)[:, :, None]
    quantum = np.array([c.sensors.speed_quantum for c in cases], dtype=float)
    rounded = np.flatnonzero(quantum > 0.0)
    if rounded.size:
        j = CHANNELS.index("omega1")
        q = quantum[rounded, None]
        channels[rounded, j] = q * np.round(channels[rounded, j] / q)


def run_cases(
    cases: Sequence[Case],
    solver: SolverSettings = DEFAULT_SOLVER,
    grid: SampleGrid = PROTOCOL_GRID,
    first: int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulate validated cases without raising: (channels, event_times, status).

    For search loops (calibration) that prefer an infinite cost to an
    exception; ``status`` holds the kernel's codes (0 is success).

    With ``first``, only the grid's first samples are rendered: the kernel stops integrating
    after the last of them, so a fit on the early part of a record pays only for that part. The
    samples are bit for bit those of the whole grid, because the kernel integrates sample
    instant after sample instant and every step of the readout but one is per sample; that one,
    a sensor offset (its RMS is taken over the whole test window), makes its batch render the
    whole grid and cut it. Only the rendered samples decide a divergence: a case that would turn
    non-finite after them is a success here.

    Parameters
    ----------
    cases : sequence of Case
        Validated cases (see :meth:`Case.validate`).
    solver : SolverSettings
        Integrator settings: each interval between sample instants is split into equal RK4
        steps of at most ``solver.max_step`` [s].
    grid : SampleGrid
        Sample instants of the records (default: MODEL.md's grid).
    first : int, optional
        Render only the first ``first`` samples of ``grid`` (1 to ``grid.n_samples``; None: all).

    Returns
    -------
    channels : ndarray, shape (n_cases, 5, first or grid.n_samples)
        a1 [m/s^2], m_el [pu], omega1 [rad/s], a2 [m/s^2], v2 [m/s], after the whole sensor chain.
    event_times : ndarray, shape (n_cases,)
        t_e [s] since switch-on (NaN where the case failed).
    status : ndarray of int, shape (n_cases,)
        The kernel's status codes.

    Raises
    ------
    ValueError
        ``first`` is not a sample count of ``grid``.
    """
    solver.validate()
    n_first = grid.n_samples if first is None else int(first)
    if first is not None and (isinstance(first, bool) or n_first != first or not 1 <= n_first <= grid.n_samples):
        raise ValueError(f"first must be a sample count from 1 to {grid.n_samples}, got {first}")
    render = grid  # the kernel renders as many samples as its output holds; the grid must hold the event
    n_render = max(n_first, grid.event_index + 1, 2)
    if n_render < grid.n_samples and not any(c.sensors.offset_rms != 0.0 for c in cases):
        render = SampleGrid(grid.sample_interval, n_render, grid.event_index)
    P = np.stack([parameter_vector(c, solver, render) for c in cases]) if cases else np.empty((0, kern.N_PARAMS))
    n = P.shape[0]
    out = np.zeros((n, kern.N_CHANNELS, render.n_samples))
    t_e = np.full(n, np.nan)
    status = np.zeros(n, dtype=np.int64)
    if n == 1 or (n and getattr(_THREAD, "serial", False) and _n_serial > 1):
        kern.simulate_serial(P, out, t_e, status)  # no threading layer: no lock needed
    elif n:
        with _KERNEL_LOCK:
            kern.simulate_many(P, out, t_e, status)
    # a record with a non-finite sample is a failed integration, never a result
    diverged = (status == kern.OK) & ~np.isfinite(out).all(axis=(1, 2))
    status[diverged] = kern.NON_FINITE
    # gain, offset and quantisation (post-sampling: properties of the reading)
    apply_sensor_readout(out, cases, render)
    return out[:, :, :n_first], t_e, status


def simulate_batch(
    cases: Sequence[Case | PlantParameters],
    effects: Mapping[str, float] | Sequence[Mapping[str, float]] | None = None,
    solver: SolverSettings = DEFAULT_SOLVER,
    grid: SampleGrid = PROTOCOL_GRID,
    library: EffectLibrary = CATALOGUE,
) -> SimulationResult:
    """Simulate many cases of the backlash test in one call.

    Parameters
    ----------
    cases : sequence of Case or PlantParameters
        The cases; every MODEL.md parameter can differ per case.
    effects : mapping or sequence of mappings, optional
        Unmodelled effects by name (in ``library``) and value (see
        :mod:`engine.simulation.effects`), one mapping for all cases or one per case.
    solver : SolverSettings
        Integrator settings.
    grid : SampleGrid
        Sample instants of the records (default: MODEL.md's grid, 2048 samples of 0.1 ms,
        the event at sample 48); e.g. a measured record's ``grid`` to compare with it.
    library : EffectLibrary
        Where the names of ``effects`` are looked up: the catalogue by default;
        e.g. :data:`~engine.simulation.held_back.HELD_BACK` for the held-back effects,
        :data:`~engine.simulation.held_out.HELD_OUT` for the held-out ones (model 1.2),
        :data:`~engine.simulation.sealed.SEALED` for the sealed ones (model 1.3),
        :data:`~engine.simulation.sealed2.SEALED2` for the second sealed family (model 1.4),
        :data:`~engine.simulation.sealed3.SEALED3` for the third (model 1.5),
        :data:`~engine.simulation.sealed4.SEALED4` for the fourth (model 1.6),
        :data:`~engine.simulation.sealed5.SEALED5` for the fifth (model 1.7).

    Returns
    -------
    SimulationResult

    Raises
    ------
    ParameterError
        A parameter or effect is out of range.
    GridError
        A case has a ``sensor_offset`` and ``grid`` does not cover the test window.
    SimulationError
        A case has no event within ``solver.t_event_max`` or diverged.
    """
    norm = [c if isinstance(c, Case) else Case(c) for c in cases]
    if effects is not None:
        per_case = [effects] * len(norm) if isinstance(effects, Mapping) else list(effects)
        if len(per_case) != len(norm):
            raise ValueError(f"got {len(per_case)} effect mappings for {len(norm)} cases")
        norm = [apply_effects(c, e, library) for c, e in zip(norm, per_case, strict=True)]
    for c in norm:
        c.validate()
        check_step(c, solver)
    if not isinstance(grid, SampleGrid):
        raise TypeError(f"grid must be an engine.records.SampleGrid, got {type(grid).__name__}")
    out, t_e, status = run_cases(norm, solver, grid)
    failures = {i: _STATUS_TEXT[int(s)].format(t_max=solver.t_event_max) for i, s in enumerate(status) if s != kern.OK}
    if failures:
        raise SimulationError(failures)
    logger.debug("simulated %d cases on %s", len(norm), grid)
    return SimulationResult(cases=norm, channels=out, event_times=t_e, grid=grid)


def simulate(
    case: Case | PlantParameters,
    effects: Mapping[str, float] | None = None,
    solver: SolverSettings = DEFAULT_SOLVER,
    grid: SampleGrid = PROTOCOL_GRID,
    library: EffectLibrary = CATALOGUE,
) -> Record:
    """Simulate one case and return its record on ``grid`` (see :func:`simulate_batch`)."""
    return simulate_batch([case], effects, solver, grid, library).record(0)
