"""The model versions' families of effects, checked alike (docs/model-changes.md, versions 1.1 to 1.7).

Each version from 1.1 on added a family of effects outside the catalogue, each effect a new term of
the kernel: 1.1 the held-back family HELD_BACK (and the additive unknown input), 1.2 the held-out
family HELD_OUT, 1.3 the sealed family SEALED, 1.4 the second sealed family SEALED2, 1.5 the third
sealed family SEALED3, 1.6 the fourth sealed family SEALED4, 1.7 the fifth sealed family SEALED5. The checks they share run here from one table,
:data:`VERSIONS`; a case id names the version and the effect (``1.3-supply_flicker``), or the version
and the family (``1.2-held_out``) where the check is of a family. What one version alone has stays in
its module: the unknown input of 1.1 in ``tests/test_simulation_model_1_1.py``, the terms of 1.3 that
have a physics of their own (the leakages, the progressive contact, the cross-talk's a1, the
visibility table) in ``tests/test_simulation_model_1_3.py``, and those of 1.4 (the DC offset, the
core losses, the squeeze film's zone, the hub's play, the bump, the speed's sample-and-hold) in
``tests/test_simulation_model_1_4.py``, and those of 1.5 in ``tests/test_simulation_model_1_5.py``, and those
of 1.6 in ``tests/test_simulation_model_1_6.py``, and those of 1.7 in ``tests/test_simulation_model_1_7.py``.

Simulation only. HELD_OUT, SEALED, SEALED2, SEALED3, SEALED4 and SEALED5 are kept for scoring: nothing
here diagnoses, calibrates, locates or validates a record of their effects (the case generator is run
without its absorption rule, which refits, and not on SEALED3, SEALED4 and SEALED5, which were defined
without running anything of engine.validation on them).

* every new term is exactly neutral at its neutral value: the records are bit for bit those without
  it (model 1.0's for 1.1), from 1.2 on also inside the kernel's extended path (``P_EXTENDED``),
  which the terms of the earlier versions switch on; forcing that path on with every term zero is
  model 1.0 bit for bit;
* the kernel agrees with the independent scipy reference (engine.simulation.reference) for every
  effect at its upper bound, for an unknown input at every locus (1.1) and in the combinations where
  two terms meet (1.2 to 1.7): MODEL.md section 4's spec, plus a regression guard at about twice the
  worst error measured;
* from 1.2 on, at half its upper bound every effect is visible at 40 dB on the nominal plant, keeps
  the event across the plausible box at its upper bound, and has a slot of its own in the kernel's
  parameter vector;
* every family is disjoint from the catalogue and the earlier families, is known to the reference at
  its neutral values, is registered by its name for blind runs (``backlash validate --held-back
  NAME``), and refuses an absurd value with its name; from 1.2 on it has one effect per locus, each a
  new term neutral at zero, its rule is stated in its module and the docs, and (1.2 to 1.4) the case
  generator of protocol 2 draws held-back cases from it.

Measured with the default SolverSettings against the reference (DOP853, rtol 1e-9), worst over the
cases, in % of peak-to-peak:

* 1.1: held-back effects at their upper bound 0.0195 % (a1, clutch_offset 0.005 rad), |dt_e|
  8.7e-9 s; unknown inputs (20 knots of 10 ms, random values and step) 0.0183 % (a1, drive_train),
  |dt_e| 2.2e-8 s. Guards: 0.04 % and 5e-8 s.
* 1.2: effects at their upper bound 0.0137 % (a1, magnetic_saturation 0.5), |dt_e| 1.0e-8 s
  (clutch_preload_spring 0.02); combinations 0.0228 % (a1, saturation with the switch-off decay at
  0.2), |dt_e| 9.5e-9 s. Guards as for model 1.1: 0.04 % and 5e-8 s.
* 1.3: effects at their upper bound 0.0160 % (a1, leakage_reactance 0.02), |dt_e| 1.9e-8 s
  (leakage_reactance 0.02); combinations 0.0339 % (a1, the leakages with saturation 0.5: the
  kernel's step, 0.0060 % at 10 us), |dt_e| 2.0e-8 s (every sealed effect at once). Guards as for
  model 1.1 and 1.2: 0.04 % and 5e-8 s.
* 1.4: effects at their upper bound 0.0257 % (a1, supply_dc_offset 0.01: the kernel's step, 0.0057 %
  at 10 us), |dt_e| 1.3e-8 s (supply_dc_offset 0.01); combinations and inputs 0.0100 % (a1, the core
  losses with the switch-off decay), |dt_e| 4.2e-9 s (the core losses with saturation and leakages).
  Guards as for model 1.1 to 1.3: 0.04 % and 5e-8 s.
* 1.5: effects at their upper bound 0.0035 % (a1, supply_loose_connection 0.05), |dt_e| 3.7e-9 s
  (motor_brake 1); combinations and inputs 0.0214 % (a1, the loose connection with the DC offset and
  the unbalance), |dt_e| 2.4e-8 s (every sealed3 effect at once). Guards as for model 1.1 to 1.4:
  0.04 % and 5e-8 s.
* 1.6: effects at their upper bound 0.0115 % (a1, motor_rotor_rub 0.1), |dt_e| 6.7e-9 s (the same);
  combinations and inputs 0.0210 % (a1, the late pole on a supply input), |dt_e| 6.0e-8 s (the
  clutch seal's drag on a clutch input: the integrator step's error on the smoothed sign of w_1 - w_2
  as the zone moves; 7.9e-9 s at a 2 us step). Guards 0.04 % and, for the event time, 1.2e-7 s.
* 1.7: effects at their upper bound 0.0046 % (a1, clutch_hub_runout 0.5), |dt_e| 1.2e-8 s (the same);
  combinations and inputs 0.0145 % (a1, the harmonics with the unbalance, the flicker and saturation),
  |dt_e| 1.9e-8 s (the misaligned shaft with the cogging and the brake). Guards as for 1.1 to 1.5:
  0.04 % and 5e-8 s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from engine.constants import CHANNELS, MODEL_VERSION
from engine.records import SampleGrid
from engine.simulation import (
    CATALOGUE,
    DISTURBANCE_LOCI,
    HELD_BACK,
    HELD_OUT,
    LOCI,
    SEALED,
    SEALED2,
    SEALED3,
    SEALED4,
    SEALED5,
    Case,
    Disturbance,
    ParameterError,
    PlantParameters,
    SensorParameters,
    SimulationResult,
    SolverSettings,
    UnknownEffectError,
    held_out,
    noise_std,
    sealed,
    sealed2,
    sealed3,
    sealed4,
    sealed5,
    simulate,
    simulate_batch,
)
from engine.simulation import _kernel as kern
from engine.simulation.effects import EffectLibrary
from engine.simulation.families import FAMILIES, locus_of
from engine.simulation.reference import (
    HELD_BACK_NEUTRAL,
    HELD_OUT_NEUTRAL,
    SEALED2_NEUTRAL,
    SEALED3_NEUTRAL,
    SEALED4_NEUTRAL,
    SEALED5_NEUTRAL,
    SEALED_NEUTRAL,
    reference_inputs,
    reference_simulate,
)
from engine.simulation.simulator import parameter_vector

SPEC_REL = 0.005
SPEC_EVENT_TIME = 1e-6
GUARD_REL = 4e-4
GUARD_EVENT_TIME = 5e-8
#: The event time's guard of a version whose worst error needs a wider one (about twice that error).
GUARD_EVENT_TIME_OF = {"1.6": 1.2e-7}
PLANT = {"K": 0.005, "J1": 0.87, "c": 1.0}
NOMINAL = PlantParameters(K=0.005, J1=0.87, c=1.0)  # PLANT, by the simulator's names
DOCS = Path(__file__).resolve().parents[1] / "docs"


@dataclass(frozen=True, eq=False)  # hashed by identity: a key of the cached runs
class Version:
    """One version of the model and the family of effects it added (docs/model-changes.md)."""

    #: The model version that added the family, e.g. ``"1.2"``.
    version: str
    #: The family's name in FAMILIES (``backlash validate --held-back NAME``).
    name: str
    family: EffectLibrary
    #: The catalogue and the families of the versions before, in order.
    earlier: tuple[EffectLibrary, ...]
    #: The model version this one bumped.
    previous: str
    #: The reference's table of the family's neutral values.
    reference_neutral: Mapping[str, float]
    #: What each new term is neutral on, by a label for the failure message: the nominal plant,
    #: and from 1.2 on the plant with the earlier families' terms on (the kernel's extended path).
    bases: tuple[tuple[str, Case], ...]

    @property
    def library(self) -> EffectLibrary:
        """The catalogue, the earlier families and this one: every effect the version knows by name."""
        library = self.earlier[0]
        for other in (*self.earlier[1:], self.family):
            library = library + other
        return library


_PLAIN = ("nominal plant", Case(NOMINAL))
_COGGING = ("on motor_cogging 0.03", HELD_BACK["motor_cogging"].apply(Case(NOMINAL), 0.03))
_EVERY_HELD_OUT = (
    "on every held-out effect at half its bound",
    HELD_OUT.apply(Case(NOMINAL), {n: 0.5 * e.bounds[1] for n, e in HELD_OUT.items()}),
)

V1_1 = Version("1.1", "held_back", HELD_BACK, (CATALOGUE,), "1.0", HELD_BACK_NEUTRAL, (_PLAIN,))
V1_2 = Version("1.2", "held_out", HELD_OUT, (CATALOGUE, HELD_BACK), "1.1", HELD_OUT_NEUTRAL, (_PLAIN, _COGGING))
V1_3 = Version(
    "1.3",
    "sealed",
    SEALED,
    (CATALOGUE, HELD_BACK, HELD_OUT),
    "1.2",
    SEALED_NEUTRAL,
    (_PLAIN, _COGGING, _EVERY_HELD_OUT),
)
_EVERY_SEALED = (
    "on every sealed effect at half its bound",
    SEALED.apply(Case(NOMINAL), {n: 0.5 * e.bounds[1] for n, e in SEALED.items()}),
)
V1_4 = Version(
    "1.4",
    "sealed2",
    SEALED2,
    (CATALOGUE, HELD_BACK, HELD_OUT, SEALED),
    "1.3",
    SEALED2_NEUTRAL,
    (_PLAIN, _COGGING, _EVERY_HELD_OUT, _EVERY_SEALED),
)
_EVERY_SEALED2 = (
    "on every sealed2 effect at half its bound",
    SEALED2.apply(Case(NOMINAL), {n: 0.5 * e.bounds[1] for n, e in SEALED2.items()}),
)
V1_5 = Version(
    "1.5",
    "sealed3",
    SEALED3,
    (CATALOGUE, HELD_BACK, HELD_OUT, SEALED, SEALED2),
    "1.4",
    SEALED3_NEUTRAL,
    (_PLAIN, _COGGING, _EVERY_HELD_OUT, _EVERY_SEALED, _EVERY_SEALED2),
)
_EVERY_SEALED3 = (
    "on every sealed3 effect at half its bound",
    SEALED3.apply(Case(NOMINAL), {n: 0.5 * e.bounds[1] for n, e in SEALED3.items()}),
)
V1_6 = Version(
    "1.6",
    "sealed4",
    SEALED4,
    (CATALOGUE, HELD_BACK, HELD_OUT, SEALED, SEALED2, SEALED3),
    "1.5",
    SEALED4_NEUTRAL,
    (_PLAIN, _COGGING, _EVERY_HELD_OUT, _EVERY_SEALED, _EVERY_SEALED2, _EVERY_SEALED3),
)
_EVERY_SEALED4 = (
    "on every sealed4 effect at half its bound",
    SEALED4.apply(Case(NOMINAL), {n: 0.5 * e.bounds[1] for n, e in SEALED4.items()}),
)
V1_7 = Version(
    "1.7",
    "sealed5",
    SEALED5,
    (CATALOGUE, HELD_BACK, HELD_OUT, SEALED, SEALED2, SEALED3, SEALED4),
    "1.6",
    SEALED5_NEUTRAL,
    (_PLAIN, _COGGING, _EVERY_HELD_OUT, _EVERY_SEALED, _EVERY_SEALED2, _EVERY_SEALED3, _EVERY_SEALED4),
)
#: Every version with a family of its own, oldest first; a new version adds its row here.
VERSIONS = (V1_1, V1_2, V1_3, V1_4, V1_5, V1_6, V1_7)


def _families(*versions: Version) -> list[Any]:
    """One case per version, its id the version and the family (``1.2-held_out``)."""
    return [pytest.param(v, id=f"{v.version}-{v.name}") for v in versions]


def _effects(*versions: Version) -> list[Any]:
    """One case per effect of each version, its id the version and the effect (``1.2-supply_unbalance``)."""
    return [pytest.param(v, n, id=f"{v.version}-{n}") for v in versions for n in v.family]


# --- the kernel against the reference -------------------------------------------------------------

#: A random schedule per locus (20 knots of 10 ms from 10 ms on) and a step, scaled to the locus.
_SCALE = {
    "supply": 0.05,
    "motor_electrical": 0.2,
    "motor_shaft": 0.2,
    "clutch": 0.003,
    "drive_train": 0.1,
    "load": 0.1,
    "clutch_torque": 0.1,
}


def _schedule(locus: str) -> dict[str, Any]:
    rng = np.random.default_rng(DISTURBANCE_LOCI.index(locus))
    scale = _SCALE[locus]
    return {
        "locus": locus,
        "t0": 0.01,
        "dt": 0.01,
        "values": [float(v) for v in scale * rng.standard_normal(20)],
        "step": float(scale * rng.standard_normal()),
    }


#: Where two terms meet: each case by effect name and value (the reference takes the same names).
COMBINATIONS: dict[str, dict[str, dict[str, float]]] = {
    "1.2": {
        "saturation-and-switch-off-decay": {"magnetic_saturation": 0.5, "switch_off_decay": 0.2},
        "preload-and-zone-offset": {"clutch_preload_spring": 0.02, "clutch_offset": -0.004},
        "encoder-and-lowpass": {"speed_encoder_eccentricity": 0.2, "sensor_lowpass": 1000.0},
        "every-held-out-effect": {n: e.bounds[1] for n, e in HELD_OUT.items()},
    },
    "1.3": {
        "leakages-and-saturation": {"leakage_reactance": 0.02, "magnetic_saturation": 0.5},
        "progressive-contact-zone-offset-and-preload": {
            "clutch_progressive_contact": 1.0,
            "clutch_offset": -0.004,
            "clutch_preload_spring": 0.02,
        },
        "stribeck-and-coulomb": {"motor_stribeck": 0.1, "motor_coulomb_friction": 0.1},
        "dry-friction-and-hardening": {"resilient_dry_friction": 0.05, "resilient_hardening": 1.0},
        "drag-and-load-spring": {"load_quadratic_drag": 20.0, "load_position_spring": 0.5},
        "crosstalk-lowpass-and-gain": {"accelerometer_crosstalk": 0.1, "sensor_lowpass": 1000.0, "sensor_gain": 1.2},
        "every-sealed-effect": {n: e.bounds[1] for n, e in SEALED.items()},
    },
    "1.4": {
        "core-loss-saturation-and-leakages": {
            "core_loss_resistance": 0.1,
            "magnetic_saturation": 0.5,
            "leakage_reactance": 0.02,
        },
        "core-loss-and-switch-off-decay": {"core_loss_resistance": 0.1, "switch_off_decay": 0.2},
        "bearing-friction-progressive-contact-and-squeeze-film": {
            "motor_bearing_load_friction": 0.02,
            "clutch_progressive_contact": 1.0,
            "clutch_squeeze_film": 2.0,
        },
        "squeeze-film-zone-offset-and-preload": {
            "clutch_squeeze_film": 2.0,
            "clutch_offset": -0.004,
            "clutch_preload_spring": 0.02,
        },
        "hub-play-hardening-and-dry-friction": {
            "resilient_hub_play": 0.005,
            "resilient_hardening": 1.0,
            "resilient_dry_friction": 0.05,
        },
        "bump-load-spring-and-drag": {
            "load_track_bump": 0.05,
            "load_position_spring": 0.5,
            "load_quadratic_drag": 20.0,
        },
        "hold-lowpass-encoder-and-gain": {
            "speed_sample_hold": 0.002,
            "sensor_lowpass": 1000.0,
            "speed_encoder_eccentricity": 0.2,
            "sensor_gain": 1.2,
        },
        "hold-delay-and-late-trigger": {
            "speed_sample_hold": 0.002,
            "measurement_delay": 0.0005,
            "trigger_offset": -0.002,
        },
        "every-sealed2-effect": {n: e.bounds[1] for n, e in SEALED2.items()},
    },
    "1.5": {
        "loose-connection-dc-offset-and-unbalance": {
            "supply_loose_connection": 0.05,
            "supply_dc_offset": 0.01,
            "supply_unbalance": 0.1,
        },
        "broken-bar-core-loss-and-saturation": {
            "rotor_broken_bar": 0.2,
            "core_loss_resistance": 0.1,
            "magnetic_saturation": 0.5,
        },
        "brake-coulomb-and-switch-off-decay": {
            "motor_brake": 1.0,
            "motor_coulomb_friction": 0.1,
            "switch_off_decay": 0.2,
        },
        "hysteresis-progressive-contact-and-squeeze-film": {
            "clutch_hysteretic_contact": 0.3,
            "clutch_progressive_contact": 1.0,
            "clutch_squeeze_film": 2.0,
        },
        "mesh-stiffness-hardening-and-hub-play": {
            "resilient_mesh_stiffness": 0.2,
            "resilient_hardening": 1.0,
            "resilient_hub_play": 0.005,
        },
        "eddy-brake-drag-and-bump": {
            "load_eddy_current_brake": 0.05,
            "load_quadratic_drag": 20.0,
            "load_track_bump": 0.05,
        },
        "hum-crosstalk-lowpass-and-late-trigger": {
            "accelerometer_mains_hum": 1.0,
            "accelerometer_crosstalk": 0.1,
            "sensor_lowpass": 1000.0,
            "trigger_offset": -0.002,
        },
        "every-sealed3-effect": {n: e.bounds[1] for n, e in SEALED3.items()},
    },
    "1.6": {
        "late-pole-unbalance-dc-offset-and-saturation": {
            "supply_late_pole": 0.005,
            "supply_unbalance": 0.1,
            "supply_dc_offset": 0.01,
            "magnetic_saturation": 0.5,
        },
        "coil-bypass-saturation-leakage-and-switch-off-decay": {
            "stator_coil_bypass": 0.1,
            "magnetic_saturation": 0.5,
            "leakage_reactance": 0.02,
            "switch_off_decay": 0.2,
        },
        "coil-bypass-loose-connection-and-broken-bar": {
            "stator_coil_bypass": 0.1,
            "supply_loose_connection": 0.05,
            "rotor_broken_bar": 0.2,
        },
        "rotor-rub-coulomb-and-brake": {
            "motor_rotor_rub": 0.1,
            "motor_coulomb_friction": 0.1,
            "motor_brake": 1.0,
        },
        "seal-drag-squeeze-film-and-preload-spring": {
            "clutch_seal_drag": 0.05,
            "clutch_squeeze_film": 2.0,
            "clutch_preload_spring": 0.02,
        },
        "gear-loss-hub-play-and-mesh-stiffness": {
            "resilient_gear_loss": 0.2,
            "resilient_hub_play": 0.005,
            "resilient_mesh_stiffness": 0.2,
        },
        "guide-binding-position-spring-and-bump": {
            "load_guide_binding": 0.05,
            "load_position_spring": 0.5,
            "load_track_bump": 0.05,
        },
        "current-gain-lowpass-late-trigger-and-switch-off-decay": {
            "torque_current_gain": 0.05,
            "sensor_lowpass": 1000.0,
            "trigger_offset": -0.002,
            "switch_off_decay": 0.2,
        },
        "every-sealed4-effect": {n: e.bounds[1] for n, e in SEALED4.items()},
    },
    "1.7": {
        "harmonics-unbalance-flicker-and-saturation": {
            "supply_harmonics": 0.2,
            "supply_unbalance": 0.1,
            "supply_flicker": 0.02,
            "magnetic_saturation": 0.5,
        },
        "residual-flux-saturation-leakage-and-late-pole": {
            "rotor_residual_flux": 0.3,
            "magnetic_saturation": 0.5,
            "leakage_reactance": 0.02,
            "supply_late_pole": 0.005,
        },
        "residual-flux-coil-bypass-and-broken-bar": {
            "rotor_residual_flux": 0.3,
            "stator_coil_bypass": 0.1,
            "rotor_broken_bar": 0.2,
        },
        "misalignment-cogging-and-brake": {
            "shaft_misalignment": 0.05,
            "motor_cogging": 0.05,
            "motor_brake": 1.0,
        },
        "hub-runout-offset-squeeze-film-and-progressive-contact": {
            "clutch_hub_runout": 0.5,
            "clutch_offset": 0.005,
            "clutch_squeeze_film": 2.0,
            "clutch_progressive_contact": 1.0,
        },
        "imbalance-wheel-friction-and-mesh-stiffness": {
            "wheel_imbalance": 0.05,
            "wheel_coulomb_friction": 0.1,
            "resilient_mesh_stiffness": 0.2,
        },
        "end-buffer-bump-and-guide-binding": {
            "load_end_buffer": 0.5,
            "load_track_bump": 0.05,
            "load_guide_binding": 0.05,
        },
        "a1-saturation-hum-crosstalk-and-lowpass": {
            "accelerometer_saturation": 0.05,
            "accelerometer_mains_hum": 1.0,
            "accelerometer_crosstalk": 0.1,
            "sensor_lowpass": 1000.0,
        },
        "every-sealed5-effect": {n: e.bounds[1] for n, e in SEALED5.items()},
    },
}
_SUPPLY_INPUT = {"locus": "supply", "t0": 0.01, "dt": 0.01, "values": [0.04, -0.03, 0.05, 0.02, -0.05] * 4}
#: Unknown inputs, with the effects on top of them: (effects, the input's schedule) by case name.
INPUTS: dict[str, dict[str, tuple[dict[str, float] | None, dict[str, Any]]]] = {
    "1.1": {locus: (None, _schedule(locus)) for locus in DISTURBANCE_LOCI},
    # the unbalance on top of a supply input: u includes the input's factor
    "1.2": {
        "supply_unbalance-and-supply-input": (
            {"supply_unbalance": HELD_OUT["supply_unbalance"].bounds[1]},
            _SUPPLY_INPUT,
        )
    },
    # the flicker and the unbalance on top of a supply input: u includes every factor
    "1.3": {
        "flicker-unbalance-and-supply-input": (
            {"supply_flicker": SEALED["supply_flicker"].bounds[1], "supply_unbalance": 0.1},
            _SUPPLY_INPUT,
        )
    },
    # the DC offset beside a supply input, the flicker and the unbalance (which scale the AC part only);
    # the squeeze film's gap follows a clutch input
    "1.4": {
        "dc-offset-flicker-unbalance-and-supply-input": (
            {
                "supply_dc_offset": SEALED2["supply_dc_offset"].bounds[1],
                "supply_flicker": 0.02,
                "supply_unbalance": 0.1,
            },
            _SUPPLY_INPUT,
        ),
        "squeeze-film-and-clutch-input": (
            {"clutch_squeeze_film": SEALED2["clutch_squeeze_film"].bounds[1]},
            _schedule("clutch"),
        ),
    },
    # the loose connection's drop follows the current of a disturbed supply; the hysteresis's sign
    # follows a clutch input's moving zone
    "1.5": {
        "loose-connection-and-supply-input": (
            {"supply_loose_connection": SEALED3["supply_loose_connection"].bounds[1]},
            _SUPPLY_INPUT,
        ),
        "hysteretic-contact-and-clutch-input": (
            {"clutch_hysteretic_contact": SEALED3["clutch_hysteretic_contact"].bounds[1]},
            _schedule("clutch"),
        ),
    },
    # the late pole's open phase under a disturbed supply; the seal's drag across a moving zone
    "1.6": {
        "late-pole-and-supply-input": (
            {"supply_late_pole": SEALED4["supply_late_pole"].bounds[1]},
            _SUPPLY_INPUT,
        ),
        "seal-drag-and-clutch-input": (
            {"clutch_seal_drag": SEALED4["clutch_seal_drag"].bounds[1]},
            _schedule("clutch"),
        ),
    },
    # the harmonics under a disturbed supply; the hub's runout across a moving zone
    "1.7": {
        "harmonics-and-supply-input": (
            {"supply_harmonics": SEALED5["supply_harmonics"].bounds[1]},
            _SUPPLY_INPUT,
        ),
        "hub-runout-and-clutch-input": (
            {"clutch_hub_runout": SEALED5["clutch_hub_runout"].bounds[1]},
            _schedule("clutch"),
        ),
    },
}

#: (version, effects, unknown input) of each comparison with the reference, by version; the id is
#: version-kind-name: each effect at its upper bound, the combinations, the inputs.
REFERENCE_CASES = [
    case
    for v in VERSIONS
    for case in (
        *(pytest.param(v, {n: e.bounds[1]}, None, id=f"{v.version}-effect-{n}") for n, e in v.family.items()),
        *(
            pytest.param(v, effects, None, id=f"{v.version}-combination-{name}")
            for name, effects in COMBINATIONS.get(v.version, {}).items()
        ),
        *(
            pytest.param(v, effects, spec, id=f"{v.version}-input-{name}")
            for name, (effects, spec) in INPUTS[v.version].items()
        ),
    )
]


@pytest.mark.parametrize(("version", "effects", "disturbance"), REFERENCE_CASES)
def test_kernel_meets_the_spec_and_the_guard_against_the_reference(
    version: Version, effects: dict[str, float] | None, disturbance: dict[str, Any] | None
) -> None:
    """The kernel's record and event time against the reference's, nominal plant.

    Relative error per channel as max |kernel - reference| / peak-to-peak of the reference; the
    event time t_e in s.
    """
    plant = NOMINAL
    if disturbance is not None:
        d = disturbance
        plant = NOMINAL.replace(
            disturbance=Disturbance(d["locus"], d["t0"], d["dt"], tuple(d["values"]), d.get("step", 0.0))
        )
    sim = simulate_batch([Case(plant)], effects, library=version.library)
    ref = reference_simulate(PLANT, effects, disturbance=disturbance)
    kernel, te_k, te_r = sim.channels[0], float(sim.event_times[0]), ref.event_time
    rel = np.max(np.abs(kernel - ref.channels), axis=1) / np.ptp(ref.channels, axis=1)
    assert abs(te_k - te_r) < min(SPEC_EVENT_TIME, GUARD_EVENT_TIME_OF.get(version.version, GUARD_EVENT_TIME))
    assert np.all(rel < min(SPEC_REL, GUARD_REL)), dict(zip(CHANNELS, rel.round(6), strict=True))


# --- neutral at the neutral value, acting otherwise -----------------------------------------------


@cache
def _neutral_and_bound_runs(version: Version) -> tuple[SimulationResult, ...]:
    """Per base, one batch: the base, then each effect at its neutral value and at its upper bound."""
    runs = []
    for _, base in version.bases:
        cases = [base]
        for e in version.family.values():
            cases += [e.apply(base, e.neutral), e.apply(base, e.bounds[1])]
        runs.append(simulate_batch(cases))
    return tuple(runs)


@pytest.mark.parametrize(("version", "name"), _effects(*VERSIONS))
def test_every_effect_is_neutral_at_its_neutral_value_and_acts_otherwise(version: Version, name: str) -> None:
    """At its neutral value the record and the event time are bit for bit the previous version's.

    Alone, and from 1.2 on also on top of a held-back effect (which switches the kernel's extended
    path on) and from 1.3 on on top of every held-out effect; at its upper bound the record moves by
    more than 1e-3 (in the channels' units) somewhere. Each base is one batch with every effect of
    the family, as the records of a version are compared in one run.
    """
    i = list(version.family).index(name)
    for (label, _), res in zip(version.bases, _neutral_and_bound_runs(version), strict=True):
        plain, neutral, strong = res.channels[0], res.channels[1 + 2 * i], res.channels[2 + 2 * i]
        assert neutral.tobytes() == plain.tobytes(), f"{name} at its neutral value changed the record ({label})"
        assert res.event_times[1 + 2 * i] == res.event_times[0], f"{name} moved the event ({label})"
        assert np.max(np.abs(strong - plain)) > 1e-3, f"{name} at its bound left the record unchanged ({label})"


@pytest.mark.parametrize(
    ("solver", "n", "grid"),
    [
        pytest.param(SolverSettings(), 2048, None, id="MODEL.md-grid"),
        pytest.param(SolverSettings(max_step=1e-5), 8400, SampleGrid(2.5e-5, 8400, 200), id="25us-grid-10us-step"),
    ],
)
def test_the_extended_path_with_every_term_zero_is_model_1_0_bit_for_bit(
    solver: SolverSettings, n: int, grid: SampleGrid | None
) -> None:
    """Forcing P_EXTENDED on with every 1.1 to 1.7 term zero changes no bit: each term is guarded.

    Not a check of one version: the kernel's path of every version at once. MODEL.md's grid at the
    default step (the check since 1.2), and a 25 us grid at a 10 us step (added with 1.3).
    """
    cases = [Case(NOMINAL), Case(PlantParameters(K=0.0025, J1=0.7612, c=0.8), SensorParameters(1e-3, 1000.0))]
    P = np.stack([parameter_vector(c, solver) if grid is None else parameter_vector(c, solver, grid) for c in cases])
    assert np.all(P[:, kern.P_EXTENDED] == 0.0)
    assert np.all(P[:, kern.P_FLICKER : kern.P_XTALK2 + 1] == 0.0)
    assert np.all(P[:, kern.P_U_DC : kern.P_HOLD1 + 1] == 0.0)
    assert np.all(P[:, kern.P_R_CON : kern.P_HUM + 1] == 0.0)
    assert np.all(P[:, kern.P_T_POLE : kern.P_IGAIN_A + 1] == 0.0)
    assert np.all(P[:, kern.P_U_H57 : kern.P_SAT_A1 + 1] == 0.0)
    forced = P.copy()
    forced[:, kern.P_EXTENDED] = 1.0
    runs = []
    for vectors in (P, forced):
        out = np.zeros((len(cases), kern.N_CHANNELS, n))
        t_e = np.zeros(len(cases))
        status = np.zeros(len(cases), dtype=np.int64)
        kern.simulate_serial(vectors, out, t_e, status)
        assert np.all(status == kern.OK)
        runs.append((out, t_e))
    assert runs[0][0].tobytes() == runs[1][0].tobytes()
    assert runs[0][1].tobytes() == runs[1][1].tobytes()


# --- the kernel's parameter vector ------------------------------------------------------------------

#: The kernel's slot of each value a version from 1.2 on added.
SLOTS: dict[str, dict[str, int]] = {
    "1.2": {
        "u_neg": kern.P_U_NEG,
        "sat": kern.P_SAT,
        "b_2": kern.P_B_2,
        "k_pre": kern.P_K_PRE,
        "hard2": kern.P_HARD2,
        "k_3": kern.P_K_3,
        "ecc1": kern.P_ECC1,
    },
    "1.3": {
        "u_flicker": kern.P_FLICKER,
        "tau_S1": kern.P_TAU_S1,
        "prog12": kern.P_PROG12,
        "tau_dry2": kern.P_TAU_DRY2,
        "b_3": kern.P_B_3,
        "xtalk2": kern.P_XTALK2,
    },
    "1.4": {
        "u_dc": kern.P_U_DC,
        "r_m": kern.P_R_M,
        "mu_1": kern.P_MU1,
        "sq12": kern.P_SQ12,
        "play2": kern.P_PLAY2,
        "bump3": kern.P_BUMP3,
        "hold1": kern.P_HOLD1,
    },
    "1.5": {
        "r_con": kern.P_R_CON,
        "r_bar": kern.P_R_BAR,
        "tau_brake": kern.P_TAU_BRAKE,
        "hyst12": kern.P_HYST12,
        "mesh2": kern.P_MESH2,
        "eddy3": kern.P_EDDY3,
        "hum": kern.P_HUM,
    },
    "1.6": {
        "t_pole": kern.P_T_POLE,
        "bypass_a": kern.P_BYPASS_A,
        "tau_rub": kern.P_TAU_RUB,
        "seal12": kern.P_SEAL12,
        "gear2": kern.P_GEAR2,
        "bind3": kern.P_BIND3,
        "igain_a": kern.P_IGAIN_A,
    },
    "1.7": {
        "u_h57": kern.P_U_H57,
        "psi_r0": kern.P_PSI_R0,
        "tau_mis1": kern.P_TAU_MIS1,
        "ecc12": kern.P_ECC12,
        "tau_unb2": kern.P_TAU_UNB2,
        "buf3": kern.P_BUF3,
        "sat_a1": kern.P_SAT_A1,
    },
}
#: The slots of each version, appended after the previous version's: range(start, stop) (1.4's
#: after the per-unit base values P_W_B and P_OMEGA_B, which came within 1.3).
SLOT_RANGES = {
    "1.2": (kern.P_T_SWITCH_OFF + 1, kern.P_ECC1 + 1),
    "1.3": (kern.P_ECC1 + 1, kern.P_XTALK2 + 1),
    "1.4": (kern.P_OMEGA_B + 1, kern.P_HOLD1 + 1),
    "1.5": (kern.P_HOLD1 + 1, kern.P_HUM + 1),
    "1.6": (kern.P_HUM + 1, kern.P_IGAIN_A + 1),
    "1.7": (kern.P_IGAIN_A + 1, kern.P_SAT_A1 + 1),
}
#: The values without a slot: the leakages enter x_s and x_r (tests/test_simulation_model_1_3.py).
NO_SLOT = {"1.2": set(), "1.3": {"x_leak"}, "1.4": set(), "1.5": set(), "1.6": set(), "1.7": set()}


def _family_slots(P: np.ndarray) -> int:
    """How many of the slots of every family from 1.2 on hold a non-zero value."""
    return int(sum(np.count_nonzero(P[start:stop]) for start, stop in SLOT_RANGES.values()))


@pytest.mark.parametrize("version", _families(V1_2, V1_3, V1_4, V1_5, V1_6, V1_7))
def test_the_version_s_slots_are_appended_after_the_previous_version_s(version: Version) -> None:
    slots = SLOTS[version.version]
    assert sorted(slots.values()) == list(range(*SLOT_RANGES[version.version]))
    assert {e.field for e in version.family.values()} == set(slots) | NO_SLOT[version.version]


@pytest.mark.parametrize(
    ("version", "name"),
    [
        pytest.param(v, n, id=f"{v.version}-{n}")
        for v in (V1_2, V1_3, V1_4, V1_5, V1_6, V1_7)
        for n, e in v.family.items()
        if e.field not in NO_SLOT[v.version]
    ],
)
def test_each_value_switches_the_extended_path_on_in_its_own_slot(version: Version, name: str) -> None:
    """At half its upper bound: P_EXTENDED on, the value in its slot and in no other, x_s and x_r kept."""
    e = version.family[name]
    value = 0.5 * e.bounds[1]
    plain = parameter_vector(Case(NOMINAL))
    P = parameter_vector(e.apply(Case(NOMINAL), value))
    assert P[kern.P_EXTENDED] == 1.0
    assert P[SLOTS[version.version][e.field]] == value
    assert _family_slots(P) == 1
    assert P[kern.P_X_S] == plain[kern.P_X_S] and P[kern.P_X_R] == plain[kern.P_X_R]


# --- visible at its bounds ------------------------------------------------------------------------


@cache
def _half_bound_runs(version: Version) -> SimulationResult:
    """One batch: the nominal plant, then each effect at half its upper bound."""
    base = Case(NOMINAL)
    return simulate_batch([base] + [e.apply(base, 0.5 * e.bounds[1]) for e in version.family.values()])


@pytest.mark.parametrize(("version", "name"), _effects(V1_2, V1_3, V1_4, V1_5, V1_6, V1_7))
def test_half_the_upper_bound_is_visible_at_40_db_on_the_nominal_plant(version: Version, name: str) -> None:
    """The bounds' rule (docs/model-changes.md, 1.2 to 1.7): > 3 noise RMS on two channels at half the bound.

    The sensors' effects are in one channel by definition (the speed encoder's error and the speed's
    sample-and-hold in omega1, the accelerometer's cross-talk in a2, the torque estimate's current
    sensor of 1.6 in m_el, the accelerometer's saturation of 1.7 in a1): one channel for them (the mains hum of 1.5 is in two, a1 and a2, and
    passes with two).
    """
    e = version.family[name]
    res = _half_bound_runs(version)
    plain = res.channels[0]
    sd = noise_std(plain, 40.0)[:, 0]
    rms = np.sqrt(np.mean((res.channels[1 + list(version.family).index(name)] - plain) ** 2, axis=1)) / sd
    need = 1 if e.locus == "sensors" else 2
    assert np.sum(rms > 3.0) >= need, (name, dict(zip(CHANNELS, rms.round(1), strict=True)))


@pytest.mark.parametrize(("version", "name"), _effects(V1_2, V1_3, V1_4, V1_5, V1_6, V1_7))
def test_every_effect_at_its_upper_bound_keeps_the_event_across_the_plausible_box(version: Version, name: str) -> None:
    """The nominal plant and the eight corners of the plausible box (K, J1, c)."""
    e = version.family[name]
    corners = [PlantParameters(K=K, J1=J1, c=c) for K in (0.001, 0.015) for J1 in (0.6, 1.2) for c in (0.5, 2.0)]
    res = simulate_batch([e.apply(Case(p), e.bounds[1]) for p in [NOMINAL, *corners]])
    assert np.all(np.isfinite(res.event_times))  # simulate_batch raises on a missing event


# --- by name --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("version", "name", "value", "direct"),
    [
        pytest.param(V1_2, "resilient_hardening", 0.5, NOMINAL.replace(hard2=0.5), id="1.2-resilient_hardening"),
        pytest.param(
            V1_2,
            "speed_encoder_eccentricity",
            0.1,
            Case(NOMINAL, SensorParameters(ecc1=0.1)),
            id="1.2-speed_encoder_eccentricity",
        ),
        pytest.param(
            V1_3, "clutch_progressive_contact", 0.5, NOMINAL.replace(prog12=0.5), id="1.3-clutch_progressive_contact"
        ),
        pytest.param(
            V1_3,
            "accelerometer_crosstalk",
            0.05,
            Case(NOMINAL, SensorParameters(xtalk2=0.05)),
            id="1.3-accelerometer_crosstalk",
        ),
        pytest.param(V1_4, "resilient_hub_play", 0.002, NOMINAL.replace(play2=0.002), id="1.4-resilient_hub_play"),
        pytest.param(
            V1_4,
            "speed_sample_hold",
            0.001,
            Case(NOMINAL, SensorParameters(hold1=0.001)),
            id="1.4-speed_sample_hold",
        ),
        pytest.param(V1_5, "motor_brake", 0.4, NOMINAL.replace(tau_brake=0.4), id="1.5-motor_brake"),
        pytest.param(
            V1_5,
            "accelerometer_mains_hum",
            0.3,
            Case(NOMINAL, SensorParameters(hum=0.3)),
            id="1.5-accelerometer_mains_hum",
        ),
        pytest.param(V1_6, "supply_late_pole", 0.003, NOMINAL.replace(t_pole=0.003), id="1.6-supply_late_pole"),
        pytest.param(
            V1_6,
            "torque_current_gain",
            0.02,
            Case(NOMINAL, SensorParameters(igain_a=0.02)),
            id="1.6-torque_current_gain",
        ),
        pytest.param(V1_7, "wheel_imbalance", 0.03, NOMINAL.replace(tau_unb2=0.03), id="1.7-wheel_imbalance"),
        pytest.param(
            V1_7,
            "accelerometer_saturation",
            0.02,
            Case(NOMINAL, SensorParameters(sat_a1=0.02)),
            id="1.7-accelerometer_saturation",
        ),
    ],
)
def test_simulate_takes_an_effect_by_name_from_its_family(
    version: Version, name: str, value: float, direct: PlantParameters | Case
) -> None:
    """By name from its family's library, the record is bit for bit that of the field set directly."""
    rec = simulate(NOMINAL, {name: value}, library=version.family)
    same = simulate(direct)
    for ch in CHANNELS:
        assert rec.channels[ch].tobytes() == same.channels[ch].tobytes(), ch
    with pytest.raises(UnknownEffectError):
        simulate(NOMINAL, {name: value})  # not in the catalogue


