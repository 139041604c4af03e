"""Parameters of the reference plant, its sensors and the solver.

Names follow the maths of MODEL.md; units are in each field's docstring.
Some fields are *extensions* of MODEL.md with a neutral default (zero), so the
reference plant is unchanged unless an effect sets them: ``tau_C1`` and
``b_1`` (motor-shaft friction); since model 1.1 the terms of the held-back
effects (``tau_ripple3``, ``clutch_offset``, ``tau_cog``, ``tau_C2``,
``m_off``) and an additive unknown input at one locus of the plant
(:class:`Disturbance`); since model 1.2 the terms of the held-out effects
(``u_neg``, ``sat``, ``b_2``, ``k_pre``, ``hard2``, ``k_3`` and the sensors'
``ecc1``); since model 1.3 the terms of the sealed effects (``u_flicker``,
``x_leak``, ``tau_S1``, ``prog12``, ``tau_dry2``, ``b_3`` and the sensors'
``xtalk2``); since model 1.4 the terms of the second sealed family (``u_dc``,
``r_m``, ``mu_1``, ``sq12``, ``play2``, ``bump3`` and the sensors' ``hold1``);
since model 1.5 the terms of the third sealed family (``r_con``, ``r_bar``,
``tau_brake``, ``hyst12``, ``mesh2``, ``eddy3`` and the sensors' ``hum``);
since model 1.6 the terms of the fourth sealed family (``t_pole``, ``bypass_a``,
``tau_rub``, ``seal12``, ``gear2``, ``bind3`` and the sensors' ``igain_a``);
since model 1.7 the terms of the fifth sealed family (``u_h57``, ``psi_r0``,
``tau_mis1``, ``ecc12``, ``tau_unb2``, ``buf3`` and the sensors' ``sat_a1``).
The sensor chain (delay, trigger offset, low-pass, gain, offset,
quantisation) is also an extension with neutral defaults. See
``docs/model-changes.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np

from engine import constants as const
from engine.constants import (
    C_GROUPS,
    DISTURBANCE_MAX_KNOTS,
    J1_GRID,
    K_GRID,
    SAMPLE_INTERVAL,
    T_EVENT_MAX,
    TM_PER_J,
)

#: Loci of the plant where an unknown input can enter (:class:`Disturbance`), in the kernel's
#: order; every locus of :data:`engine.simulation.LOCI` but the measurement chain.
#: ``clutch_torque`` (model 1.8) is a second input of the clutch: a torque its halves exert on each
#: other (a drag, a seal, a spring of the coupling), where ``clutch`` moves its zone.
DISTURBANCE_LOCI: tuple[str, ...] = (
    "supply",
    "motor_electrical",
    "motor_shaft",
    "clutch",
    "drive_train",
    "load",
    "clutch_torque",
)
#: What the unknown input is at each locus, and its unit.
DISTURBANCE_MEANING: dict[str, tuple[str, str]] = {
    "supply": ("relative deviation of the supply voltage amplitude, u -> u (1 + d)", "x u"),
    "motor_electrical": ("additive electromagnetic torque (in m_el and on J1)", "pu"),
    "motor_shaft": ("torque on the motor shaft J1 (not in m_el)", "pu"),
    "clutch": ("angle offset of the backlash zone, theta_1 - theta_2 - d", "rad"),
    "drive_train": ("torque on the drive wheel J2", "pu"),
    "load": ("torque on the load (mass m2)", "pu"),
    "clutch_torque": ("torque across the clutch, from the motor shaft J1 to the drive wheel J2", "pu"),
}
#: The part of the plant (one of :data:`engine.simulation.LOCI`) where each unknown input enters, where
#: the input's name is not the part's.
DISTURBANCE_PART: dict[str, str] = {"clutch_torque": "clutch"}


def input_part(name: str) -> str:
    """The part of the plant where the unknown input ``name`` (or a locus's library) enters."""
    return DISTURBANCE_PART.get(name, name)


#: Loci the recorded channels cannot tell apart, by the name a sentence gives the group. The
#: supply and the motor's electrics reach every recorded channel only through the electromagnetic
#: torque m_el, itself a channel: a record holds none of the stator's voltages, currents or fluxes,
#: so whatever a change at either does to the record is a change of m_el(t) while the motor is on,
#: which an additive electromagnetic torque reproduces on every channel (``tests/test_locus_groups.py``:
#: 99 % of a supply deviation's change on each channel), and which a deviation of the supply's
#: voltage, or of the motor's windings, can make too. Only an assumption about the shape of the
#: missing physics would tell them apart, not the record: the locus estimate names the group
#: (:func:`locus_group`). A record with a current or voltage channel would separate them; this
#: plant has none (MODEL.md section 3).
LOCUS_GROUPS: dict[str, tuple[str, ...]] = {"the supply or the motor's electrics": ("supply", "motor_electrical")}
#: Why the record cannot tell each group's loci apart, and what would, as the answer says it.
LOCUS_GROUP_REASONS: dict[str, str] = {
    "the supply or the motor's electrics": (
        "both reach the record only through m_el; a stator current or voltage channel would"
    ),
}


def locus_group(locus: str) -> tuple[str, ...]:
    """The loci the record cannot tell from ``locus`` (:data:`LOCUS_GROUPS`), ``locus`` first; ``(locus,)`` alone
    when it is in no group."""
    for members in LOCUS_GROUPS.values():
        if locus in members:
            return (locus, *(m for m in members if m != locus))
    return (locus,)


def locus_group_name(locus: str) -> str | None:
    """What a sentence calls the group of ``locus`` (None when it is in no group)."""
    return next((name for name, members in LOCUS_GROUPS.items() if locus in members), None)


#: The plant's Coulomb friction against the motion of the part at each torque locus:
#: ``field * tanh(w / W_SMOOTH)`` against the part's own speed w (w_1 of the motor shaft, w_2 of
#: the drive wheel, w_3 of the load, the last being the absorber's discontinuity c_1). The locus
#: estimate tries these as terms that follow the state, which a schedule d(t) found around the
#: calibrated trajectory cannot represent once the part sticks (``engine.diagnosis.locus``).
COULOMB_FIELDS: dict[str, str] = {"motor_shaft": "tau_C1", "drive_train": "tau_C2", "load": "c1"}

#: The plant's own MODEL.md parameters at each locus, with what each is and the plausible range
#: of its drift factor (a regulated supply's frequency within 10 %, masses and stiffnesses within a
#: factor 2, dampings, which are poorly known, as the catalogue's contact damping). The locus estimate lets
#: each drift by a factor, one at a time, fitted with the calibrated parameters, as a term of its
#: part: a gap at a part is often one of its own parameters off its nominal value, and a drift that
#: is large (a load 40 % heavier) or acts through the whole run (the supply frequency) is out of
#: reach of a schedule d(t) linearised around the calibrated trajectory. The list is every MODEL.md
#: parameter of the part with a non-zero nominal value, not a choice made for any effect, less the
#: reactances (a factor on one of x_s, x_r, x_m alone changes the leakages too, and can make the
#: inductance matrix singular) and the wheel radius (a scale of the channels); the calibrated ones
#: (K, J1, c) are left to the calibration.
PART_FIELDS: dict[str, dict[str, tuple[str, tuple[float, float]]]] = {
    "supply": {"u": ("supply voltage amplitude u", (0.8, 1.2)), "f": ("supply frequency f", (0.9, 1.1))},
    "motor_electrical": {
        "r_s": ("stator resistance r_s", (0.5, 2.0)),
        "r_r": ("rotor resistance r_r", (0.5, 2.0)),
    },
    "motor_shaft": {"J1": ("motor inertia J1", (0.5, 2.0))},
    "clutch": {
        "k12": ("contact stiffness k12 of the clutch", (0.1, 10.0)),
        "d12": ("contact damping d12 of the clutch", (0.1, 20.0)),
    },
    "drive_train": {
        "J2": ("wheel inertia J2", (0.5, 2.0)),
        "k2": ("stiffness k2 of the resilient element", (0.5, 2.0)),
        "d2": ("damping d2 of the resilient element", (0.1, 20.0)),
    },
    "load": {
        "T3": ("mechanical time constant T3 of the load", (0.5, 2.0)),
        "c": ("viscous coefficient c of the absorber", (0.5, 2.0)),
    },
}


class ParameterError(ValueError):
    """Raised for a physically absurd or non-finite parameter; the message says what to fix."""


@dataclass(frozen=True)
class Disturbance:
    """An additive unknown input d(t) at one locus of the plant (model 1.1).

    A piecewise-linear schedule: knot j lies at ``t0 + j * dt`` [s since switch-on] and holds
    ``values[j]``; d is zero one spacing before the first knot and one spacing after the last,
    and linear in between (so it is continuous). A schedule with a single non-zero knot is a
    hat function of half-width ``dt``, the basis an estimator uses. The integrator cuts its
    steps at the knots, so the kinks cost no accuracy.

    Parameters
    ----------
    locus : str
        Where it enters, one of :data:`DISTURBANCE_LOCI` (meaning and unit:
        :data:`DISTURBANCE_MEANING`): ``supply`` relative voltage deviation [x u],
        ``motor_electrical`` additive electromagnetic torque [pu], ``motor_shaft`` torque on
        J1 [pu], ``clutch`` angle offset of the backlash zone [rad], ``drive_train`` torque on
        J2 [pu], ``load`` torque on the mass m2 [pu], ``clutch_torque`` (model 1.8) torque across the
        clutch from J1 to J2 (-d on J1, +d on J2) [pu].
    t0 : float
        Time of the first knot [s since switch-on], >= 0.
    dt : float
        Knot spacing [s], > 0.
    values : tuple of float
        Knot values in the locus's unit, 1 to ``DISTURBANCE_MAX_KNOTS`` of them.
    step : float
        Added to d from the switch-off (the event t_e) on, in the locus's unit: a jump at the
        instant the motor's torque jumps too (e.g. a torque left at the switch-off).
    """

    locus: str
    t0: float
    dt: float
    values: tuple[float, ...]
    step: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "values", tuple(float(v) for v in self.values))

    @property
    def unit(self) -> str:
        """Unit of the values."""
        return DISTURBANCE_MEANING[self.locus][1]

    def validate(self) -> Disturbance:
        """Raise :class:`ParameterError` on an unknown locus or a malformed schedule."""
        if self.locus not in DISTURBANCE_LOCI:
            raise ParameterError(f"disturbance locus {self.locus!r} is not one of {', '.join(DISTURBANCE_LOCI)}")
        if not (math.isfinite(self.t0) and self.t0 >= 0.0):
            raise ParameterError(f"disturbance t0 = {self.t0} s must be a finite time since switch-on (>= 0)")
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ParameterError(f"disturbance knot spacing dt = {self.dt} s must be positive")
        if not (1 <= len(self.values) <= DISTURBANCE_MAX_KNOTS):
            raise ParameterError(
                f"a disturbance needs 1 to {DISTURBANCE_MAX_KNOTS} knot values, got {len(self.values)}"
            )
        if not all(math.isfinite(v) for v in (*self.values, self.step)):
            raise ParameterError("disturbance knot values and step must be finite")
        if self.locus == "supply" and min(self.values) <= -1.0:
            raise ParameterError("a supply disturbance must keep the voltage positive (values > -1)")
        return self

    def at(self, t: np.ndarray, t_event: float = math.inf) -> np.ndarray:
        """d at times ``t`` [s since switch-on], in :attr:`unit`, with the step from ``t_event`` [s] on."""
        t = np.asarray(t, dtype=float)
        knots = self.t0 + self.dt * np.arange(-1, len(self.values) + 1)
        d = np.interp(t, knots, np.concatenate([[0.0], self.values, [0.0]]))
        return d + np.where(t >= t_event, self.step, 0.0)


