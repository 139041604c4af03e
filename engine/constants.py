"""One place for the reference model's constants, grids and test protocol.

Every value here comes from ``MODEL.md`` (the project's reference plant, copied
into ``docs/MODEL.md``) or from the paper; the module is the single source the
rest of the package reads. Changing a value here is a *model change*: bump
:data:`MODEL_VERSION` and record it in ``docs/model-changes.md``.

The numba kernel (:mod:`engine.simulation._kernel`) freezes the constants it
reads at compile time, and numba's on-disk cache is keyed on the kernel's own
source file only: after changing a value here, delete
``engine/simulation/__pycache__/_kernel.*.nb[ic]`` (or touch ``_kernel.py``).
"""

from __future__ import annotations

import math
from typing import Final

#: Version of the reference model implemented by :mod:`engine.simulation`.
#: Stored with every pattern set so that patterns trained on another model
#: version are never silently mixed with this one.
#: 1.2 (docs/model-changes.md): the held-out family's seven terms, neutral by default.
#: 1.3: the sealed family's seven terms, neutral by default.
#: 1.4: the second sealed family's seven terms (SEALED2), neutral by default.
#: 1.5: the third sealed family's seven terms (SEALED3), neutral by default.
#: 1.6: the fourth sealed family's seven terms (SEALED4), neutral by default.
#: 1.7: the fifth sealed family's seven terms (SEALED5), neutral by default.
#: 1.8: a second unknown input of the clutch, a torque across it (``clutch_torque``), zero by default.
MODEL_VERSION: Final[str] = "1.8"

# --- base quantities -------------------------------------------------------
#: Rated supply frequency [Hz], the electrical base (MODEL.md section 1.1).
RATED_FREQUENCY: Final[float] = 50.0
#: Electrical base angular frequency w_b [rad/s] (50 Hz supply).
W_B: Final[float] = 2.0 * math.pi * RATED_FREQUENCY
#: Pole pairs p [-] (chosen in MODEL.md).
POLE_PAIRS: Final[int] = 2
#: Mechanical base speed Omega_b = w_b / p [rad/s]; 1 pu speed.
OMEGA_B: Final[float] = W_B / POLE_PAIRS

# --- reference plant (MODEL.md section 1) ----------------------------------
# Induction motor (section 1.1), per unit.
#: Stator resistance r_s [pu] (paper).
R_S: Final[float] = 0.059
#: Rotor resistance r_r [pu] (paper: r_w).
R_R: Final[float] = 0.048
#: Total stator reactance x_s [pu] (paper).
X_S: Final[float] = 1.92
#: Total rotor reactance x_r [pu] (paper).
X_R: Final[float] = 1.92
#: Magnetising reactance x_m [pu] (paper).
X_M: Final[float] = 1.82
#: Supply voltage amplitude u [pu] (chosen: direct-on-line).
U_SUPPLY: Final[float] = 1.0
#: Supply frequency f [pu of 50 Hz] (chosen: direct-on-line).
F_SUPPLY: Final[float] = 1.0
# Mechanics (section 1.2).
#: Drive-wheel inertia J2 [kg m^2] (paper).
J2: Final[float] = 0.348
#: Mechanical time constant of the mass m2 referred to the motor shaft, T_3 [s] (chosen).
T3: Final[float] = 0.30
#: Drive-wheel radius r [m] (chosen).
WHEEL_RADIUS: Final[float] = 0.1
#: Contact stiffness of the clutch k_12 [pu/rad] (chosen: contact mode near 60 Hz).
K12: Final[float] = 222.0
#: Contact damping of the clutch d_12 [pu torque / pu speed] (chosen).
D12: Final[float] = 0.5
#: Stiffness of the resilient element k_2 [pu/rad] (chosen: resilient mode near 15 Hz).
K2: Final[float] = 9.0
#: Damping of the resilient element d_2 [pu torque / pu speed] (chosen).
D2: Final[float] = 0.02
#: Nominal motor-side inertia J1 [kg m^2] (paper; the first value of its grid K_I).
J1_NOMINAL: Final[float] = 0.87
#: Paper's mechanical time constant Tm [s] at the nominal J1.
TM_NOMINAL: Final[float] = 0.86
#: Mechanical time constant per unit inertia, T_i = J_i * TM_PER_J (MODEL.md section 1.2) [s / (kg m^2)].
TM_PER_J: Final[float] = TM_NOMINAL / J1_NOMINAL
#: Nominal backlash zone width K [m]: the third of the paper's six widths (chosen), the default of a
#: simulated case.
K_NOMINAL: Final[float] = 0.005
#: Nominal apparent viscosity of the absorber c [pu torque / pu speed]: one of the paper's c groups
#: (chosen), used where a record gives none.
C_NOMINAL: Final[float] = 1.0
#: Discontinuity at zero speed of the absorber characteristic c_1 [pu torque] (paper).
C1_NOMINAL: Final[float] = 0.2
#: Speed scale of the smoothed sign functions tanh(w / W_SMOOTH) [pu speed] (MODEL.md section 1.2:
#: the absorber's c_1 term; also the motor Coulomb-friction extension).
W_SMOOTH: Final[float] = 1e-3

