"""Numba kernel: fixed-step RK4 integration of the reference plant with the backlash test.

The equations are those of MODEL.md section 1 written out in real
(alpha, beta) components; :mod:`engine.simulation.reference` holds an
independent numpy transcription in complex notation that the tests compare
against with scipy's solve_ivp.

State vector ``y`` (15 entries; a tuple inside the integrator, so that a step runs in registers:
about 2x the records per core of the array form it replaced, with the same floating-point
operations in the same order, so the same records bit for bit)::

    0..3   psi_s_alpha, psi_s_beta, psi_r_alpha, psi_r_beta   [pu]
    4..6   w_1, w_2, w_3                                      [pu speed]
    7..9   theta_1, theta_2, theta_3                          [mechanical rad]
    10..14 low-pass sensor states of the five channels       [channel units]

Model 1.1 (``docs/model-changes.md``) adds terms that are all neutral at zero:
five parametric ones (load torque ripple, clutch offset, motor cogging, wheel
Coulomb friction, and a share of the torque that decays after the switch-off) and an additive
*unknown input* d(t) at one locus of the plant, a piecewise-linear schedule of up
to ``N_DIST_MAX`` knots (:func:`disturbance`). With every new entry zero the
kernel performs the same floating-point operations as model 1.0, so its records
are bit for bit the same.

Model 1.2 adds seven more parametric terms, one per locus, all neutral at zero and active
only under the same guard (``P_EXTENDED``): a negative-sequence share of the supply voltage,
saturation of the magnetising reactance, fan (windage) torque on the motor shaft, a weak
spring across the clutch, hardening of the resilient element, a spring from the load to
ground, and a once-per-revolution error of the speed encoder (the held-out family,
:data:`engine.simulation.held_out.HELD_OUT`). With all of them zero the kernel performs
model 1.1's floating-point operations.

Model 1.3 adds six more behind the same guard (the sealed family,
:data:`engine.simulation.sealed.SEALED`): a flicker of the supply voltage's amplitude, Stribeck
friction on the motor shaft, a progressive (hardening) contact spring of the clutch, dry friction
inside the resilient element, quadratic drag on the load, and the load accelerometer's cross-axis
sensitivity to a1. (The seventh, higher leakage reactances, needs no term: the simulator adds it to
``P_X_S`` and ``P_X_R``.) With all of them zero the kernel performs model 1.2's floating-point
operations.

Model 1.4 adds seven more behind the same guard (the second sealed family,
:data:`engine.simulation.sealed2.SEALED2`): a DC component of the supply voltage, the core losses as
a resistance in the magnetising branch, bearing friction of the motor under the clutch's load, a
squeeze film in the clutch's gap, play in the resilient element's hub, a bump on the load's track,
and a sample-and-hold of omega1 (in :func:`simulate_one`: the speed at the last hold instant, from
a copy of the state advanced to it, so the plant's own path and the other channels are untouched).
With all of them zero the kernel performs model 1.3's floating-point operations.

Model 1.5 adds seven more behind the same guard (the third sealed family,
:data:`engine.simulation.sealed3.SEALED3`): a high-resistance connection in one phase of the supply,
a broken rotor bar (the rotor's resistance higher along one of its axes), the
spring-applied brake of a brake motor, hysteretic damping of the clutch's contact, the mesh
stiffness variation of a gear stage in the resilient path, an eddy-current brake on the load, and
the mains' hum of a ground loop on the accelerometers' channels. With all of them zero the kernel
performs model 1.4's floating-point operations.

Model 1.6 adds seven more behind the same guard (the fourth sealed family,
:data:`engine.simulation.sealed4.SEALED4`): a pole of the supply's contactor closing late, a share of
phase a's turns bypassed, the rotor rubbing the stator's bore under the magnetic pull, dry friction
between the clutch's halves, the mesh friction of a gear stage in the resilient path, misaligned
guides pinching the load, and a gain error of a current sensor of the torque's estimate (the m_el
channel only). With all of them zero the kernel performs model 1.5's floating-point operations.

Model 1.7 adds seven more behind the same guard (the fifth sealed family,
:data:`engine.simulation.sealed5.SEALED5`): the 5th and 7th harmonics of the supply voltage, the
rotor's residual flux at switch-on (the initial state, :func:`initial_state`), a misaligned motor
shaft (a torque twice per revolution), the runout of the clutch's toothed hub (the backlash's
half-width varying once per revolution, :func:`half_width`), a mass imbalance of the drive wheel,
an elastomer end buffer on the load's track, and the saturation of a1's accelerometer (the a1
channel only). With all of them zero the kernel performs model 1.6's floating-point operations.

Every function but the entry points compiles without numba's reference-counting runtime
(``_nrt=False``, a CPU target option of numba's, used where a function allocates nothing): with it,
the parameter vector P was reference-counted at every call and every inlined call of a step, atomic
increments and decrements that made up 30 % of the kernel's time (``perf``); without it, the same
floating-point operations in the same order, so the same records bit for bit, 1.2x per core. Such a
function must not allocate an array (the entry point :func:`simulate_one` owns every array and keeps
it alive while they run).

The parameter vector layout is given by the ``P_*`` indices below and built by
:func:`engine.simulation.simulator.parameter_vector`; it carries the record's
sample grid too (``P_TS``, ``P_EVENT_INDEX``), and the number of samples is the
length of the output array, so one compiled kernel renders any grid.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from engine.constants import (
    CHANNELS,
    COGGING_ORDER,
    DISTURBANCE_MAX_KNOTS,
    F_FLICKER,
    H_SQUEEZE,
    LOAD_RIPPLE_HZ,
    MESH_ORDER,
    SWITCH_OFF_DECAY_TIME,
    T_BRAKE_APPLY,
    T_BRAKE_RELEASE,
    T_BRAKE_TRAVEL,
    T_POLE_GUARD,
    THETA_BIND,
    THETA_BUMP,
    THETA_STOP,
    W_BUMP,
    W_EDDY,
    W_SMOOTH,
    W_STRIBECK,
    X_REF,
)

#: numba's option for the kernel's functions but its entry points: no reference-counting runtime
#: (``_nrt``, a CPU target option numba's own stubs do not list; see the module docstring).
_NO_NRT: dict[str, Any] = {"_nrt": False}

# parameter vector layout
P_R_S, P_R_R, P_X_S, P_X_R, P_X_M, P_U, P_F = 0, 1, 2, 3, 4, 5, 6
P_T1, P_T2, P_T3 = 7, 8, 9
P_B, P_K12, P_D12, P_K2, P_D2, P_C, P_C1 = 10, 11, 12, 13, 14, 15, 16
P_TAU_C1, P_B_1, P_RADIUS = 17, 18, 19
P_DELAY, P_LOWPASS, P_STEP, P_T_MAX = 20, 21, 22, 23
P_TS, P_EVENT_INDEX, P_TRIGGER_OFFSET = 24, 25, 26
# model 1.1: 1.0 when any of its terms below is active, else 0.0 (then the kernel runs model 1.0's
# operations only, as fast as before); set by engine.simulation.simulator.parameter_vector
P_EXTENDED = 27
# model 1.1: parametric terms of the held-back effects (engine.simulation.held_back)
P_TAU_RIPPLE3, P_CLUTCH_OFFSET, P_TAU_COG, P_TAU_C2, P_M_OFF = 28, 29, 30, 31, 32
# model 1.1: additive unknown input d(t) (see disturbance): locus code, first knot [s since
# switch-on], knot spacing [s], number of knots, a step added from the switch-off on, then the
# knot values
P_DIST_LOCUS, P_DIST_T0, P_DIST_DT, P_DIST_N, P_DIST_STEP = 33, 34, 35, 36, 37
P_DIST_VALUES = 38
#: Most knots of the unknown input's schedule.
N_DIST_MAX = DISTURBANCE_MAX_KNOTS
#: Switch-off instant t_e [s]: not an input; :func:`simulate_one` writes it into its working copy
#: of the parameter vector for the torque's decay after the switch-off (``P_M_OFF``).
P_T_SWITCH_OFF = P_DIST_VALUES + N_DIST_MAX
# model 1.2: parametric terms of the held-out effects (engine.simulation.held_out), appended:
# negative-sequence share of the supply [x u], saturation of x_m [1/pu^2], motor windage
# [pu torque / pu speed^2], clutch preload spring [x k12], hardening of the resilient element
# [1/pu^2], load position spring [pu torque / revolution], speed-encoder eccentricity [x]
P_U_NEG = P_T_SWITCH_OFF + 1
P_SAT = P_U_NEG + 1
P_B_2 = P_SAT + 1
P_K_PRE = P_B_2 + 1
P_HARD2 = P_K_PRE + 1
P_K_3 = P_HARD2 + 1
P_ECC1 = P_K_3 + 1
# model 1.3: parametric terms of the sealed effects (engine.simulation.sealed), appended: flicker of
# the supply voltage [x u], Stribeck friction on J1 [pu torque], progressive contact of the clutch
# [x], dry friction in the resilient element [pu torque], quadratic drag on the load
# [pu torque / pu speed^2], cross-axis sensitivity of the load accelerometer [x]
P_FLICKER = P_ECC1 + 1
P_TAU_S1 = P_FLICKER + 1
P_PROG12 = P_TAU_S1 + 1
P_TAU_DRY2 = P_PROG12 + 1
P_B_3 = P_TAU_DRY2 + 1
P_XTALK2 = P_B_3 + 1
# base values of the per-unit system (MODEL.md section 1): electrical base angular frequency w_b
# [rad/s] and mechanical base speed Omega_b = w_b / p [rad/s]. Parameters, not constants, so that a
# drive described as data (another supply frequency, another pole count) runs on the same kernel;
# the reference plant's values multiply exactly as the constants did (same records bit for bit).
P_W_B = P_XTALK2 + 1
P_OMEGA_B = P_W_B + 1
# model 1.4: parametric terms of the second sealed family (engine.simulation.sealed2), appended:
# DC component of the supply [x u], core-loss resistance of the magnetising branch [pu], bearing
# friction of the motor under the clutch's load [x], squeeze film in the clutch's gap
# [pu torque / pu speed], play in the resilient element's hub [rad], bump on the load's track
# [pu torque], sample-and-hold period of omega1 [s]
P_U_DC = P_OMEGA_B + 1
P_R_M = P_U_DC + 1
P_MU1 = P_R_M + 1
P_SQ12 = P_MU1 + 1
P_PLAY2 = P_SQ12 + 1
P_BUMP3 = P_PLAY2 + 1
P_HOLD1 = P_BUMP3 + 1
# model 1.5: parametric terms of the third sealed family (engine.simulation.sealed3), appended:
# high-resistance connection in phase a of the supply [pu resistance], broken rotor bar [x r_r], the motor's brake
# [pu torque], hysteretic damping of the clutch's contact [x], mesh stiffness variation of the
# resilient stage [x], eddy-current brake on the load [pu torque], mains hum on a1 and a2 [m/s^2]
P_R_CON = P_HOLD1 + 1
P_R_BAR = P_R_CON + 1
P_TAU_BRAKE = P_R_BAR + 1
P_HYST12 = P_TAU_BRAKE + 1
P_MESH2 = P_HYST12 + 1
P_EDDY3 = P_MESH2 + 1
P_HUM = P_EDDY3 + 1
# model 1.6: parametric terms of the fourth sealed family (engine.simulation.sealed4), appended: the
# late pole's closing delay [s], the bypassed share of phase a's turns [x], the rotor's rub [pu torque
# at |psi_s| = 1], dry friction across the clutch [pu torque], the resilient path's gear friction
# [x], the load's binding guides [pu torque at THETA_BIND], the phase-a current sensor's gain error [x]
P_T_POLE = P_HUM + 1
P_BYPASS_A = P_T_POLE + 1
P_TAU_RUB = P_BYPASS_A + 1
P_SEAL12 = P_TAU_RUB + 1
P_GEAR2 = P_SEAL12 + 1
P_BIND3 = P_GEAR2 + 1
P_IGAIN_A = P_BIND3 + 1
# model 1.7: parametric terms of the fifth sealed family (engine.simulation.sealed5), appended: the
# supply's 5th and 7th harmonics [x u], the rotor's residual flux at switch-on [pu], the misaligned
# motor shaft [pu torque], the clutch hub's runout [x b], the drive wheel's imbalance [pu torque],
# the load's end buffer [pu torque at THETA_STOP of compression], a1's saturation [s^2/m]
P_U_H57 = P_IGAIN_A + 1
P_PSI_R0 = P_U_H57 + 1
P_TAU_MIS1 = P_PSI_R0 + 1
P_ECC12 = P_TAU_MIS1 + 1
P_TAU_UNB2 = P_ECC12 + 1
P_BUF3 = P_TAU_UNB2 + 1
P_SAT_A1 = P_BUF3 + 1
N_PARAMS = P_SAT_A1 + 1
#: sqrt(3), of the phase-c axis e^(j 4 pi / 3) = (-1/2, -sqrt(3)/2) and of the current sensor's error.
SQRT3 = math.sqrt(3.0)
#: sqrt(2 e): the bump's force v BUMP_NORM s exp(-s^2) peaks at v (at s = +-1/sqrt(2)).
BUMP_NORM = math.sqrt(2.0 * math.e)

# locus codes of the unknown input (P_DIST_LOCUS): what d(t) is and where it enters
DIST_NONE = 0
DIST_SUPPLY = 1  # relative deviation of the supply voltage amplitude: u -> u (1 + d)
DIST_MOTOR_ELECTRICAL = 2  # additive electromagnetic torque [pu]: in m_el and on J1
DIST_MOTOR_SHAFT = 3  # torque on J1 [pu] (not in m_el)
DIST_CLUTCH = 4  # angle offset of the backlash zone [rad]: d = theta_1 - theta_2 - offset
DIST_DRIVE_TRAIN = 5  # torque on the wheel J2 [pu]
DIST_LOAD = 6  # torque on the load (mass m2, T_3) [pu]
DIST_CLUTCH_TORQUE = 7  # model 1.8: torque across the clutch [pu], from J1 to J2: -d on J1, +d on J2

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


@njit(cache=True, fastmath=False, **_NO_NRT)
def ring_size(P):
    """Checkpoints to keep so that one lies at or before the record's first sample instant.

    The record reaches ``event_index * Ts + max(shift, 0)`` [s] before t_e (shift = delay +
    trigger offset). Checkpoint j is taken at the start of the first step at or after
    j * CHECKPOINT_INTERVAL (steps are shorter than it), so ``span / CHECKPOINT_INTERVAL`` plus
    a margin of a few entries always holds one at or before the first instant. History older
    than ``t_event_max`` is never needed: a first instant before switch-on starts from rest. A
    sample-and-hold of omega1 (model 1.4, ``P_HOLD1``) reaches one hold period further back.
    """
    span = P[P_EVENT_INDEX] * P[P_TS] + max(P[P_DELAY] + P[P_TRIGGER_OFFSET], 0.0)
    if P[P_EXTENDED] != 0.0 and P[P_HOLD1] != 0.0:
        span += P[P_HOLD1]
    span = min(span, P[P_T_MAX])
    return max(MIN_RING, math.ceil(span / CHECKPOINT_INTERVAL) + _RING_MARGIN)


@njit(cache=True, fastmath=False, **_NO_NRT)
def smooth_sign(w):
    """tanh(w / W_SMOOTH), MODEL.md's smoothed sign; exactly +-1 in double precision beyond |w| > 20 W_SMOOTH.

    Evaluated as ``(1 - e) / (1 + e)`` with ``e = exp(-2 |x|)``, within 2.2e-16 (absolute) of the C
    library's ``tanh`` (1 unit in the last place of 1; 2 ulp of the value for |x| >= 1): the C
    library's ``tanh`` goes through ``expm1``, about three times the cost of ``exp``, and the test's
    speeds stay below the smoothing scale for most of a record (the motor below 0.02 pu, the load
    below 0.03 pu), so this sign ran four times per step and was a fifth of the kernel's time
    (1.2x records per core; ``docs/identification.md``). Not bit for bit the records of the ``tanh``
    form: MODEL.md's accuracy (0.5 % of peak-to-peak) is met with the same margin.
    """
    x = w / W_SMOOTH
    if x > 20.0:
        return 1.0
    if x < -20.0:
        return -1.0
    e = math.exp(-2.0 * abs(x))
    z = (1.0 - e) / (1.0 + e)
    return z if x >= 0.0 else -z


@njit(cache=True, fastmath=False, **_NO_NRT)
def disturbance(t, P):
    """The unknown input d(t) of the schedule in P (unit of its locus, see ``DIST_*``).

    Knot j (0 <= j < n) lies at ``P[P_DIST_T0] + j * P[P_DIST_DT]`` [s since switch-on] and holds
    ``P[P_DIST_VALUES + j]``; d is zero one spacing before the first knot and one after the last,
    and linear in between: continuous, and a schedule with one non-zero knot is a hat function
    of half-width one spacing. The integrator cuts its steps at the knots (:func:`step_to_knot`).
    From the switch-off on, the callers add the step ``P[P_DIST_STEP]`` (a jump of d at the
    event, where the motor's torque jumps too).
    """
    n = int(P[P_DIST_N])
    x = (t - P[P_DIST_T0]) / P[P_DIST_DT]
    if n < 1 or x <= -1.0 or x >= n:
        return 0.0
    j = math.floor(x)
    frac = x - j
    left = P[P_DIST_VALUES + j] if j >= 0 else 0.0
    right = P[P_DIST_VALUES + j + 1] if j + 1 < n else 0.0
    return (1.0 - frac) * left + frac * right


@njit(cache=True, fastmath=False, **_NO_NRT)
def step_to_knot(t, h, P):
    """The step h [s] from t, shortened to end at the next kink of the unknown input if it lies within.

    The kinks are the knots and the two zero points one spacing outside them. A kink closer to t
    than 1e-7 spacings counts as passed (so a step never shrinks to nothing). With model 1.6's late
    pole (``P_T_POLE``) a step also ends T_POLE_GUARD before the pole's closing instant, where the
    right-hand side jumps, and the next one T_POLE_GUARD after it: every stage of a step then lies on
    one side of the jump but for that short step's (an instant closer than a tenth of T_POLE_GUARD
    counts as passed).
    """
    if P[P_EXTENDED] == 0.0:
        return h
    if P[P_T_POLE] != 0.0:
        t_cut = P[P_T_POLE] - T_POLE_GUARD
        if t_cut - t <= 0.1 * T_POLE_GUARD:
            t_cut = P[P_T_POLE] + T_POLE_GUARD
        if t_cut - t > 0.1 * T_POLE_GUARD:
            h = min(h, t_cut - t)
    if P[P_DIST_LOCUS] == DIST_NONE:
        return h
    dt = P[P_DIST_DT]
    n = int(P[P_DIST_N])
    j = math.floor((t - P[P_DIST_T0]) / dt + 1e-7) + 1
    j = max(j, -1)
    if j > n:
        return h
    t_knot = P[P_DIST_T0] + j * dt
    return min(h, t_knot - t)


@njit(cache=True, fastmath=False, **_NO_NRT)
def clutch_deflection(t, y, P, motor_on):
    """theta_1 - theta_2 less the offset of the backlash zone [rad] (model 1.1: fixed plus unknown input)."""
    d = y[7] - y[8] - P[P_CLUTCH_OFFSET]
    if P[P_DIST_LOCUS] == DIST_CLUTCH:
        d -= disturbance(t, P) if motor_on else disturbance(t, P) + P[P_DIST_STEP]
    return d


@njit(cache=True, fastmath=False, **_NO_NRT)
def contact_push(d, dw, b, P, ext):
    """The clutch's contact torque before its clip, k12 x + d12 dw [pu], at a deflection d outside the zone.

    x = d - b or d + b is the signed penetration beyond the zone's edge [rad], b the zone's half-width
    (:func:`half_width`: model 1.7's runout makes it vary with theta_1); with model 1.3's
    progressive contact (``P_PROG12``, under the guard ``ext``) the spring is k12 x (1 + prog12 |x| / X_REF), and
    with model 1.5's hysteresis (``P_HYST12``) also times 1 + hyst12 tanh(sgn(x) dw / W_SMOOTH)
    (:func:`shaped_contact_spring`).
    The caller clips it (a contact can push, never pull). Inlined (numba IR) into its callers,
    :func:`rhs` and :func:`zone`, which evaluate it at every stage of every step.
    """
    x = d - b if d > b else d + b
    spring = P[P_K12] * x
    if ext and (P[P_PROG12] != 0.0 or P[P_HYST12] != 0.0):
        spring = shaped_contact_spring(spring, x, dw, P)
    return spring + P[P_D12] * dw


@njit(cache=True, fastmath=False, **_NO_NRT)
def shaped_contact_spring(spring, x, dw, P):
    """The contact spring k12 x [pu] shaped by model 1.3's progressive contact and model 1.5's hysteresis.

    Progressive (``P_PROG12``): times 1 + prog12 |x| / X_REF. Hysteretic (``P_HYST12``): times
    1 + hyst12 tanh(sgn(x) dw / W_SMOOTH), stiffer while the penetration x deepens, softer while it
    recedes. A function of its own, called only when one of them is on: the hysteresis's branch in
    :func:`contact_push`, inlined at every stage of every step, cost the kernel time with every term
    off (as model 1.4's mechanical terms did in :func:`rhs`).
    """
    if P[P_PROG12] != 0.0:  # progressive contact: the spring hardens with the penetration
        spring = spring * (1.0 + P[P_PROG12] * abs(x) / X_REF)
    if P[P_HYST12] != 0.0:  # hysteresis: stiffer while x deepens, softer while it recedes
        spring = spring * (1.0 + P[P_HYST12] * smooth_sign(dw if x > 0.0 else -dw))
    return spring


@njit(cache=True, fastmath=False, **_NO_NRT)
def sealed2_torques(y, d, dw, m_c, b, P):
    """The mechanical torques of model 1.4's second sealed family at (y, d, dw) [pu], each 0 when its value is.

    Returns ``m_sq``, the squeeze film in the clutch's gap h = max(b - |d|, 0) (b the zone's
    half-width, :func:`half_width`; from J1 to J2, beside
    the contact torque ``m_c``, unclipped); ``m_play``, what the hub's play takes off the resilient
    spring, k2 play2 tanh((theta_2 - theta_3) / play2) (from J2 to the mass); ``m_bearing``, the
    motor's bearing friction mu_1 |m_c + m_sq| tanh(w_1 / W_SMOOTH) (against J1); and ``m_bump``, the
    track bump's force on the mass. A function of its own, called only when one of them is on: with
    these terms written into :func:`rhs`, the kernel ran 3-4 % slower with every term off (the code
    generated for the right-hand side, not the skipped branches; the same with them inside its
    ``if ext`` block).
    """
    m_sq = 0.0
    if P[P_SQ12] != 0.0:
        g = H_SQUEEZE / (H_SQUEEZE + b - abs(d)) if abs(d) < b else 1.0
        m_sq = P[P_SQ12] * g * g * g * dw
    m_play = 0.0
    if P[P_PLAY2] != 0.0:
        m_play = P[P_K2] * P[P_PLAY2] * math.tanh((y[8] - y[9]) / P[P_PLAY2])
    m_bearing = 0.0
    if P[P_MU1] != 0.0:
        m_bearing = P[P_MU1] * abs(m_c + m_sq) * smooth_sign(y[4])
    m_bump = 0.0
    if P[P_BUMP3] != 0.0:
        sb = (y[9] - THETA_BUMP) / W_BUMP
        m_bump = P[P_BUMP3] * BUMP_NORM * sb * math.exp(-(sb * sb))
    return m_sq, m_play, m_bearing, m_bump


@njit(cache=True, fastmath=False, **_NO_NRT)
def smoothstep(x):
    """3 x^2 - 2 x^3 for x in [0, 1], 0 below, 1 above: a ramp with zero slope at both ends."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x * x * (3.0 - 2.0 * x)


@njit(cache=True, fastmath=False, **_NO_NRT)
def sealed3_torques(t, y, P, motor_on):
    """The mechanical torques of model 1.5's third sealed family at (t, y) [pu], each 0 when its value is.

    Returns ``m_brake``, the motor brake's torque against J1's motion, tau_brake g_b(t)
    tanh(w_1 / W_SMOOTH), g_b the brake's engagement (1 at switch-on, lifting T_BRAKE_RELEASE after
    it, falling again T_BRAKE_APPLY after the switch-off ``P[P_T_SWITCH_OFF]``, each along a
    smoothstep of T_BRAKE_TRAVEL); ``m_mesh``, what the mesh stiffness variation adds to the
    resilient element's torque, k2 x mesh2 sin(MESH_ORDER theta_2) (from J2 to the mass); and
    ``m_eddy``, the eddy-current brake's force against the mass's motion, eddy3 2 s / (1 + s^2),
    s = w_3 / W_EDDY. A function of its own, called only when one of them is on (as model 1.4's
    :func:`sealed2_torques`, so that the right-hand side's code is unchanged with every term off).
    """
    m_brake = 0.0
    if P[P_TAU_BRAKE] != 0.0:
        if motor_on:
            g = 1.0 - smoothstep((t - T_BRAKE_RELEASE) / T_BRAKE_TRAVEL)
        else:
            g = smoothstep((t - P[P_T_SWITCH_OFF] - T_BRAKE_APPLY) / T_BRAKE_TRAVEL)
        m_brake = P[P_TAU_BRAKE] * g * smooth_sign(y[4])
    m_mesh = 0.0
    if P[P_MESH2] != 0.0:
        m_mesh = P[P_K2] * (y[8] - y[9]) * P[P_MESH2] * math.sin(MESH_ORDER * y[8])
    m_eddy = 0.0
    if P[P_EDDY3] != 0.0:
        s = y[6] / W_EDDY
        m_eddy = P[P_EDDY3] * 2.0 * s / (1.0 + s * s)
    return m_brake, m_mesh, m_eddy


@njit(cache=True, fastmath=False, **_NO_NRT)
def sealed4_torques(y, m_s, P, motor_on):
    """The mechanical torques of model 1.6's fourth sealed family at y [pu], each 0 when its value is.

    Returns ``m_rub``, the rotor's rub on the stator's bore against J1's motion, tau_rub |psi_s|^2
    tanh(w_1 / W_SMOOTH) while the motor is on (0 after the switch-off); ``m_seal``, the dry friction
    between the clutch's halves, seal12 tanh((w_1 - w_2) / W_SMOOTH) (from J1 to J2, at every
    deflection); ``m_gear``, the resilient path's gear friction against the wheel's motion, gear2
    |m_s| tanh(w_2 / W_SMOOTH); and ``m_bind``, the binding guides' friction against the mass's
    motion, bind3 |theta_3| / THETA_BIND tanh(w_3 / W_SMOOTH). A function of its own, called only when
    one of them is on (as :func:`sealed2_torques` and :func:`sealed3_torques`).
    """
    m_rub = 0.0
    if P[P_TAU_RUB] != 0.0 and motor_on:
        m_rub = P[P_TAU_RUB] * (y[0] * y[0] + y[1] * y[1]) * smooth_sign(y[4])
    m_seal = 0.0
    if P[P_SEAL12] != 0.0:
        m_seal = P[P_SEAL12] * smooth_sign(y[4] - y[5])
    m_gear = 0.0
    if P[P_GEAR2] != 0.0:
        m_gear = P[P_GEAR2] * abs(m_s) * smooth_sign(y[5])
    m_bind = 0.0
    if P[P_BIND3] != 0.0:
        m_bind = P[P_BIND3] * abs(y[9]) / THETA_BIND * smooth_sign(y[6])
    return m_rub, m_seal, m_gear, m_bind


@njit(cache=True, fastmath=False, **_NO_NRT)
def half_width(y, P, ext):
    """The backlash zone's half-width [rad]: b, or with model 1.7's hub runout b (1 + ecc12 sin(theta_1)).

    The runout of the clutch's toothed hub (``P_ECC12``, under the guard ``ext``) moves the mesh's
    centre distance once per revolution of the motor, and with it the backlash: the contact, its
    modes, the squeeze film's gap and the event all see this half-width.
    """
    if ext and P[P_ECC12] != 0.0:
        return P[P_B] * (1.0 + P[P_ECC12] * math.sin(y[7]))
    return P[P_B]


@njit(cache=True, fastmath=False, **_NO_NRT)
def sealed5_torques(y, P):
    """The mechanical torques of model 1.7's fifth sealed family at y [pu], each 0 when its value is.

    Returns ``m_mis``, the misaligned motor shaft's torque on J1, -tau_mis1 sin(2 theta_1);
    ``m_unb``, the drive wheel's imbalance on J2, -tau_unb2 sin(theta_2); and ``m_buf``, the end
    buffer's force on the mass, -buf3 ((theta_3 - THETA_STOP) / THETA_STOP)^2 from theta_3 =
    THETA_STOP on (zero before). A function of its own, called only when one of them is on (as
    :func:`sealed2_torques` to :func:`sealed4_torques`).
    """
    m_mis = 0.0
    if P[P_TAU_MIS1] != 0.0:
        m_mis = -P[P_TAU_MIS1] * math.sin(2.0 * y[7])
    m_unb = 0.0
    if P[P_TAU_UNB2] != 0.0:
        m_unb = -P[P_TAU_UNB2] * math.sin(y[8])
    m_buf = 0.0
    if P[P_BUF3] != 0.0 and y[9] > THETA_STOP:
        x = (y[9] - THETA_STOP) / THETA_STOP
        m_buf = -P[P_BUF3] * x * x
    return m_mis, m_unb, m_buf


@njit(cache=True, fastmath=False, **_NO_NRT)
def bypassed_currents(psa, pra, xs, xr, xm, P):
    """(i_s_alpha, i_r_alpha) [pu] with a share ``P[P_BYPASS_A]`` of phase a's turns bypassed (model 1.6).

    The alpha axis's inductances: the stator's n^2 x_m + s (x_s - x_m), the mutual n x_m, the rotor's
    x_r, with n = 1 - (2/3) v and s = 1 - (4/3) v + (2/3) v^2 (phase a's turns (1 - v), its leakage
    (1 - v)^2, seen from the alpha axis with the star point floating); the beta axis is unchanged.
    """
    v = P[P_BYPASS_A]
    n = 1.0 - 2.0 / 3.0 * v
    a11 = n * n * xm + (1.0 - 4.0 / 3.0 * v + 2.0 / 3.0 * v * v) * (xs - xm)
    a12 = n * xm
    det = a11 * xr - a12 * a12
    return (xr * psa - a12 * pra) / det, (a11 * pra - a12 * psa) / det


@njit(cache=True, fastmath=False, **_NO_NRT)
def electromagnetic_torque(y, P):
    """m_el = psi_s_alpha i_s_beta - psi_s_beta i_s_alpha [pu] of the fluxes in y (model 1.2: saturated x_m)."""
    xs = P[P_X_S]
    xr = P[P_X_R]
    xm = P[P_X_M]
    if P[P_EXTENDED] != 0.0 and P[P_SAT] != 0.0:
        xm_eff = xm / (1.0 + P[P_SAT] * (y[0] * y[0] + y[1] * y[1]))
        xs = xs - xm + xm_eff
        xr = xr - xm + xm_eff
        xm = xm_eff
    det = xs * xr - xm * xm
    isa = (xr * y[0] - xm * y[2]) / det
    isb = (xr * y[1] - xm * y[3]) / det
    if P[P_EXTENDED] != 0.0 and P[P_BYPASS_A] != 0.0:  # model 1.6: the torque on the rotor, alpha asymmetric
        ira = bypassed_currents(y[0], y[2], xs, xr, xm, P)[1]
        irb = (xs * y[3] - xm * y[1]) / det
        return y[3] * ira - y[2] * irb
    return y[0] * isb - y[1] * isa


@njit(cache=True, fastmath=False, **_NO_NRT)
def rhs(t, y, P, motor_on):
    """Right-hand side dy/dt and the five channel values at (t, y).

    Parameters
    ----------
    t : float
        Time since switch-on [s].
    y : tuple of float, length N_STATES
        The state (layout in the module docstring). A tuple, not an array: the integrator keeps
        the state in registers, which makes a step about twice as fast as with arrays (the same
        floating-point operations, so the same records bit for bit).
    P : ndarray, shape (N_PARAMS,)
        Parameter vector.
    motor_on : bool
        Whether the supply is on (before the switch-off t_e).

    Returns
    -------
    dy : tuple of float, length N_STATES
        dy/dt.
    ch : tuple of float, length N_CHANNELS
        [a1 m/s^2, m_el pu, omega1 rad/s, a2 m/s^2, v2 m/s]; with a low-pass sensor
        (P[P_LOWPASS] > 0) these are the unfiltered values that drive the sensor states y[10:15].
    """
    psa = y[0]
    psb = y[1]
    pra = y[2]
    prb = y[3]
    w1 = y[4]
    w2 = y[5]
    w3 = y[6]
    ext = P[P_EXTENDED] != 0.0
    locus = P[P_DIST_LOCUS] if ext else DIST_NONE
    dd = 0.0
    m_err = 0.0  # model 1.6: the torque estimate's error (the m_el channel only)
    if locus != DIST_NONE:
        dd = disturbance(t, P) if motor_on else disturbance(t, P) + P[P_DIST_STEP]
    if motor_on:
        xs = P[P_X_S]
        xr = P[P_X_R]
        xm = P[P_X_M]
        if ext and P[P_SAT] != 0.0:  # saturation: x_m falls with the stator flux, leakages unchanged
            xm_eff = xm / (1.0 + P[P_SAT] * (psa * psa + psb * psb))
            xs = xs - xm + xm_eff
            xr = xr - xm + xm_eff
            xm = xm_eff
        det = xs * xr - xm * xm
        isa = (xr * psa - xm * pra) / det
        isb = (xr * psb - xm * prb) / det
        ira = (xs * pra - xm * psa) / det
        irb = (xs * prb - xm * psb) / det
        bypass = ext and P[P_BYPASS_A] != 0.0
        if bypass:  # model 1.6: a share of phase a's turns bypassed: the alpha axis's own inductances
            isa, ira = bypassed_currents(psa, pra, xs, xr, xm, P)
        ang = P[P_F] * P[P_W_B] * t
        u = P[P_U]
        if locus == DIST_SUPPLY:
            u = u * (1.0 + dd)
        if ext and P[P_FLICKER] != 0.0:  # flicker of the voltage's amplitude at F_FLICKER
            u = u * (1.0 + P[P_FLICKER] * math.sin(2.0 * math.pi * F_FLICKER * t))
        usa = u * math.cos(ang)
        usb = u * math.sin(ang)
        if ext and P[P_U_NEG] != 0.0:  # negative sequence: u (e^{j ang} + u_neg e^{-j ang})
            usa += P[P_U_NEG] * u * math.cos(ang)
            usb -= P[P_U_NEG] * u * math.sin(ang)
        if ext and P[P_U_DC] != 0.0:  # a DC component of the supply in the alpha axis (phase a)
            usa += P[P_U_DC] * P[P_U]
        if ext and P[P_U_H57] != 0.0:  # model 1.7: 5th (negative) and 7th (positive sequence) harmonics
            uh = P[P_U_H57] * P[P_U]
            usa += uh * (math.cos(5.0 * ang) + math.cos(7.0 * ang))
            usb += uh * (math.sin(7.0 * ang) - math.sin(5.0 * ang))
        if ext and P[P_R_CON] != 0.0:  # a resistance in phase a (star point floating): 2/3 r_con i_sa off u_sa
            usa -= 2.0 / 3.0 * P[P_R_CON] * isa
        dpsa = P[P_W_B] * (usa - P[P_R_S] * isa)
        dpsb = P[P_W_B] * (usb - P[P_R_S] * isb)
        dpra = P[P_W_B] * (-P[P_R_R] * ira - w1 * prb)
        dprb = P[P_W_B] * (-P[P_R_R] * irb + w1 * pra)
        if ext and P[P_R_M] != 0.0:  # core losses: r_m in the magnetising branch, on i_m = i_s + i_r
            rma = P[P_W_B] * P[P_R_M] * (isa + ira)
            rmb = P[P_W_B] * P[P_R_M] * (isb + irb)
            dpsa -= rma
            dpsb -= rmb
            dpra -= rma
            dprb -= rmb
        if ext and P[P_R_BAR] != 0.0:  # broken rotor bar: r_bar r_r more along the rotor's axis at p theta_1
            gam = y[7] * (P[P_W_B] / P[P_OMEGA_B])
            cg = math.cos(gam)
            sg = math.sin(gam)
            drop = P[P_W_B] * P[P_R_BAR] * P[P_R_R] * (ira * cg + irb * sg)
            dpra -= drop * cg
            dprb -= drop * sg
        if bypass:  # the alpha axis's resistance is n r_s: (2/3) v r_s i_s_alpha back
            dpsa += P[P_W_B] * (2.0 / 3.0 * P[P_BYPASS_A]) * P[P_R_S] * isa
        if ext and P[P_T_POLE] != 0.0 and t < P[P_T_POLE]:  # phase c open: i_s along e_c stays zero
            along = (xm / xr) * (-0.5 * dpra - 0.5 * SQRT3 * dprb) - (-0.5 * dpsa - 0.5 * SQRT3 * dpsb)
            dpsa -= 0.5 * along
            dpsb -= 0.5 * SQRT3 * along
        # with bypassed turns, the torque on the rotor (the stator's alpha axis is not the beta axis's)
        m_el = prb * ira - pra * irb if bypass else psa * isb - psb * isa
        if ext and P[P_IGAIN_A] != 0.0:  # the phase-a current sensor of the torque's estimate reads high
            m_err = P[P_IGAIN_A] * isa * (psa / SQRT3 - psb)
    else:
        dpsa = 0.0
        dpsb = 0.0
        dpra = 0.0
        dprb = 0.0
        m_el = 0.0
        if ext and P[P_M_OFF] != 0.0:  # a share of the torque at the switch-off decays (the fluxes are frozen since)
            decay = math.exp(-(t - P[P_T_SWITCH_OFF]) / SWITCH_OFF_DECAY_TIME)
            m_el = P[P_M_OFF] * electromagnetic_torque(y, P) * decay
    if locus == DIST_MOTOR_ELECTRICAL:
        m_el += dd
    # clutch with backlash: a contact can push, never pull
    d = clutch_deflection(t, y, P, motor_on) if ext else y[7] - y[8]
    dw = w1 - w2
    b = half_width(y, P, ext)
    if d > b:
        m_c = max(0.0, contact_push(d, dw, b, P, ext))
    elif d < -b:
        m_c = min(0.0, contact_push(d, dw, b, P, ext))
    else:
        m_c = 0.0
    m_s = P[P_K2] * (y[8] - y[9]) + P[P_D2] * (w2 - w3)
    if ext and P[P_HARD2] != 0.0:  # hardening resilient element: k2 x (1 + hard2 (k2 x)^2)
        kx = P[P_K2] * (y[8] - y[9])
        m_s += P[P_HARD2] * kx * kx * kx
    if ext and P[P_TAU_DRY2] != 0.0:  # dry friction inside the resilient element
        m_s += P[P_TAU_DRY2] * smooth_sign(w2 - w3)
    m_a = P[P_C] * w3 + P[P_C1] * smooth_sign(w3)
    m_f = P[P_B_1] * w1
    if P[P_TAU_C1] != 0.0:
        m_f += P[P_TAU_C1] * smooth_sign(w1)
    m_1 = m_el - m_c - m_f
    m_2 = m_c - m_s
    m_3 = m_s - m_a
    if ext:
        m_res = m_s  # the resilient element's whole torque, with 1.4's play and 1.5's mesh (for 1.6's gear)
        # cogging: periodic in the motor angle, COGGING_ORDER periods per revolution
        m_1 -= P[P_TAU_COG] * math.sin(COGGING_ORDER * y[7])
        m_2 -= P[P_TAU_C2] * smooth_sign(w2)  # Coulomb friction of the wheel
        m_3 += P[P_TAU_RIPPLE3] * math.sin(2.0 * math.pi * LOAD_RIPPLE_HZ * t)  # load torque ripple
        if P[P_B_2] != 0.0:  # windage (fan) torque against the motor's motion
            m_1 -= P[P_B_2] * w1 * abs(w1)
        if P[P_K_PRE] != 0.0:  # a weak spring across the clutch, inside and outside the zone
            m_pre = P[P_K_PRE] * P[P_K12] * d
            m_1 -= m_pre
            m_2 += m_pre
        if P[P_K_3] != 0.0:  # a spring from the load to ground [pu torque per revolution]
            m_3 -= P[P_K_3] * y[9] / (2.0 * math.pi)
        if P[P_TAU_S1] != 0.0:  # Stribeck friction of the motor shaft, fading above W_STRIBECK
            s = w1 / W_STRIBECK
            m_1 -= P[P_TAU_S1] * smooth_sign(w1) * math.exp(-(s * s))
        if P[P_B_3] != 0.0:  # quadratic drag on the load against its motion
            m_3 -= P[P_B_3] * w3 * abs(w3)
        if P[P_SQ12] != 0.0 or P[P_PLAY2] != 0.0 or P[P_MU1] != 0.0 or P[P_BUMP3] != 0.0:  # model 1.4
            m_sq, m_play, m_bearing, m_bump = sealed2_torques(y, d, dw, m_c, b, P)
            m_1 -= m_sq + m_bearing
            m_2 += m_sq + m_play
            m_3 += m_bump - m_play
            m_res -= m_play
        if P[P_TAU_BRAKE] != 0.0 or P[P_MESH2] != 0.0 or P[P_EDDY3] != 0.0:  # model 1.5
            m_brake, m_mesh, m_eddy = sealed3_torques(t, y, P, motor_on)
            m_1 -= m_brake
            m_2 -= m_mesh
            m_3 += m_mesh - m_eddy
            m_res += m_mesh
        if P[P_TAU_RUB] != 0.0 or P[P_SEAL12] != 0.0 or P[P_GEAR2] != 0.0 or P[P_BIND3] != 0.0:  # model 1.6
            m_rub, m_seal, m_gear, m_bind = sealed4_torques(y, m_res, P, motor_on)
            m_1 -= m_rub + m_seal
            m_2 += m_seal - m_gear
            m_3 -= m_bind
        if P[P_TAU_MIS1] != 0.0 or P[P_TAU_UNB2] != 0.0 or P[P_BUF3] != 0.0:  # model 1.7
            m_mis, m_unb, m_buf = sealed5_torques(y, P)
            m_1 += m_mis
            m_2 += m_unb
            m_3 += m_buf
        if locus == DIST_MOTOR_SHAFT:
            m_1 += dd
        elif locus == DIST_DRIVE_TRAIN:
            m_2 += dd
        elif locus == DIST_LOAD:
            m_3 += dd
        elif locus == DIST_CLUTCH_TORQUE:  # model 1.8: a torque the clutch's halves exert on each other
            m_1 -= dd
            m_2 += dd
    dw1 = m_1 / P[P_T1]
    dw2 = m_2 / P[P_T2]
    dw3 = m_3 / P[P_T3]
    r = P[P_RADIUS]
    ch0 = r * P[P_OMEGA_B] * dw1
    ch2 = P[P_OMEGA_B] * w1
    if ext and P[P_ECC1] != 0.0:  # once-per-revolution error of the speed encoder
        ch2 = P[P_OMEGA_B] * w1 * (1.0 + P[P_ECC1] * math.sin(y[7]))
    ch3 = r * P[P_OMEGA_B] * dw3
    if ext and P[P_XTALK2] != 0.0:  # cross-axis sensitivity of the load accelerometer to a1
        ch3 += P[P_XTALK2] * ch0
    if ext and P[P_HUM] != 0.0:  # mains hum of a ground loop in the accelerometers' cabling
        hum = P[P_HUM] * math.sin(P[P_F] * P[P_W_B] * t)
        ch0 += hum
        ch3 += hum
    if ext and P[P_SAT_A1] != 0.0:  # model 1.7: a1's accelerometer saturates (a2's cross-talk took the true a1)
        ch0 = math.tanh(P[P_SAT_A1] * ch0) / P[P_SAT_A1]
    ch4 = r * P[P_OMEGA_B] * w3
    ch1 = m_el
    if ext and P[P_IGAIN_A] != 0.0:  # the torque estimate's error, in the channel only (not on J1)
        ch1 = m_el + m_err
    fc = P[P_LOWPASS]
    if fc > 0.0:
        a = 2.0 * math.pi * fc
        f0 = a * (ch0 - y[10])
        f1 = a * (ch1 - y[11])
        f2 = a * (ch2 - y[12])
        f3 = a * (ch3 - y[13])
        f4 = a * (ch4 - y[14])
    else:
        f0 = f1 = f2 = f3 = f4 = 0.0
    dy = (
        dpsa,
        dpsb,
        dpra,
        dprb,
        dw1,
        dw2,
        dw3,
        P[P_OMEGA_B] * w1,
        P[P_OMEGA_B] * w2,
        P[P_OMEGA_B] * w3,
        f0,
        f1,
        f2,
        f3,
        f4,
    )
    return dy, (ch0, ch1, ch2, ch3, ch4)


@njit(cache=True, fastmath=False, **_NO_NRT)
def _axpy(y, a, k):
    """The state y + a k, element by element (tuples of N_STATES floats)."""
    return (
        y[0] + a * k[0],
        y[1] + a * k[1],
        y[2] + a * k[2],
        y[3] + a * k[3],
        y[4] + a * k[4],
        y[5] + a * k[5],
        y[6] + a * k[6],
        y[7] + a * k[7],
        y[8] + a * k[8],
        y[9] + a * k[9],
        y[10] + a * k[10],
        y[11] + a * k[11],
        y[12] + a * k[12],
        y[13] + a * k[13],
        y[14] + a * k[14],
    )


@njit(cache=True, fastmath=False, **_NO_NRT)
def _rk4_sum(y, h6, k1, k2, k3, k4):
    """RK4's new state y + h/6 (k1 + 2 k2 + 2 k3 + k4), element by element, evaluated left to right."""
    return (
        y[0] + h6 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
        y[1] + h6 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        y[2] + h6 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
        y[3] + h6 * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]),
        y[4] + h6 * (k1[4] + 2.0 * k2[4] + 2.0 * k3[4] + k4[4]),
        y[5] + h6 * (k1[5] + 2.0 * k2[5] + 2.0 * k3[5] + k4[5]),
        y[6] + h6 * (k1[6] + 2.0 * k2[6] + 2.0 * k3[6] + k4[6]),
        y[7] + h6 * (k1[7] + 2.0 * k2[7] + 2.0 * k3[7] + k4[7]),
        y[8] + h6 * (k1[8] + 2.0 * k2[8] + 2.0 * k3[8] + k4[8]),
        y[9] + h6 * (k1[9] + 2.0 * k2[9] + 2.0 * k3[9] + k4[9]),
        y[10] + h6 * (k1[10] + 2.0 * k2[10] + 2.0 * k3[10] + k4[10]),
        y[11] + h6 * (k1[11] + 2.0 * k2[11] + 2.0 * k3[11] + k4[11]),
        y[12] + h6 * (k1[12] + 2.0 * k2[12] + 2.0 * k3[12] + k4[12]),
        y[13] + h6 * (k1[13] + 2.0 * k2[13] + 2.0 * k3[13] + k4[13]),
        y[14] + h6 * (k1[14] + 2.0 * k2[14] + 2.0 * k3[14] + k4[14]),
    )


