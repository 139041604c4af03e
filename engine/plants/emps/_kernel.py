"""Numba kernel: the EMPS axis in its PD loop, sampled at the controller's rate.

The closed loop transcribes the authors' Simulink model ``Simulink_EMPS_Rigide(_Pulse).slx``
(block by block, see :mod:`engine.plants.emps.model`): at every sample k the controller reads the
position q_k, filters it by ``[0.5 0.5]``, differences it over one sample, computes
``u_k = kv (kp (qg_k - q_k) - dqf_k)``; the drive applies the *previous* sample's command
(a unit delay), saturated at +-10 V, plus the pulse signal [V]; the force ``g_tau v`` is held
over the sample interval while the mechanics are integrated by fixed-step RK4 sub-steps.

Mechanics (rigid axis of the published model, with every candidate effect of the catalogue, of
the held-back family and of the sealed family written in, each neutral at its neutral value)::

    m1 q1'' = F_drive + f_ext - F_f(q1') - F_pos(q1) - F_h(q1, q1') - F_z(q1, q1', F_drive)
              - (offset + d_offset) - f_s
    F_drive = g_tau (1 + eps_g) (1 + eps_a sign(v_d)) v_d,     v_d = dz(v(t - tau), v0)

(the delay tau acts on the held command, linearly mixed within one RK4 sub-step)
    m2 q2'' = f_s,        f_s = k (q1 - q2) + d (q1' - q2')     (flexible transmission only)

    F_f(v) = (Fc + dFc sign v) sign v + (Fv + dFv sign v) v + Fs exp(-(v / v_s)^2) sign v
    F_pos(q) = A_pos sin(2 pi q / p_pos) sign(q1')
    F_h(q, v) = c_q v |v| + A_rip sin(2 pi q / p_pos) + k_c q        (held-back family)
    dz(v, v0) = sign(v) max(|v| - v0, 0)      (amplifier dead band; dz(v, 0) = v)
    F_z(q, v, F) = F_d exp(-((q - q_d) / w_d)^2) sign v + mu |F| sign v        (sealed family)

with f_ext [N] the additive force of the plant's ``force`` entry and of the sealed floor vibration
(added by the model), one value per sample held over the sample interval (none: the input array
is empty). The held-back scalars (parameter entries
``P_DEAD_BAND`` v0 [V], ``P_QUAD_DRAG`` c_q [N s^2/m^2], ``P_RIPPLE`` A_rip [N], ``P_CABLE_K``
k_c [N/m]) are outside the catalogue (:data:`engine.plants.emps.catalogue.HELD_BACK`); so are the
sealed family's in-loop scalars (:data:`engine.plants.emps.catalogue.SEALED`, kept for scoring a
diagnosis once: ``P_GAIN_ASYM`` eps_a [-], ``P_CONTAM_F`` F_d [N] with its documented constants
``P_CONTAM_Q`` q_d [m] and ``P_CONTAM_W`` w_d [m], ``P_SCREW_MU`` mu [-]). Every such term is
skipped at 0, so the neutral model runs exactly the published one's operations.

With the flexibility off (``f_flex <= 0``) m1 = M and m2 carries nothing: the published rigid
model. The parameter vector layout is given by the ``P_*`` indices below; the module
:mod:`engine.plants.emps.model` builds it and documents every entry with its unit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# parameter vector layout
P_M, P_FV, P_FC, P_OFFSET = 0, 1, 2, 3
P_DFC, P_DFV, P_FS, P_VS = 4, 5, 6, 7
P_F_FLEX, P_RHO_FLEX, P_ZETA_FLEX = 8, 9, 10
P_GAIN_ERR, P_D_OFFSET, P_A_POS, P_PERIOD_POS, P_DELAY = 11, 12, 13, 14, 15
P_KP, P_KV, P_GTAU, P_V_SAT, P_TS, P_NSUB = 16, 17, 18, 19, 20, 21
# held-back family (outside the catalogue): v0 [V], c_q [N s^2/m^2], A_rip [N], k_c [N/m]
P_DEAD_BAND, P_QUAD_DRAG, P_RIPPLE, P_CABLE_K = 22, 23, 24, 25
# sealed family (scored once): gain asymmetry eps_a [-], contamination F_d [N] at q_d [m] over w_d [m],
# the screw's load friction mu [-]
P_GAIN_ASYM, P_CONTAM_F, P_CONTAM_Q, P_CONTAM_W, P_SCREW_MU = 26, 27, 28, 29, 30
N_P = 31


@njit(cache=True)
def _sign(x: float) -> float:
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


#: The motor-side force law's parameters as a tuple of scalars (:func:`_forces`), read once per
#: simulation: the right-hand side then keeps them in registers instead of reading the parameter
#: vector at every stage (1.7-2x the kernel's speed, the same operations in the same order).
ForceParameters = tuple[
    float, float, float, float, float, float, float, float, float, float, float, float, float, float, float, float
]


@njit(cache=True)
def _forces(p: np.ndarray) -> ForceParameters:
    """Fc, dFc, Fv, dFv, Fs, v_s, A_pos, p_pos, c_q, A_rip, k_c, F_d, q_d, w_d, offset, d_offset of ``p``."""
    return (
        p[P_FC],
        p[P_DFC],
        p[P_FV],
        p[P_DFV],
        p[P_FS],
        p[P_VS],
        p[P_A_POS],
        p[P_PERIOD_POS],
        p[P_QUAD_DRAG],
        p[P_RIPPLE],
        p[P_CABLE_K],
        p[P_CONTAM_F],
        p[P_CONTAM_Q],
        p[P_CONTAM_W],
        p[P_OFFSET],
        p[P_D_OFFSET],
    )


@njit(cache=True, inline="always")
def _motor_force(c: ForceParameters, q1: float, v1: float) -> float:
    """Friction, position-dependent forces and offset on the motor side [N], counted opposing the drive.

    F_f(v) + F_pos(q) + F_h(q, v) + offset + d_offset of the module docstring and the sealed
    contamination's term of F_z, with ``c`` from :func:`_forces`: a positive value pushes the motor
    backward (it is subtracted from the drive's force ``g_tau v``). The screw's load friction, which
    needs the drive's force, is added in :func:`_rhs`.
    """
    fc, dfc, fv, dfv, fs, vs, a_pos, period, quad, ripple, cable, cf, cq, cw, offset, d_offset = c
    s = _sign(v1)
    f = (fc + dfc * s) * s + (fv + dfv * s) * v1
    if fs != 0.0:
        f += fs * math.exp(-((v1 / vs) ** 2)) * s
    if a_pos != 0.0:
        f += a_pos * math.sin(2.0 * math.pi * q1 / period) * s
    if quad != 0.0:
        f += quad * v1 * abs(v1)
    if ripple != 0.0:
        f += ripple * math.sin(2.0 * math.pi * q1 / period)
    if cable != 0.0:
        f += cable * q1
    if cf != 0.0:
        f += cf * math.exp(-(((q1 - cq) / cw) ** 2)) * s
    return f + offset + d_offset


@njit(cache=True)
def _dead_band(v: float, v0: float) -> float:
    """The amplifier's dead band dz(v, v0) = sign(v) max(|v| - v0, 0) [V]."""
    a = abs(v) - v0
    return _sign(v) * a if a > 0.0 else 0.0


#: The state (q1, v1, q2, v2) [m, m/s, m, m/s], or its derivatives.
State = tuple[float, float, float, float]
#: What a sub-step holds fixed: the total force on the motor side and its drive's part F_drive [N],
#: the two masses m1, m2 [kg], the transmission's stiffness k [N/m] and damping d [N s/m].
SubStep = tuple[float, float, float, float, float, float]


@njit(cache=True, inline="always")
def _rhs(c: ForceParameters, mu: float, x: State, sub: SubStep) -> State:
    """Right-hand side at the state ``x``, with ``sub`` the sub-step's forces and masses and ``mu`` the
    screw's load friction; returns the four derivatives."""
    q1, v1, q2, v2 = x
    force, drive, m1, m2, k, d = sub
    f_s = 0.0
    if k > 0.0:
        f_s = k * (q1 - q2) + d * (v1 - v2)
    f_m = _motor_force(c, q1, v1)
    if mu != 0.0:
        f_m += mu * abs(drive) * _sign(v1)
    return v1, (force - f_m - f_s) / m1, v2, (f_s / m2 if k > 0.0 else 0.0)


@njit(cache=True, inline="always")
def _stage(c: ForceParameters, mu: float, x: State, dx: State, step: float, sub: SubStep) -> State:
    """:func:`_rhs` at ``x + step * dx``, an RK4 stage (``step`` = ``0.5 * h`` gives what
    ``x + 0.5 * h * dx`` computes, to the last bit)."""
    return _rhs(c, mu, (x[0] + step * dx[0], x[1] + step * dx[1], x[2] + step * dx[2], x[3] + step * dx[3]), sub)


@njit(cache=True, nogil=True)
def simulate_loop(p: np.ndarray, qg: np.ndarray, pulse: np.ndarray, f_ext: np.ndarray) -> np.ndarray:
    """Closed-loop response on the record's grid.

    Parameters
    ----------
    p : ndarray, shape (N_P,)
        Parameter vector (layout ``P_*``).
    qg : ndarray, shape (n,)
        Reference position at the samples [m].
    pulse : ndarray, shape (n,)
        Pulse signal added to the saturated command at the samples [V] (zeros without pulses).
    f_ext : ndarray, shape (n,) or (0,)
        Additive force on the motor side per sample [N], held over the sample interval, positive
        forward like the drive's force; empty for none (the loop then skips it). The model adds the
        sealed ``load_vibration`` here (and the ``force`` entry's schedule).

    Returns
    -------
    ndarray, shape (n, 4)
        Per sample: motor position q1 [m], velocity [m/s], acceleration [m/s^2] (the right-hand
        side at the sample instant) and the drive command v applied over the following interval [V]
        (after delay, saturation and pulse: the signal ``vir`` the authors' model outputs).
    """
    n = qg.size
    out = np.zeros((n, 4))
    ts = p[P_TS]
    nsub = int(p[P_NSUB])
    h = ts / nsub
    mass = p[P_M]
    flex = p[P_F_FLEX] > 0.0
    if flex:
        m1 = mass * (1.0 - p[P_RHO_FLEX])
        m2 = mass * p[P_RHO_FLEX]
        m_red = m1 * m2 / mass
        w = 2.0 * math.pi * p[P_F_FLEX]
        k = m_red * w * w
        d = 2.0 * p[P_ZETA_FLEX] * math.sqrt(k * m_red)
    else:
        m1, m2, k, d = mass, 1.0, 0.0, 0.0
    gain = p[P_GTAU] * (1.0 + p[P_GAIN_ERR])
    v0 = p[P_DEAD_BAND]
    eps_a = p[P_GAIN_ASYM]
    has_ext = f_ext.size > 0
    c = _forces(p)
    mu = p[P_SCREW_MU]
    if has_ext and f_ext.size != n:
        raise ValueError("EMPS kernel: the force input needs one value per sample")
    # extra actuator delay in sub-steps: whole part and fraction (the force over a sub-step is the
    # mix of the two commands the delayed switch instant falls between, so the delay is continuous)
    delay_sub = max(p[P_DELAY], 0.0) / h
    delay_steps = int(delay_sub)  # floor: delay_sub >= 0
    delay_frac = delay_sub - delay_steps
    x0 = x1 = x2 = x3 = 0.0  # q1, v1, q2, v2
    v_applied = np.zeros(n)  # drive command per sample interval [V] (after unit delay, saturation, pulse)
    q_prev = 0.0
    qf_prev = 0.0
    u_prev = 0.0
    vsat = p[P_V_SAT]
    for i in range(n):
        q = x0
        qf = 0.5 * q + 0.5 * q_prev
        dqf = (qf - qf_prev) / ts if i > 0 else 0.0
        u_cmd = p[P_KV] * (p[P_KP] * (qg[i] - q) - dqf)
        v = min(max(u_prev, -vsat), vsat) + pulse[i]
        v_applied[i] = v
        u_prev = u_cmd
        q_prev = q
        qf_prev = qf
        for j in range(nsub):
            # the command reaching the drive at this sub-step, delay_steps sub-steps late
            s = i * nsub + j - delay_steps
            v_now = v_applied[s // nsub] if s >= 0 else 0.0
            if delay_frac > 0.0:
                v_before = v_applied[(s - 1) // nsub] if s >= 1 else 0.0
                v_now = (1.0 - delay_frac) * v_now + delay_frac * v_before
            if v0 != 0.0:
                v_now = _dead_band(v_now, v0)
            if eps_a != 0.0:
                v_now *= 1.0 + eps_a * _sign(v_now)
            drive = gain * v_now
            force = drive
            if has_ext:
                force += f_ext[i]
            # RK4 on the state held in scalars (the same operations, in the same order, as on arrays)
            x = (x0, x1, x2, x3)
            sub = (force, drive, m1, m2, k, d)
            a0, a1, a2, a3 = _rhs(c, mu, x, sub)
            if j == 0:
                out[i, 0] = x0
                out[i, 1] = x1
                out[i, 2] = a1
                out[i, 3] = v
            b0, b1, b2, b3 = _stage(c, mu, x, (a0, a1, a2, a3), 0.5 * h, sub)
            e0, e1, e2, e3 = _stage(c, mu, x, (b0, b1, b2, b3), 0.5 * h, sub)
            g0, g1, g2, g3 = _stage(c, mu, x, (e0, e1, e2, e3), h, sub)
            x0 += h * (a0 + 2.0 * b0 + 2.0 * e0 + g0) / 6.0
            x1 += h * (a1 + 2.0 * b1 + 2.0 * e1 + g1) / 6.0
            x2 += h * (a2 + 2.0 * b2 + 2.0 * e2 + g2) / 6.0
            x3 += h * (a3 + 2.0 * b3 + 2.0 * e3 + g3) / 6.0
            if not np.isfinite(x0) or not np.isfinite(x1):
                raise FloatingPointError("EMPS integration diverged")
    return out