# --- model 1.1 extensions (docs/model-changes.md; ours, not MODEL.md) ------------
#: Frequency of the load torque ripple [Hz] (held-back effect ``load_torque_ripple``): a fixed
#: frequency unrelated to the supply (50 Hz) and to the plant's resonances (15 Hz, 60 Hz).
LOAD_RIPPLE_HZ: Final[float] = 37.0
#: Periods of the cogging torque per mechanical revolution of the motor [-] (held-back effect
#: ``motor_cogging``): high enough that the slow motor of the backlash test (a few rad/s) passes
#: several periods within the test window.
COGGING_ORDER: Final[int] = 72
#: Time constant of the decay of the torque left at the switch-off [s] (held-back effect
#: ``switch_off_decay``): long enough to be seen over several samples of every accepted grid.
SWITCH_OFF_DECAY_TIME: Final[float] = 0.01
#: Most knots of the piecewise-linear schedule of the unknown input d(t) (``Disturbance``); the
#: kernel's parameter vector holds that many slots.
DISTURBANCE_MAX_KNOTS: Final[int] = 256

# --- model 1.2 extensions (docs/model-changes.md) ----------------------------
# The seven terms of the held-out family (engine.simulation.held_out) need no constant of their
# own: each is its one value times the state (the load spring's unit is per revolution, 2 pi rad).

# --- model 1.3 extensions (docs/model-changes.md) ----------------------------
# Constants of the sealed family's terms (engine.simulation.sealed).
#: Frequency of the supply's voltage flicker [Hz] (sealed effect ``supply_flicker``): the peak of
#: the flicker sensitivity of IEC 61000-4-15 (the lamp-eye-brain model), the flicker a supply is
#: judged by.
F_FLICKER: Final[float] = 8.8
#: Speed scale of the Stribeck friction on the motor shaft [pu speed] (sealed effect
#: ``motor_stribeck``): the friction ``v tanh(w_1 / W_SMOOTH) exp(-(w_1 / W_STRIBECK)^2)`` fades
#: within a few tenths of the backlash test's top motor speed (1-2 % of synchronous).
W_STRIBECK: Final[float] = 0.005
#: Reference penetration of the clutch's contact [rad] (sealed effect
#: ``clutch_progressive_contact``: the contact spring ``k_12 x (1 + v x / X_REF)``): the largest
#: penetration beyond the zone's edge in the nominal plant's backlash test (K 5 mm, J1 0.87 kg m^2,
#: c 1.0), 0.0107 rad (at 27.6 ms, between the first contact and the event; scipy reference,
#: DOP853 at rtol 1e-10, and the kernel on a 1 us grid agree), rounded. At x = X_REF the spring is
#: stiffer by the factor 1 + v.
X_REF: Final[float] = 0.01

# --- model 1.4 extensions (docs/model-changes.md) ----------------------------
# Constants of the second sealed family's terms (engine.simulation.sealed2).
#: Film scale of the squeeze film in the clutch's gap [rad] (sealed2 effect
#: ``clutch_squeeze_film``: the torque ``v (H_SQUEEZE / (H_SQUEEZE + h))^3 dw`` at the gap
#: h = max(b - |d|, 0) to the zone's edge): a tenth of the nominal zone's half-width (K 5 mm / r,
#: 0.05 rad), 0.5 mm of the gap at the wheel's radius. The cube is Reynolds' squeeze film between
#: two flat faces (a damping that grows as 1 / h^3), kept finite at the edge by the film scale.
H_SQUEEZE: Final[float] = 0.005
#: Position of the bump on the load's track [rad of theta_3] (sealed2 effect ``load_track_bump``):
#: 10 mm of travel of the mass at the wheel's radius (0.1 m) from where the test starts. The mass
#: of the nominal plant passes it about 35 ms after the event (theta_3 reaches 0.25 rad).
THETA_BUMP: Final[float] = 0.1
#: Half-width of the bump [rad of theta_3] (sealed2 effect ``load_track_bump``): 2 mm of travel.
W_BUMP: Final[float] = 0.02