@dataclass(frozen=True)
class PlantParameters:
    """Reference plant of MODEL.md section 1 (per unit unless stated).

    Every default is MODEL.md's value, read from :mod:`engine.constants` (the
    single home of the numbers); the nominal K, c and J1 are used where a record
    gives none.

    Parameters
    ----------
    K : float
        Backlash zone width [m]; the clutch dead zone has half-width b = K / r [rad].
    J1 : float
        Motor-side inertia [kg m^2]; T_1 = J1 * tm_per_j [s] (MODEL.md: 0.86 / 0.87 s / (kg m^2)).
    J2 : float
        Drive-wheel inertia [kg m^2]; T_2 = J2 * tm_per_j [s].
    T3 : float
        Mechanical time constant of the mass m2 referred to the motor shaft [s].
    c : float
        Apparent viscosity of the absorber [pu torque / pu speed].
    c1 : float
        Discontinuity at zero speed of the absorber characteristic [pu torque].
    r : float
        Drive-wheel radius [m].
    k12, d12 : float
        Contact stiffness [pu/rad] and contact damping [pu/pu speed] of the clutch.
    k2, d2 : float
        Stiffness [pu/rad] and damping [pu/pu speed] of the resilient element.
    r_s, r_r, x_s, x_r, x_m : float
        Stator and rotor resistance, total stator and rotor reactance, magnetising
        reactance [pu].
    u, f : float
        Supply voltage amplitude [pu] and frequency [pu of the rated frequency, w_b / (2 pi); MODEL.md: 50 Hz].
    tau_C1 : float
        Extension: Coulomb friction torque on the motor shaft, tau_C1 * tanh(w_1 / W_SMOOTH) [pu].
    b_1 : float
        Extension: viscous friction on the motor shaft, b_1 * w_1 [pu torque / pu speed].
    tau_ripple3 : float
        Extension (1.1): torque ripple on the load, tau_ripple3 * sin(2 pi LOAD_RIPPLE_HZ t) [pu],
        t since switch-on.
    clutch_offset : float
        Extension (1.1): offset of the backlash zone [rad]: contact at theta_1 - theta_2 - offset
        = +-b; |offset| < b (the clutch starts inside the zone).
    tau_cog : float
        Extension (1.1): cogging torque on the motor shaft, -tau_cog * sin(COGGING_ORDER theta_1) [pu].
    tau_C2 : float
        Extension (1.1): Coulomb friction of the drive wheel, tau_C2 * tanh(w_2 / W_SMOOTH) [pu].
    m_off : float
        Extension (1.1): share of the electromagnetic torque at the switch-off that remains and
        decays as exp(-(t - t_e) / SWITCH_OFF_DECAY_TIME) [x]; 0 means it vanishes at once (MODEL.md).
    disturbance : Disturbance or None
        Extension (1.1): an additive unknown input at one locus; None means none.
    u_neg : float
        Extension (1.2): negative-sequence share of the supply voltage [x u]: the stator voltage
        is u (exp(j f w_b t) + u_neg exp(-j f w_b t)) (u including a supply disturbance).
    sat : float
        Extension (1.2): saturation of the magnetising reactance [1/pu^2]: x_m -> x_m / (1 + sat
        |psi_s|^2), the leakages x_s - x_m and x_r - x_m unchanged.
    b_2 : float
        Extension (1.2): windage (fan) torque on the motor shaft, b_2 * w_1 * abs(w_1) against its
        motion [pu torque / pu speed^2] (not in m_el).
    k_pre : float
        Extension (1.2): a weak spring across the clutch acting always, k_pre * k12 * d on J1
        (against) and J2, d the clutch deflection (zone offset subtracted) [x k12].
    hard2 : float
        Extension (1.2): hardening of the resilient element [1/pu^2]: its spring torque is
        k2 x (1 + hard2 (k2 x)^2), x = theta_2 - theta_3.
    k_3 : float
        Extension (1.2): a spring from the load to ground, -k_3 * theta_3 / (2 pi) on the mass
        [pu torque per revolution of theta_3].
    u_flicker : float
        Extension (1.3): flicker of the supply voltage [x u]: its amplitude is
        u (1 + u_flicker sin(2 pi F_FLICKER t)), F_FLICKER = 8.8 Hz, t since switch-on (u including
        a supply disturbance; the negative sequence of ``u_neg`` follows it).
    x_leak : float
        Extension (1.3): both leakage reactances higher by x_leak [pu]: x_s -> x_s + x_leak,
        x_r -> x_r + x_leak, x_m unchanged (the simulator adds it to x_s and x_r).
    tau_S1 : float
        Extension (1.3): Stribeck friction on the motor shaft against its motion [pu torque],
        tau_S1 * tanh(w_1 / W_SMOOTH) * exp(-(w_1 / W_STRIBECK)^2), W_STRIBECK = 0.005 pu (not in m_el).
    prog12 : float
        Extension (1.3): progressive contact of the clutch [x]: the contact spring k12 x becomes
        k12 x (1 + prog12 x / X_REF), x >= 0 the penetration beyond the zone's edge [rad],
        X_REF = 0.01 rad (the contact damping and the push-never-pull clip unchanged).
    tau_dry2 : float
        Extension (1.3): dry friction inside the resilient element [pu torque]:
        tau_dry2 * tanh((w_2 - w_3) / W_SMOOTH) added to its torque m_s (against the relative
        motion of the wheel and the load).
    b_3 : float
        Extension (1.3): quadratic drag on the load, b_3 * w_3 * abs(w_3) against its motion
        [pu torque / pu speed^2].
    u_dc : float
        Extension (1.4): a DC component of the supply voltage in the alpha axis (phase a) [x u]:
        u_s + u_dc * u, u this plant's amplitude (a supply disturbance and the flicker do not scale
        the DC part).
    r_m : float
        Extension (1.4): the core (iron) losses as a resistance in the magnetising branch, in series
        with x_m [pu]: dpsi_s/dt and dpsi_r/dt each less w_b r_m (i_s + i_r); m_el unchanged.
    mu_1 : float
        Extension (1.4): bearing friction of the motor shaft under the load the clutch transmits [x]:
        mu_1 * abs(m_c) * tanh(w_1 / W_SMOOTH) against the motor's motion (not in m_el).
    sq12 : float
        Extension (1.4): a squeeze film in the clutch's gap [pu torque / pu speed]: the clutch
        transmits sq12 (H_SQUEEZE / (H_SQUEEZE + h))^3 (w_1 - w_2) besides its contact, h =
        max(b - |d|, 0) the gap to the zone's edge, H_SQUEEZE = 0.005 rad: growing as the gap closes,
        at its largest (sq12) in contact, and not clipped (the film also resists the parting).
    play2 : float
        Extension (1.4): play in the hub of the resilient element [rad]: its spring torque k2 x
        becomes k2 (x - play2 tanh(x / play2)), x = theta_2 - theta_3 (a dead zone of half-width
        play2, smoothed over play2; the damping unchanged).
    bump3 : float
        Extension (1.4): a bump on the load's track [pu torque, the largest force]: on the mass
        bump3 sqrt(2 e) s exp(-s^2), s = (theta_3 - THETA_BUMP) / W_BUMP (a hill at THETA_BUMP = 0.1
        rad of half-width W_BUMP = 0.02 rad: against the motion up to its crest, with it beyond).
    r_con : float
        Extension (1.5): a high-resistance connection in phase a of the supply (a loose terminal, a
        pitted contactor contact) [pu resistance]: the star point floats, so the motor's voltage is
        u_s - (2/3) r_con i_s_alpha along the alpha axis (phase a) and u_s along beta; motor on.
    r_bar : float
        Extension (1.5): a broken rotor bar [x r_r]: the rotor's resistance higher by r_bar * r_r along
        one axis of the rotor, at the electrical angle g = p theta_1 (on the alpha axis at switch-on):
        dpsi_r/dt less w_b r_bar r_r Re(i_r e^(-j g)) e^(j g); m_el unchanged.
    tau_brake : float
        Extension (1.5): the spring-applied brake of a brake motor [pu torque]: tau_brake g_b(t)
        tanh(w_1 / W_SMOOTH) against the motor's motion (not in m_el), g_b 1 at switch-on, lifting to 0
        T_BRAKE_RELEASE after it and back to 1 T_BRAKE_APPLY after the switch-off, each along a
        smoothstep of T_BRAKE_TRAVEL.
    hyst12 : float
        Extension (1.5): hysteretic (rate-independent) damping of the clutch's contact [x], in [0, 1):
        the contact spring k12 x (x the signed penetration beyond the zone's edge) becomes
        k12 x (1 + hyst12 tanh(sgn(x) (w_1 - w_2) / W_SMOOTH)), stiffer while the penetration deepens,
        softer while it recedes (after the progressive contact of 1.3; damping and clip unchanged).
    mesh2 : float
        Extension (1.5): the mesh stiffness variation of a gear stage in the resilient path [x], in
        [0, 1): the resilient spring k2 x becomes k2 x (1 + mesh2 sin(MESH_ORDER theta_2)),
        x = theta_2 - theta_3 (the hardening of 1.2 and the hub's play of 1.4 unchanged).
    eddy3 : float
        Extension (1.5): an eddy-current brake on the load [pu torque, the largest force]: on the mass
        -eddy3 2 s / (1 + s^2), s = w_3 / W_EDDY (linear in the speed below W_EDDY, falling above it).
    t_pole : float
        Extension (1.6): one pole of the supply's contactor (phase c's) closes t_pole [s] after the
        other two, in [0, 0.05]: until then phase c carries no current (i_s along e^(j 4 pi / 3)
        stays zero; the motor's star point floats), so the stator flux's component along that axis
        follows (x_m / x_r) times the rotor flux's instead of the supply (the reactances of the
        instant); 0 means all three poles close at switch-on.
    bypass_a : float
        Extension (1.6): a share bypass_a [x] of phase a's turns bypassed (a coil jumpered out in an
        emergency repair), in [0, 0.5]: the stator's alpha axis couples to the air gap with
        n = 1 - (2/3) bypass_a of the turns, its leakage is s = 1 - (4/3) bypass_a + (2/3) bypass_a^2
        times x_s - x_m and its resistance n r_s; the beta axis is unchanged, and m_el is the
        torque on the rotor, psi_r_beta i_r_alpha - psi_r_alpha i_r_beta.
    tau_rub : float
        Extension (1.6): the rotor rubbing the stator's bore under the unbalanced magnetic pull
        [pu torque at |psi_s| = 1 pu]: tau_rub |psi_s|^2 tanh(w_1 / W_SMOOTH) against the motor's
        motion while the motor is on (the pull is the air gap's field's; not in m_el).
    seal12 : float
        Extension (1.6): dry friction between the clutch's halves [pu torque] (a coupling's seal, or a
        misaligned insert rubbing): seal12 tanh((w_1 - w_2) / W_SMOOTH) from J1 to J2 at every
        deflection, beside the contact.
    gear2 : float
        Extension (1.6): the mesh friction of a gear stage in the resilient path [x], 1 - its
        efficiency: gear2 |m_s| tanh(w_2 / W_SMOOTH) against the wheel's motion (m_s the resilient
        element's torque).
    bind3 : float
        Extension (1.6): misaligned guides of the load, pinching it harder the further it travels
        [pu torque at THETA_BIND of travel]: bind3 |theta_3| / THETA_BIND tanh(w_3 / W_SMOOTH)
        against the mass's motion.
    u_h57 : float
        Extension (1.7): the 5th and 7th harmonics of the supply voltage [x u], each of amplitude
        u_h57 u (the voltage drop of six-pulse rectifiers' currents across the network's
        impedance): u_s = u (exp(j f w_b t) + u_h57 (exp(-j 5 f w_b t) + exp(j 7 f w_b t))), the 5th
        of negative sequence, the 7th of positive sequence.
    psi_r0 : float
        Extension (1.7): the rotor's residual flux at switch-on [pu flux] (a restart before the
        flux of the previous run has decayed): at t = 0 the rotor's flux is psi_r0 along the alpha
        axis and the stator's (x_m / x_r) psi_r0 (the stator current zero; x_m, x_r without
        saturation), the plant otherwise at rest; it decays with the rotor's time constant.
    tau_mis1 : float
        Extension (1.7): a misaligned motor shaft [pu torque] (angular misalignment against the
        clutch's hub, flexing the shaft twice per revolution): -tau_mis1 sin(2 theta_1) on J1.
    ecc12 : float
        Extension (1.7): runout of the clutch's toothed hub [x b]: the backlash's half-width varies
        once per revolution of the motor, b (1 + ecc12 sin(theta_1)) (the centre distance of an
        eccentric mesh), in the contact, its modes and the event alike.
    tau_unb2 : float
        Extension (1.7): a mass imbalance of the drive wheel [pu torque]: the gravity torque
        -tau_unb2 sin(theta_2) on J2 (the heavy spot at the bottom at rest).
    buf3 : float
        Extension (1.7): an elastomer end buffer on the load's track [pu torque at THETA_STOP of
        compression]: from theta_3 = THETA_STOP on, -buf3 ((theta_3 - THETA_STOP) / THETA_STOP)^2 on
        the mass (progressive, as a rubber buffer's; zero before it).
    w_b : float
        Base value (issue 52): electrical base angular frequency w_b [rad/s], 2 pi times the rated
        supply frequency (MODEL.md: 2 pi 50).
    pole_pairs : int
        Base value (issue 52): pole pairs p [-]; the mechanical base speed is Omega_b = w_b / p [rad/s]
        (MODEL.md: 2).
    tm_per_j : float
        Base value (issue 52): mechanical time constant per unit inertia, T_i = J_i * tm_per_j
        [s / (kg m^2)], i.e. Omega_b / M_b with M_b the base torque [N m] (MODEL.md: 0.86 / 0.87).
    """

    K: float = const.K_NOMINAL
    J1: float = const.J1_NOMINAL
    J2: float = const.J2
    T3: float = const.T3
    c: float = const.C_NOMINAL
    c1: float = const.C1_NOMINAL
    r: float = const.WHEEL_RADIUS
    k12: float = const.K12
    d12: float = const.D12
    k2: float = const.K2
    d2: float = const.D2
    r_s: float = const.R_S
    r_r: float = const.R_R
    x_s: float = const.X_S
    x_r: float = const.X_R
    x_m: float = const.X_M
    u: float = const.U_SUPPLY
    f: float = const.F_SUPPLY
    tau_C1: float = 0.0
    b_1: float = 0.0
    tau_ripple3: float = 0.0
    clutch_offset: float = 0.0
    tau_cog: float = 0.0
    tau_C2: float = 0.0
    m_off: float = 0.0
    disturbance: Disturbance | None = None
    u_neg: float = 0.0
    sat: float = 0.0
    b_2: float = 0.0
    k_pre: float = 0.0
    hard2: float = 0.0
    k_3: float = 0.0
    u_flicker: float = 0.0
    x_leak: float = 0.0
    tau_S1: float = 0.0
    prog12: float = 0.0
    tau_dry2: float = 0.0
    b_3: float = 0.0
    u_dc: float = 0.0
    r_m: float = 0.0
    mu_1: float = 0.0
    sq12: float = 0.0
    play2: float = 0.0
    bump3: float = 0.0
    r_con: float = 0.0
    r_bar: float = 0.0
    tau_brake: float = 0.0
    hyst12: float = 0.0
    mesh2: float = 0.0
    eddy3: float = 0.0
    t_pole: float = 0.0
    bypass_a: float = 0.0
    tau_rub: float = 0.0
    seal12: float = 0.0
    gear2: float = 0.0
    bind3: float = 0.0
    u_h57: float = 0.0
    psi_r0: float = 0.0
    tau_mis1: float = 0.0
    ecc12: float = 0.0
    tau_unb2: float = 0.0
    buf3: float = 0.0
    w_b: float = const.W_B
    pole_pairs: int = const.POLE_PAIRS
    tm_per_j: float = TM_PER_J

    @property
    def T1(self) -> float:
        """Mechanical time constant of the motor side [s]."""
        return self.J1 * self.tm_per_j

    @property
    def T2(self) -> float:
        """Mechanical time constant of the drive wheel [s]."""
        return self.J2 * self.tm_per_j

    @property
    def omega_b(self) -> float:
        """Mechanical base speed Omega_b = w_b / p [rad/s]: 1 pu of speed."""
        return self.w_b / self.pole_pairs

    @property
    def b(self) -> float:
        """Half-width of the backlash dead zone, K / r [rad]."""
        return self.K / self.r

    def validate(self) -> PlantParameters:
        """Raise :class:`ParameterError` on a non-finite or physically absurd value."""
        for f in fields(self):
            if f.name == "disturbance":
                continue
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ParameterError(f"plant parameter {f.name} must be a finite number, got {v!r}")
        if self.disturbance is not None:
            if not isinstance(self.disturbance, Disturbance):
                raise ParameterError(
                    f"disturbance must be a Disturbance or None, got {type(self.disturbance).__name__}"
                )
            self.disturbance.validate()
        _check_range("K", self.K, 1e-5, 0.05, "m")
        for name in ("J1", "J2"):
            _check_range(name, getattr(self, name), 0.05, 20.0, "kg m^2")
        _check_range("T3", self.T3, 1e-3, 20.0, "s")
        _check_range("r", self.r, 1e-3, 10.0, "m")
        for name in ("c", "c1", "d12", "d2", "tau_C1", "b_1", "tau_ripple3", "tau_cog", "tau_C2"):
            _check_range(name, getattr(self, name), 0.0, 100.0, "pu")
        if not abs(self.clutch_offset) < self.b:
            raise ParameterError(
                f"clutch_offset = {self.clutch_offset} rad must be smaller in magnitude than the zone's "
                f"half-width b = K / r = {self.b:.4g} rad (the clutch starts inside the zone)"
            )
        _check_range("m_off", self.m_off, -1.0, 1.0, "x")
        _check_range("u_neg", self.u_neg, 0.0, 0.5, "x u")
        _check_range("sat", self.sat, 0.0, 10.0, "1/pu^2")
        _check_range("b_2", self.b_2, 0.0, 100.0, "pu")
        _check_range("k_pre", self.k_pre, 0.0, 1.0, "x k12")
        _check_range("hard2", self.hard2, 0.0, 100.0, "1/pu^2")
        _check_range("k_3", self.k_3, 0.0, 100.0, "pu/rev")
        _check_range("u_flicker", self.u_flicker, 0.0, 0.5, "x u")
        _check_range("x_leak", self.x_leak, 0.0, 1.0, "pu")
        _check_range("tau_S1", self.tau_S1, 0.0, 100.0, "pu")
        _check_range("prog12", self.prog12, 0.0, 1000.0, "x")
        _check_range("tau_dry2", self.tau_dry2, 0.0, 100.0, "pu")
        _check_range("b_3", self.b_3, 0.0, 1000.0, "pu")
        _check_range("u_dc", self.u_dc, 0.0, 0.2, "x u")
        _check_range("r_m", self.r_m, 0.0, 1.0, "pu")
        _check_range("mu_1", self.mu_1, 0.0, 1.0, "x")
        _check_range("sq12", self.sq12, 0.0, 1000.0, "pu")
        _check_range("play2", self.play2, 0.0, 0.1, "rad")
        _check_range("bump3", self.bump3, 0.0, 100.0, "pu")
        _check_range("r_con", self.r_con, 0.0, 1.0, "pu")
        _check_range("r_bar", self.r_bar, 0.0, 10.0, "x r_r")
        _check_range("tau_brake", self.tau_brake, 0.0, 10.0, "pu")
        _check_range("hyst12", self.hyst12, 0.0, 0.9, "x")
        _check_range("mesh2", self.mesh2, 0.0, 0.9, "x")
        _check_range("eddy3", self.eddy3, 0.0, 100.0, "pu")
        _check_range("t_pole", self.t_pole, 0.0, 0.05, "s")
        _check_range("bypass_a", self.bypass_a, 0.0, 0.5, "x")
        _check_range("tau_rub", self.tau_rub, 0.0, 10.0, "pu")
        _check_range("seal12", self.seal12, 0.0, 10.0, "pu")
        _check_range("gear2", self.gear2, 0.0, 0.9, "x")
        _check_range("bind3", self.bind3, 0.0, 100.0, "pu")
        _check_range("u_h57", self.u_h57, 0.0, 0.5, "x u")
        _check_range("psi_r0", self.psi_r0, 0.0, 1.0, "pu")
        _check_range("tau_mis1", self.tau_mis1, 0.0, 10.0, "pu")
        _check_range("ecc12", self.ecc12, 0.0, 0.9, "x")
        _check_range("tau_unb2", self.tau_unb2, 0.0, 10.0, "pu")
        _check_range("buf3", self.buf3, 0.0, 100.0, "pu")
        for name in ("k12", "k2"):
            _check_range(name, getattr(self, name), 1e-3, 1e5, "pu/rad")
        for name in ("r_s", "r_r"):
            _check_range(name, getattr(self, name), 1e-4, 10.0, "pu")
        for name in ("x_s", "x_r", "x_m"):
            _check_range(name, getattr(self, name), 1e-3, 100.0, "pu")
        if self.x_s * self.x_r - self.x_m**2 <= 0:
            raise ParameterError("x_s * x_r must exceed x_m^2 (leakage reactances must be positive)")
        _check_range("u", self.u, 0.05, 2.0, "pu")
        _check_range("f", self.f, 0.05, 2.0, "pu")
        _check_range("w_b", self.w_b, 2.0 * math.pi * 1.0, 2.0 * math.pi * 1000.0, "rad/s")
        if self.pole_pairs != int(self.pole_pairs):
            raise ParameterError(f"pole_pairs = {self.pole_pairs} must be a whole number of pole pairs")
        _check_range("pole_pairs", self.pole_pairs, 1, 64, "")
        _check_range("tm_per_j", self.tm_per_j, 1e-4, 1e4, "s/(kg m^2)")
        return self

    def replace(self, **changes: Any) -> PlantParameters:
        """Copy with some fields changed (unknown names raise :class:`ParameterError`)."""
        _check_names(self, changes)
        return replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """Every field by name; the disturbance (if any) as a dict of its own."""
        return asdict(self)


