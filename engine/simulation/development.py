"""Development effects: outside the catalogue, open to development of the open-world step.

The locus estimate (:mod:`engine.diagnosis.locus`) must say where a gap outside the catalogue
lies. Families of effects outside the catalogue serve to measure it, with opposite rules:

* :data:`DEVELOPMENT` (this module) may be run, read and tuned on. It holds the held-back five
  of model 1.1 (:data:`~engine.simulation.held_back.HELD_BACK`, developed on since issue 10)
  and three drifts of plant parameters that no catalogue effect and no calibrated parameter
  moves: the supply frequency, the resilient element's damping and the load's inertia. They
  need no new term in the simulator (each multiplies one field of MODEL.md).
* :data:`~engine.simulation.held_out.HELD_OUT` (model 1.2),
  :data:`~engine.simulation.sealed.SEALED` (model 1.3),
  :data:`~engine.simulation.sealed2.SEALED2` (model 1.4),
  :data:`~engine.simulation.sealed3.SEALED3` (model 1.5),
  :data:`~engine.simulation.sealed4.SEALED4` (model 1.6) and
  :data:`~engine.simulation.sealed5.SEALED5` (model 1.7) are kept for scoring: development never
  reads their scores (SEALED to SEALED5 have had their one blind run each and are spent).

=============================  ===============  ===============================  =============
effect                         locus            term                             bounds
=============================  ===============  ===============================  =============
``supply_frequency_drift``     supply           f -> value * f                   [0.96, 1.04]
``resilient_damping_drift``    drive_train      d_2 -> value * d_2               [2.0, 20.0]
``load_mass_drift``            load             T_3 -> value * T_3               [0.7, 1.5]
=============================  ===============  ===============================  =============

plus the five of :data:`~engine.simulation.held_back.HELD_BACK`.
"""

from __future__ import annotations

from engine.simulation.effects import Effect, EffectLibrary
from engine.simulation.held_back import HELD_BACK

__all__ = ["DEVELOPMENT", "PARAMETER_DRIFTS"]

# One row per effect: name, description, target, field, mode, bounds, neutral value, unit, locus.
# fmt: off
PARAMETER_DRIFTS = EffectLibrary(
    [
        Effect("supply_frequency_drift", "supply frequency f multiplied by value",
               "plant", "f", "multiply", (0.96, 1.04), 1.0, "x", "supply"),
        Effect("resilient_damping_drift", "resilient-element damping d_2 multiplied by value",
               "plant", "d2", "multiply", (2.0, 20.0), 1.0, "x", "drive_train"),
        Effect("load_mass_drift", "mechanical time constant T_3 of the load multiplied by value",
               "plant", "T3", "multiply", (0.7, 1.5), 1.0, "x", "load"),
    ]
)
# fmt: on

#: The development family: the held-back five of model 1.1 and the parameter drifts.
DEVELOPMENT = HELD_BACK + PARAMETER_DRIFTS