# --- model 1.5 extensions (docs/model-changes.md) ----------------------------
# Constants of the third sealed family's terms (engine.simulation.sealed3).
#: Delay of the motor brake's release after switch-on [s] (sealed3 effect ``motor_brake``): the
#: brake's coil is fed from the motor's terminals through a rectifier, so the spring-applied brake
#: lifts only once its coil current has pulled the armature in (10 ms: a rectifier with
#: over-excitation; a plain half-wave one needs several times that).
T_BRAKE_RELEASE: Final[float] = 0.01
#: Delay of the motor brake's application after the switch-off [s] (sealed3 effect
#: ``motor_brake``): the armature's fall time with the brake's coil switched on its DC side.
T_BRAKE_APPLY: Final[float] = 0.01
#: Travel time of the brake's armature [s] (sealed3 effect ``motor_brake``): the brake's torque goes
#: from full to none at the release and back at the application along a smoothstep of this length.
T_BRAKE_TRAVEL: Final[float] = 0.005
#: Tooth-mesh order of the resilient stage [per revolution of the wheel] (sealed3 effect
#: ``resilient_mesh_stiffness``): the teeth of a gear (or toothed-belt) stage in the resilient
#: path, whose stiffness varies as the number of teeth in mesh alternates; 40 teeth, a mesh
#: period of 0.157 rad, so that the wheel's travel over a record (about 0.2 rad) holds more than one.
MESH_ORDER: Final[int] = 40
#: Critical speed of the eddy-current brake on the load [pu speed] (sealed3 effect
#: ``load_eddy_current_brake``: the force ``v 2 s / (1 + s^2)``, s = w_3 / W_EDDY, largest, v, at
#: w_3 = W_EDDY): 0.16 m/s at the wheel's radius, within the load's speeds in the test (up to
#: 0.03 pu), so that both the rising and the falling branch of the characteristic are met.
W_EDDY: Final[float] = 0.01

# --- model 1.6 extensions (docs/model-changes.md) ----------------------------
# Constants of the fourth sealed family's terms (engine.simulation.sealed4).
#: How long before and after the late pole's closing instant the integrator ends a step [s] (sealed4
#: effect ``supply_late_pole``): the right-hand side jumps there, so one step ends just before it and
#: one just after, and only that 2 ns step straddles the jump (erring by about 2 ns times the jump).
T_POLE_GUARD: Final[float] = 1e-9
#: Travel of the load at which the misaligned guides' friction reaches its value [rad of theta_3]
#: (sealed4 effect ``load_guide_binding``): 10 mm at the wheel's radius, about half the load's
#: travel over a record.
THETA_BIND: Final[float] = 0.1

# --- model 1.7 extensions (docs/model-changes.md) ----------------------------
# Constants of the fifth sealed family's terms (engine.simulation.sealed5).
#: Travel of the load at which it meets the end buffer [rad of theta_3] (sealed5 effect
#: ``load_end_buffer``): 10 mm at the wheel's radius, reached after the event on the nominal plant
#: (which travels about 0.26 rad over a record). The buffer's force is v at THETA_STOP of compression.
THETA_STOP: Final[float] = 0.1

# --- test protocol (MODEL.md section 2) ------------------------------------
#: Sample interval Ts [s].
SAMPLE_INTERVAL: Final[float] = 1e-4
#: Samples in one record.
N_SAMPLES: Final[int] = 2048
#: Samples before the event; sample EVENT_INDEX is at t_e.
EVENT_INDEX: Final[int] = 48
#: Longest simulated time before the event must have happened [s].
T_EVENT_MAX: Final[float] = 1.0

