"""A plant from an FMU: the short description that says what the FMU is to the diagnosis (issue 55).

A user's simulator, exported as an FMI 2.0 FMU, co-simulation or model exchange (Simulink, Simscape, Dymola,
OpenModelica, a vendor's tool), becomes a plant of :mod:`engine.plants.base` with a TOML file
beside it::

    name = "quarter_car"
    description = "a car's corner on a road-simulator rig"
    fmu = "quarter_car.fmu"           # relative to this file; a folder is a source FMU, built on load
    interface = "co-simulation"       # or "model-exchange": its derivatives, integrated on the record's grid
    loci = ["body", "suspension", "wheel", "rig"]
    time = "t"                        # the record's time column [s], on the FMU's time axis

    [[inputs]]                        # FMU inputs: driven by a record column, or an unknown-input entry
    variable = "z_r"
    column = "z_road"                 # omit for an input the record does not drive (held at 0)
    unit = "m"
    locus = "rig"

    [[channels]]                      # FMU outputs that are the record's measured channels
    name = "a_body"                   # the record's column
    variable = "a_s"
    unit = "m/s2"
    full_scale = 20.0                 # the sensor's range [unit]: bounds of its offset and quantisation

    [[calibrated]]                    # FMU parameters refitted on every record
    name = "m_s"
    nominal = 300.0
    lo = 200.0
    hi = 450.0
    unit = "kg"

    [[effects]]                       # candidate effects that are FMU parameters
    name = "damper_friction"
    variable = "F_c"
    neutral = 0.0
    bounds = [0.0, 150.0]
    unit = "N"
    locus = "suspension"
    description = "Coulomb friction of the damper's seals"

Every effect of the generic measurement chain (a gain, an offset, a delay, a first-order lag and a
quantisation of every channel; a gain, a delay and a saturation of every driven input;
:mod:`engine.plants.fmu.generic`) joins the catalogue unless ``[generic]`` turns it off. Missing
optional keys take the defaults below; an unknown key, a name used twice, a nominal value outside
its interval, a locus not in ``loci``, or a variable the FMU does not have (or has with another
causality or unit) is refused with a message that says what to fix (:class:`DescriptionError`).
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from engine.plants.fmu.runner import Interface

__all__ = [
    "ACTUATOR_LOCUS",
    "SENSOR_LOCUS",
    "CalibratedSpec",
    "ChannelSpec",
    "DescriptionError",
    "EffectSpec",
    "GenericSpec",
    "InputSpec",
    "PlantDescription",
    "load_description",
]

#: The locus of the generic measurement chain's effects (added to the description's loci).
SENSOR_LOCUS: str = "sensors"
#: The locus of the generic actuator effects of the driven inputs.
ACTUATOR_LOCUS: str = "actuators"

_Name = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_.\[\]]*$", max_length=80)]
_Finite = Annotated[float, Field(allow_inf_nan=False)]


class DescriptionError(ValueError):
    """Raised for a plant description the diagnosis cannot use; the message names the key and what to fix."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class InputSpec(_Strict):
    """One FMU input.

    Attributes
    ----------
    variable : str
        The FMU's input variable.
    column : str or None
        The record column that drives it (held over each sample interval); None for an input no record
        drives, held at 0: an unknown-input entry of the locus estimate.
    unit : str
        Its unit.
    locus : str
        The part of the machine it acts on.
    description : str
        What it is.
    """

    variable: _Name
    column: _Name | None = None
    unit: str = ""
    locus: _Name
    description: str = ""


class ChannelSpec(_Strict):
    """One measured channel: an FMU output.

    Attributes
    ----------
    name : str
        The channel's name and its record column.
    variable : str
        The FMU's output variable.
    unit : str
        Its unit.
    full_scale : float
        The sensor's range [unit] (> 0): the generic offset is searched within 5 % of it, the
        quantisation step up to 1 %.
    description : str
        What it measures.
    """

    name: _Name
    variable: _Name
    unit: str = ""
    full_scale: _Finite = Field(gt=0.0)
    description: str = ""


