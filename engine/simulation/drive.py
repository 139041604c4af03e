"""The user's own drive, as data: a drive description (issue 52, item 3).

A :class:`DriveDescription` holds every parameter of MODEL.md section 1 by the project's names (the
motor's equivalent circuit, the supply, the pole pairs, the inertias, the wheel radius, the
stiffnesses and dampings, the absorber), the base values that convert per unit to SI (the rated
supply frequency and the pole pairs give w_b and Omega_b; a base torque or base power gives the
mechanical time constant per inertia), and the items of the test protocol (MODEL.md section 2) that
may differ. Every default is MODEL.md's value, read from :mod:`engine.constants`: an empty
description is exactly the reference plant, and simulates bit for bit the same records.

A description is written in TOML or JSON, in sections::

    name = "conveyor 3"

    [supply]
    frequency = 60.0        # rated supply frequency [Hz]; w_b = 2 pi frequency

    [motor]
    pole_pairs = 3
    r_s = 0.045

    [base]
    base_torque = 320.0     # [N m]; or base_power [W]

    [mechanics]
    J1 = 1.4
    r = 0.16

Missing sections and keys keep MODEL.md's values; an unknown section or key is refused with the
list of the known ones, and an impossible value with a message saying what to fix
(:class:`~engine.simulation.parameters.ParameterError`). ``docs/drive-description.md`` says how to fill
one from a motor's nameplate and datasheet and a drive train's drawing.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Final

from engine import constants as const
from engine.records.grid import GridError, SampleGrid
from engine.records.limits import MAX_SAMPLES
from engine.simulation.parameters import Case, ParameterError, PlantParameters, SolverSettings

__all__ = [
    "REFERENCE_DRIVE",
    "SECTIONS",
    "DriveDescription",
    "load_drive",
    "parse_drive",
]

logger = logging.getLogger(__name__)

#: The sections of a description and the keys each holds (the project's names).
SECTIONS: Final[dict[str, tuple[str, ...]]] = {
    "supply": ("frequency", "u", "f"),
    "motor": ("r_s", "r_r", "x_s", "x_r", "x_m", "pole_pairs"),
    "base": ("base_torque", "base_power"),
    "mechanics": ("J1", "J2", "T3", "r", "K", "c", "c1", "k12", "d12", "k2", "d2"),
    "protocol": ("sample_interval", "n_samples", "event_index", "t_event_max"),
}
#: Keys that hold whole numbers.
_INTEGER_KEYS: Final[frozenset[str]] = frozenset({"pole_pairs", "n_samples", "event_index"})
#: Keys that may be absent (None): the base torque or power, one of which sets the time constants.
_OPTIONAL_KEYS: Final[frozenset[str]] = frozenset({"base_torque", "base_power"})
#: Keys that must be > 0 (the physics divides by them or needs them to be there).
_POSITIVE_KEYS: Final[tuple[str, ...]] = (
    "frequency",
    "u",
    "f",
    "r_s",
    "r_r",
    "x_s",
    "x_r",
    "x_m",
    "pole_pairs",
    "base_torque",
    "base_power",
    "J1",
    "J2",
    "T3",
    "r",
    "K",
    "k12",
    "k2",
    "sample_interval",
    "n_samples",
    "t_event_max",
)
#: Keys that must be >= 0 (dampings and the absorber; zero means none).
_NON_NEGATIVE_KEYS: Final[tuple[str, ...]] = ("c", "c1", "d12", "d2", "event_index")


@dataclass(frozen=True)
class DriveDescription:
    """One drive: MODEL.md's plant parameters, the per-unit base values and the test protocol.

    Every default is MODEL.md's value (:mod:`engine.constants`), so ``DriveDescription()`` is the
    reference plant. Values are checked on construction (:meth:`validate`).

    Parameters
    ----------
    name : str
        A label for people (not part of the :attr:`fingerprint`).
    frequency : float
        Rated supply frequency [Hz], the electrical base: w_b = 2 pi frequency [rad/s] (MODEL.md: 50).
    u, f : float
        Supply voltage amplitude [pu] and frequency [pu of ``frequency``] of the test (MODEL.md: 1, 1,
        direct-on-line).
    r_s, r_r, x_s, x_r, x_m : float
        Stator and rotor resistance, total stator and rotor reactance, magnetising reactance [pu]
        (MODEL.md: 0.059, 0.048, 1.92, 1.92, 1.82); x_m must be below x_s and x_r.
    pole_pairs : int
        Pole pairs p [-]; Omega_b = w_b / p [rad/s] is 1 pu of speed (MODEL.md: 2).
    base_torque : float or None
        Base torque M_b [N m]; the mechanical time constants are T_i = J_i Omega_b / M_b [s].
    base_power : float or None
        Base power P_b [W] instead of ``base_torque`` (M_b = P_b / Omega_b); at most one of the two.
        With neither, T_i = J_i * 0.86 / 0.87 s / (kg m^2) (MODEL.md's, M_b = 158.9 N m at 50 Hz and
        2 pole pairs).
    J1, J2 : float
        Nominal motor-side inertia and drive-wheel inertia [kg m^2] (MODEL.md: 0.87, 0.348).
    T3 : float
        Mechanical time constant of the load mass m2 referred to the motor shaft [s] (MODEL.md: 0.30).
    r : float
        Drive-wheel radius [m] (MODEL.md: 0.1).
    K : float
        Nominal backlash zone width [m] (MODEL.md: 0.005).
    c, c1 : float
        Nominal apparent viscosity of the absorber [pu torque / pu speed] and its discontinuity at
        zero speed [pu torque] (MODEL.md: 1.0, 0.2).
    k12, d12 : float
        Contact stiffness [pu torque / rad] and damping [pu torque / pu speed] of the clutch
        (MODEL.md: 222, 0.5).
    k2, d2 : float
        Stiffness [pu torque / rad] and damping [pu torque / pu speed] of the resilient element
        (MODEL.md: 9.0, 0.02).
    sample_interval : float
        Ts of the simulated record [s] (MODEL.md: 1e-4).
    n_samples : int
        Samples of the simulated record (MODEL.md: 2048).
    event_index : int
        The sample at the event t_e (MODEL.md: 48).
    t_event_max : float
        Simulated time within which the event must occur [s] (MODEL.md: 1.0).

    Raises
    ------
    ParameterError
        A value that is not a finite number, not positive where the physics needs it, x_m not below
        x_s and x_r, both base torque and base power, a record grid that does not cover the test
        window, or a plant the simulator refuses; the message names the key and what to fix.
    """

    name: str = "MODEL.md reference plant"
    frequency: float = const.RATED_FREQUENCY
    u: float = const.U_SUPPLY
    f: float = const.F_SUPPLY
    r_s: float = const.R_S
    r_r: float = const.R_R
    x_s: float = const.X_S
    x_r: float = const.X_R
    x_m: float = const.X_M
    pole_pairs: int = const.POLE_PAIRS
    base_torque: float | None = None
    base_power: float | None = None
    J1: float = const.J1_NOMINAL
    J2: float = const.J2
    T3: float = const.T3
    r: float = const.WHEEL_RADIUS
    K: float = const.K_NOMINAL
    c: float = const.C_NOMINAL
    c1: float = const.C1_NOMINAL
    k12: float = const.K12
    d12: float = const.D12
    k2: float = const.K2
    d2: float = const.D2
    sample_interval: float = const.SAMPLE_INTERVAL
    n_samples: int = const.N_SAMPLES
    event_index: int = const.EVENT_INDEX
    t_event_max: float = const.T_EVENT_MAX

    def __post_init__(self) -> None:
        for key in _keys():
            value = getattr(self, key)
            if value is None and key in _OPTIONAL_KEYS:
                continue
            object.__setattr__(self, key, _number(key, value))
        if not isinstance(self.name, str):
            raise ParameterError(f"drive description: name must be a string, got {self.name!r}")
        self.validate()

    # -- the base values ----------------------------------------------------------------
    @property
    def w_b(self) -> float:
        """Electrical base angular frequency w_b = 2 pi frequency [rad/s]."""
        return 2.0 * math.pi * self.frequency  # MODEL.md's W_B, to the last bit, at 50 Hz

    @property
    def omega_b(self) -> float:
        """Mechanical base speed Omega_b = w_b / p [rad/s]: 1 pu of speed."""
        return self.w_b / self.pole_pairs

    @property
    def tm_per_j(self) -> float:
        """Mechanical time constant per unit inertia, Omega_b / M_b [s / (kg m^2)]."""
        if self.base_torque is not None:
            return self.omega_b / self.base_torque
        if self.base_power is not None:
            return self.omega_b**2 / self.base_power
        return const.TM_PER_J

    @property
    def torque_base(self) -> float:
        """Base torque M_b [N m]: the one given, or P_b / Omega_b, or MODEL.md's Omega_b / TM_PER_J."""
        if self.base_torque is not None:
            return self.base_torque
        if self.base_power is not None:
            return self.base_power / self.omega_b
        return self.omega_b / const.TM_PER_J

    # -- what the engine runs -----------------------------------------------------------
    def plant(self, **changes: Any) -> PlantParameters:
        """The nominal plant of this drive (MODEL.md's names), with ``changes`` applied.

        Parameters
        ----------
        **changes
            Fields of :class:`PlantParameters` to set (e.g. ``K=0.004`` [m], an effect's term).

        Returns
        -------
        PlantParameters
            Not validated when ``changes`` are given (the caller validates the case it builds).
        """
        plant = PlantParameters(
            K=self.K,
            J1=self.J1,
            J2=self.J2,
            T3=self.T3,
            c=self.c,
            c1=self.c1,
            r=self.r,
            k12=self.k12,
            d12=self.d12,
            k2=self.k2,
            d2=self.d2,
            r_s=self.r_s,
            r_r=self.r_r,
            x_s=self.x_s,
            x_r=self.x_r,
            x_m=self.x_m,
            u=self.u,
            f=self.f,
            w_b=self.w_b,
            pole_pairs=self.pole_pairs,
            tm_per_j=self.tm_per_j,
        )
        return plant.replace(**changes) if changes else plant

    def j1_grid(self) -> tuple[float, ...]:
        """The paper's J1 grid K_I scaled to this drive's nominal J1 [kg m^2] (MODEL.md's grid for the reference).

        The default inertias a pattern set of this drive is trained on: J1_GRID * J1 / 0.87, the nominal first.
        """
        if self.J1 == const.J1_NOMINAL:
            return const.J1_GRID
        return tuple(v / const.J1_NOMINAL * self.J1 for v in const.J1_GRID)  # the nominal first, exactly J1

    def k_grid(self) -> tuple[float, ...]:
        """The paper's six training widths K_GRID scaled to this drive's nominal K [m] (MODEL.md's grid, exactly, for
        a drive whose nominal K is MODEL.md's 5 mm).

        The widths a pattern set of this drive is trained on and identifies: K_GRID * K / 0.005 (2.5-10 mm about a
        nominal 5 mm become 2-8 mm about a nominal 4 mm).
        """
        if self.K == const.K_NOMINAL:
            return const.K_GRID
        return tuple(v / const.K_NOMINAL * self.K for v in const.K_GRID)

    def c_groups(self) -> tuple[float, ...]:
        """The paper's c groups C_GROUPS scaled to this drive's nominal c [pu] (MODEL.md's, exactly, for c = 1 pu or
        a drive without absorber viscosity): the groups a record's c is matched to when patterns are chosen."""
        if self.c == const.C_NOMINAL or not self.c > 0:
            return const.C_GROUPS
        return tuple(v / const.C_NOMINAL * self.c for v in const.C_GROUPS)

    def nominal_case(self) -> Case:
        """The nominal plant with a neutral measurement chain."""
        return Case(self.plant())

    def grid(self) -> SampleGrid:
        """The sample grid of this drive's records (MODEL.md: 2048 samples of 0.1 ms, the event at 48)."""
        return SampleGrid(self.sample_interval, self.n_samples, self.event_index)

    def solver(self, max_step: float | None = None) -> SolverSettings:
        """Integrator settings: RK4 steps of at most ``max_step`` [s] (default the simulator's) and this drive's
        ``t_event_max`` [s]."""
        if max_step is None:
            return SolverSettings(t_event_max=self.t_event_max)
        return SolverSettings(max_step=max_step, t_event_max=self.t_event_max)

    # -- checks ------------------------------------------------------------------------
    def validate(self) -> DriveDescription:
        """Raise :class:`ParameterError` on an impossible value; the message says what to fix."""
        for key in _POSITIVE_KEYS:
            value = getattr(self, key)
            if value is not None and not value > 0:
                raise ParameterError(f"drive description: {_where(key)} = {value} must be positive")
        for key in _NON_NEGATIVE_KEYS:
            if getattr(self, key) < 0:
                raise ParameterError(f"drive description: {_where(key)} = {getattr(self, key)} must be >= 0")
        if not (self.x_m < self.x_s and self.x_m < self.x_r):
            raise ParameterError(
                f"drive description: motor.x_m = {self.x_m} must be smaller than motor.x_s = {self.x_s} and "
                f"motor.x_r = {self.x_r}: x_s and x_r are the total reactances (magnetising plus leakage), so the "
                "leakages x_s - x_m and x_r - x_m must be positive (otherwise the inductance matrix is singular)"
            )
        if self.base_torque is not None and self.base_power is not None:
            raise ParameterError(
                "drive description: give base.base_torque [N m] or base.base_power [W], not both "
                "(M_b = P_b / Omega_b ties them)"
            )
        if self.n_samples > MAX_SAMPLES:
            raise ParameterError(
                f"drive description: protocol.n_samples = {self.n_samples} exceeds the {MAX_SAMPLES} samples a record "
                "may hold; 2048 at 0.1 ms cover the test window"
            )
        try:
            self.grid().require_test_window()
        except GridError as exc:
            raise ParameterError(f"drive description: [protocol] {exc}") from None
        try:
            self.plant().validate()
            self.solver().validate()
        except ParameterError as exc:
            raise ParameterError(f"drive description: {exc}") from None
        return self

    # -- as data -------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Every value, by section (``base`` only holds what was given); :meth:`from_mapping` reads it back."""
        out: dict[str, Any] = {"name": self.name}
        for section, keys in SECTIONS.items():
            out[section] = {k: getattr(self, k) for k in keys if getattr(self, k) is not None}
        return out

    @functools.cached_property  # computed once per description: it is frozen
    def fingerprint(self) -> str:
        """SHA-256 (hex) of the physical content: every value but ``name``, in a canonical JSON form.

        Two descriptions of the same drive have the same fingerprint whatever their names, key order
        or file format; any value that differs changes it.
        """
        content = {k: v for k, v in self.to_dict().items() if k != "name"}
        text = json.dumps(content, sort_keys=True, separators=(",", ":"), allow_nan=False)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()

    @functools.cached_property
    def is_reference(self) -> bool:
        """Whether this is MODEL.md's reference plant (the same fingerprint)."""
        return self.fingerprint == REFERENCE_DRIVE.fingerprint

    @staticmethod
    def fingerprint_of(provenance: Mapping[str, Any] | None) -> str:
        """The fingerprint in a stored :meth:`provenance` (a record's, a pattern set's); the reference's when None.

        Everything stored before drive descriptions existed was made on the reference plant.
        """
        if provenance is None:
            return REFERENCE_DRIVE.fingerprint
        return str(provenance["fingerprint"])

    def provenance(self) -> dict[str, Any]:
        """What a record, pattern set or diagnosis stores of the drive: its fingerprint and its description."""
        return {"fingerprint": self.fingerprint, "description": self.to_dict()}

    @classmethod
    def from_provenance(cls, provenance: Mapping[str, Any]) -> DriveDescription:
        """The description a stored :meth:`provenance` holds (a record's, a run's), checked against its fingerprint.

        Raises
        ------
        ParameterError
            No description, one the engine refuses, or one that does not give the stated fingerprint (an
            edited file); the message says which.
        """
        description = provenance.get("description") if isinstance(provenance, Mapping) else None
        if not isinstance(description, Mapping):
            raise ParameterError("the drive provenance holds no description (only its fingerprint)")
        drive = cls.from_mapping(description)
        if drive.fingerprint != cls.fingerprint_of(provenance):
            raise ParameterError(
                f"the drive description gives fingerprint {drive.fingerprint[:12]}, not the stated "
                f"{str(provenance.get('fingerprint'))[:12]}: was it edited? Give the drive's own description"
            )
        return drive

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> DriveDescription:
        """A description from its sections (a parsed TOML or JSON document).

        Parameters
        ----------
        data : mapping
            ``name`` and the sections of :data:`SECTIONS`, each a mapping of its keys to values in
            the units of :class:`DriveDescription`; everything is optional.

        Raises
        ------
        ParameterError
            Not a mapping, an unknown section or key (the message lists the known ones), or an
            impossible value.
        """
        if not isinstance(data, Mapping):
            raise ParameterError(f"a drive description must be a table of sections, got {type(data).__name__}")
        values: dict[str, Any] = {}
        for section, content in data.items():
            if section == "name":
                values["name"] = content
                continue
            if section not in SECTIONS:
                known = ", ".join(["name", *SECTIONS])
                raise ParameterError(f"drive description: unknown section {section!r}; known sections: {known}")
            if not isinstance(content, Mapping):
                raise ParameterError(f"drive description: [{section}] must be a table of keys, got {content!r}")
            unknown = sorted(set(content) - set(SECTIONS[section]))
            if unknown:
                raise ParameterError(
                    f"drive description: unknown key(s) {unknown} in [{section}]; known: {', '.join(SECTIONS[section])}"
                )
            values.update(content)
        description = cls(**values)
        logger.debug("drive description %r (%s)", description.name, description.fingerprint[:12])
        return description