@dataclass(frozen=True)
class SensorParameters:
    """Measurement chain between the plant and the record (extension of MODEL.md).

    Every field's default is neutral (the record is then MODEL.md's). The chain acts in
    the order of the measurement:

    1. **delay and trigger shift**: sample k of a record on a grid of interval Ts with the
       event at sample E holds the value at ``t_e + (k - E) Ts - (delay + trigger_offset)``
       (an instant before switch-on reads the plant at rest: 0);
    2. **low-pass**: a first-order filter on every channel (continuous-time, integrated with
       the plant from switch-on);
    3. **gain**: every channel multiplied by ``gain``;
    4. **offset**: ``offset_rms`` times the channel's RMS added to every channel, the RMS taken
       after the gain over the test window's samples (4.8 ms before to 200 ms after the event,
       :meth:`engine.records.SampleGrid.window`), so it does not depend on the record's length;
    5. **quantisation** of omega1 to multiples of ``speed_quantum``.

    Model 1.2 adds an error of the speed encoder before the chain: omega1 reads
    ``Omega_b w_1 (1 + ecc1 sin(theta_1))`` (once per revolution of the motor shaft). Model 1.3
    adds the cross-axis sensitivity of the load's accelerometer before the chain: a2 reads
    ``a2 + xtalk2 a1``. Model 1.4 adds a sample-and-hold of omega1 after the low-pass: sample k's
    omega1 is the value at ``hold1 floor(t_k / hold1)``, t_k its instant since switch-on (step 1).
    Model 1.5 adds the mains' hum of a ground loop in the accelerometers' cabling before the chain:
    a1 and a2 each read ``hum sin(f w_b t)`` more. Model 1.6 adds a gain error of the phase-a current
    sensor of the torque's estimate: while the motor is on, m_el reads
    ``m_el + igain_a i_s_alpha (psi_s_alpha / sqrt(3) - psi_s_beta)``. Model 1.7 adds the saturation
    of a1's accelerometer (its amplifier's range): a1 reads ``tanh(sat_a1 a1) / sat_a1``.

    Steps 1-2 (and the encoder's and the accelerometer's errors, the hold, the hum, the current sensor's gain and a1's saturation) are in the kernel, 3-5
    act on the sampled values (:func:`engine.simulation.simulator.apply_sensor_readout`).

    Parameters
    ----------
    delay : float
        Every channel is recorded ``delay`` seconds late [s], in [0, 5e-3].
    lowpass_hz : float
        Cut-off of a first-order low-pass on every channel [Hz]; 0 means none.
    speed_quantum : float
        omega1 is rounded to multiples of this [rad/s]; 0 means none.
    trigger_offset : float
        The record's alignment is off by this [s], in [-5e-3, 5e-3]: the true event lies
        ``trigger_offset`` after the labelled one (the same shift as ``delay``, of either sign;
        negative: samples taken later than nominal).
    gain : float
        Every channel scaled by this [x], in [0.1, 10]; 1 means none.
    offset_rms : float
        Constant offset of every channel in units of the channel's RMS [x RMS], in [-1, 1]; 0 means none.
    ecc1 : float
        Extension (1.2): eccentricity of the speed encoder [x], in [0, 0.5]: omega1 reads
        Omega_b w_1 (1 + ecc1 sin(theta_1)) before the low-pass, gain, offset and quantisation; 0 means none.
    xtalk2 : float
        Extension (1.3): cross-axis sensitivity of the load's accelerometer [x], in [0, 1]: a2 reads
        a2 + xtalk2 a1 [m/s^2] (the analog values, before the low-pass, gain and offset); 0 means none.
    hold1 : float
        Extension (1.4): sample-and-hold period of omega1 [s], in [0, 0.01]: the speed is updated
        every hold1 seconds from switch-on and held in between (a drive publishing its speed at a
        slower cycle than the logger samples), read after the encoder's error and the low-pass and
        before the gain, offset and quantisation; 0 means none.
    hum : float
        Extension (1.5): mains hum of a ground loop in the accelerometers' cabling [m/s^2], in
        [0, 100]: a1 and a2 each read hum * sin(f w_b t) more (t since switch-on, f w_b the supply's
        angular frequency; after the accelerometer's cross-talk, before the low-pass, gain and
        offset); 0 means none.
    igain_a : float
        Extension (1.6): gain error of the phase-a current sensor of the torque's estimate [x], in
        [0, 1]: the estimate (the stator flux times the measured currents, phase c's computed from
        a's and b's) sees i_a (1 + igain_a), so that m_el reads igain_a i_s_alpha (psi_s_alpha /
        sqrt(3) - psi_s_beta) more while the motor is on (before the low-pass, gain and offset); 0
        means none.
    sat_a1 : float
        Extension (1.7): saturation of a1's accelerometer [s^2/m], 1 / its range, in [0, 1]: a1
        reads tanh(sat_a1 a1) / sat_a1 (after the mains hum, before the low-pass, gain and offset;
        a2's cross-talk takes the true a1); 0 means none.
    """

    delay: float = 0.0
    lowpass_hz: float = 0.0
    speed_quantum: float = 0.0
    trigger_offset: float = 0.0
    gain: float = 1.0
    offset_rms: float = 0.0
    ecc1: float = 0.0
    xtalk2: float = 0.0
    hold1: float = 0.0
    hum: float = 0.0
    igain_a: float = 0.0
    sat_a1: float = 0.0

    def validate(self) -> SensorParameters:
        for f in fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ParameterError(f"sensor parameter {f.name} must be a finite number, got {v!r}")
        _check_range("delay", self.delay, 0.0, 0.005, "s")
        if self.lowpass_hz != 0.0:
            _check_range("lowpass_hz", self.lowpass_hz, 10.0, 50_000.0, "Hz")
        _check_range("speed_quantum", self.speed_quantum, 0.0, 10.0, "rad/s")
        _check_range("trigger_offset", self.trigger_offset, -0.005, 0.005, "s")
        _check_range("gain", self.gain, 0.1, 10.0, "x")
        _check_range("offset_rms", self.offset_rms, -1.0, 1.0, "x RMS")
        _check_range("ecc1", self.ecc1, 0.0, 0.5, "x")
        _check_range("xtalk2", self.xtalk2, 0.0, 1.0, "x")
        _check_range("hold1", self.hold1, 0.0, 0.01, "s")
        _check_range("hum", self.hum, 0.0, 100.0, "m/s^2")
        _check_range("igain_a", self.igain_a, 0.0, 1.0, "x")
        _check_range("sat_a1", self.sat_a1, 0.0, 1.0, "s^2/m")
        return self

    def replace(self, **changes: Any) -> SensorParameters:
        _check_names(self, changes)
        return replace(self, **changes)