@pytest.mark.parametrize(
    ("version", "name", "value", "channel"),
    [
        pytest.param(V1_2, "speed_encoder_eccentricity", 0.2, "omega1", id="1.2-speed_encoder_eccentricity"),
        pytest.param(V1_3, "accelerometer_crosstalk", 0.1, "a2", id="1.3-accelerometer_crosstalk"),
        pytest.param(V1_4, "speed_sample_hold", 0.002, "omega1", id="1.4-speed_sample_hold"),
        pytest.param(V1_6, "torque_current_gain", 0.05, "m_el", id="1.6-torque_current_gain"),
        pytest.param(V1_7, "accelerometer_saturation", 0.05, "a1", id="1.7-accelerometer_saturation"),
    ],
)
def test_a_sensor_s_effect_is_in_its_channel_only(version: Version, name: str, value: float, channel: str) -> None:
    res = simulate_batch([Case(NOMINAL), version.family[name].apply(Case(NOMINAL), value)])
    changed = [ch for j, ch in enumerate(CHANNELS) if res.channels[0, j].tobytes() != res.channels[1, j].tobytes()]
    assert changed == [channel]


# --- the family -------------------------------------------------------------------------------------


@pytest.mark.parametrize("version", _families(*VERSIONS))
def test_the_family_is_outside_the_catalogue_and_the_earlier_families(version: Version) -> None:
    for other in version.earlier:
        assert not set(version.family) & set(other)
    assert {e.locus for e in version.family.values()} <= set(LOCI)
    assert version.previous != MODEL_VERSION  # this version bumped it


