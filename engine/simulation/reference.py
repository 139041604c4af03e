"""Reference solution of the backlash test with scipy's ``solve_ivp``.

A second, independent transcription of MODEL.md, of the effect catalogue, of the
held-back effects and of the additive unknown input of model 1.1, of the held-out
effects of model 1.2, of the sealed effects of model 1.3, of the second sealed family of
model 1.4, of the third sealed family of model 1.5, of the fourth sealed family of model 1.6 and of
the fifth sealed family of model 1.7,
used as the yardstick of the numba kernel (MODEL.md section 4, relative
tolerance 1e-9; ``tests/test_simulation_accuracy.py``) and as the baseline of
``bench/bench_simulator.py``. It is slow on purpose: plain numpy, complex
notation, the events located by ``solve_ivp``'s event functions.

Independence
------------
The reference shares no code with the kernel's physics path: it does not use
:class:`~engine.simulation.parameters.PlantParameters`,
:func:`~engine.simulation.effects.apply_effects` or the kernel. Its input is a
flat mapping of MODEL.md's names to values (:data:`MODEL_DEFAULTS`), plus
effects by catalogue name, and it writes every effect's physics out again
from the effect's documented meaning (:data:`EFFECT_NEUTRAL`). The only thing
shared are the *numbers* of the spec, read from :mod:`engine.constants`, and the record's grid (only its three numbers:
interval, length, event index).

Model 1.1 (``docs/model-changes.md``)
-------------------------------------
The held-back effects (:data:`engine.simulation.HELD_BACK`) are effects by name here
too: a load torque ripple ``v sin(2 pi LOAD_RIPPLE_HZ t)`` on the mass, the backlash
zone centred on ``v`` instead of 0, a cogging torque ``-v sin(COGGING_ORDER theta_1)`` on
the motor shaft, a Coulomb friction ``v tanh(w_2 / W_SMOOTH)`` of the wheel, and an
share v of the electromagnetic torque at the switch-off that decays as
``v m_el(t_e) exp(-(t - t_e) / SWITCH_OFF_DECAY_TIME)`` after the
switch-off (written in closed form here; the kernel integrates it as a state). The
unknown input is a plain mapping ``{"locus", "t0", "dt", "values"}`` (see
:func:`reference_simulate`), interpolated with ``numpy.interp``.

Model 1.2 (``docs/model-changes.md``)
-------------------------------------
The held-out effects (:data:`engine.simulation.HELD_OUT`), written out here from their
definitions: a negative-sequence share v of the supply, ``u_s = u (1 + d_supply) (e^{j f w_b t}
+ v e^{-j f w_b t})``; saturation, the inductance matrix rebuilt at every call from
``x_m' = x_m / (1 + v |psi_s|^2)`` with the leakages kept (also for the torque at the
switch-off); windage ``-v w_1 |w_1|`` on the motor shaft; a spring ``v k_12 d`` across the clutch
(d the deflection from the zone's centre) against J1 and on J2; a hardening resilient element
``k_2 x (1 + v (k_2 x)^2)``; a spring ``-v theta_3 / (2 pi)`` from the load to ground; and the
speed encoder's ``omega1 = Omega_b w_1 (1 + v sin theta_1)`` before the sensor chain.

Model 1.3 (``docs/model-changes.md``)
-------------------------------------
The sealed effects (:data:`engine.simulation.SEALED`), written out here from their definitions:
the supply's amplitude times ``1 + v sin(2 pi F_FLICKER t)`` (with the unbalance and a supply
input as above); both leakages higher by v, ``x_s + v`` and ``x_r + v`` in the inductance matrix
(x_m kept, so with saturation too); Stribeck friction ``v tanh(w_1 / W_SMOOTH) exp(-(w_1 /
W_STRIBECK)^2)`` against the motor shaft; the contact spring ``k_12 x (1 + v x / X_REF)`` of the
penetration ``x = |d| - b`` beyond the zone's edge, with the sign of d; dry friction
``v tanh((w_2 - w_3) / W_SMOOTH)`` in the resilient element's torque; drag ``-v w_3 |w_3|`` on the
load; and the load accelerometer's ``a2 + v a1`` before the sensor chain.

Model 1.4 (``docs/model-changes.md``)
-------------------------------------
The second sealed family (:data:`engine.simulation.SEALED2`), written out here from its
definitions: a DC voltage ``v u`` added to the real (alpha) part of u_s; the core losses as a
resistance v in the magnetising branch, ``v (i_s + i_r)`` subtracted in both flux equations; the
motor's bearing friction ``v |m_c| tanh(w_1 / W_SMOOTH)`` (m_c with the film); a squeeze film
``v (H_SQUEEZE / (H_SQUEEZE + h))^3 (w_1 - w_2)`` added to the clutch's torque at every deflection,
``h = max(b - |d|, 0)`` (not clipped, the factor 1 in contact); the resilient spring
``k_2 (x - v tanh(x / v))``; the force ``v sqrt(2 e) s exp(-s^2)``, ``s = (theta_3 - THETA_BUMP) /
W_BUMP``, on the mass; and omega1 read at ``v floor(t_k / v)`` instead of t_k (after the low-pass,
before the gain), from the same dense solution.

Model 1.5 (``docs/model-changes.md``)
-------------------------------------
The third sealed family (:data:`engine.simulation.SEALED3`), written out here from its
definitions: the voltage drop of a resistance v in phase a with the star point floating,
``(2/3) v Re(i_s)`` off the real part of u_s; a broken rotor bar, the rotor's resistance higher by
``v r_r`` along the rotor's axis ``e^(j g)``, ``g = p theta_1``, so that ``v r_r Re(i_r e^(-j g))
e^(j g)`` is subtracted in the rotor's flux equation; the brake ``v g_b(t) tanh(w_1 / W_SMOOTH)``
against the motor, g_b a smoothstep from 1 to 0 between T_BRAKE_RELEASE and T_BRAKE_RELEASE +
T_BRAKE_TRAVEL after switch-on and from 0 to 1 between T_BRAKE_APPLY and T_BRAKE_APPLY +
T_BRAKE_TRAVEL after t_e; the contact spring times ``1 + v tanh(sgn(x) (w_1 - w_2) / W_SMOOTH)``,
x the signed penetration; the resilient spring plus ``v k_2 x sin(MESH_ORDER theta_2)``; the force
``-v 2 s / (1 + s^2)``, ``s = w_3 / W_EDDY``, on the mass; and ``v sin(f w_b t)`` added to a1 and a2
after the cross-talk.

Model 1.6 (``docs/model-changes.md``)
-------------------------------------
The fourth sealed family (:data:`engine.simulation.SEALED4`), written out here from its
definitions: phase c open until ``t = v`` (the solution in two pieces, split there), the stator
flux's derivative along ``e_c = e^(j 4 pi / 3)`` replaced by ``(x_m / x_r)`` times the rotor flux's,
so that ``Re(i_s conj(e_c))`` keeps its zero; a share v of phase a's turns bypassed, the real (alpha)
parts of the currents from the alpha axis's own inductance matrix ``[[n^2 x_m + s (x_s - x_m),
n x_m], [n x_m, x_r]]``, ``n = 1 - 2 v / 3``, ``s = 1 - 4 v / 3 + 2 v^2 / 3``, its resistance
``n r_s``, and the torque ``Im(conj(i_r) psi_r)`` on the rotor; the rub ``v |psi_s|^2 tanh(w_1 /
W_SMOOTH)`` against the motor while it is on; ``v tanh((w_1 - w_2) / W_SMOOTH)`` from J1 to J2; ``v
|m_s| tanh(w_2 / W_SMOOTH)`` against the wheel; ``v |theta_3| / THETA_BIND tanh(w_3 / W_SMOOTH)``
against the mass; and the m_el channel (not the torque on J1) reading ``v Re(i_s) (Re(psi_s) /
sqrt(3) - Im(psi_s))`` more while the motor is on.

Model 1.7 (``docs/model-changes.md``)
-------------------------------------
The fifth sealed family (:data:`engine.simulation.SEALED5`), written out here from its
definitions: ``u_s`` plus ``v u (exp(-5 j f w_b t) + exp(7 j f w_b t))``; the initial state with the
rotor's flux v and the stator's ``(x_m / x_r) v`` on the real axis (the unsaturated reactances);
``-v sin(2 theta_1)`` on J1; the zone's half-width ``b (1 + v sin(theta_1))`` in the contact, the
squeeze film's gap and the event functions alike; ``-v sin(theta_2)`` on J2; ``-v ((theta_3 -
THETA_STOP) / THETA_STOP)^2`` on the mass beyond THETA_STOP; and a1 (after the hum) read as
``tanh(v a1) / v``.

Sensor chain
------------
Applied in the order of the measurement:

1. **Delay and trigger offset**: on a grid of interval Ts, n samples, the event
   at sample E, sample k is taken at ``t_e + (k - E) Ts - delay - offset``
   (``offset``: the ``trigger_offset`` effect, either sign); an instant before
   switch-on reads the plant at rest (zeros).
2. **First-order low-pass** on every channel, ``tau dy/dt = x - y`` with
   ``tau = 1 / (2 pi f_c)``, integrated as five extra ODE states from
   ``t = 0`` together with the plant (so to the solver's tolerance); the
   filter states are continuous across the event.
3. **Gain**: every sampled channel multiplied by the ``sensor_gain`` value.
4. **Offset**: every sampled channel plus the ``sensor_offset`` value times
   that channel's root mean square (after the gain) over the test window:
   the samples from ``ceil(4.8 ms / Ts)`` before the event to
   ``ceil(200 ms / Ts)`` from it on.
5. **Quantisation** of omega1 to the nearest multiple of the quantum
   (``q * floor(x / q + 1/2)``), after sampling.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.integrate import solve_ivp

from engine import constants as const
from engine.constants import (
    CHANNELS,
    COGGING_ORDER,
    F_FLICKER,
    H_SQUEEZE,
    LOAD_RIPPLE_HZ,
    MESH_ORDER,
    OMEGA_B,
    POLE_PAIRS,
    POST_EVENT_TIME,
    PRE_EVENT_TIME,
    SWITCH_OFF_DECAY_TIME,
    T_BRAKE_APPLY,
    T_BRAKE_RELEASE,
    T_BRAKE_TRAVEL,
    T_EVENT_MAX,
    THETA_BIND,
    THETA_BUMP,
    THETA_STOP,
    TM_PER_J,
    W_B,
    W_BUMP,
    W_EDDY,
    W_SMOOTH,
    W_STRIBECK,
    X_REF,
)

if TYPE_CHECKING:
    from engine.records.grid import SampleGrid
    from engine.simulation.parameters import Case

#: MODEL.md's parameters by their MODEL.md names, at the spec's values.
MODEL_DEFAULTS: Mapping[str, float] = {
    "r_s": const.R_S,
    "r_r": const.R_R,
    "x_s": const.X_S,
    "x_r": const.X_R,
    "x_m": const.X_M,
    "u": const.U_SUPPLY,
    "f": const.F_SUPPLY,
    "J1": const.J1_NOMINAL,
    "J2": const.J2,
    "T3": const.T3,
    "r": const.WHEEL_RADIUS,
    "K": const.K_NOMINAL,
    "c": const.C_NOMINAL,
    "c1": const.C1_NOMINAL,
    "k12": const.K12,
    "d12": const.D12,
    "k2": const.K2,
    "d2": const.D2,
}

#: The catalogued effects this reference implements, at their "no effect" value.
#: Their meaning, as written in the catalogue and ``docs/model-changes.md``:
#: the two motor frictions add a torque on the motor shaft, the ``*_drift`` /
#: stiffness / damping / inertia / discontinuity / voltage effects multiply one
#: MODEL.md parameter, and the three sensor effects build the measurement chain
#: of the module docstring.
EFFECT_NEUTRAL: Mapping[str, float] = {
    "motor_coulomb_friction": 0.0,  # pu torque: + value * tanh(w_1 / W_SMOOTH) on the motor shaft
    "motor_viscous_friction": 0.0,  # pu torque / pu speed: + value * w_1 on the motor shaft
    "rotor_resistance_drift": 1.0,  # r_r -> value * r_r
    "stator_resistance_drift": 1.0,  # r_s -> value * r_s
    "contact_stiffness": 1.0,  # k_12 -> value * k_12
    "contact_damping": 1.0,  # d_12 -> value * d_12
    "resilient_stiffness": 1.0,  # k_2 -> value * k_2
    "load_inertia": 1.0,  # J2 -> value * J2
    "absorber_discontinuity": 1.0,  # c_1 -> value * c_1
    "supply_voltage": 1.0,  # u -> value * u
    "speed_quantization": 0.0,  # rad/s: omega1 rounded to multiples of value (0: none)
    "measurement_delay": 0.0,  # s: every channel recorded value late
    "sensor_lowpass": 0.0,  # Hz: first-order low-pass of cut-off value on every channel (0: none)
    "trigger_offset": 0.0,  # s: the true event lies value after the labelled one (either sign)
    "sensor_gain": 1.0,  # every channel multiplied by value
    "sensor_offset": 0.0,  # every channel plus value * its RMS over the test window
}

#: The held-back effects (model 1.1), at their "no effect" value.
HELD_BACK_NEUTRAL: Mapping[str, float] = {
    "load_torque_ripple": 0.0,  # pu: + value * sin(2 pi LOAD_RIPPLE_HZ t) on the mass m2
    "clutch_offset": 0.0,  # rad: contact where theta_1 - theta_2 - value = +-b
    "motor_cogging": 0.0,  # pu: - value * sin(COGGING_ORDER theta_1) on the motor shaft
    "wheel_coulomb_friction": 0.0,  # pu: - value * tanh(w_2 / W_SMOOTH) on the wheel
    "switch_off_decay": 0.0,  # after t_e, m_el = value m_el(t_e) exp(-(t - t_e) / SWITCH_OFF_DECAY_TIME)
}

#: Loci of the unknown input, what it is there (see the kernel): the supply voltage is scaled
#: by (1 + d); an electromagnetic torque d is added (channel and shaft); a torque d acts on
#: the motor shaft, the wheel or the mass; the backlash zone is moved by d [rad]; (model 1.8) a
#: torque d acts across the clutch, from the motor shaft to the wheel.
DISTURBANCE_LOCI: tuple[str, ...] = (
    "supply",
    "motor_electrical",
    "motor_shaft",
    "clutch",
    "drive_train",
    "load",
    "clutch_torque",
)

#: The held-out effects (model 1.2), at their "no effect" value.
HELD_OUT_NEUTRAL: Mapping[str, float] = {
    "supply_unbalance": 0.0,  # x u: u_s = u (e^{j f w_b t} + value e^{-j f w_b t})
    "magnetic_saturation": 0.0,  # 1/pu^2: x_m -> x_m / (1 + value |psi_s|^2), leakages unchanged
    "motor_windage": 0.0,  # pu torque / pu speed^2: - value w_1 |w_1| on the motor shaft
    "clutch_preload_spring": 0.0,  # x k_12: value k_12 d from J1 to J2, d from the zone's centre, always
    "resilient_hardening": 0.0,  # 1/pu^2: resilient spring k_2 x (1 + value (k_2 x)^2)
    "load_position_spring": 0.0,  # pu torque per revolution: - value theta_3 / (2 pi) on the mass m2
    "speed_encoder_eccentricity": 0.0,  # omega1 read as Omega_b w_1 (1 + value sin theta_1)
}

#: The sealed effects (model 1.3), at their "no effect" value.
SEALED_NEUTRAL: Mapping[str, float] = {
    "supply_flicker": 0.0,  # x u: u -> u (1 + value sin(2 pi F_FLICKER t))
    "leakage_reactance": 0.0,  # pu: x_s -> x_s + value, x_r -> x_r + value, x_m unchanged
    "motor_stribeck": 0.0,  # pu: - value tanh(w_1 / W_SMOOTH) exp(-(w_1 / W_STRIBECK)^2) on the motor shaft
    "clutch_progressive_contact": 0.0,  # x: contact spring k_12 x (1 + value x / X_REF), x the penetration
    "resilient_dry_friction": 0.0,  # pu: + value tanh((w_2 - w_3) / W_SMOOTH) in the resilient torque m_s
    "load_quadratic_drag": 0.0,  # pu torque / pu speed^2: - value w_3 |w_3| on the mass m2
    "accelerometer_crosstalk": 0.0,  # a2 read as a2 + value a1
}

#: The second sealed family (model 1.4), at its "no effect" value.
SEALED2_NEUTRAL: Mapping[str, float] = {
    "supply_dc_offset": 0.0,  # x u: u_s + value u on the alpha axis
    "core_loss_resistance": 0.0,  # pu: resistance in the magnetising branch, - value (i_s + i_r) in both loops
    "motor_bearing_load_friction": 0.0,  # x: - value |m_c| tanh(w_1 / W_SMOOTH) on the motor shaft
    "clutch_squeeze_film": 0.0,  # pu: + value (H / (H + max(b - |d|, 0)))^3 (w_1 - w_2) in m_c, unclipped
    "resilient_hub_play": 0.0,  # rad: resilient spring k_2 (x - value tanh(x / value))
    "load_track_bump": 0.0,  # pu: value sqrt(2 e) s exp(-s^2) on the mass, s = (theta_3 - THETA_BUMP) / W_BUMP
    "speed_sample_hold": 0.0,  # s: omega1 read at value floor(t / value)
}

#: The third sealed family (model 1.5), at its "no effect" value.
SEALED3_NEUTRAL: Mapping[str, float] = {
    "supply_loose_connection": 0.0,  # pu: a resistance in phase a, u_s less (2/3) value Re(i_s)
    "rotor_broken_bar": 0.0,  # x r_r: the rotor's resistance higher by value r_r along its axis at p theta_1
    "motor_brake": 0.0,  # pu: - value g_b(t) tanh(w_1 / W_SMOOTH) on the motor shaft
    "clutch_hysteretic_contact": 0.0,  # x: contact spring k_12 x (1 + value tanh(sgn(x) dw / W_SMOOTH))
    "resilient_mesh_stiffness": 0.0,  # x: resilient spring k_2 x (1 + value sin(MESH_ORDER theta_2))
    "load_eddy_current_brake": 0.0,  # pu: - value 2 s / (1 + s^2) on the mass, s = w_3 / W_EDDY
    "accelerometer_mains_hum": 0.0,  # m/s^2: a1 and a2 read value sin(f w_b t) more
}

#: The fourth sealed family (model 1.6), at its "no effect" value.
SEALED4_NEUTRAL: Mapping[str, float] = {
    "supply_late_pole": 0.0,  # s: phase c carries no current until t = value
    "stator_coil_bypass": 0.0,  # x: phase a with (1 - value) of its turns (the alpha axis's own inductances)
    "motor_rotor_rub": 0.0,  # pu: - value |psi_s|^2 tanh(w_1 / W_SMOOTH) on the motor shaft, motor on
    "clutch_seal_drag": 0.0,  # pu: value tanh((w_1 - w_2) / W_SMOOTH) from J1 to J2, every deflection
    "resilient_gear_loss": 0.0,  # x: - value |m_s| tanh(w_2 / W_SMOOTH) on the wheel
    "load_guide_binding": 0.0,  # pu: - value |theta_3| / THETA_BIND tanh(w_3 / W_SMOOTH) on the mass
    "torque_current_gain": 0.0,  # x: m_el read + value Re(i_s) (Re(psi_s) / sqrt(3) - Im(psi_s)), motor on
}

#: The fifth sealed family (model 1.7), at its "no effect" value.
SEALED5_NEUTRAL: Mapping[str, float] = {
    "supply_harmonics": 0.0,  # x u: u_s + value u (exp(-5 j f w_b t) + exp(7 j f w_b t))
    "rotor_residual_flux": 0.0,  # pu: psi_r(0) = value, psi_s(0) = (x_m / x_r) value (real axis)
    "shaft_misalignment": 0.0,  # pu: - value sin(2 theta_1) on the motor shaft
    "clutch_hub_runout": 0.0,  # x b: the zone's half-width b (1 + value sin(theta_1))
    "wheel_imbalance": 0.0,  # pu: - value sin(theta_2) on the wheel
    "load_end_buffer": 0.0,  # pu: - value ((theta_3 - THETA_STOP) / THETA_STOP)^2 beyond THETA_STOP
    "accelerometer_saturation": 0.0,  # s^2/m: a1 read as tanh(value a1) / value
}

_N_PLANT = 10  # psi_s (2), psi_r (2), w_1..3, theta_1..3
_N_CHANNELS = len(CHANNELS)
_OMEGA1 = CHANNELS.index("omega1")


@dataclass(frozen=True)
class ReferenceResult:
    """Record of the reference solution.

    Attributes
    ----------
    channels : ndarray, shape (5, n_samples)
        a1 [m/s^2], m_el [pu], omega1 [rad/s], a2 [m/s^2], v2 [m/s] after the
        whole sensor chain.
    unquantised : ndarray, shape (5, n_samples)
        The same before the quantisation of omega1 (delay, trigger offset, low-pass,
        gain and offset applied).
    event_time : float
        t_e [s] since switch-on.
    n_rhs : int
        Right-hand-side evaluations.
    """

    channels: np.ndarray
    unquantised: np.ndarray
    event_time: float
    n_rhs: int


def _resolve(parameters: Mapping[str, float] | None, effects: Mapping[str, float] | None) -> dict[str, float]:
    values = dict(MODEL_DEFAULTS)
    for name, value in (parameters or {}).items():
        if name not in MODEL_DEFAULTS:
            raise ValueError(f"unknown MODEL.md parameter {name!r}; known: {', '.join(MODEL_DEFAULTS)}")
        values[name] = float(value)
    neutral_values = {
        **EFFECT_NEUTRAL,
        **HELD_BACK_NEUTRAL,
        **HELD_OUT_NEUTRAL,
        **SEALED_NEUTRAL,
        **SEALED2_NEUTRAL,
        **SEALED3_NEUTRAL,
        **SEALED4_NEUTRAL,
        **SEALED5_NEUTRAL,
    }
    for name in effects or {}:
        if name not in neutral_values:
            raise ValueError(f"the reference does not implement effect {name!r}; known: {', '.join(neutral_values)}")
    values.update({name: float((effects or {}).get(name, neutral)) for name, neutral in neutral_values.items()})
    return values


class _Input:
    """The unknown input d(t) of a ``{"locus", "t0", "dt", "values"}`` mapping (zero one spacing outside its knots)."""

    def __init__(self, spec: Mapping[str, Any] | None):
        self.locus = None if spec is None else str(spec["locus"])
        if self.locus is not None and self.locus not in DISTURBANCE_LOCI:
            raise ValueError(f"unknown disturbance locus {self.locus!r}; known: {', '.join(DISTURBANCE_LOCI)}")
        self.step = 0.0 if spec is None else float(spec.get("step", 0.0))
        self.values: np.ndarray
        self.knots: np.ndarray
        if spec is None:
            self.knots = self.values = np.zeros(1)
        else:
            # zero one spacing outside the knots, linear in between
            self.values = np.concatenate([[0.0], np.asarray(spec["values"], dtype=float), [0.0]])
            self.knots = float(spec["t0"]) + float(spec["dt"]) * np.arange(-1, self.values.size - 1)

    def at(self, locus: str, t: float, motor_on: bool = True) -> float:
        """d(t) if the input acts at ``locus``, else 0 (the step is added once the motor is off)."""
        if locus != self.locus:
            return 0.0
        return float(np.interp(t, self.knots, self.values)) + (0.0 if motor_on else self.step)


class ReferenceModel:
    """Right-hand side of MODEL.md plus the catalogued effects, in complex notation.

    State: [Re psi_s, Re psi_r, Im psi_s, Im psi_r, w_1, w_2, w_3, theta_1,
    theta_2, theta_3] and, with a low-pass sensor, the five filtered channels.

    Parameters
    ----------
    values : mapping
        Every MODEL.md name and every effect name of :data:`EFFECT_NEUTRAL`,
        :data:`HELD_BACK_NEUTRAL`, :data:`HELD_OUT_NEUTRAL`, :data:`SEALED_NEUTRAL`,
        :data:`SEALED2_NEUTRAL`, :data:`SEALED3_NEUTRAL`, :data:`SEALED4_NEUTRAL` and
        :data:`SEALED5_NEUTRAL` (see :func:`reference_simulate`).
    disturbance : mapping, optional
        The unknown input ``{"locus", "t0", "dt", "values"}``.

    Attributes
    ----------
    switch_off : tuple of float
        (t_e [s], m_el at t_e [pu]), set by the caller at the switch-off; the torque's decay
        after it (``switch_off_decay``) starts from there.
    """

    def __init__(self, values: Mapping[str, float], disturbance: Mapping[str, Any] | None = None):
        v = values
        self.input = _Input(disturbance)
        self.ripple, self.offset = v["load_torque_ripple"], v["clutch_offset"]
        self.cogging, self.wheel_friction = v["motor_cogging"], v["wheel_coulomb_friction"]
        self.decay = v["switch_off_decay"]
        self.unbalance, self.saturation = v["supply_unbalance"], v["magnetic_saturation"]
        self.windage, self.preload = v["motor_windage"], v["clutch_preload_spring"]
        self.hardening, self.load_spring = v["resilient_hardening"], v["load_position_spring"]
        self.eccentricity = v["speed_encoder_eccentricity"]
        self.flicker, self.stribeck = v["supply_flicker"], v["motor_stribeck"]
        self.progressive, self.dry_friction = v["clutch_progressive_contact"], v["resilient_dry_friction"]
        self.drag, self.crosstalk = v["load_quadratic_drag"], v["accelerometer_crosstalk"]
        self.dc, self.core_loss = v["supply_dc_offset"], v["core_loss_resistance"]
        self.bearing, self.squeeze = v["motor_bearing_load_friction"], v["clutch_squeeze_film"]
        self.play, self.bump = v["resilient_hub_play"], v["load_track_bump"]
        self.connection, self.broken_bar = v["supply_loose_connection"], v["rotor_broken_bar"]
        self.brake, self.hysteresis = v["motor_brake"], v["clutch_hysteretic_contact"]
        self.mesh, self.eddy = v["resilient_mesh_stiffness"], v["load_eddy_current_brake"]
        self.hum = v["accelerometer_mains_hum"]
        self.late_pole, self.bypass = v["supply_late_pole"], v["stator_coil_bypass"]
        self.rub, self.seal = v["motor_rotor_rub"], v["clutch_seal_drag"]
        self.gear, self.binding = v["resilient_gear_loss"], v["load_guide_binding"]
        self.current_gain = v["torque_current_gain"]
        self.harmonics, self.residual_flux = v["supply_harmonics"], v["rotor_residual_flux"]
        self.misalignment, self.runout = v["shaft_misalignment"], v["clutch_hub_runout"]
        self.imbalance, self.buffer = v["wheel_imbalance"], v["load_end_buffer"]
        self.a1_saturation = v["accelerometer_saturation"]
        leak = v["leakage_reactance"]  # both leakages x_s - x_m and x_r - x_m higher by it
        self.x_s, self.x_r, self.x_m = v["x_s"] + leak, v["x_r"] + leak, v["x_m"]
        self.switch_off = (math.inf, 0.0)
        self.u = v["u"] * v["supply_voltage"]
        self.f = v["f"]
        self.r_s = v["r_s"] * v["stator_resistance_drift"]
        self.r_r = v["r_r"] * v["rotor_resistance_drift"]
        det = self.x_s * self.x_r - self.x_m**2
        # [i_s, i_r] = L^-1 [psi_s, psi_r]
        self.Linv = np.array([[self.x_r, -self.x_m], [-self.x_m, self.x_s]]) / det
        # MODEL.md: T_i = J_i * 0.86 / 0.87 s; T_3 is given directly
        self.T = np.array([v["J1"] * TM_PER_J, v["J2"] * v["load_inertia"] * TM_PER_J, v["T3"]])
        self.half_gap = v["K"] / v["r"]
        self.k12 = v["k12"] * v["contact_stiffness"]
        self.d12 = v["d12"] * v["contact_damping"]
        self.k2, self.d2 = v["k2"] * v["resilient_stiffness"], v["d2"]
        self.c, self.c1 = v["c"], v["c1"] * v["absorber_discontinuity"]
        self.coulomb, self.viscous = v["motor_coulomb_friction"], v["motor_viscous_friction"]
        self.r = v["r"]
        fc = v["sensor_lowpass"]
        self.filter_rate = 2.0 * math.pi * fc if fc > 0 else 0.0  # 1 / tau [1/s]
        self.n_states = _N_PLANT + (_N_CHANNELS if self.filter_rate else 0)
        self.n_rhs = 0

    def derivatives(
        self, t: float, y: np.ndarray, motor_on: bool, pole_open: bool | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """dy/dt and the unfiltered channels [a1, m_el, omega1, a2, v2] (MODEL.md section 3 units).

        ``pole_open``: whether phase c is still open (model 1.6's late pole); by default while
        t < its closing instant (the piece before it is solved with True up to that instant).
        """
        self.n_rhs += 1
        psi = y[0:2] + 1j * y[2:4]  # [psi_s, psi_r]
        w, th = y[4:7], y[7:10]
        dpsi = np.zeros(2, dtype=complex)
        m_el = 0.0
        error = 0.0  # the torque estimate's error (the m_el channel only)
        if pole_open is None:
            pole_open = t < self.late_pole
        if motor_on:
            i_s, i_r = self.currents(psi)
            phase = np.exp(1j * self.f * W_B * t)
            amplitude = self.u * (1.0 + self.input.at("supply", t))
            amplitude *= 1.0 + self.flicker * math.sin(2.0 * math.pi * F_FLICKER * t)
            u_s = amplitude * (phase + self.unbalance * np.conj(phase))
            u_s += self.dc * self.u  # a DC voltage in phase a (the real axis)
            if self.harmonics:  # the 5th (negative sequence) and the 7th (positive sequence) harmonics
                u_s += self.harmonics * self.u * (np.conj(phase) ** 5 + phase**7)
            u_s -= 2.0 / 3.0 * self.connection * i_s.real  # phase a's resistance, seen from a floating star point
            loss = self.core_loss * (i_s + i_r)  # the magnetising current through the core-loss resistance
            axis = np.exp(1j * POLE_PAIRS * th[0])  # the broken bar's rotor axis, electrical angle p theta_1
            bar = self.broken_bar * self.r_r * (i_r * np.conj(axis)).real * axis
            dpsi[0] = W_B * (u_s - self.r_s * i_s - loss)
            dpsi[0] += W_B * 2.0 / 3.0 * self.bypass * self.r_s * i_s.real  # phase a's resistance n r_s
            dpsi[1] = W_B * (-self.r_r * i_r - bar - loss + 1j * w[0] * psi[1])
            if pole_open:  # phase c open: the stator flux along e_c follows (x_m / x_r) the rotor's
                _, x_r, x_m = self.reactances(psi[0])
                e_c = np.exp(4j * math.pi / 3.0)
                along = x_m / x_r * (dpsi[1] * np.conj(e_c)).real - (dpsi[0] * np.conj(e_c)).real
                dpsi[0] += along * e_c
            m_el = self.torque(psi, i_s, i_r)
            error = self.current_gain * i_s.real * (psi[0].real / math.sqrt(3.0) - psi[0].imag)
        elif self.decay != 0:
            t_e, m_e = self.switch_off
            m_el = self.decay * m_e * math.exp(-(t - t_e) / SWITCH_OFF_DECAY_TIME)
        m_el += self.input.at("motor_electrical", t, motor_on)
        d, dw, b = self.deflection(t, y, motor_on), w[0] - w[1], self.half_width(y)
        penetration = abs(d) - b  # beyond the zone's edge [rad]
        contact_spring = self.k12 * penetration * (1.0 + self.progressive * penetration / X_REF)
        if self.hysteresis:  # stiffer while the penetration deepens (|d| grows), softer while it recedes
            contact_spring *= 1.0 + self.hysteresis * math.tanh(math.copysign(1.0, d) * dw / W_SMOOTH)
        if d > b:
            m_c = max(0.0, contact_spring + self.d12 * dw)
        elif d < -b:
            m_c = min(0.0, -contact_spring + self.d12 * dw)
        else:
            m_c = 0.0
        if self.squeeze:  # a squeeze film in the gap, neither clipped nor zoned
            gap = max(b - abs(d), 0.0)  # the film's thickness, none in contact
            m_c += self.squeeze * (H_SQUEEZE / (H_SQUEEZE + gap)) ** 3 * dw
        spring = self.k2 * (th[1] - th[2])
        m_s = spring * (1.0 + self.hardening * spring**2) + self.d2 * (w[1] - w[2])
        m_s += self.dry_friction * math.tanh((w[1] - w[2]) / W_SMOOTH)
        if self.play:  # the hub's play: the spring k_2 (x - play tanh(x / play))
            m_s -= self.k2 * self.play * math.tanh((th[1] - th[2]) / self.play)
        m_s += self.mesh * self.k2 * (th[1] - th[2]) * math.sin(MESH_ORDER * th[1])  # the teeth in mesh
        m_a = self.c * w[2] + self.c1 * np.tanh(w[2] / W_SMOOTH)
        m_f = self.coulomb * np.tanh(w[0] / W_SMOOTH) + self.viscous * w[0]
        m_f += self.cogging * math.sin(COGGING_ORDER * th[0])
        m_f += self.windage * w[0] * abs(w[0])
        m_f += self.stribeck * math.tanh(w[0] / W_SMOOTH) * math.exp(-((w[0] / W_STRIBECK) ** 2))
        m_f += self.bearing * abs(m_c) * math.tanh(w[0] / W_SMOOTH)  # the bearings under the clutch's load
        m_f += self.brake * self.brake_engagement(t, motor_on) * math.tanh(w[0] / W_SMOOTH)
        if motor_on:  # the rotor's rub under the magnetic pull of the air gap's field
            m_f += self.rub * abs(psi[0]) ** 2 * math.tanh(w[0] / W_SMOOTH)
        m_seal = self.seal * math.tanh((w[0] - w[1]) / W_SMOOTH)  # dry friction between the clutch's halves
        m_gear = self.gear * abs(m_s) * math.tanh(w[1] / W_SMOOTH)  # the resilient path's mesh friction
        binding = self.binding * abs(th[2]) / THETA_BIND * math.tanh(w[2] / W_SMOOTH)  # the guides' friction
        m_f += self.misalignment * math.sin(2.0 * th[0])  # the misaligned shaft, flexed twice per revolution
        unbalance = self.imbalance * math.sin(th[1])  # the wheel's heavy spot under gravity
        compression = max(th[2] - THETA_STOP, 0.0) / THETA_STOP  # the end buffer's, none before it
        buffer = self.buffer * compression**2  # the end buffer's force against the mass
        s_eddy = w[2] / W_EDDY
        eddy = self.eddy * 2.0 * s_eddy / (1.0 + s_eddy**2)  # the eddy-current brake's force on the mass
        s_bump = (th[2] - THETA_BUMP) / W_BUMP  # where the mass is on the bump
        bump = self.bump * math.sqrt(2.0 * math.e) * s_bump * math.exp(-(s_bump**2)) if self.bump else 0.0
        m_pre = self.preload * self.k12 * d  # the spring across the clutch, inside the zone too
        m_pre += self.input.at("clutch_torque", t, motor_on)  # model 1.8: an unknown torque across the clutch
        torques = np.array(
            [
                m_el - m_c - m_pre - m_f - m_seal + self.input.at("motor_shaft", t, motor_on),
                m_c
                + m_pre
                + m_seal
                - m_gear
                - m_s
                - self.wheel_friction * math.tanh(w[1] / W_SMOOTH)
                - unbalance
                + self.input.at("drive_train", t, motor_on),
                m_s
                - m_a
                + self.ripple * math.sin(2.0 * math.pi * LOAD_RIPPLE_HZ * t)
                - self.load_spring * th[2] / (2.0 * math.pi)
                - self.drag * w[2] * abs(w[2])
                + bump
                - eddy
                - binding
                - buffer
                + self.input.at("load", t, motor_on),
            ]
        )
        dw_dt = torques / self.T
        omega1 = OMEGA_B * w[0] * (1.0 + self.eccentricity * math.sin(th[0]))  # the encoder's reading
        a1, a2 = self.r * OMEGA_B * dw_dt[0], self.r * OMEGA_B * dw_dt[2]
        a2 += self.crosstalk * a1  # the load accelerometer's cross-axis sensitivity
        hum = self.hum * math.sin(self.f * W_B * t)  # the mains in the accelerometers' cabling
        a1_read = a1 + hum
        if self.a1_saturation:  # a1's amplifier saturates (a2's cross-talk took the true a1)
            a1_read = math.tanh(self.a1_saturation * a1_read) / self.a1_saturation
        raw = np.array([a1_read, m_el + error, omega1, a2 + hum, self.r * OMEGA_B * w[2]])
        parts = [dpsi.real, dpsi.imag, dw_dt, OMEGA_B * w]
        if self.filter_rate:
            parts.append(self.filter_rate * (raw - y[_N_PLANT:]))
        return np.concatenate(parts), raw

    def brake_engagement(self, t: float, motor_on: bool) -> float:
        """g_b(t) of the motor brake: 1 applied, 0 lifted (t [s] since switch-on; the switch-off from ``switch_off``)."""

        def ramp(x: float) -> float:  # smoothstep: 0 below 0, 1 above 1, 3 x^2 - 2 x^3 between
            x = min(max(x, 0.0), 1.0)
            return x * x * (3.0 - 2.0 * x)

        if motor_on:
            return 1.0 - ramp((t - T_BRAKE_RELEASE) / T_BRAKE_TRAVEL)
        return ramp((t - self.switch_off[0] - T_BRAKE_APPLY) / T_BRAKE_TRAVEL)

    def inverse_inductance(self, psi_s: complex) -> np.ndarray:
        """L^-1 with [i_s, i_r] = L^-1 [psi_s, psi_r]; with saturation x_m depends on |psi_s|."""
        if not self.saturation:
            return self.Linv
        x_s, x_r, x_m = self.reactances(psi_s)
        return np.array([[x_r, -x_m], [-x_m, x_s]]) / (x_s * x_r - x_m**2)

    def reactances(self, psi_s: complex) -> tuple[float, float, float]:
        """(x_s, x_r, x_m) [pu] at the stator flux psi_s: with saturation x_m falls, the leakages kept."""
        if not self.saturation:
            return self.x_s, self.x_r, self.x_m
        x_m = self.x_m / (1.0 + self.saturation * abs(psi_s) ** 2)
        return self.x_s - self.x_m + x_m, self.x_r - self.x_m + x_m, x_m

    def currents(self, psi: np.ndarray) -> tuple[complex, complex]:
        """(i_s, i_r) [pu] of the fluxes [psi_s, psi_r]; with phase a's turns bypassed, the alpha axis its own."""
        i_s, i_r = self.inverse_inductance(psi[0]) @ psi
        if self.bypass:  # phase a with (1 - v) of its turns: the real (alpha) axis's own inductance matrix
            x_s, x_r, x_m = self.reactances(psi[0])
            n = 1.0 - 2.0 / 3.0 * self.bypass
            leak = (1.0 - 4.0 / 3.0 * self.bypass + 2.0 / 3.0 * self.bypass**2) * (x_s - x_m)
            alpha = np.array([[n * n * x_m + leak, n * x_m], [n * x_m, x_r]])
            i_sa, i_ra = np.linalg.solve(alpha, psi.real)
            i_s, i_r = complex(i_sa, i_s.imag), complex(i_ra, i_r.imag)
        return complex(i_s), complex(i_r)

    def torque(self, psi: np.ndarray, i_s: complex, i_r: complex) -> float:
        """m_el [pu]: Im(conj(psi_s) i_s), or with phase a's turns bypassed the torque on the rotor, Im(conj(i_r) psi_r)."""
        if self.bypass:
            return float(np.imag(np.conj(i_r) * psi[1]))
        return float(np.imag(np.conj(psi[0]) * i_s))

    def half_width(self, y: np.ndarray) -> float:
        """The backlash zone's half-width [rad]: b, with the hub's runout b (1 + v sin(theta_1))."""
        return float(self.half_gap * (1.0 + self.runout * math.sin(y[7])))

    def initial_state(self) -> np.ndarray:
        """The state at switch-on: at rest, with the rotor's residual flux v and (x_m / x_r) v the stator's."""
        y0 = np.zeros(self.n_states)
        y0[0] = self.x_m / self.x_r * self.residual_flux  # Re(psi_s) (y holds Re, then Im, of [psi_s, psi_r])
        y0[1] = self.residual_flux  # Re(psi_r)
        return y0

    def deflection(self, t: float, y: np.ndarray, motor_on: bool = True) -> float:
        """theta_1 - theta_2 measured from the centre of the backlash zone [rad]."""
        return float(y[7] - y[8] - self.offset - self.input.at("clutch", t, motor_on))

    def channels(self, t: float, y: np.ndarray, motor_on: bool) -> np.ndarray:
        """Channels a1, m_el, omega1, a2, v2 as the sensors read them at (t, y), before quantisation."""
        if self.filter_rate:
            return np.array(y[_N_PLANT:], dtype=float)
        return self.derivatives(t, y, motor_on)[1]


def reference_simulate(
    parameters: Mapping[str, float] | None = None,
    effects: Mapping[str, float] | None = None,
    method: str = "DOP853",
    rtol: float = 1e-9,
    atol: float = 1e-12,
    grid: SampleGrid | None = None,
    disturbance: Mapping[str, Any] | None = None,
) -> ReferenceResult:
    """Solve the backlash test with ``solve_ivp`` (see the module docstring).

    Parameters
    ----------
    parameters : mapping, optional
        MODEL.md parameters that differ from :data:`MODEL_DEFAULTS`, by their
        MODEL.md names (e.g. ``{"K": 0.005, "J1": 0.87, "c": 1.0}``).
    effects : mapping, optional
        Catalogued, held-back, held-out and sealed effects (the five sealed families) by name and
        value (keys of :data:`EFFECT_NEUTRAL`, :data:`HELD_BACK_NEUTRAL`, :data:`HELD_OUT_NEUTRAL`,
        :data:`SEALED_NEUTRAL`, :data:`SEALED2_NEUTRAL`, :data:`SEALED3_NEUTRAL`,
        :data:`SEALED4_NEUTRAL` and :data:`SEALED5_NEUTRAL`).
    method, rtol, atol
        ``solve_ivp`` settings.
    grid : SampleGrid, optional
        The record's sample grid (its ``sample_interval`` [s], ``n_samples`` and
        ``event_index`` only); default MODEL.md's (0.1 ms, 2048 samples, event at 48).
    disturbance : mapping, optional
        An unknown input: ``locus`` (one of :data:`DISTURBANCE_LOCI`), ``t0`` (first knot [s
        since switch-on]), ``dt`` (knot spacing [s]) and ``values`` (knot values in the locus's
        unit); zero one spacing before the first knot and after the last, linear in between;
        optionally ``step``, added from the switch-off (the event) on.

    Returns
    -------
    ReferenceResult

    Raises
    ------
    ValueError
        An unknown parameter or effect name.
    RuntimeError
        No event within 1 s, or the solver failed.
    """
    values = _resolve(parameters, effects)
    model = ReferenceModel(values, disturbance)

    def f_on(t: float, y: np.ndarray) -> np.ndarray:
        return model.derivatives(t, y, True)[0]

    def f_off(t: float, y: np.ndarray) -> np.ndarray:
        return model.derivatives(t, y, False)[0]

    def event(direction: float) -> Callable[[float, np.ndarray], float]:
        def gap(t: float, y: np.ndarray) -> float:
            return abs(model.deflection(t, y)) - model.half_width(y)

        gap.terminal = True  # type: ignore[attr-defined]
        gap.direction = direction  # type: ignore[attr-defined]
        return gap

    kw: dict[str, Any] = dict(method=method, rtol=rtol, atol=atol, dense_output=True)
    y0 = model.initial_state()
    t_pole = model.late_pole
    s0 = None
    if t_pole > 0:  # phase c closes at t_pole: the first piece with it open, up to that instant
        s0 = solve_ivp(lambda t, y: model.derivatives(t, y, True, True)[0], (0.0, t_pole), y0, events=event(1.0), **kw)
        if s0.status != 0:
            raise RuntimeError(f"reference: the first contact before the late pole closes ({s0.message})")
        y0 = s0.y[:, -1]
    s1 = solve_ivp(f_on, (t_pole, T_EVENT_MAX), y0, events=event(1.0), **kw)
    if s1.status != 1:
        raise RuntimeError(f"reference: no first contact within {T_EVENT_MAX} s ({s1.message})")
    t_c = s1.t_events[0][0]
    s2 = solve_ivp(f_on, (t_c, T_EVENT_MAX), s1.y_events[0][0], events=event(-1.0), **kw)
    if s2.status != 1:
        raise RuntimeError(f"reference: no re-entry into the backlash zone within {T_EVENT_MAX} s ({s2.message})")
    t_e = float(s2.t_events[0][0])
    y_e = s2.y_events[0][0]
    psi_e = y_e[0:2] + 1j * y_e[2:4]
    model.switch_off = (t_e, model.torque(psi_e, *model.currents(psi_e)))
    ts, n, e = _grid_numbers(grid)
    t_k = t_e + (np.arange(n) - e) * ts - values["measurement_delay"] - values["trigger_offset"]
    s3 = solve_ivp(f_off, (t_e, max(t_k[-1], t_e) + 1e-9), y_e, **kw)
    if not s3.success:
        raise RuntimeError(f"reference: solver failed after the event ({s3.message})")
    analog = np.zeros((_N_CHANNELS, n))

    def read(t: float) -> np.ndarray:
        """The channels as the sensors read them at t [s since switch-on] (zeros before it)."""
        if t < 0:
            return np.zeros(_N_CHANNELS)  # before switch-on: the plant at rest
        if s0 is not None and t < t_pole:
            return model.channels(t, s0.sol(t), True)
        if t < t_c:
            return model.channels(t, s1.sol(t), True)
        if t < t_e:
            return model.channels(t, s2.sol(t), True)
        return model.channels(t, s3.sol(t), False)

    hold = values["speed_sample_hold"]
    for k, t in enumerate(t_k):
        analog[:, k] = read(t)
        if hold > 0 and t >= 0:  # omega1 as last updated, at the hold instant at or before t
            analog[_OMEGA1, k] = read(hold * math.floor(t / hold))[_OMEGA1]
    analog = analog * values["sensor_gain"]
    first = e - math.ceil(PRE_EVENT_TIME / ts - 1e-9)
    stop = e + math.ceil(POST_EVENT_TIME / ts - 1e-9)
    if values["sensor_offset"] != 0.0:
        if first < 0 or stop > n:
            raise ValueError("reference: sensor_offset needs a grid covering the test window")
        rms = np.sqrt(np.mean(analog[:, first:stop] ** 2, axis=1))
        analog = analog + values["sensor_offset"] * rms[:, None]
    out = analog.copy()
    q = values["speed_quantization"]
    if q > 0:
        out[_OMEGA1] = q * np.floor(analog[_OMEGA1] / q + 0.5)
    return ReferenceResult(out, analog, t_e, model.n_rhs)


def _grid_numbers(grid: SampleGrid | None) -> tuple[float, int, int]:
    """(interval [s], samples, event index) of ``grid``; MODEL.md section 2's without one."""
    if grid is None:
        return const.SAMPLE_INTERVAL, const.N_SAMPLES, const.EVENT_INDEX
    return float(grid.sample_interval), int(grid.n_samples), int(grid.event_index)


def reference_inputs(case: Case) -> tuple[dict[str, float], dict[str, float]]:
    """The reference's ``(parameters, effects)`` for a simulator :class:`~engine.simulation.parameters.Case`.

    A thin adapter for running both on cases built for the kernel (the
    benchmark's grid): MODEL.md fields are copied by name, the plant's
    extension fields and the sensor chain become their catalogue effects.
    Multiplicative effects are already folded into the case's values. The
    accuracy tests describe their cases to the reference directly, so that
    :func:`~engine.simulation.effects.apply_effects` is checked too. The case's unknown
    input, if any, is :func:`reference_disturbance`.
    """
    p, s = case.plant, case.sensors
    parameters = {name: float(getattr(p, name)) for name in MODEL_DEFAULTS}
    effects = {
        "motor_coulomb_friction": p.tau_C1,
        "motor_viscous_friction": p.b_1,
        "measurement_delay": s.delay,
        "sensor_lowpass": s.lowpass_hz,
        "speed_quantization": s.speed_quantum,
        "trigger_offset": s.trigger_offset,
        "sensor_gain": s.gain,
        "sensor_offset": s.offset_rms,
        "load_torque_ripple": p.tau_ripple3,
        "clutch_offset": p.clutch_offset,
        "motor_cogging": p.tau_cog,
        "wheel_coulomb_friction": p.tau_C2,
        "switch_off_decay": p.m_off,
        "supply_unbalance": p.u_neg,
        "magnetic_saturation": p.sat,
        "motor_windage": p.b_2,
        "clutch_preload_spring": p.k_pre,
        "resilient_hardening": p.hard2,
        "load_position_spring": p.k_3,
        "speed_encoder_eccentricity": s.ecc1,
        "supply_flicker": p.u_flicker,
        "leakage_reactance": p.x_leak,
        "motor_stribeck": p.tau_S1,
        "clutch_progressive_contact": p.prog12,
        "resilient_dry_friction": p.tau_dry2,
        "load_quadratic_drag": p.b_3,
        "accelerometer_crosstalk": s.xtalk2,
        "supply_dc_offset": p.u_dc,
        "core_loss_resistance": p.r_m,
        "motor_bearing_load_friction": p.mu_1,
        "clutch_squeeze_film": p.sq12,
        "resilient_hub_play": p.play2,
        "load_track_bump": p.bump3,
        "speed_sample_hold": s.hold1,
        "supply_loose_connection": p.r_con,
        "rotor_broken_bar": p.r_bar,
        "motor_brake": p.tau_brake,
        "clutch_hysteretic_contact": p.hyst12,
        "resilient_mesh_stiffness": p.mesh2,
        "load_eddy_current_brake": p.eddy3,
        "accelerometer_mains_hum": s.hum,
        "supply_late_pole": p.t_pole,
        "stator_coil_bypass": p.bypass_a,
        "motor_rotor_rub": p.tau_rub,
        "clutch_seal_drag": p.seal12,
        "resilient_gear_loss": p.gear2,
        "load_guide_binding": p.bind3,
        "torque_current_gain": s.igain_a,
        "supply_harmonics": p.u_h57,
        "rotor_residual_flux": p.psi_r0,
        "shaft_misalignment": p.tau_mis1,
        "clutch_hub_runout": p.ecc12,
        "wheel_imbalance": p.tau_unb2,
        "load_end_buffer": p.buf3,
        "accelerometer_saturation": s.sat_a1,
    }
    return parameters, effects


def reference_disturbance(case: Case) -> dict[str, Any] | None:
    """The reference's ``disturbance`` mapping of a simulator case's unknown input (None without one)."""
    d = case.plant.disturbance
    if d is None:
        return None
    return {"locus": d.locus, "t0": d.t0, "dt": d.dt, "values": list(d.values), "step": d.step}