@njit(cache=True, fastmath=False, **_NO_NRT)
def rk4_step(t, y, h, P, motor_on):
    """One classical Runge-Kutta step of size h [s] from (t, y); returns the new state (a tuple).

    Called by :func:`hybrid_step` only. It and its helpers are plain calls: inlined in numba IR
    (``inline="always"``) they made the kernel compile for 180 s, as calls 15 s, with every record bit for bit
    and the kernel 1.12x faster (docs/diagnosis.md, "The inlining undone").
    """
    hh = 0.5 * h  # the operations of y + 0.5 * h * k, evaluated left to right
    t_half = t + hh
    k1 = rhs(t, y, P, motor_on)[0]
    k2 = rhs(t_half, _axpy(y, hh, k1), P, motor_on)[0]
    k3 = rhs(t_half, _axpy(y, hh, k2), P, motor_on)[0]
    k4 = rhs(t + h, _axpy(y, h, k3), P, motor_on)[0]
    return _rk4_sum(y, h / 6.0, k1, k2, k3, k4)


@njit(cache=True, fastmath=False, **_NO_NRT)
def zone(t, y, P, motor_on):
    """Clutch mode of state y at time t [s] (the zone's offset may depend on t and on ``motor_on``).

    0 inside the backlash (|d| <= b); +1 / -1 in contact and pushing;
    +2 / -2 penetrated but with the contact force clipped to zero (the contact
    can push, never pull). Mode changes are where the right-hand side is
    discontinuous (contact entry) or kinked (clipping).
    """
    ext = P[P_EXTENDED] != 0.0
    b = half_width(y, P, ext)
    d = clutch_deflection(t, y, P, motor_on) if ext else y[7] - y[8]
    if -b <= d <= b:
        return 0
    dw = y[4] - y[5]
    if d > b:
        return 1 if contact_push(d, dw, b, P, ext) > 0.0 else 2
    return -1 if contact_push(d, dw, b, P, ext) < 0.0 else -2


