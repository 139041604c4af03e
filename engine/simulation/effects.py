"""Catalogue of unmodelled physical effects: named, one-parameter extensions of the model.

Each :class:`Effect` changes one field of the plant or of the measurement chain
(:class:`~engine.simulation.parameters.Case`), either by multiplying it or by
setting it. An :class:`EffectLibrary` is a named, composable collection (in the
spirit of pysindy's feature libraries): the gap diagnosis fits every member,
and a blind validation can hand the diagnosis a library *without* one member.

Adding an effect is a local change: one entry in :data:`CATALOGUE` (plus, if it
needs a new physical term, one field in ``PlantParameters`` with a neutral
default and its term in the kernel's right-hand side).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Literal, get_args

from engine.constants import W_SMOOTH
from engine.simulation.parameters import Case, ParameterError

#: The parts of the plant where an effect (or a missing term) acts: the supply; the stator and
#: rotor circuits; torques on the motor shaft J1; the backlash contact of the clutch; the wheel J2
#: and the resilient element; the mass m2 with the absorber and any external load torque; the
#: measurement chain.
Locus = Literal["supply", "motor_electrical", "motor_shaft", "clutch", "drive_train", "load", "sensors"]
LOCI: tuple[str, ...] = get_args(Locus)


class UnknownEffectError(ParameterError):
    """Raised for an effect name that is not in the library."""


@dataclass(frozen=True)
class Effect:
    """One unmodelled effect with one scalar parameter.

    Parameters
    ----------
    name : str
        Catalogue name (used by the API's ``effects`` and by the diagnosis).
    description : str
        What it models, with the parameter's meaning and unit.
    target : {"plant", "sensors"}
        Which part of the case it changes.
    field : str
        The field of ``PlantParameters`` or ``SensorParameters`` it changes.
    mode : {"multiply", "set"}
        ``multiply``: field = nominal * value; ``set``: field = value.
    bounds : tuple of float
        Accepted range of the value (inclusive).
    neutral : float
        Value that leaves the model unchanged (the "no effect" point).
    unit : str
        Unit of the value.
    locus : str
        The part of the plant where it acts (one of :data:`LOCI`).
    """

    name: str
    description: str
    target: Literal["plant", "sensors"]
    field: str
    mode: Literal["multiply", "set"]
    bounds: tuple[float, float]
    neutral: float
    unit: str
    locus: Locus

    def __post_init__(self) -> None:
        if self.locus not in LOCI:
            raise ValueError(f"effect {self.name!r}: locus {self.locus!r} is not one of {', '.join(LOCI)}")

    def check(self, value: float) -> float:
        value = float(value)
        lo, hi = self.bounds
        if not (lo <= value <= hi):
            raise ParameterError(
                f"effect {self.name!r} = {value} {self.unit} is outside its range [{lo}, {hi}] {self.unit}"
            )
        return value

    def apply(self, case: Case, value: float) -> Case:
        """Return ``case`` with this effect at ``value`` (raises if out of range)."""
        value = self.check(value)
        if self.target == "plant":
            new = self._new_value(getattr(case.plant, self.field), value)
            return Case(case.plant.replace(**{self.field: new}), case.sensors)
        new = self._new_value(getattr(case.sensors, self.field), value)
        return Case(case.plant, case.sensors.replace(**{self.field: new}))

    def _new_value(self, old: float, value: float) -> float:
        return value * old if self.mode == "multiply" else value


class EffectLibrary(Mapping[str, Effect]):
    """An ordered, named collection of effects."""

    def __init__(self, effects: list[Effect]):
        self._effects = {e.name: e for e in effects}

    def __getitem__(self, name: str) -> Effect:
        try:
            return self._effects[name]
        except KeyError:
            raise UnknownEffectError(f"unknown effect {name!r}; known effects: {', '.join(self._effects)}") from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._effects)

    def __contains__(self, name: object) -> bool:
        # Mapping's default relies on __getitem__ raising KeyError; ours raises UnknownEffectError
        return name in self._effects

    def __len__(self) -> int:
        return len(self._effects)

    def without(self, *names: str) -> EffectLibrary:
        """The library less some members (leave-one-effect-out)."""
        for n in names:
            self[n]  # raise on unknown names
        return EffectLibrary([e for n, e in self._effects.items() if n not in names])

    def __add__(self, other: EffectLibrary) -> EffectLibrary:
        return EffectLibrary(list(self.values()) + [e for n, e in other.items() if n not in self])

    def apply(self, case: Case, effects: Mapping[str, float] | None) -> Case:
        """Apply several effects to a case, in the given order."""
        for name, value in (effects or {}).items():
            case = self[name].apply(case, value)
        return case


# One row per effect: name, description, target, field, mode, bounds, neutral value, unit, locus.
# fmt: off
CATALOGUE = EffectLibrary(
    [
        Effect("motor_coulomb_friction", f"Coulomb friction on the motor shaft: value * tanh(w_1 / {W_SMOOTH:g})",
               "plant", "tau_C1", "set", (0.0, 0.1), 0.0, "pu", "motor_shaft"),
        Effect("motor_viscous_friction", "viscous friction on the motor shaft: value * w_1",
               "plant", "b_1", "set", (0.0, 0.1), 0.0, "pu", "motor_shaft"),
        Effect("rotor_resistance_drift", "rotor resistance r_r multiplied by value",
               "plant", "r_r", "multiply", (0.6, 1.6), 1.0, "x", "motor_electrical"),
        Effect("stator_resistance_drift", "stator resistance r_s multiplied by value",
               "plant", "r_s", "multiply", (0.6, 1.6), 1.0, "x", "motor_electrical"),
        Effect("contact_stiffness", "clutch contact stiffness k_12 multiplied by value",
               "plant", "k12", "multiply", (0.1, 10.0), 1.0, "x", "clutch"),
        Effect("contact_damping", "clutch contact damping d_12 multiplied by value",
               "plant", "d12", "multiply", (0.1, 20.0), 1.0, "x", "clutch"),
        Effect("resilient_stiffness", "resilient-element stiffness k_2 multiplied by value",
               "plant", "k2", "multiply", (0.5, 2.0), 1.0, "x", "drive_train"),
        Effect("load_inertia", "drive-wheel inertia J2 multiplied by value",
               "plant", "J2", "multiply", (0.5, 2.0), 1.0, "x", "drive_train"),
        Effect("absorber_discontinuity", "absorber discontinuity c_1 multiplied by value",
               "plant", "c1", "multiply", (0.0, 3.0), 1.0, "x", "load"),
        Effect("supply_voltage", "supply voltage u multiplied by value",
               "plant", "u", "multiply", (0.8, 1.1), 1.0, "x", "supply"),
        Effect("speed_quantization", "omega1 rounded to multiples of value",
               "sensors", "speed_quantum", "set", (0.0, 0.5), 0.0, "rad/s", "sensors"),
        Effect("measurement_delay", "every channel delayed by value",
               "sensors", "delay", "set", (0.0, 0.001), 0.0, "s", "sensors"),
        Effect("sensor_lowpass", "first-order low-pass of cut-off value on every channel",
               "sensors", "lowpass_hz", "set", (200.0, 5000.0), 0.0, "Hz", "sensors"),
        Effect("trigger_offset", "the record's alignment is off by value: the true event lies value after the labelled one",
               "sensors", "trigger_offset", "set", (-0.002, 0.002), 0.0, "s", "sensors"),
        Effect("sensor_gain", "every channel scaled by value",
               "sensors", "gain", "multiply", (0.8, 1.2), 1.0, "x", "sensors"),
        Effect("sensor_offset", "constant offset of value times the channel's RMS over the test window on every channel",
               "sensors", "offset_rms", "set", (-0.2, 0.2), 0.0, "x RMS", "sensors"),
    ]
)
# fmt: on


def apply_effects(case: Case, effects: Mapping[str, float] | None, library: EffectLibrary = CATALOGUE) -> Case:
    """Apply named effects from ``library`` to ``case`` (see :meth:`EffectLibrary.apply`)."""
    return library.apply(case, effects)
