"""Fifth sealed family (model 1.7): a seventh family outside the catalogue, kept for scoring.

SEALED5 is kept for scoring. Development never reads its scores: no diagnosis, locus, calibration or validation result on these effects is looked at while developing; it is run once, in one blind protocol-2 run of committed code, reported as out-of-sample figures.

Why a seventh family: the fourth sealed family of model 1.6 (:data:`~engine.simulation.sealed4.SEALED4`)
has had its one blind run and its figures are published; code developed since then is developed
knowing them, and a blind run is blind only for the code it ran on. :data:`SEALED5` keeps physics
whose scores nobody has read. It was defined, with its bounds, before any diagnosis, calibration,
locus estimate or validation was run on it: one scalar effect per locus of
:data:`~engine.simulation.effects.LOCI`, none of them in the catalogue, in HELD_BACK, HELD_OUT,
SEALED, SEALED2, SEALED3 or SEALED4, none a rescaled or reshaped version of one of theirs, and none
the drift of one MODEL.md parameter by a factor (which the locus estimate already fits). Their
signatures differ in kind: a source at 250 and 350 Hz (the harmonics), an initial condition decaying
with the rotor's time constant (the residual flux), torques periodic in the motor's and the wheel's
angles at two and one periods per revolution, a zone whose width follows the motor's angle, a
one-sided force past a point of the load's travel, and a nonlinearity of one channel's amplitude.
The simulator implements every term (``docs/model-changes.md``, version 1.7; equations in
``docs/MODEL.md`` section 5); the bounds were chosen from visibility alone (nominal plant, half the
upper bound, 40 dB: at least two channels change by more than 3 noise RMS, a1 alone for its
accelerometer's saturation, which changes nothing else) and from the event still occurring at the
upper bound (``bench/family_visibility.py --family sealed5``).

============================  ================  ==============================================================
effect                        locus             term (value v)
============================  ================  ==============================================================
``supply_harmonics``          supply            u_s + v u (exp(-j 5 f w_b t) + exp(j 7 f w_b t))
``rotor_residual_flux``       motor_electrical  at t = 0: psi_r = v, psi_s = (x_m / x_r) v (alpha axis) [pu]
``shaft_misalignment``        motor_shaft       -v sin(2 theta_1) on J1 [pu]
``clutch_hub_runout``         clutch            half-width b (1 + v sin(theta_1)): contact, modes, event
``wheel_imbalance``           drive_train       -v sin(theta_2) on J2 [pu]
``load_end_buffer``           load              -v ((theta_3 - THETA_STOP) / THETA_STOP)^2 for theta_3 > THETA_STOP
``accelerometer_saturation``  sensors           a1 reads tanh(v a1) / v [v in s^2/m]
============================  ================  ==============================================================

:data:`engine.constants.THETA_STOP` is 0.1 rad (10 mm of the load's travel). Every value is neutral
at 0 and lies in ``[0, bound]``.
"""

from __future__ import annotations

from engine.constants import THETA_STOP
from engine.simulation.effects import Effect, EffectLibrary

__all__ = ["RULE", "SEALED5"]

#: The rule of the family, verbatim in ``docs/model-changes.md`` (version 1.7).
RULE = (
    "SEALED5 is kept for scoring. Development never reads its scores: no diagnosis, locus, calibration or "
    "validation result on these effects is looked at while developing; it is run once, in one blind "
    "protocol-2 run of committed code, reported as out-of-sample figures."
)

# One row per effect: name, description, target, field, mode, bounds, neutral value, unit, locus.
# fmt: off
SEALED5 = EffectLibrary(
    [
        Effect("supply_harmonics",
               "the 5th and 7th harmonics of the supply voltage (six-pulse rectifiers on the same network), "
               "each of value times its amplitude: u_s = u (exp(j f w_b t) + value (exp(-j 5 f w_b t) + "
               "exp(j 7 f w_b t))), the 5th of negative, the 7th of positive sequence",
               "plant", "u_h57", "set", (0.0, 0.2), 0.0, "x u", "supply"),
        Effect("rotor_residual_flux",
               "the motor switched on again before the rotor's flux of the previous run decayed: at switch-on "
               "the rotor's flux is value along the alpha axis and the stator's (x_m / x_r) value (no stator "
               "current), decaying with the rotor's time constant",
               "plant", "psi_r0", "set", (0.0, 0.3), 0.0, "pu", "motor_electrical"),
        Effect("shaft_misalignment",
               "an angular misalignment of the motor shaft against the clutch's hub (a soft foot, a bent "
               "shaft), flexing it twice per revolution: -value * sin(2 theta_1) on the motor shaft",
               "plant", "tau_mis1", "set", (0.0, 0.05), 0.0, "pu", "motor_shaft"),
        Effect("clutch_hub_runout",
               "runout of the clutch's toothed hub: the mesh's centre distance, and with it the backlash, "
               "varies once per revolution of the motor: half-width b * (1 + value * sin(theta_1))",
               "plant", "ecc12", "set", (0.0, 0.5), 0.0, "x b", "clutch"),
        Effect("wheel_imbalance",
               "a mass imbalance of the drive wheel (a heavy spot, hanging at the bottom at rest): the "
               "gravity torque -value * sin(theta_2) on the wheel",
               "plant", "tau_unb2", "set", (0.0, 0.05), 0.0, "pu", "drive_train"),
        Effect("load_end_buffer",
               f"an elastomer end buffer on the load's track, met after {THETA_STOP:g} rad (10 mm) of travel: "
               f"-value * ((theta_3 - {THETA_STOP:g}) / {THETA_STOP:g})^2 on the mass beyond it (value at "
               f"{THETA_STOP:g} rad of compression), zero before",
               "plant", "buf3", "set", (0.0, 0.5), 0.0, "pu", "load"),
        Effect("accelerometer_saturation",
               "the motor-side accelerometer's amplifier saturates (a range too small for the contact's "
               "impacts): a1 reads tanh(value * a1) / value, value = 1 / its range",
               "sensors", "sat_a1", "set", (0.0, 0.05), 0.0, "s^2/m", "sensors"),
    ]
)
# fmt: on