@njit(cache=True, fastmath=False, **_NO_NRT)
def hybrid_step(t, y, h, P, motor_on, z0):
    """One RK4 step of at most h from (t, y) that stops at a clutch-zone change.

    The contact torque is discontinuous where the clutch enters contact
    (it jumps to d_12 * dw), so a step that crosses a zone boundary is cut at
    the crossing, located by bisection to 1e-12 s; RK4 then only integrates a
    smooth right-hand side and keeps its order.

    The whole step, the bisection's trial steps and the step to the crossing are one loop with
    one RK4 call.

    Parameters
    ----------
    z0 : int
        The zone at (t, y), ``zone(t, y, P, motor_on)``: the callers carry it from step to step
        (the last step's ``z1``) instead of evaluating it again.

    Returns
    -------
    y_new : tuple of float
        The state at the step's end.
    h_taken : float
        Step actually taken [s] (h, or the time to the zone change).
    crossed : bool
        Whether the step ended at a zone change.
    z1 : int
        The zone at the step's end (t + h_taken, ``work[0]``).
    """
    lo = 0.0
    hi = h
    h_try = h
    stage = 0  # 0: the whole step; 1: bisecting the zone change; 2: the step to it
    while True:
        out = rk4_step(t, y, h_try, P, motor_on)
        z1 = zone(t + h_try, out, P, motor_on)
        if stage == 0:
            if z1 == z0:
                return out, h, False, z1
            stage = 1
        elif stage == 1:
            if z1 == z0:
                lo = h_try
            else:
                hi = h_try
        else:
            return out, hi, True, z1
        if hi - lo > 1e-12:
            h_try = 0.5 * (lo + hi)
        else:
            stage = 2
            h_try = hi