def test_the_model_version_is_the_last_version_s() -> None:
    """1.8 adds an unknown input and no family (``tests/test_simulation_model_1_8.py``): the last family is 1.7's."""
    assert VERSIONS[-1].version == "1.7" and MODEL_VERSION == "1.8"


@pytest.mark.parametrize("version", _families(V1_2, V1_3, V1_4, V1_5, V1_6, V1_7))
def test_the_family_has_one_new_term_per_locus_neutral_at_zero(version: Version) -> None:
    assert sorted(e.locus for e in version.family.values()) == sorted(LOCI)
    fields_before = {(e.target, e.field) for library in version.earlier for e in library.values()}
    assert not {(e.target, e.field) for e in version.family.values()} & fields_before  # new terms, not new values
    assert all(e.neutral == 0.0 and e.bounds[0] == 0.0 < e.bounds[1] for e in version.family.values())


@pytest.mark.parametrize("version", _families(*VERSIONS))
def test_the_family_is_registered_by_its_name_for_blind_runs(version: Version) -> None:
    from app.cli.main import build_parser

    assert FAMILIES[version.name] is version.family
    assert all(locus_of(n) == e.locus for n, e in version.family.items())
    args = build_parser().parse_args(["validate", "--held-back", version.name, "--mix", "held_back=1"])
    assert args.held_back == version.name  # parsed only: nothing is run


