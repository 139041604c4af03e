"""Held-back effects: physical effects deliberately kept *out of* the catalogue.

The gap diagnosis fits the effects of :data:`~engine.simulation.effects.CATALOGUE`;
a record whose gap none of them explains gets the verdict "unexplained", and the
diagnosis must then say *where* in the plant the missing physics acts and *what*
the missing term looks like (:func:`engine.diagnosis.locus.estimate_locus`).
:data:`HELD_BACK` is the yardstick of that open-world step: one-scalar effects at
different loci and of different shapes (following time, angle, speed, or
constant) that the simulator implements (model 1.1, ``docs/model-changes.md``)
but that are never in the catalogue, so a validation can hide them from the
diagnosis completely.

=========================  ===================  ================  ===============================
effect                     locus                shape             term (value v)
=========================  ===================  ================  ===============================
``load_torque_ripple``     load                 time (37 Hz)      v sin(2 pi 37 Hz t) on m2 [pu]
``clutch_offset``          clutch               constant          zone centred on v [rad]
``motor_cogging``          motor_shaft          angle (72/rev)    -v sin(72 theta_1) on J1 [pu]
``wheel_coulomb_friction`` drive_train          speed (sign)      -v tanh(w_2 / 1e-3) on J2 [pu]
``switch_off_decay``       motor_electrical     time (decay)      v m_el(t_e) exp(-(t - t_e) / 10 ms)
=========================  ===================  ================  ===============================

The frequency of the ripple and the cogging order are :data:`engine.constants.LOAD_RIPPLE_HZ`
and :data:`engine.constants.COGGING_ORDER`, the decay's time constant
:data:`engine.constants.SWITCH_OFF_DECAY_TIME`. Every value is neutral at 0 and lies in
``[0, bound]`` except the clutch offset, which has either sign. Visibility at half the upper
bound, nominal plant, 40 dB: ``docs/model-changes.md`` (version 1.1).
"""

from __future__ import annotations

from engine.constants import COGGING_ORDER, LOAD_RIPPLE_HZ, SWITCH_OFF_DECAY_TIME, W_SMOOTH
from engine.simulation.effects import Effect, EffectLibrary

__all__ = ["HELD_BACK"]

# One row per effect: name, description, target, field, mode, bounds, neutral value, unit, locus.
# fmt: off
HELD_BACK = EffectLibrary(
    [
        Effect("load_torque_ripple",
               f"periodic torque on the load at a fixed frequency: value * sin(2 pi {LOAD_RIPPLE_HZ:g} Hz t)",
               "plant", "tau_ripple3", "set", (0.0, 0.05), 0.0, "pu", "load"),
        Effect("clutch_offset",
               "the backlash zone is off-centre by value (contact at theta_1 - theta_2 - value = +-b)",
               "plant", "clutch_offset", "set", (-0.005, 0.005), 0.0, "rad", "clutch"),
        Effect("motor_cogging",
               f"cogging torque on the motor shaft, periodic in its angle: -value * sin({COGGING_ORDER} theta_1)",
               "plant", "tau_cog", "set", (0.0, 0.05), 0.0, "pu", "motor_shaft"),
        Effect("wheel_coulomb_friction",
               f"Coulomb friction of the drive wheel: value * tanh(w_2 / {W_SMOOTH:g}) against its motion",
               "plant", "tau_C2", "set", (0.0, 0.1), 0.0, "pu", "drive_train"),
        Effect("switch_off_decay",
               f"a share value of the electromagnetic torque remains at the switch-off and decays with "
               f"{SWITCH_OFF_DECAY_TIME * 1e3:g} ms",
               "plant", "m_off", "set", (0.0, 0.2), 0.0, "x", "motor_electrical"),
    ]
)
# fmt: on