class CalibratedSpec(_Strict):
    """One FMU parameter refitted on every record, with its nominal value and plausible interval [unit]."""

    name: _Name
    variable: _Name | None = None
    nominal: _Finite
    lo: _Finite
    hi: _Finite
    unit: str = ""
    log: bool = False

    @model_validator(mode="after")
    def _interval(self) -> CalibratedSpec:
        if not self.lo < self.hi:
            raise ValueError(f"{self.name}: lo = {self.lo} must be below hi = {self.hi}")
        if not self.lo <= self.nominal <= self.hi:
            raise ValueError(f"{self.name}: nominal = {self.nominal} lies outside [{self.lo}, {self.hi}]")
        if self.log and self.lo <= 0.0:
            raise ValueError(f"{self.name}: a log-scaled interval needs lo > 0, got {self.lo}")
        return self

    @property
    def fmu_variable(self) -> str:
        """The FMU parameter it sets (its name unless ``variable`` says otherwise)."""
        return self.variable or self.name


class EffectSpec(_Strict):
    """One candidate effect that is an FMU parameter: its neutral value, search bounds [unit] and locus."""

    name: _Name
    variable: _Name | None = None
    neutral: _Finite
    bounds: tuple[_Finite, _Finite]
    unit: str = ""
    locus: _Name
    description: str = ""
    log: bool = False

    @model_validator(mode="after")
    def _bounds(self) -> EffectSpec:
        lo, hi = self.bounds
        if not lo < hi:
            raise ValueError(f"{self.name}: bounds [{lo}, {hi}] must be increasing")
        if not lo <= self.neutral <= hi:
            raise ValueError(f"{self.name}: neutral = {self.neutral} lies outside its bounds [{lo}, {hi}]")
        if self.log and lo <= 0.0:
            raise ValueError(f"{self.name}: log-scaled bounds need a positive lower bound, got {lo}")
        return self

    @property
    def fmu_variable(self) -> str:
        """The FMU parameter it sets (its name unless ``variable`` says otherwise)."""
        return self.variable or self.name


class GenericSpec(_Strict):
    """Which generic effects join the catalogue, and their search bounds.

    Attributes
    ----------
    sensors : bool
        A gain, an offset, a delay, a first-order lag and a quantisation of every channel.
    actuators : bool
        A gain, a delay and a saturation of every driven input.
    max_delay : float
        Upper bound of a sensor's or an actuator's delay [s].
    max_lag : float
        Upper bound of a sensor's first-order time constant [s].
    """

    sensors: bool = True
    actuators: bool = True
    max_delay: _Finite = Field(default=5e-3, gt=0.0)
    max_lag: _Finite = Field(default=5e-3, gt=0.0)