@pytest.mark.parametrize("version", _families(*VERSIONS))
def test_reference_knows_every_effect_at_its_neutral_value(version: Version) -> None:
    assert {n: e.neutral for n, e in version.family.items()} == dict(version.reference_neutral)


@pytest.mark.parametrize(
    ("version", "case", "expected"),
    [
        pytest.param(
            V1_2,
            Case(
                NOMINAL.replace(u_neg=0.01, sat=0.02, b_2=0.03, k_pre=0.004, hard2=0.05, k_3=0.06),
                SensorParameters(ecc1=0.07),
            ),
            {
                "supply_unbalance": 0.01,
                "magnetic_saturation": 0.02,
                "motor_windage": 0.03,
                "clutch_preload_spring": 0.004,
                "resilient_hardening": 0.05,
                "load_position_spring": 0.06,
                "speed_encoder_eccentricity": 0.07,
            },
            id="1.2-held_out",
        ),
        pytest.param(
            V1_3,
            Case(
                NOMINAL.replace(u_flicker=0.01, x_leak=0.02, tau_S1=0.03, prog12=0.04, tau_dry2=0.05, b_3=0.06),
                SensorParameters(xtalk2=0.07),
            ),
            {
                "supply_flicker": 0.01,
                "leakage_reactance": 0.02,
                "motor_stribeck": 0.03,
                "clutch_progressive_contact": 0.04,
                "resilient_dry_friction": 0.05,
                "load_quadratic_drag": 0.06,
                "accelerometer_crosstalk": 0.07,
            },
            id="1.3-sealed",
        ),
        pytest.param(
            V1_4,
            Case(
                NOMINAL.replace(u_dc=0.01, r_m=0.02, mu_1=0.03, sq12=0.04, play2=0.05, bump3=0.06),
                SensorParameters(hold1=0.007),
            ),
            {
                "supply_dc_offset": 0.01,
                "core_loss_resistance": 0.02,
                "motor_bearing_load_friction": 0.03,
                "clutch_squeeze_film": 0.04,
                "resilient_hub_play": 0.05,
                "load_track_bump": 0.06,
                "speed_sample_hold": 0.007,
            },
            id="1.4-sealed2",
        ),
        pytest.param(
            V1_5,
            Case(
                NOMINAL.replace(r_con=0.01, r_bar=0.02, tau_brake=0.03, hyst12=0.04, mesh2=0.05, eddy3=0.06),
                SensorParameters(hum=0.07),
            ),
            {
                "supply_loose_connection": 0.01,
                "rotor_broken_bar": 0.02,
                "motor_brake": 0.03,
                "clutch_hysteretic_contact": 0.04,
                "resilient_mesh_stiffness": 0.05,
                "load_eddy_current_brake": 0.06,
                "accelerometer_mains_hum": 0.07,
            },
            id="1.5-sealed3",
        ),
        pytest.param(
            V1_6,
            Case(
                NOMINAL.replace(t_pole=0.001, bypass_a=0.02, tau_rub=0.03, seal12=0.04, gear2=0.05, bind3=0.06),
                SensorParameters(igain_a=0.07),
            ),
            {
                "supply_late_pole": 0.001,
                "stator_coil_bypass": 0.02,
                "motor_rotor_rub": 0.03,
                "clutch_seal_drag": 0.04,
                "resilient_gear_loss": 0.05,
                "load_guide_binding": 0.06,
                "torque_current_gain": 0.07,
            },
            id="1.6-sealed4",
        ),
        pytest.param(
            V1_7,
            Case(
                NOMINAL.replace(u_h57=0.01, psi_r0=0.02, tau_mis1=0.03, ecc12=0.04, tau_unb2=0.05, buf3=0.06),
                SensorParameters(sat_a1=0.07),
            ),
            {
                "supply_harmonics": 0.01,
                "rotor_residual_flux": 0.02,
                "shaft_misalignment": 0.03,
                "clutch_hub_runout": 0.04,
                "wheel_imbalance": 0.05,
                "load_end_buffer": 0.06,
                "accelerometer_saturation": 0.07,
            },
            id="1.7-sealed5",
        ),
    ],
)
def test_the_reference_reads_every_effect_of_a_case(version: Version, case: Case, expected: dict[str, float]) -> None:
    """Each field at a value of its own, so that two fields swapped in the adapter would show."""
    _, effects = reference_inputs(case)
    assert {n: effects[n] for n in version.family} == expected


