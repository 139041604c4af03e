"""Numba kernel: fixed-step RK4 integration of the reference plant with the backlash test.

The equations are those of MODEL.md section 1 written out in real
(alpha, beta) components; :mod:`engine.simulation.reference` holds an
independent numpy transcription in complex notation that the tests compare
against with scipy's solve_ivp.

State vector ``y`` (15 entries)::

    0..3   psi_s_alpha, psi_s_beta, psi_r_alpha, psi_r_beta   [pu]
    4..6   w_1, w_2, w_3                                      [pu speed]
    7..9   theta_1, theta_2, theta_3                          [mechanical rad]
    10..14 low-pass sensor states of the five channels       [channel units]

The parameter vector layout is given by the ``P_*`` indices below and built by
:func:`engine.simulation.simulator.parameter_vector`; it carries the record's
sample grid too (``P_TS``, ``P_EVENT_INDEX``), and the number of samples is the
length of the output array, so one compiled kernel renders any grid.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from engine.constants import CHANNELS, OMEGA_B, W_B, W_SMOOTH

# parameter vector layout
P_R_S, P_R_R, P_X_S, P_X_R, P_X_M, P_U, P_F = 0, 1, 2, 3, 4, 5, 6
P_T1, P_T2, P_T3 = 7, 8, 9
P_B, P_K12, P_D12, P_K2, P_D2, P_C, P_C1 = 10, 11, 12, 13, 14, 15, 16
P_TAU_C1, P_B_1, P_RADIUS = 17, 18, 19
P_DELAY, P_LOWPASS, P_STEP, P_T_MAX = 20, 21, 22, 23
P_TS, P_EVENT_INDEX, P_TRIGGER_OFFSET = 24, 25, 26
N_PARAMS = 27

N_CHANNELS = len(CHANNELS)
N_STATES = 10 + N_CHANNELS

# status codes returned per case
OK = 0
NO_EVENT = 1
NON_FINITE = 2
HISTORY_TOO_SHORT = 3

# checkpoint ring used to re-integrate the pre-event window on the sample grid: a checkpoint
# every CHECKPOINT_INTERVAL [s]; at least MIN_RING entries (16 ms of history), more when the
# record reaches further back (see ring_size)
CHECKPOINT_INTERVAL = 2.5e-4
MIN_RING = 64
_RING_MARGIN = 4


@njit(cache=True, fastmath=False)
def ring_size(P):
    """Checkpoints to keep so that one lies at or before the record's first sample instant.

    The record reaches ``event_index * Ts + max(shift, 0)`` [s] before t_e (shift = delay +
    trigger offset). Checkpoint j is taken at the start of the first step at or after
    j * CHECKPOINT_INTERVAL (steps are shorter than it), so ``span / CHECKPOINT_INTERVAL`` plus
    a margin of a few entries always holds one at or before the first instant. History older
    than ``t_event_max`` is never needed: a first instant before switch-on starts from rest.
    """
    span = P[P_EVENT_INDEX] * P[P_TS] + max(P[P_DELAY] + P[P_TRIGGER_OFFSET], 0.0)
    span = min(span, P[P_T_MAX])
    return max(MIN_RING, math.ceil(span / CHECKPOINT_INTERVAL) + _RING_MARGIN)


@njit(cache=True, fastmath=False)
def smooth_sign(w):
    """tanh(w / W_SMOOTH), MODEL.md's smoothed sign; exactly +-1 in double precision beyond |w| > 20 W_SMOOTH."""
    x = w / W_SMOOTH
    if x > 20.0:
        return 1.0
    if x < -20.0:
        return -1.0
    return math.tanh(x)