@njit(cache=True, fastmath=False, **_NO_NRT)
def advance(t, y, t_end, P, motor_on):
    """Integrate the state y (a tuple) from t to t_end [s] with hybrid steps no longer than P[P_STEP].

    Returns the new state and whether it stayed finite.
    """
    n_bad = 0
    z = zone(t, y, P, motor_on)
    while t_end - t > 1e-15:
        span = t_end - t
        n = math.ceil(span / P[P_STEP] - 1e-9)
        h = span / max(n, 1)
        h_knot = step_to_knot(t, h, P)
        short = h_knot < h
        y, taken, crossed, z = hybrid_step(t, y, h_knot, P, motor_on, z)
        t_next = t_end if (not crossed and not short and n <= 1) else t + taken
        if t_next != t + taken:  # the zone may depend on t (an unknown input in the clutch)
            z = zone(t_next, y, P, motor_on)
        t = t_next
        if not (abs(y[4]) < 1e6):
            n_bad += 1
            break
    return y, n_bad == 0


#: The plant at rest before switch-on: every state zero.
_REST = (0.0,) * N_STATES


@njit(cache=True, fastmath=False, **_NO_NRT)
def initial_state(P):
    """The state at switch-on: at rest, or with model 1.7's residual rotor flux psi_r0 along alpha.

    With ``P_PSI_R0`` (under the guard ``P_EXTENDED``) the rotor's flux is psi_r0 and the stator's
    (x_m / x_r) psi_r0 on the alpha axis (the stator current zero; the unsaturated reactances), every
    other state zero (a low-pass's states too: they read the channels from zero, as at rest).
    """
    if P[P_EXTENDED] == 0.0 or P[P_PSI_R0] == 0.0:
        return _REST
    v = P[P_PSI_R0]
    return (
        P[P_X_M] / P[P_X_R] * v, 0.0, v, 0.0, 0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    )  # fmt: skip