@dataclass(frozen=True)
class SolverSettings:
    """Settings of the fixed-step integrator.

    Parameters
    ----------
    max_step : float
        Largest RK4 step [s]; every interval between sample instants is split
        into equal steps no longer than this (on a grid finer than it, the steps are the
        sample spacing). The default MODEL.md's Ts / 3 (33 us) meets MODEL.md section 4 with
        a wide margin on every grid (tests/test_simulation_accuracy.py).
    t_event_max : float
        Simulated time within which the backlash event must occur [s].
    """

    max_step: float = SAMPLE_INTERVAL / 3
    t_event_max: float = T_EVENT_MAX

    def validate(self) -> SolverSettings:
        _check_range("max_step", self.max_step, 1e-7, 5e-5, "s")
        _check_range("t_event_max", self.t_event_max, 1e-3, 10.0, "s")
        return self


@dataclass(frozen=True)
class Case:
    """One simulation case: plant plus measurement chain."""

    plant: PlantParameters = PlantParameters()
    sensors: SensorParameters = SensorParameters()

    def validate(self) -> Case:
        self.plant.validate()
        self.sensors.validate()
        return self

    @classmethod
    def from_overrides(cls, overrides: Mapping[str, float] | None = None) -> Case:
        """Build a case from flat overrides of plant or sensor fields (e.g. ``{"K": 0.005, "delay": 1e-4}``)."""
        overrides = dict(overrides or {})
        plant_names = {f.name for f in fields(PlantParameters) if f.name != "disturbance"}  # scalars only
        sensor_names = {f.name for f in fields(SensorParameters)}
        unknown = set(overrides) - plant_names - sensor_names
        if unknown:
            raise ParameterError(
                f"unknown parameter(s) {sorted(unknown)}; plant parameters: {sorted(plant_names)}, "
                f"sensor parameters: {sorted(sensor_names)}"
            )
        plant = PlantParameters().replace(**{k: float(v) for k, v in overrides.items() if k in plant_names})
        sensors = SensorParameters(**{k: float(v) for k, v in overrides.items() if k in sensor_names})
        return cls(plant, sensors)