# --- records as a bench gives them (issue 9; ours, not MODEL.md) -------------
#: Shortest accepted sample interval of a record [s] (100 kHz).
MIN_SAMPLE_INTERVAL: Final[float] = 1e-5
#: Longest accepted sample interval of a record [s] (1 kHz).
MAX_SAMPLE_INTERVAL: Final[float] = 1e-3
#: Time a record must cover before the event [s]: MODEL.md's 48 samples of 0.1 ms.
PRE_EVENT_TIME: Final[float] = EVENT_INDEX * SAMPLE_INTERVAL
#: Time a record must cover from the event on [s]: MODEL.md's 2000 samples of 0.1 ms. A sample
#: covers the interval [t_k, t_k + Ts), so a record of n samples with the event at sample e covers
#: ``e * Ts`` before the event and ``(n - e) * Ts`` from it on.
POST_EVENT_TIME: Final[float] = (N_SAMPLES - EVENT_INDEX) * SAMPLE_INTERVAL

# --- paper grids (MODEL.md section 1.2) --------------------------------------
#: J1 grid K_I [kg m^2], in the paper's order (nominal first).
J1_GRID: Final[tuple[float, ...]] = (J1_NOMINAL, 0.8482, 0.8265, 0.8047, 0.7612, 0.8917, 0.9135)
#: Backlash zone widths K [m], in the paper's order (index nr5 = 1..6).
K_GRID: Final[tuple[float, ...]] = (0.0025, 0.00375, 0.005, 0.0075, 0.009, 0.01)
#: Apparent-viscosity groups c [pu].
C_GROUPS: Final[tuple[float, ...]] = (0.8, 1.0, 1.25, 1.4)

# --- operating range (ours, not MODEL.md) -----------------------------------
#: Plausible operating range of the uncertain plant parameters: ``name -> (low, high, unit)``.
#: K spans the paper's width grid; J1 [kg m^2] and c [pu] the ranges of the held-out records.
#: The held-out evaluation, the v1 blind validation and the benchmarks draw operating points
#: from it; the calibration searches the wider :data:`PLAUSIBLE_RANGE`.
OPERATING_RANGE: Final[dict[str, tuple[float, float, str]]] = {
    "K": (min(K_GRID), max(K_GRID), "m"),
    "J1": (0.75, 0.93, "kg m^2"),
    "c": (0.8, 1.5, "pu"),
}
#: Plausible box of the uncertain plant parameters: ``name -> (low, high, unit)``: everything a drive
#: of this kind may have, far wider than :data:`OPERATING_RANGE` (K 1-15 mm, J1 0.6-1.2 kg m^2,
#: c 0.5-2.0 pu). The default search box of the diagnosis's calibration
#: (engine.diagnosis.space.DEFAULT_BOUNDS); a caller may narrow it.
PLAUSIBLE_RANGE: Final[dict[str, tuple[float, float, str]]] = {
    "K": (0.001, 0.015, "m"),
    "J1": (0.6, 1.2, "kg m^2"),
    "c": (0.5, 2.0, "pu"),
}

# --- channels (MODEL.md section 3) -----------------------------------------
#: Recorded channels, in the canonical order.
CHANNELS: Final[tuple[str, ...]] = ("a1", "m_el", "omega1", "a2", "v2")
#: Unit of each channel.
CHANNEL_UNITS: Final[dict[str, str]] = {
    "a1": "m/s^2",
    "m_el": "pu",
    "omega1": "rad/s",
    "a2": "m/s^2",
    "v2": "m/s",
}
#: Channels that are the time derivative of another, times a scale (MODEL.md section 3): a1 is r
#: times d(omega1)/dt, a2 is d(v2)/dt. (derivative, channel, scale: a plant parameter's name or None
#: for 1.) A periodic component that two such channels carry with this ratio is a motion of the plant.
DERIVATIVE_CHANNELS: Final[tuple[tuple[str, str, str | None], ...]] = (("a1", "omega1", "r"), ("a2", "v2", None))
#: Paper's wavelet for each channel.
CHANNEL_WAVELETS: Final[dict[str, str]] = {
    "a1": "sym5",
    "m_el": "db6",
    "omega1": "sym5",
    "a2": "db6",
    "v2": "sym5",
}
#: Wavelet decomposition level (paper: 10 for every channel).
WAVELET_LEVEL: Final[int] = 10
#: Two-sided 95 % quantile of the standard normal distribution (a 95 % interval is +- Z95 sigma).
Z95: Final[float] = 1.959963984540054
