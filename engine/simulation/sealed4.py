"""Fourth sealed family (model 1.6): a sixth family outside the catalogue, kept for scoring.

SEALED4 is kept for scoring. Development never reads its scores: no diagnosis, locus, calibration or validation result on these effects is looked at while developing; it is run once, in one blind protocol-2 run of committed code, reported as out-of-sample figures.

Why a sixth family: the third sealed family of model 1.5 (:data:`~engine.simulation.sealed3.SEALED3`)
has had its one blind run (seed 269, code ada3284), and its figures are published; code developed
since then is developed knowing them, and a blind run is blind only for the code it ran on.
:data:`SEALED4` keeps physics whose scores nobody has read. It was defined, with its bounds, before
any diagnosis, calibration, locus estimate or validation was run on it: one scalar effect per locus
of :data:`~engine.simulation.effects.LOCI`, none of them in the catalogue, in HELD_BACK, HELD_OUT,
SEALED, SEALED2 or SEALED3, none a rescaled or reshaped version of one of theirs, and none the drift
of one MODEL.md parameter by a factor (which the locus estimate already fits). The simulator
implements every term (``docs/model-changes.md``, version 1.6; equations in ``docs/MODEL.md``
section 5); the bounds were chosen from visibility alone (nominal plant, half the upper bound,
40 dB: at least two channels change by more than 3 noise RMS, m_el alone for the torque estimate's
current sensor, which changes nothing else) and from the event still occurring at the upper bound
(``bench/family_visibility.py --family sealed4``). Each bound is a value a real drive of this kind
may have: a contactor pole closing a quarter of a mains period late, one coil of ten of a phase
jumpered out, a rub of a tenth of the rated torque, a seal's drag of 5 % of it, the mesh losses of a
worm stage (efficiency 0.8), guides pinching the load with a twentieth of the rated torque after
10 mm, and a current sensor 5 % off.

=======================  ================  ==============================================================
effect                   locus             term (value v)
=======================  ================  ==============================================================
``supply_late_pole``     supply            phase c open until t = v: i_s along e^(j 4 pi / 3) kept zero
``stator_coil_bypass``   motor_electrical  phase a with (1 - v) of its turns: the alpha axis's own x, r
``motor_rotor_rub``      motor_shaft       -v abs(psi_s)^2 tanh(w_1 / W_SMOOTH) on J1, motor on [pu]
``clutch_seal_drag``     clutch            v tanh((w_1 - w_2) / W_SMOOTH) from J1 to J2, every deflection
``resilient_gear_loss``  drive_train       -v abs(m_s) tanh(w_2 / W_SMOOTH) on J2 [x]
``load_guide_binding``   load              -v abs(theta_3) / THETA_BIND tanh(w_3 / W_SMOOTH) on the mass
``torque_current_gain``  sensors           m_el reads + v i_s_alpha (psi_s_alpha / sqrt(3) - psi_s_beta)
=======================  ================  ==============================================================

With phase c open the stator flux's component along e_c = e^(j 4 pi / 3) follows (x_m / x_r) times
the rotor flux's (the reactances of the instant), so that i_c = Re(i_s conj(e_c)) stays zero, the
star point floating; with phase a's turns (1 - v) the alpha axis's stator inductance is n^2 x_m +
s (x_s - x_m), its mutual one n x_m and its resistance n r_s, n = 1 - (2/3) v, s = 1 - (4/3) v +
(2/3) v^2, and m_el is the torque on the rotor; m_s is the resilient element's whole torque;
:data:`engine.constants.THETA_BIND` is 0.1 rad (10 mm of the load's travel); W_SMOOTH is MODEL.md's
smoothing speed. Every value is neutral at 0 and lies in ``[0, bound]``.
"""

from __future__ import annotations

from engine.constants import THETA_BIND, W_SMOOTH
from engine.simulation.effects import Effect, EffectLibrary

__all__ = ["RULE", "SEALED4"]

#: The rule of the family, verbatim in ``docs/model-changes.md`` (version 1.6).
RULE = (
    "SEALED4 is kept for scoring. Development never reads its scores: no diagnosis, locus, calibration or "
    "validation result on these effects is looked at while developing; it is run once, in one blind "
    "protocol-2 run of committed code, reported as out-of-sample figures."
)

# One row per effect: name, description, target, field, mode, bounds, neutral value, unit, locus.
# fmt: off
SEALED4 = EffectLibrary(
    [
        Effect("supply_late_pole",
               "one pole of the supply's contactor (phase c's) closes value seconds after the other two (a worn "
               "or burnt contact, a weak contact spring): until then phase c carries no current, the motor fed "
               "from one line voltage, its star point floating",
               "plant", "t_pole", "set", (0.0, 0.005), 0.0, "s", "supply"),
        Effect("stator_coil_bypass",
               "a share value of phase a's turns bypassed (a failed coil jumpered out in an emergency repair): "
               "the stator's alpha axis couples to the air gap with (1 - 2 value / 3) of its turns, with less "
               "leakage and resistance; the beta axis unchanged",
               "plant", "bypass_a", "set", (0.0, 0.1), 0.0, "x", "motor_electrical"),
        Effect("motor_rotor_rub",
               f"the rotor rubbing the stator's bore under the unbalanced magnetic pull (worn bearings): "
               f"value * |psi_s|^2 * tanh(w_1 / {W_SMOOTH:g}) against the motor's motion while the motor is on",
               "plant", "tau_rub", "set", (0.0, 0.1), 0.0, "pu", "motor_shaft"),
        Effect("clutch_seal_drag",
               f"dry friction between the clutch's halves (a coupling's seal, or a misaligned insert rubbing): "
               f"value * tanh((w_1 - w_2) / {W_SMOOTH:g}) from the motor to the wheel at every deflection",
               "plant", "seal12", "set", (0.0, 0.05), 0.0, "pu", "clutch"),
        Effect("resilient_gear_loss",
               f"the mesh friction of a gear stage in the resilient path (value = 1 - its efficiency): "
               f"value * |m_s| * tanh(w_2 / {W_SMOOTH:g}) against the wheel's motion, m_s the resilient torque",
               "plant", "gear2", "set", (0.0, 0.2), 0.0, "x", "drive_train"),
        Effect("load_guide_binding",
               f"misaligned guides pinching the load harder the further it travels: value * |theta_3| / "
               f"{THETA_BIND:g} * tanh(w_3 / {W_SMOOTH:g}) against the mass's motion (value after "
               f"{THETA_BIND:g} rad, 10 mm)",
               "plant", "bind3", "set", (0.0, 0.05), 0.0, "pu", "load"),
        Effect("torque_current_gain",
               "the phase-a current sensor of the torque's estimate reads (1 + value) times the current (phase "
               "c's computed from a's and b's): m_el reads value * i_s_alpha * (psi_s_alpha / sqrt(3) - "
               "psi_s_beta) more while the motor is on",
               "sensors", "igain_a", "set", (0.0, 0.05), 0.0, "x", "sensors"),
    ]
)
# fmt: on