def paper_grid(
    c: float, J1_values: tuple[float, ...] | None = None, K_values: tuple[float, ...] | None = None
) -> list[Case]:
    """The paper's cases of one c group: every J1 for every width, width-major order.

    Returns ``len(K_values) * len(J1_values)`` cases; case ``i * n_J1 + p`` has
    width ``K_values[i]`` and inertia ``J1_values[p]``.
    """
    J1_values = tuple(J1_GRID if J1_values is None else J1_values)
    K_values = tuple(K_GRID if K_values is None else K_values)
    return [Case(PlantParameters(K=K, J1=J1, c=c)) for K in K_values for J1 in J1_values]


def full_grid() -> list[Case]:
    """The paper's full grid: 4 c groups x 6 widths x 7 J1 = 168 cases."""
    return [case for c in C_GROUPS for case in paper_grid(c)]


def _check_range(name: str, value: float, lo: float, hi: float, unit: str) -> None:
    if not (lo <= value <= hi):
        raise ParameterError(f"{name} = {value} {unit} is outside the accepted range [{lo}, {hi}] {unit}")


def _check_names(obj: Any, changes: Mapping[str, Any]) -> None:
    known = {f.name for f in fields(obj)}
    unknown = set(changes) - known
    if unknown:
        raise ParameterError(f"unknown parameter(s) {sorted(unknown)} for {type(obj).__name__}; known: {sorted(known)}")