#: Row of omega1 in a record (the channel a sample-and-hold acts on, model 1.4).
_OMEGA1 = CHANNELS.index("omega1")


@njit(cache=True, fastmath=False, **_NO_NRT)
def state_at(t, y, motor_on, t_end, P):
    """The state at t_end >= t [s] advanced from (t, y), the motor switched off at ``P[P_T_SWITCH_OFF]``.

    For a sample-and-hold of omega1 (model 1.4): the caller advances a copy of its state, so its
    own path (and every other channel) stays as without the hold. Returns the state, whether the
    motor is on at t_end, and whether the state stayed finite.
    """
    ok = True
    if motor_on and t_end >= P[P_T_SWITCH_OFF]:
        y, ok = advance(t, y, P[P_T_SWITCH_OFF], P, True)
        t = P[P_T_SWITCH_OFF]
        motor_on = False
    if ok:
        y, ok = advance(t, y, t_end, P, motor_on)
    return y, motor_on, ok


@njit(cache=True, fastmath=False, **_NO_NRT)
def _state_from_row(a, j):
    """Row j of the 2-D array a as a state tuple."""
    return (
        a[j, 0], a[j, 1], a[j, 2], a[j, 3], a[j, 4], a[j, 5], a[j, 6], a[j, 7],
        a[j, 8], a[j, 9], a[j, 10], a[j, 11], a[j, 12], a[j, 13], a[j, 14],
    )  # fmt: skip