@pytest.mark.parametrize(
    ("version", "module"),
    [
        pytest.param(V1_2, held_out, id="1.2-held_out"),
        pytest.param(V1_3, sealed, id="1.3-sealed"),
        pytest.param(V1_4, sealed2, id="1.4-sealed2"),
        pytest.param(V1_5, sealed3, id="1.5-sealed3"),
        pytest.param(V1_6, sealed4, id="1.6-sealed4"),
        pytest.param(V1_7, sealed5, id="1.7-sealed5"),
    ],
)
def test_the_rule_is_stated_in_the_module_and_in_the_docs(version: Version, module: ModuleType) -> None:
    assert getattr(module, version.name.upper()) is version.family
    assert module.__doc__ is not None and module.RULE in module.__doc__
    assert module.RULE in " ".join((DOCS / "model-changes.md").read_text().split())


@pytest.mark.parametrize("version", _families(V1_2, V1_3, V1_4))
def test_the_case_generator_draws_held_back_cases_from_the_family(version: Version) -> None:
    from engine.validation.cases import generate_cases

    family = version.family
    n = len(family)  # its pool gives every effect once per round
    cases, key = generate_cases(n, 5, CATALOGUE, family, {"held_back": 1.0}, absorption=False)
    assert len(cases) == n
    assert {k.kind for k in key} == {"held_back"}
    assert sorted(t.name for k in key for t in k.effects) == sorted(family)
    assert all(t.locus == family[t.name].locus for k in key for t in k.effects)
    with pytest.raises(ValueError, match="never be in the catalogue"):
        generate_cases(1, 5, CATALOGUE + family, family, {"held_back": 1.0}, absorption=False)