@njit(cache=True, fastmath=False)
def rhs(t, y, P, motor_on, dy, ch):
    """Right-hand side dy/dt and the five channel values at (t, y).

    ``ch`` receives [a1 m/s^2, m_el pu, omega1 rad/s, a2 m/s^2, v2 m/s]; with a
    low-pass sensor (P[P_LOWPASS] > 0) these are the unfiltered values that
    drive the sensor states y[10:15].
    """
    psa = y[0]
    psb = y[1]
    pra = y[2]
    prb = y[3]
    w1 = y[4]
    w2 = y[5]
    w3 = y[6]
    if motor_on:
        xs = P[P_X_S]
        xr = P[P_X_R]
        xm = P[P_X_M]
        det = xs * xr - xm * xm
        isa = (xr * psa - xm * pra) / det
        isb = (xr * psb - xm * prb) / det
        ira = (xs * pra - xm * psa) / det
        irb = (xs * prb - xm * psb) / det
        ang = P[P_F] * W_B * t
        usa = P[P_U] * math.cos(ang)
        usb = P[P_U] * math.sin(ang)
        dy[0] = W_B * (usa - P[P_R_S] * isa)
        dy[1] = W_B * (usb - P[P_R_S] * isb)
        dy[2] = W_B * (-P[P_R_R] * ira - w1 * prb)
        dy[3] = W_B * (-P[P_R_R] * irb + w1 * pra)
        m_el = psa * isb - psb * isa
    else:
        dy[0] = 0.0
        dy[1] = 0.0
        dy[2] = 0.0
        dy[3] = 0.0
        m_el = 0.0
    # clutch with backlash: a contact can push, never pull
    d = y[7] - y[8]
    dw = w1 - w2
    b = P[P_B]
    if d > b:
        m_c = max(0.0, P[P_K12] * (d - b) + P[P_D12] * dw)
    elif d < -b:
        m_c = min(0.0, P[P_K12] * (d + b) + P[P_D12] * dw)
    else:
        m_c = 0.0
    m_s = P[P_K2] * (y[8] - y[9]) + P[P_D2] * (w2 - w3)
    m_a = P[P_C] * w3 + P[P_C1] * smooth_sign(w3)
    m_f = P[P_B_1] * w1
    if P[P_TAU_C1] != 0.0:
        m_f += P[P_TAU_C1] * smooth_sign(w1)
    dw1 = (m_el - m_c - m_f) / P[P_T1]
    dw2 = (m_c - m_s) / P[P_T2]
    dw3 = (m_s - m_a) / P[P_T3]
    dy[4] = dw1
    dy[5] = dw2
    dy[6] = dw3
    dy[7] = OMEGA_B * w1
    dy[8] = OMEGA_B * w2
    dy[9] = OMEGA_B * w3
    r = P[P_RADIUS]
    ch[0] = r * OMEGA_B * dw1
    ch[1] = m_el
    ch[2] = OMEGA_B * w1
    ch[3] = r * OMEGA_B * dw3
    ch[4] = r * OMEGA_B * w3
    fc = P[P_LOWPASS]
    if fc > 0.0:
        a = 2.0 * math.pi * fc
        for i in range(N_CHANNELS):
            dy[10 + i] = a * (ch[i] - y[10 + i])
    else:
        for i in range(N_CHANNELS):
            dy[10 + i] = 0.0


@njit(cache=True, fastmath=False)
def rk4_step(t, y, h, P, motor_on, out, k1, k2, k3, k4, tmp, ch):
    """One classical Runge-Kutta step of size h from (t, y) into ``out``."""
    n = y.shape[0]
    rhs(t, y, P, motor_on, k1, ch)
    for i in range(n):
        tmp[i] = y[i] + 0.5 * h * k1[i]
    rhs(t + 0.5 * h, tmp, P, motor_on, k2, ch)
    for i in range(n):
        tmp[i] = y[i] + 0.5 * h * k2[i]
    rhs(t + 0.5 * h, tmp, P, motor_on, k3, ch)
    for i in range(n):
        tmp[i] = y[i] + h * k3[i]
    rhs(t + h, tmp, P, motor_on, k4, ch)
    for i in range(n):
        out[i] = y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit(cache=True, fastmath=False)
def zone(y, P):
    """Clutch mode of state y.

    0 inside the backlash (|d| <= b); +1 / -1 in contact and pushing;
    +2 / -2 penetrated but with the contact force clipped to zero (the contact
    can push, never pull). Mode changes are where the right-hand side is
    discontinuous (contact entry) or kinked (clipping).
    """
    b = P[P_B]
    d = y[7] - y[8]
    if -b <= d <= b:
        return 0
    dw = y[4] - y[5]
    if d > b:
        return 1 if P[P_K12] * (d - b) + P[P_D12] * dw > 0.0 else 2
    return -1 if P[P_K12] * (d + b) + P[P_D12] * dw < 0.0 else -2


@njit(cache=True, fastmath=False)
def hybrid_step(t, y, h, P, motor_on, work):
    """One RK4 step of at most h from (t, y) that stops at a clutch-zone change.

    The contact torque is discontinuous where the clutch enters contact
    (it jumps to d_12 * dw), so a step that crosses a zone boundary is cut at
    the crossing, located by bisection to 1e-12 s; RK4 then only integrates a
    smooth right-hand side and keeps its order. The new state is in
    ``work[0]``.

    Returns
    -------
    h_taken : float
        Step actually taken [s] (h, or the time to the zone change).
    crossed : bool
        Whether the step ended at a zone change.
    """
    z0 = zone(y, P)
    out = work[0]
    rk4_step(t, y, h, P, motor_on, out, work[1], work[2], work[3], work[4], work[5], work[6])
    if zone(out, P) == z0:
        return h, False
    lo = 0.0
    hi = h
    trial = work[7]
    while hi - lo > 1e-12:
        mid = 0.5 * (lo + hi)
        rk4_step(t, y, mid, P, motor_on, trial, work[1], work[2], work[3], work[4], work[5], work[6])
        if zone(trial, P) == z0:
            lo = mid
        else:
            hi = mid
    rk4_step(t, y, hi, P, motor_on, out, work[1], work[2], work[3], work[4], work[5], work[6])
    return hi, True


@njit(cache=True, fastmath=False)
def advance(t, y, t_end, P, motor_on, work):
    """Integrate y in place from t to t_end with hybrid steps no longer than P[P_STEP]."""
    n_bad = 0
    while t_end - t > 1e-15:
        span = t_end - t
        n = math.ceil(span / P[P_STEP] - 1e-9)
        h = span / max(n, 1)
        taken, crossed = hybrid_step(t, y, h, P, motor_on, work)
        for i in range(y.shape[0]):
            y[i] = work[0][i]
        t = t_end if (not crossed and n <= 1) else t + taken
        if not (abs(y[4]) < 1e6):
            n_bad += 1
            break
    return n_bad == 0