@njit(cache=True, fastmath=False)
def simulate_one(P, out):
    """Run the backlash test of MODEL.md section 2 for one parameter vector.

    Sample k of the record is taken at ``t_e + (k - P[P_EVENT_INDEX]) * P[P_TS] - shift`` with
    ``shift = P[P_DELAY] + P[P_TRIGGER_OFFSET]`` [s] (a negative shift samples later than
    nominal); an instant before switch-on (t < 0) reads the plant at rest (zeros). With a
    sample-and-hold of omega1 (model 1.4, ``P_HOLD1`` = h > 0), sample k's omega1 is the value at
    the hold instant ``h floor(t_k / h)`` at or before its instant t_k.

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
    P = P.copy()  # working copy: the switch-off instant is written into it
    P[P_T_SWITCH_OFF] = math.inf
    h = P[P_STEP]
    y = initial_state(P)
    n_ring = ring_size(P)
    ring_t = np.zeros(n_ring)
    ring_y = np.zeros((n_ring, N_STATES))
    ck_dt = CHECKPOINT_INTERVAL
    next_ck = 0.0
    t = 0.0
    armed = False
    t_e = math.nan
    n_ck = 0
    z = zone(t, y, P, True)
    while t < P[P_T_MAX]:
        if t >= next_ck:
            slot = n_ck % n_ring
            ring_t[slot] = t
            for i in range(N_STATES):
                ring_y[slot, i] = y[i]
            n_ck += 1
            next_ck += ck_dt
        y, taken, crossed, z = hybrid_step(t, y, step_to_knot(t, h, P), P, True, z)
        t += taken  # the instant hybrid_step evaluated z at
        if not (abs(y[4]) < 1e6 and abs(y[7] - y[8]) < 1e6):
            return NON_FINITE, math.nan
        if z != 0:
            armed = True
        elif armed and crossed:
            t_e = t
            break
    if math.isnan(t_e):
        return NO_EVENT, math.nan
    P[P_T_SWITCH_OFF] = t_e

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
        y = initial_state(P)
    elif best < 0:
        return HISTORY_TOO_SHORT, math.nan
    else:
        y = _state_from_row(ring_y, best)
    t = best_t
    motor_on = True
    lowpass = P[P_LOWPASS] > 0.0
    hold = P[P_HOLD1] if P[P_EXTENDED] != 0.0 else 0.0
    held_at = -1.0  # the hold instant of the held omega1 [s]
    held = 0.0
    for k in range(out.shape[1]):
        tk = t_e + (k - e_idx) * ts - shift
        if tk < 0.0:
            for i in range(N_CHANNELS):
                out[i, k] = 0.0
            continue
        if hold > 0.0:  # sample-and-hold of omega1: its value at the last hold instant th <= tk
            th = math.floor(tk / hold) * hold
            if th != held_at:
                held_at = th
                if th >= t:  # from the path's state at the last sample (a new instant lies after it)
                    yh, on_h, ok = state_at(t, y, motor_on, th, P)
                else:  # the first sample's instant may lie before the path's start: a checkpoint
                    best_h = -1
                    best_th = -1.0
                    for s in range(n_valid):
                        if ring_t[s] <= th and ring_t[s] > best_th:
                            best_h = s
                            best_th = ring_t[s]
                    if best_h < 0:
                        return HISTORY_TOO_SHORT, math.nan
                    yh, on_h, ok = state_at(best_th, _state_from_row(ring_y, best_h), True, th, P)
                if not ok:
                    return NON_FINITE, math.nan
                held = yh[10 + _OMEGA1] if lowpass else rhs(th, yh, P, on_h)[1][_OMEGA1]
        if motor_on and tk >= t_e:
            y, ok = advance(t, y, t_e, P, True)
            if not ok:
                return NON_FINITE, math.nan
            t = t_e
            motor_on = False
        y, ok = advance(t, y, tk, P, motor_on)
        if not ok:
            return NON_FINITE, math.nan
        t = tk
        chv = rhs(tk, y, P, motor_on)[1]
        for i in range(N_CHANNELS):
            out[i, k] = y[10 + i] if lowpass else chv[i]
        if hold > 0.0:
            out[_OMEGA1, k] = held
    return OK, t_e


@njit(cache=True, parallel=True, nogil=True)
def simulate_many(P_mat, out, t_e, status):
    """Run :func:`simulate_one` for every row of ``P_mat`` in parallel, without the GIL.

    The calling thread gives the GIL up while the batch runs, so the service's event loop and its other
    threads go on (with the GIL held, a batch of a few hundred ms stalled every request: bench/bench_load.py).
    Launches stay serialised by the caller (``_KERNEL_LOCK``): the threading layer takes one at a time.
    """
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