@pytest.mark.parametrize(
    ("parameters", "changes", "match"),
    [
        pytest.param(
            PlantParameters, {"K": 0.005, "clutch_offset": 0.06}, "half-width", id="1.1-clutch_offset-beyond-half-width"
        ),
        pytest.param(PlantParameters, {"u_neg": -0.01}, "u_neg", id="1.2-supply_unbalance-negative"),
        pytest.param(PlantParameters, {"sat": -0.1}, "sat", id="1.2-magnetic_saturation-negative"),
        pytest.param(PlantParameters, {"b_2": float("nan")}, "finite", id="1.2-motor_windage-nan"),
        pytest.param(PlantParameters, {"k_pre": 2.0}, "k_pre", id="1.2-clutch_preload_spring-too-stiff"),
        pytest.param(PlantParameters, {"hard2": -1.0}, "hard2", id="1.2-resilient_hardening-negative"),
        pytest.param(PlantParameters, {"k_3": -0.1}, "k_3", id="1.2-load_position_spring-negative"),
        pytest.param(SensorParameters, {"ecc1": 0.9}, "ecc1", id="1.2-speed_encoder_eccentricity-too-large"),
        pytest.param(PlantParameters, {"u_flicker": -0.01}, "u_flicker", id="1.3-supply_flicker-negative"),
        pytest.param(PlantParameters, {"u_flicker": 0.9}, "u_flicker", id="1.3-supply_flicker-too-large"),
        pytest.param(PlantParameters, {"x_leak": -0.1}, "x_leak", id="1.3-leakage_reactance-negative"),
        pytest.param(PlantParameters, {"tau_S1": float("nan")}, "finite", id="1.3-motor_stribeck-nan"),
        pytest.param(PlantParameters, {"prog12": -1.0}, "prog12", id="1.3-clutch_progressive_contact-negative"),
        pytest.param(PlantParameters, {"tau_dry2": -0.1}, "tau_dry2", id="1.3-resilient_dry_friction-negative"),
        pytest.param(PlantParameters, {"b_3": -1.0}, "b_3", id="1.3-load_quadratic_drag-negative"),
        pytest.param(SensorParameters, {"xtalk2": 1.5}, "xtalk2", id="1.3-accelerometer_crosstalk-too-large"),
        pytest.param(PlantParameters, {"u_dc": -0.01}, "u_dc", id="1.4-supply_dc_offset-negative"),
        pytest.param(PlantParameters, {"u_dc": 0.5}, "u_dc", id="1.4-supply_dc_offset-too-large"),
        pytest.param(PlantParameters, {"r_m": -0.1}, "r_m", id="1.4-core_loss_resistance-negative"),
        pytest.param(PlantParameters, {"mu_1": float("nan")}, "finite", id="1.4-motor_bearing_load_friction-nan"),
        pytest.param(PlantParameters, {"sq12": -1.0}, "sq12", id="1.4-clutch_squeeze_film-negative"),
        pytest.param(PlantParameters, {"play2": 0.5}, "play2", id="1.4-resilient_hub_play-too-large"),
        pytest.param(PlantParameters, {"bump3": -0.1}, "bump3", id="1.4-load_track_bump-negative"),
        pytest.param(SensorParameters, {"hold1": 0.05}, "hold1", id="1.4-speed_sample_hold-too-long"),
        pytest.param(PlantParameters, {"r_con": -0.01}, "r_con", id="1.5-supply_loose_connection-negative"),
        pytest.param(PlantParameters, {"r_bar": float("nan")}, "finite", id="1.5-rotor_broken_bar-nan"),
        pytest.param(PlantParameters, {"tau_brake": -0.1}, "tau_brake", id="1.5-motor_brake-negative"),
        pytest.param(PlantParameters, {"hyst12": 1.0}, "hyst12", id="1.5-clutch_hysteretic_contact-too-large"),
        pytest.param(PlantParameters, {"mesh2": 1.0}, "mesh2", id="1.5-resilient_mesh_stiffness-too-large"),
        pytest.param(PlantParameters, {"eddy3": -0.1}, "eddy3", id="1.5-load_eddy_current_brake-negative"),
        pytest.param(SensorParameters, {"hum": -1.0}, "hum", id="1.5-accelerometer_mains_hum-negative"),
        pytest.param(PlantParameters, {"t_pole": -0.001}, "t_pole", id="1.6-supply_late_pole-negative"),
        pytest.param(PlantParameters, {"t_pole": 0.5}, "t_pole", id="1.6-supply_late_pole-too-late"),
        pytest.param(PlantParameters, {"bypass_a": 0.9}, "bypass_a", id="1.6-stator_coil_bypass-too-large"),
        pytest.param(PlantParameters, {"tau_rub": float("nan")}, "finite", id="1.6-motor_rotor_rub-nan"),
        pytest.param(PlantParameters, {"seal12": -0.1}, "seal12", id="1.6-clutch_seal_drag-negative"),
        pytest.param(PlantParameters, {"gear2": 1.0}, "gear2", id="1.6-resilient_gear_loss-too-large"),
        pytest.param(PlantParameters, {"bind3": -0.1}, "bind3", id="1.6-load_guide_binding-negative"),
        pytest.param(SensorParameters, {"igain_a": -0.1}, "igain_a", id="1.6-torque_current_gain-negative"),
        pytest.param(PlantParameters, {"u_h57": -0.01}, "u_h57", id="1.7-supply_harmonics-negative"),
        pytest.param(PlantParameters, {"u_h57": 0.9}, "u_h57", id="1.7-supply_harmonics-too-large"),
        pytest.param(PlantParameters, {"psi_r0": 2.0}, "psi_r0", id="1.7-rotor_residual_flux-too-large"),
        pytest.param(PlantParameters, {"tau_mis1": float("nan")}, "finite", id="1.7-shaft_misalignment-nan"),
        pytest.param(PlantParameters, {"ecc12": 1.0}, "ecc12", id="1.7-clutch_hub_runout-too-large"),
        pytest.param(PlantParameters, {"tau_unb2": -0.1}, "tau_unb2", id="1.7-wheel_imbalance-negative"),
        pytest.param(PlantParameters, {"buf3": -0.1}, "buf3", id="1.7-load_end_buffer-negative"),
        pytest.param(SensorParameters, {"sat_a1": -0.1}, "sat_a1", id="1.7-accelerometer_saturation-negative"),
    ],
)
def test_an_absurd_value_is_refused_with_its_name(
    parameters: type[PlantParameters] | type[SensorParameters], changes: dict[str, Any], match: str
) -> None:
    with pytest.raises(ParameterError, match=match):
        parameters(**changes).validate()