def parse_drive(text: str, fmt: str) -> DriveDescription:
    """A description from TOML or JSON text.

    Parameters
    ----------
    text : str
        The document.
    fmt : {"toml", "json"}
        Its format.

    Raises
    ------
    ParameterError
        Malformed text, an unknown format, or a description :meth:`DriveDescription.from_mapping` refuses.
    """
    try:
        if fmt == "toml":
            data: Any = tomllib.loads(text)
        elif fmt == "json":
            data = json.loads(text, parse_constant=_reject_constant)
        else:
            raise ParameterError(f"a drive description is TOML or JSON, not {fmt!r}")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ParameterError(f"drive description: malformed {fmt.upper()}: {exc}") from None
    return DriveDescription.from_mapping(data)


def load_drive(path: str | Path) -> DriveDescription:
    """A description from a ``.toml`` or ``.json`` file.

    Raises
    ------
    ParameterError
        Another extension, an unreadable file, or a description :func:`parse_drive` refuses; the
        message names the file.
    """
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in ("toml", "json"):
        raise ParameterError(f"drive description {path}: the file must end in .toml or .json")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise ParameterError(f"cannot read drive description {path}: {exc.strerror or exc}") from None
    try:
        return parse_drive(text, fmt)
    except ParameterError as exc:
        raise ParameterError(f"{path}: {exc}") from None


def _keys() -> tuple[str, ...]:
    return tuple(f.name for f in fields(DriveDescription) if f.name != "name")


def _where(key: str) -> str:
    """``section.key`` of a key."""
    return next(f"{s}.{key}" for s, keys in SECTIONS.items() if key in keys)


def _number(key: str, value: Any) -> float | int:
    """A finite number for ``key`` (a whole number for the integer keys); refused with a message otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError(f"drive description: {_where(key)} must be a number, got {value!r}")
    if isinstance(value, int) and abs(value) > 2**53:  # beyond exact floats (and beyond any physical count)
        raise ParameterError(f"drive description: {_where(key)} = {value} is far too large")
    if not math.isfinite(value):
        raise ParameterError(f"drive description: {_where(key)} must be finite, got {value!r}")
    if key in _INTEGER_KEYS:
        if value != int(value):
            raise ParameterError(f"drive description: {_where(key)} must be a whole number, got {value!r}")
        return int(value)
    return float(value)


def _reject_constant(token: str) -> float:
    raise ParameterError(f"drive description: {token} is not a number JSON allows")


#: MODEL.md's reference plant.
REFERENCE_DRIVE: Final[DriveDescription] = DriveDescription()
