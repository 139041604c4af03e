"""Sealed effects (model 1.3): a third family outside the catalogue, kept for scoring.

SEALED is kept for scoring. Development never reads its scores: no diagnosis, locus or validation result on these effects is looked at while developing; they are run only in blind protocol-2 runs of committed code, reported as out-of-sample figures.

Why a third family: the held-out family of model 1.2
(:data:`~engine.simulation.held_out.HELD_OUT`) has had its first blind run (seed 241), and its
figures are published; code developed since then is developed knowing them, and a blind run is
blind only for the code it ran on. :data:`SEALED` keeps physics whose scores nobody has read. It
was defined, with its bounds, before any diagnosis was run on it:
one scalar effect per locus of :data:`~engine.simulation.effects.LOCI`, none of them in the
catalogue, in HELD_BACK or in HELD_OUT. The simulator implements every term
(``docs/model-changes.md``, version 1.3; equations in ``docs/MODEL.md`` section 5); the bounds
were chosen from visibility alone (nominal plant, half the upper bound, 40 dB: at least two
channels change by more than 3 noise RMS, a2 alone for the accelerometer's cross-talk, which
changes nothing else) and from the event still occurring at the upper bound. The backlash test
runs the motor at 1-2 % of synchronous speed and the load slower still, so the load's quadratic
drag needs a value far above a real machine's to show; the cross-talk needed 10 %, twice a
datasheet's usual upper value.

==============================  ================  ==================================================
effect                          locus             term (value v)
==============================  ================  ==================================================
``supply_flicker``              supply            u -> u (1 + v sin(2 pi F_FLICKER t)), 8.8 Hz
``leakage_reactance``           motor_electrical  x_s -> x_s + v, x_r -> x_r + v, x_m kept [pu]
``motor_stribeck``              motor_shaft       -v tanh(w_1 / W_SMOOTH) exp(-(w_1 / W_STRIBECK)^2) on J1
``clutch_progressive_contact``  clutch            contact spring k_12 x (1 + v x / X_REF), x >= 0
``resilient_dry_friction``      drive_train       m_s + v tanh((w_2 - w_3) / W_SMOOTH)
``load_quadratic_drag``         load              -v w_3 abs(w_3) on the mass [pu]
``accelerometer_crosstalk``     sensors           a2 reads a2 + v a1 (before the sensor chain)
==============================  ================  ==================================================

The constants are :data:`engine.constants.F_FLICKER` (8.8 Hz, the flicker-sensitivity peak of
IEC 61000-4-15), :data:`engine.constants.W_STRIBECK` (0.005 pu),
:data:`engine.constants.X_REF` (0.01 rad, the largest penetration of the clutch in the nominal
plant's test) and :data:`engine.constants.W_SMOOTH`. Every value is neutral at 0 and lies in
``[0, bound]``.
"""

from __future__ import annotations

from engine.constants import F_FLICKER, W_SMOOTH, W_STRIBECK, X_REF
from engine.simulation.effects import Effect, EffectLibrary

__all__ = ["RULE", "SEALED"]

#: The rule of the family, verbatim in ``docs/model-changes.md`` (version 1.3).
RULE = (
    "SEALED is kept for scoring. Development never reads its scores: no diagnosis, locus or validation "
    "result on these effects is looked at while developing; they are run only in blind protocol-2 runs of "
    "committed code, reported as out-of-sample figures."
)

# One row per effect: name, description, target, field, mode, bounds, neutral value, unit, locus.
# fmt: off
SEALED = EffectLibrary(
    [
        Effect("supply_flicker",
               f"flicker of the supply voltage: u -> u (1 + value sin(2 pi {F_FLICKER:g} Hz t)), t since switch-on",
               "plant", "u_flicker", "set", (0.0, 0.02), 0.0, "x u", "supply"),
        Effect("leakage_reactance",
               "both leakage reactances higher by value: x_s -> x_s + value, x_r -> x_r + value, x_m unchanged",
               "plant", "x_leak", "set", (0.0, 0.02), 0.0, "pu", "motor_electrical"),
        Effect("motor_stribeck",
               f"Stribeck friction on the motor shaft at low speed: value tanh(w_1 / {W_SMOOTH:g}) "
               f"exp(-(w_1 / {W_STRIBECK:g})^2)",
               "plant", "tau_S1", "set", (0.0, 0.1), 0.0, "pu", "motor_shaft"),
        Effect("clutch_progressive_contact",
               f"the clutch's contact spring hardens with the penetration x: k_12 x (1 + value x / {X_REF:g} rad)",
               "plant", "prog12", "set", (0.0, 1.0), 0.0, "x", "clutch"),
        Effect("resilient_dry_friction",
               f"dry friction inside the resilient element: value tanh((w_2 - w_3) / {W_SMOOTH:g}) added to its torque",
               "plant", "tau_dry2", "set", (0.0, 0.05), 0.0, "pu", "drive_train"),
        Effect("load_quadratic_drag",
               "quadratic drag on the load against its motion: value * w_3 * |w_3|",
               "plant", "b_3", "set", (0.0, 20.0), 0.0, "pu", "load"),
        Effect("accelerometer_crosstalk",
               "cross-axis sensitivity of the load's accelerometer: a2 reads a2 + value a1",
               "sensors", "xtalk2", "set", (0.0, 0.1), 0.0, "x", "sensors"),
    ]
)
# fmt: on
