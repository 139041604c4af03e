"""Third sealed family (model 1.5): a fifth family outside the catalogue, kept for scoring.

SEALED3 is kept for scoring. Development never reads its scores: no diagnosis, locus, calibration or validation result on these effects is looked at while developing; it is run once, in one blind protocol-2 run of committed code, reported as out-of-sample figures.

Why a fifth family: the second sealed family of model 1.4 (:data:`~engine.simulation.sealed2.SEALED2`)
has had its one blind run (seed 263, code fc76e34), and its figures are published; code developed
since then is developed knowing them, and a blind run is blind only for the code it ran on.
:data:`SEALED3` keeps physics whose scores nobody has read. It was defined, with its bounds, before
any diagnosis, calibration, locus estimate or validation was run on it: one scalar effect per locus
of :data:`~engine.simulation.effects.LOCI`, none of them in the catalogue, in HELD_BACK, HELD_OUT,
SEALED or SEALED2, none a rescaled or reshaped version of one of theirs, and none the drift of one
MODEL.md parameter by a factor (which the locus estimate already fits). The simulator implements
every term (``docs/model-changes.md``, version 1.5; equations in ``docs/MODEL.md`` section 5); the
bounds were chosen from visibility alone (nominal plant, half the upper bound, 40 dB: at least two
channels change by more than 3 noise RMS) and from the event still occurring at the upper bound
(``bench/family_visibility.py --family sealed3``). Each bound is a value a real drive of this kind
may have: a connection of 0.05 pu (0.5 ohm in a 15 kW motor's phase), one to two broken bars of a
28-bar cage, a brake at the motor's rated torque, the relative damping 0.6 of a rubber insert, the
+-20 % mesh stiffness of a spur gear, an eddy-current force of a quarter of the absorber's c_1, and
0.1 g of hum. A first supply term, the 5th and 7th harmonics of rectifier loads, failed the rule at
every plausible share (the supply acts only before the event) and was replaced, not raised.

==============================  ================  ==================================================
effect                          locus             term (value v)
==============================  ================  ==================================================
``supply_loose_connection``     supply            u_s less (2/3) v i_s_alpha in the alpha axis [pu]
``rotor_broken_bar``            motor_electrical  dpsi_r/dt less w_b v r_r Re(i_r e^(-j g)) e^(j g)
``motor_brake``                 motor_shaft       -v g_b(t) tanh(w_1 / W_SMOOTH) on J1 [pu]
``clutch_hysteretic_contact``   clutch            contact spring k_12 x (1 + v sgn(x dw)), smoothed
``resilient_mesh_stiffness``    drive_train       spring k_2 x (1 + v sin(N theta_2))
``load_eddy_current_brake``     load              -v 2 s / (1 + s^2) on the mass, s = w_3 / W_EDDY
``accelerometer_mains_hum``     sensors           a1, a2 read + v sin(f w_b t) [m/s^2]
==============================  ================  ==================================================

g = p theta_1 is the rotor's electrical angle since switch-on (the broken bar's axis lies on the
alpha axis at switch-on); g_b(t) is the brake's engagement, 1 at switch-on, lifting after
:data:`engine.constants.T_BRAKE_RELEASE` (10 ms) and falling back
:data:`engine.constants.T_BRAKE_APPLY` (10 ms) after the switch-off, each along a smoothstep of
:data:`engine.constants.T_BRAKE_TRAVEL` (5 ms); x is the clutch's penetration beyond its zone's
edge and sgn(x dw) is +1 while it deepens (loading), -1 while it recedes, smoothed as
tanh(sgn(x) dw / W_SMOOTH); N is :data:`engine.constants.MESH_ORDER` (40 teeth), x = theta_2 -
theta_3 in the resilient spring; :data:`engine.constants.W_EDDY` is 0.01 pu. Every value is neutral
at 0 and lies in ``[0, bound]``.
"""

from __future__ import annotations

from engine.constants import MESH_ORDER, T_BRAKE_APPLY, T_BRAKE_RELEASE, W_EDDY, W_SMOOTH
from engine.simulation.effects import Effect, EffectLibrary

__all__ = ["RULE", "SEALED3"]

#: The rule of the family, verbatim in ``docs/model-changes.md`` (version 1.5).
RULE = (
    "SEALED3 is kept for scoring. Development never reads its scores: no diagnosis, locus, calibration or "
    "validation result on these effects is looked at while developing; it is run once, in one blind "
    "protocol-2 run of committed code, reported as out-of-sample figures."
)

# One row per effect: name, description, target, field, mode, bounds, neutral value, unit, locus.
# fmt: off
SEALED3 = EffectLibrary(
    [
        Effect("supply_loose_connection",
               "a high-resistance connection of value in phase a of the supply (a loose terminal, a pitted "
               "contactor contact), the motor's star point floating: u_s less (2/3) value i_s_alpha along alpha",
               "plant", "r_con", "set", (0.0, 0.05), 0.0, "pu", "supply"),
        Effect("rotor_broken_bar",
               "a broken rotor bar: the rotor's resistance higher by value * r_r along one axis of the rotor, "
               "which turns with it (electrical angle p theta_1)",
               "plant", "r_bar", "set", (0.0, 0.2), 0.0, "x r_r", "motor_electrical"),
        Effect("motor_brake",
               f"the spring-applied brake of a brake motor, torque value * tanh(w_1 / {W_SMOOTH:g}) against the "
               f"motor's motion: applied at switch-on and lifted {T_BRAKE_RELEASE * 1e3:g} ms after it, applied "
               f"again {T_BRAKE_APPLY * 1e3:g} ms after the switch-off",
               "plant", "tau_brake", "set", (0.0, 1.0), 0.0, "pu", "motor_shaft"),
        Effect("clutch_hysteretic_contact",
               "rate-independent (hysteretic) damping of the clutch's contact, as an elastomer insert's: its "
               "spring k_12 x is (1 + value) times as stiff while the penetration x deepens and (1 - value) "
               "while it recedes",
               "plant", "hyst12", "set", (0.0, 0.3), 0.0, "x", "clutch"),
        Effect("resilient_mesh_stiffness",
               f"the stiffness of a gear stage in the resilient path varies with the teeth in mesh: its spring "
               f"k_2 x (1 + value * sin({MESH_ORDER} theta_2)), x = theta_2 - theta_3",
               "plant", "mesh2", "set", (0.0, 0.2), 0.0, "x", "drive_train"),
        Effect("load_eddy_current_brake",
               f"an eddy-current (magnetic) brake on the load: value * 2 s / (1 + s^2) against its motion, "
               f"s = w_3 / {W_EDDY:g}, largest (value) at w_3 = {W_EDDY:g}",
               "plant", "eddy3", "set", (0.0, 0.05), 0.0, "pu", "load"),
        Effect("accelerometer_mains_hum",
               "a ground loop in the accelerometers' cabling: a1 and a2 each read value * sin(f w_b t) more, "
               "the mains' frequency, t since switch-on",
               "sensors", "hum", "set", (0.0, 1.0), 0.0, "m/s^2", "sensors"),
    ]
)
# fmt: on
