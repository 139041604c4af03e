"""Second sealed family (model 1.4): a fourth family outside the catalogue, kept for scoring.

SEALED2 is kept for scoring. Development never reads its scores: no diagnosis, locus, calibration or validation result on these effects is looked at while developing; it is run once, in one blind protocol-2 run of committed code, reported as out-of-sample figures.

Why a fourth family: the sealed family of model 1.3 (:data:`~engine.simulation.sealed.SEALED`)
has had its blind run (seed 257, code 0f293b8), and its figures are published; code developed
since then is developed knowing them, and a blind run is blind only for the code it ran on.
:data:`SEALED2` keeps physics whose scores nobody has read. It was defined, with its bounds,
before any diagnosis, calibration, locus estimate or validation was run on it: one scalar effect
per locus of :data:`~engine.simulation.effects.LOCI`, none of them in the catalogue, in HELD_BACK,
HELD_OUT or SEALED, none a rescaled or reshaped version of one of theirs, and none the drift of one
MODEL.md parameter by a factor (which the locus estimate already fits). The simulator implements
every term (``docs/model-changes.md``, version 1.4; equations in ``docs/MODEL.md`` section 5); the
bounds were chosen from visibility alone (nominal plant, half the upper bound, 40 dB: at least two
channels change by more than 3 noise RMS, omega1 alone for the speed's sample-and-hold, which
changes nothing else) and from the event still occurring at the upper bound
(``bench/family_visibility.py --family sealed2``). Each bound is a value a real drive of this kind
may have (a 1 % DC component, core losses of 3 % of the rated power, bearing friction of 2 % of the
transmitted torque, 0.5 mm of play at the wheel's radius, a fieldbus cycle of 2 ms), but the squeeze
film's: started at the contact's own damping d_12, its part in the gap (the part that makes it new)
needed four times that to show.

===============================  ================  ================================================
effect                           locus             term (value v)
===============================  ================  ================================================
``supply_dc_offset``             supply            u_s + v u in the alpha axis (phase a) [x u]
``core_loss_resistance``         motor_electrical  dpsi_s/dt, dpsi_r/dt less w_b v (i_s + i_r) [pu]
``motor_bearing_load_friction``  motor_shaft       -v abs(m_c) tanh(w_1 / W_SMOOTH) on J1 [x]
``clutch_squeeze_film``          clutch            m_c + v (H / (H + h))^3 dw, h = max(b - abs(d), 0)
``resilient_hub_play``           drive_train       spring k_2 (x - v tanh(x / v)), x = theta_2 - theta_3
``load_track_bump``              load              v sqrt(2 e) s exp(-s^2) on the mass [pu]
``speed_sample_hold``            sensors           omega1 held at v floor(t / v), t since switch-on
===============================  ================  ================================================

H is :data:`engine.constants.H_SQUEEZE` (0.005 rad, a tenth of the nominal zone's half-width);
``s = (theta_3 - THETA_BUMP) / W_BUMP`` with :data:`engine.constants.THETA_BUMP` (0.1 rad, 10 mm
of the load's travel) and :data:`engine.constants.W_BUMP` (0.02 rad); W_SMOOTH is MODEL.md's
smoothing speed. Every value is neutral at 0 and lies in ``[0, bound]``.
"""

from __future__ import annotations

from engine.constants import H_SQUEEZE, THETA_BUMP, W_BUMP, W_SMOOTH
from engine.simulation.effects import Effect, EffectLibrary

__all__ = ["RULE", "SEALED2"]

#: The rule of the family, verbatim in ``docs/model-changes.md`` (version 1.4).
RULE = (
    "SEALED2 is kept for scoring. Development never reads its scores: no diagnosis, locus, calibration or "
    "validation result on these effects is looked at while developing; it is run once, in one blind "
    "protocol-2 run of committed code, reported as out-of-sample figures."
)

# One row per effect: name, description, target, field, mode, bounds, neutral value, unit, locus.
# fmt: off
SEALED2 = EffectLibrary(
    [
        Effect("supply_dc_offset",
               "a DC component of the supply voltage in phase a: u_s + value * u along the alpha axis",
               "plant", "u_dc", "set", (0.0, 0.01), 0.0, "x u", "supply"),
        Effect("core_loss_resistance",
               "core (iron) losses as a resistance value in the magnetising branch, in series with x_m: "
               "stator and rotor flux equations each less w_b value (i_s + i_r)",
               "plant", "r_m", "set", (0.0, 0.1), 0.0, "pu", "motor_electrical"),
        Effect("motor_bearing_load_friction",
               f"bearing friction of the motor under the load the clutch transmits: value * |m_c| * "
               f"tanh(w_1 / {W_SMOOTH:g}) against the motor's motion",
               "plant", "mu_1", "set", (0.0, 0.02), 0.0, "x", "motor_shaft"),
        Effect("clutch_squeeze_film",
               f"a squeeze film in the clutch's gap h = max(b - |d|, 0): value * ({H_SQUEEZE:g} / "
               f"({H_SQUEEZE:g} + h))^3 * (w_1 - w_2) from the motor to the wheel, besides the contact",
               "plant", "sq12", "set", (0.0, 2.0), 0.0, "pu", "clutch"),
        Effect("resilient_hub_play",
               "play of half-width value in the hub of the resilient element, smoothed: its spring "
               "k_2 (x - value tanh(x / value)), x = theta_2 - theta_3",
               "plant", "play2", "set", (0.0, 0.005), 0.0, "rad", "drive_train"),
        Effect("load_track_bump",
               f"a bump on the load's track at theta_3 = {THETA_BUMP:g} rad, half-width {W_BUMP:g} rad: a force "
               f"of peak value against the mass up to its crest and with it beyond",
               "plant", "bump3", "set", (0.0, 0.05), 0.0, "pu", "load"),
        Effect("speed_sample_hold",
               "omega1 updated every value seconds from switch-on and held in between (a drive publishing "
               "its speed at a slower cycle than the logger samples)",
               "sensors", "hold1", "set", (0.0, 0.002), 0.0, "s", "sensors"),
    ]
)
# fmt: on