@njit(cache=True, fastmath=False)
def simulate_one(P, out):
    """Run the backlash test of MODEL.md section 2 for one parameter vector.

    Sample k of the record is taken at ``t_e + (k - P[P_EVENT_INDEX]) * P[P_TS] - shift`` with
    ``shift = P[P_DELAY] + P[P_TRIGGER_OFFSET]`` [s] (a negative shift samples later than
    nominal); an instant before switch-on (t < 0) reads the plant at rest (zeros).

    Parameters
    ----------
    P : ndarray, shape (N_PARAMS,)
        Parameter vector.
    out : ndarray, shape (N_CHANNELS, n_samples)
        Receives the record (a1, m_el, omega1, a2, v2) before gain, offset and quantisation;
        its length sets the number of samples.

    Returns
    -------
    status : int
        OK, NO_EVENT, NON_FINITE or HISTORY_TOO_SHORT.
    t_e : float
        Event time [s] (NaN unless OK).
    """
    h = P[P_STEP]
    y = np.zeros(N_STATES)
    work = (
        np.zeros(N_STATES),
        np.zeros(N_STATES),
        np.zeros(N_STATES),
        np.zeros(N_STATES),
        np.zeros(N_STATES),
        np.zeros(N_STATES),
        np.zeros(N_STATES),
        np.zeros(N_STATES),
    )
    n_ring = ring_size(P)
    ring_t = np.zeros(n_ring)
    ring_y = np.zeros((n_ring, N_STATES))
    ck_dt = CHECKPOINT_INTERVAL
    next_ck = 0.0
    t = 0.0
    armed = False
    t_e = math.nan
    n_ck = 0
    while t < P[P_T_MAX]:
        if t >= next_ck:
            slot = n_ck % n_ring
            ring_t[slot] = t
            for i in range(N_STATES):
                ring_y[slot, i] = y[i]
            n_ck += 1
            next_ck += ck_dt
        taken, crossed = hybrid_step(t, y, h, P, True, work)
        for i in range(N_STATES):
            y[i] = work[0][i]
        t += taken
        if not (abs(y[4]) < 1e6 and abs(y[7] - y[8]) < 1e6):
            return NON_FINITE, math.nan
        z = zone(y, P)
        if z != 0:
            armed = True
        elif armed and crossed:
            t_e = t
            break
    if math.isnan(t_e):
        return NO_EVENT, math.nan

    # re-integrate from the newest checkpoint before the first sample instant
    ts = P[P_TS]
    e_idx = P[P_EVENT_INDEX]
    shift = P[P_DELAY] + P[P_TRIGGER_OFFSET]
    t_first = t_e - e_idx * ts - shift
    best = -1
    best_t = -1.0
    n_valid = min(n_ck, n_ring)
    for s in range(n_valid):
        if ring_t[s] <= t_first and ring_t[s] > best_t:
            best = s
            best_t = ring_t[s]
    if t_first < 0.0:
        best_t = 0.0
        for i in range(N_STATES):
            y[i] = 0.0
    elif best < 0:
        return HISTORY_TOO_SHORT, math.nan
    else:
        for i in range(N_STATES):
            y[i] = ring_y[best, i]
    t = best_t
    motor_on = True
    lowpass = P[P_LOWPASS] > 0.0
    dy = np.empty(N_STATES)
    chv = np.empty(N_CHANNELS)
    for k in range(out.shape[1]):
        tk = t_e + (k - e_idx) * ts - shift
        if tk < 0.0:
            for i in range(N_CHANNELS):
                out[i, k] = 0.0
            continue
        if motor_on and tk >= t_e:
            if not advance(t, y, t_e, P, True, work):
                return NON_FINITE, math.nan
            t = t_e
            motor_on = False
        if not advance(t, y, tk, P, motor_on, work):
            return NON_FINITE, math.nan
        t = tk
        rhs(tk, y, P, motor_on, dy, chv)
        for i in range(N_CHANNELS):
            out[i, k] = y[10 + i] if lowpass else chv[i]
    return OK, t_e


@njit(cache=True, parallel=True)
def simulate_many(P_mat, out, t_e, status):
    """Run :func:`simulate_one` for every row of ``P_mat`` in parallel."""
    for i in prange(P_mat.shape[0]):
        s, te = simulate_one(P_mat[i], out[i])
        status[i] = s
        t_e[i] = te


@njit(cache=True, nogil=True)
def simulate_serial(P_mat, out, t_e, status):
    """Run :func:`simulate_one` for every row of ``P_mat`` in this thread, without the GIL.

    For callers that parallelise over threads themselves (several independent
    fits at once): unlike :func:`simulate_many` it does not use numba's
    threading layer, so any number of threads may run it concurrently.
    """
    for i in range(P_mat.shape[0]):
        s, te = simulate_one(P_mat[i], out[i])
        status[i] = s
        t_e[i] = te