class PlantDescription(_Strict):
    """A plant from an FMU (the module docstring shows the TOML form).

    Attributes
    ----------
    name : str
        The plant's name (answers and stored diagnoses carry it).
    description : str
        What the machine is.
    fmu : str
        The FMU: a ``.fmu`` file, or a source FMU's folder (``modelDescription.xml`` and
        ``sources/``, built on load with the system C compiler), relative to the description's folder.
    interface : {"co-simulation", "model-exchange"}
        The FMU's FMI 2.0 interface to run: its own solver's communication steps (co-simulation, the
        default), or its derivatives integrated by the plant's solver, chosen for the record's grid
        (model exchange; :mod:`engine.plants.fmu.runner`).
    loci : list of str
        The parts of the machine the inputs and effects belong to.
    time : str
        The record's time column [s], on the FMU's time axis (the FMU is started at
        ``start_time`` and stepped to each sample).
    start_time : float
        The FMU experiment's start [s] (the record's first sample is at or after it).
    settle : float
        Seconds from the record's first sample that no comparison scores (a start-up transient).
    diff_step : float
        Step of the diagnosis's finite differences, as a share of each parameter's search interval.
    inputs, channels, calibrated, effects, held_back
        As their specs; ``held_back`` effects are outside the catalogue, for scoring the open world.
    generic : GenericSpec
        The generic effects.
    calibration_search : int
        Points of a global (Sobol) search over the calibrated parameters' box whose best is where the
        calibration's least squares starts (0: at the nominal values). For a model whose fit has local
        minima near its nominal values (a backlash's impacts), 64 to 256.
    examples : list of str
        Record files (CSV) shipped with the description, relative to its folder; the first is the
        default example (the synthetic check of the diagnosis runs on its inputs).
    """

    name: _Name
    description: str = ""
    fmu: str
    interface: Interface = "co-simulation"
    loci: list[_Name] = Field(min_length=1)
    time: _Name = "t"
    start_time: _Finite = 0.0
    settle: _Finite = Field(default=0.0, ge=0.0)
    diff_step: _Finite = Field(default=1e-3, gt=0.0, lt=0.1)
    inputs: list[InputSpec] = []
    channels: list[ChannelSpec] = Field(min_length=1)
    calibrated: list[CalibratedSpec] = []
    effects: list[EffectSpec] = []
    held_back: list[EffectSpec] = []
    generic: GenericSpec = GenericSpec()
    examples: list[str] = []
    calibration_search: int = Field(default=0, ge=0, le=4096)

    @field_validator("loci")
    @classmethod
    def _unique_loci(cls, loci: list[str]) -> list[str]:
        dup = sorted({x for x in loci if loci.count(x) > 1})
        if dup:
            raise ValueError(f"loci named twice: {dup}")
        reserved = {SENSOR_LOCUS, ACTUATOR_LOCUS} & set(loci)
        if reserved:
            raise ValueError(f"{sorted(reserved)} are the generic effects' loci, added by themselves; leave them out")
        return loci

    @model_validator(mode="after")
    def _consistent(self) -> PlantDescription:
        loci = set(self.all_loci)
        for what, items in (("input", self.inputs), ("effect", self.effects), ("held_back effect", self.held_back)):
            for item in items:
                if item.locus not in loci:
                    raise ValueError(
                        f"{what} {getattr(item, 'name', None) or item.variable!r}: locus {item.locus!r} is not "
                        f"one of loci {sorted(loci)}"
                    )
        names = [c.name for c in self.calibrated] + [e.name for e in self.effects] + [e.name for e in self.held_back]
        dup = sorted({x for x in names if names.count(x) > 1})
        if dup:
            raise ValueError(f"calibrated parameters and effects must have distinct names; named twice: {dup}")
        columns = [self.time] + [i.column for i in self.inputs if i.column] + [c.name for c in self.channels]
        dup = sorted({x for x in columns if columns.count(x) > 1})
        if dup:
            raise ValueError(f"record columns used twice (time, inputs, channels): {dup}")
        variables = [i.variable for i in self.inputs]
        dup = sorted({x for x in variables if variables.count(x) > 1})
        if dup:
            raise ValueError(f"FMU inputs listed twice: {dup}")
        return self

    @property
    def all_loci(self) -> tuple[str, ...]:
        """The description's loci, then the generic effects' (``sensors``, ``actuators``) where they apply."""
        extra: list[str] = []
        if self.generic.sensors:
            extra.append(SENSOR_LOCUS)
        if self.generic.actuators and any(i.column for i in self.inputs):
            extra.append(ACTUATOR_LOCUS)
        return (*self.loci, *extra)

    @property
    def driven(self) -> tuple[InputSpec, ...]:
        """The inputs a record column drives."""
        return tuple(i for i in self.inputs if i.column)


def _message(exc: ValidationError) -> str:
    parts = []
    for err in exc.errors():
        where = ".".join(str(x) for x in err["loc"]) or "(top level)"
        msg = str(err["msg"]).removeprefix("Value error, ")
        parts.append(f"{where}: {msg}")
    return "; ".join(parts)


def parse_description(data: Any, where: str = "plant description") -> PlantDescription:
    """A description from its parsed TOML (or JSON) document.

    Raises
    ------
    DescriptionError
        For anything :class:`PlantDescription` refuses, each problem named by its key.
    """
    if not isinstance(data, dict):
        raise DescriptionError(f"{where}: a plant description is a table of keys, got {type(data).__name__}")
    try:
        return PlantDescription.model_validate(data)
    except ValidationError as exc:
        raise DescriptionError(f"{where}: {_message(exc)}") from None


def load_description(path: str | Path) -> PlantDescription:
    """The description in a ``.toml`` file.

    Raises
    ------
    DescriptionError
        Another extension, an unreadable or malformed file, or a description :func:`parse_description`
        refuses; the message names the file.
    """
    path = Path(path)
    if path.suffix.lower() != ".toml":
        raise DescriptionError(f"plant description {path}: the file must end in .toml")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise DescriptionError(f"cannot read plant description {path}: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DescriptionError(f"{path}: malformed TOML: {exc}") from None
    return parse_description(data, str(path))
