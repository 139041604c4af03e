"""Reference solution of the backlash test with scipy's ``solve_ivp``.

An independent transcription of MODEL.md section 1 in complex notation with a
plain numpy right-hand side; the event is located by ``solve_ivp``'s event
function. It is slow and exists for two purposes: the accuracy tests of the
numba kernel (MODEL.md section 4, relative tolerance 1e-9) and the baseline
of ``bench/bench_simulator.py``. Sensors: the measurement delay is supported
(sample instants shift); low-pass and quantisation are not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from engine.constants import EVENT_INDEX, N_SAMPLES, OMEGA_B, SAMPLE_INTERVAL, T_EVENT_MAX, W_B
from engine.simulation.parameters import Case, PlantParameters

W_SMOOTH = 1e-3  # pu, MODEL.md's smoothing of the sign functions


@dataclass(frozen=True)
class ReferenceResult:
    """Channels (5, 2048) in CHANNELS order and the event time t_e [s]."""

    channels: np.ndarray
    event_time: float
    n_rhs: int


class ReferenceModel:
    """Right-hand side of MODEL.md in complex notation; state [psi_s, psi_r, w, theta] (10 reals)."""

    def __init__(self, p: PlantParameters):
        self.p = p
        det = p.x_s * p.x_r - p.x_m**2
        # [i_s, i_r] = L^-1 [psi_s, psi_r]
        self.Linv = np.array([[p.x_r, -p.x_m], [-p.x_m, p.x_s]]) / det
        self.T = np.array([p.T1, p.T2, p.T3])
        self.n_rhs = 0

    def derivatives(self, t: float, y: np.ndarray, motor_on: bool) -> tuple[np.ndarray, np.ndarray]:
        """(dy/dt, [dw_1/dt, m_el, w_1, dw_3/dt, w_3])."""
        self.n_rhs += 1
        p = self.p
        psi = y[0:2] + 1j * y[2:4]  # [psi_s, psi_r]
        w, th = y[4:7], y[7:10]
        dpsi = np.zeros(2, dtype=complex)
        m_el = 0.0
        if motor_on:
            i_s, i_r = self.Linv @ psi
            u_s = p.u * np.exp(1j * p.f * W_B * t)
            dpsi[0] = W_B * (u_s - p.r_s * i_s)
            dpsi[1] = W_B * (-p.r_r * i_r + 1j * w[0] * psi[1])
            m_el = float(np.imag(np.conj(psi[0]) * i_s))
        d, dw, b = th[0] - th[1], w[0] - w[1], p.b
        if d > b:
            m_c = max(0.0, p.k12 * (d - b) + p.d12 * dw)
        elif d < -b:
            m_c = min(0.0, p.k12 * (d + b) + p.d12 * dw)
        else:
            m_c = 0.0
        m_s = p.k2 * (th[1] - th[2]) + p.d2 * (w[1] - w[2])
        m_a = p.c * w[2] + p.c1 * np.tanh(w[2] / W_SMOOTH)
        m_f = p.tau_C1 * np.tanh(w[0] / W_SMOOTH) + p.b_1 * w[0]
        dw_dt = np.array([m_el - m_c - m_f, m_c - m_s, m_s - m_a]) / self.T
        dy = np.concatenate([dpsi.real, dpsi.imag, dw_dt, OMEGA_B * w])
        return dy, np.array([dw_dt[0], m_el, w[0], dw_dt[2], w[2]])

    def channels(self, t: float, y: np.ndarray, motor_on: bool) -> np.ndarray:
        """Channel values a1, m_el, omega1, a2, v2 in MODEL.md section 3 units."""
        _, q = self.derivatives(t, y, motor_on)
        r = self.p.r
        return np.array([r * OMEGA_B * q[0], q[1], OMEGA_B * q[2], r * OMEGA_B * q[3], r * OMEGA_B * q[4]])


def reference_simulate(
    case: Case | PlantParameters, method: str = "DOP853", rtol: float = 1e-9, atol: float = 1e-12
) -> ReferenceResult:
    """Solve the backlash test with ``solve_ivp`` (see the module docstring).

    Raises
    ------
    RuntimeError
        No event within 1 s, or the solver failed.
    """
    case = case if isinstance(case, Case) else Case(case)
    p, delay = case.plant, case.sensors.delay
    model = ReferenceModel(p)

    def f_on(t, y):
        return model.derivatives(t, y, True)[0]

    def f_off(t, y):
        return model.derivatives(t, y, False)[0]

    def gap(t, y):
        return abs(y[7] - y[8]) - p.b

    contact = lambda t, y: gap(t, y)  # noqa: E731
    contact.terminal, contact.direction = True, 1.0
    reentry = lambda t, y: gap(t, y)  # noqa: E731
    reentry.terminal, reentry.direction = True, -1.0

    kw = dict(method=method, rtol=rtol, atol=atol, dense_output=True)
    y0 = np.zeros(10)
    s1 = solve_ivp(f_on, (0.0, T_EVENT_MAX), y0, events=contact, **kw)
    if s1.status != 1:
        raise RuntimeError(f"reference: no first contact within {T_EVENT_MAX} s ({s1.message})")
    t_c = s1.t_events[0][0]
    s2 = solve_ivp(f_on, (t_c, T_EVENT_MAX), s1.y_events[0][0], events=reentry, **kw)
    if s2.status != 1:
        raise RuntimeError(f"reference: no re-entry into the backlash zone within {T_EVENT_MAX} s ({s2.message})")
    t_e = float(s2.t_events[0][0])
    y_e = s2.y_events[0][0]
    t_k = t_e + (np.arange(N_SAMPLES) - EVENT_INDEX) * SAMPLE_INTERVAL - delay
    s3 = solve_ivp(f_off, (t_e, t_k[-1] + 1e-12), y_e, **kw)
    if not s3.success:
        raise RuntimeError(f"reference: solver failed after the event ({s3.message})")
    out = np.zeros((5, N_SAMPLES))
    for k, t in enumerate(t_k):
        if t < 0:
            continue
        if t < t_c:
            y, on = s1.sol(t), True
        elif t < t_e:
            y, on = s2.sol(t), True
        else:
            y, on = s3.sol(t), False
        out[:, k] = model.channels(t, y, on)
    return ReferenceResult(out, t_e, model.n_rhs)
