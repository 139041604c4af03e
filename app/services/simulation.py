"""Simulation for the service: request values -> engine cases -> records, rendered as a bench gives them.

Everything physical happens in :mod:`engine.simulation`; this module only builds
``Case`` objects from the request's flat values, calls ``simulate_batch``
(which is safe to call from request threads and training threads at once) on
the requested sample grid, and dresses the records the way a test bench hands
them over (:class:`Rendering`): measurement noise, the conditions the bench
states, a subset of channels, units, and whether the event index is given.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from app.services.errors import InvalidInputError
from engine.constants import POST_EVENT_TIME, PRE_EVENT_TIME, SAMPLE_INTERVAL
from engine.records import PROTOCOL_GRID, GridError, ProtocolError, Record, SampleGrid
from engine.records.units import BASE_TORQUE
from engine.simulation import (
    CATALOGUE,
    HELD_BACK,
    Case,
    ParameterError,
    SimulationResult,
    SolverSettings,
    add_white_noise,
    apply_effects,
    simulate_batch,
)
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.simulation.simulator import DEFAULT_SOLVER

logger = logging.getLogger(__name__)

#: Most samples per channel one call may render, summed over its cases (bounds the answer's size:
#: about 100 bytes of JSON per sample of five channels). MODEL.md's grid is 2048 per case.
MAX_RENDERED_SAMPLES: int = 1_000_000


@dataclass(frozen=True)
class Rendering:
    """How simulated records are rendered, the ways a test bench gives them.

    Attributes
    ----------
    sample_interval : float
        Ts [s], 10 us to 1 ms.
    before, after : float
        Time rendered before the event and from it on [s] (defaults: MODEL.md's test
        window, 4.8 ms and 200 ms).
    units : mapping of str to str
        Unit per channel the record is written in (:data:`engine.records.UNITS`); the
        others in their model units.
    channels : sequence of str or None
        Channels to keep (default all five).
    include_event_index : bool
        Whether the written record states its event index; ``False`` leaves it out, so a
        reader has to locate the event from the data.
    snr_db : float or None
        White measurement noise at this SNR [dB] on every channel (none when ``None``).
    seed : int
        Seed of the noise (one generator for all records of a call, in order).
    known : collection of str or None
        Conditions (of K, J1, c, c1) the record states; ``None`` = all of them.
    base_torque : float or None
        The motor's base torque [N*m], stated in the conditions (needed for m_el in N*m).
    """

    sample_interval: float = SAMPLE_INTERVAL
    before: float = PRE_EVENT_TIME
    after: float = POST_EVENT_TIME
    units: Mapping[str, str] = field(default_factory=dict)
    channels: Sequence[str] | None = None
    include_event_index: bool = True
    snr_db: float | None = None
    seed: int = 0
    known: Collection[str] | None = None
    base_torque: float | None = None

    def grid(self) -> SampleGrid:
        """The sample grid of the rendered records (:meth:`SampleGrid.around_event`).

        Raises
        ------
        ProtocolError
            Sample interval outside 10 us - 1 ms, or a span that does not cover the test
            window (the engine's message says how much is missing).
        """
        try:
            grid = SampleGrid.around_event(self.sample_interval, self.before, self.after)
            grid.require_test_window()
            return grid
        except GridError as exc:
            raise ProtocolError(str(exc)) from None


def make_case(
    K: float | None,
    J1: float | None = None,
    c: float | None = None,
    c1: float | None = None,
    drive: DriveDescription | None = None,
) -> Case:
    """A case with the given K [m], J1 [kg m^2], c [pu] and c1 [pu], the rest the drive's nominal values.

    Without ``drive``, the reference plant (MODEL.md's values; ``K`` is then required). With it, every value not
    given (``K`` included) is the description's (:meth:`DriveDescription.plant`).

    Raises
    ------
    engine.simulation.ParameterError
        No ``K`` without a drive (the message says to give one).
    """
    given = {k: float(v) for k, v in {"K": K, "J1": J1, "c": c, "c1": c1}.items() if v is not None}
    if drive is None:
        if K is None:
            raise ParameterError("give the backlash width K [m] (or a drive description, whose K is the default)")
        return Case.from_overrides(given)
    return Case(drive.plant(**given))


def check_units(units: Mapping[str, str], drive: DriveDescription | None) -> None:
    """Refuse a channel in a unit whose base is MODEL.md's rather than the described drive's: omega1 in pu.

    Raises
    ------
    InvalidInputError
        omega1 in ``pu`` with a drive other than the reference plant (the unit table converts it with
        MODEL.md's 157.08 rad/s, :mod:`engine.records.units`).
    """
    if drive is not None and not drive.is_reference and units.get("omega1") == "pu":
        raise InvalidInputError(
            "omega1 in pu is converted with MODEL.md's base speed (157.08 rad/s), not the described drive's "
            f"({drive.omega_b:.6g} rad/s): give omega1 in rad/s or rpm"
        )


def drive_of(data: Mapping[str, Any] | None) -> DriveDescription | None:
    """The drive description of a request's ``drive`` object (None when absent).

    Raises
    ------
    engine.simulation.ParameterError
        A description the engine refuses; the message names the key and what to fix.
    """
    return None if data is None else DriveDescription.from_mapping(data)


def drive_from_query(text: str | None) -> DriveDescription | None:
    """The CSV form's ``drive`` query parameter: a drive description as a JSON object (None when absent).

    Raises
    ------
    InvalidInputError
        Not a JSON object (a fingerprint alone, say): the message says what to give.
    engine.simulation.ParameterError
        A description the engine refuses; the message names the key and what to fix.
    """
    if text is None:
        return None
    try:
        data = json.loads(text)
    except ValueError:
        data = None
    if not isinstance(data, dict):
        raise InvalidInputError(
            "query parameter drive: give the drive description itself as a JSON object (URL-encoded), with the "
            "sections of its TOML file (docs/drive-description.md), not a fingerprint or a file name"
        )
    return drive_of(data)


def record_interval(drive: DriveDescription | None) -> float | None:
    """The sample interval [s] of a record read for ``drive`` that gives neither ``sample_interval`` nor ``t``.

    The drive's protocol interval (``drive.grid().sample_interval``); None without a drive, which the record
    readers take as MODEL.md's 0.1 ms.
    """
    return None if drive is None else drive.grid().sample_interval


def protocol_span(drive: DriveDescription | None) -> dict[str, float]:
    """The rendering's ``sample_interval`` [s], ``before`` [s] and ``after`` [s] of a drive's test protocol.

    MODEL.md's (0.1 ms, 4.8 ms, 200 ms) without a drive: the reference description's protocol.
    """
    grid = (drive or REFERENCE_DRIVE).grid()
    ts, e = grid.sample_interval, grid.event_index
    return {"sample_interval": ts, "before": e * ts, "after": (grid.n_samples - e) * ts}


#: Effects a simulation request may name: the catalogue and the held-back family of model 1.1.
SIMULATED_EFFECTS = CATALOGUE + HELD_BACK


def prepare(cases: Sequence[Case], effects: Sequence[Mapping[str, float] | None]) -> list[Case]:
    """Apply each case's effects and validate it, without simulating.

    Effects are those of the catalogue and the held-back family (:data:`SIMULATED_EFFECTS`), so users
    can render records with effects the diagnosis does not know. Raises ``ParameterError`` /
    ``UnknownEffectError`` (with the engine's message) on out-of-range values or unknown effect names.
    """
    if len(cases) != len(effects):
        raise ValueError(f"got {len(effects)} effect mappings for {len(cases)} cases")
    # each case is checked before its effects too: a value out of its range stays refused when an effect would
    # overwrite it (the schema states the ranges of both)
    return [
        apply_effects(case.validate(), eff or {}, SIMULATED_EFFECTS).validate()
        for case, eff in zip(cases, effects, strict=True)
    ]


def run(
    cases: Sequence[Case], grid: SampleGrid = PROTOCOL_GRID, solver: SolverSettings = DEFAULT_SOLVER
) -> SimulationResult:
    """Simulate prepared cases (see :func:`prepare`) on ``grid`` with ``solver``.

    Raises ``SimulationError`` for cases without an event.
    """
    return simulate_batch(list(cases), grid=grid, solver=solver)


def render(
    cases: Sequence[Case], rendering: Rendering | None = None, drive: DriveDescription | None = None
) -> list[Record]:
    """Simulate prepared cases and render their records as ``rendering`` says.

    Parameters
    ----------
    cases : sequence of Case
        Prepared cases (:func:`prepare`).
    rendering : Rendering, optional
        Default: MODEL.md's grid, all channels in model units, no noise.
    drive : DriveDescription, optional
        The drive the cases were built from (:func:`make_case`): its ``t_event_max`` [s] bounds the
        simulated time, and its base torque [N m] is stated in the records' conditions unless the
        rendering states one.

    Returns
    -------
    list of Record
        One per case, in order; noise is added in model units before any unit is applied
        (units only change how the record is written).

    Raises
    ------
    ProtocolError
        A grid that cannot hold the test (interval out of range, less than 4.8 ms before or
        200 ms after the event).
    InvalidInputError
        More than :data:`MAX_RENDERED_SAMPLES` samples per channel in all.
    engine.records.RecordError
        An unknown unit, or units for a channel not kept.
    """
    r = Rendering() if rendering is None else rendering
    grid = r.grid()
    check_units(r.units, drive)
    if drive is not None and r.base_torque is None:
        r = replace(r, base_torque=drive.torque_base)
    total = grid.n_samples * len(cases)
    if total > MAX_RENDERED_SAMPLES:
        raise InvalidInputError(
            f"{len(cases)} case(s) of {grid.n_samples} samples each ({grid.sample_interval:g} s from "
            f"{r.before:g} s before the event to {r.after:g} s after it) make {total} samples per channel; at most "
            f"{MAX_RENDERED_SAMPLES} are rendered per request: shorten the span, lengthen the interval or split the cases"
        )
    records = run(cases, grid, DEFAULT_SOLVER if drive is None else drive.solver()).records
    rng = np.random.default_rng(r.seed)
    return [_dress(record, r, rng) for record in records]


def _dress(record: Record, r: Rendering, rng: np.random.Generator) -> Record:
    """One simulated record with noise, stated conditions, kept channels and units."""
    channels: dict[str, np.ndarray] = dict(record.channels)
    if r.snr_db is not None:  # in model units, on every channel (the kept ones get the same noise whatever is kept)
        channels = {k: add_white_noise(v, r.snr_db, rng) for k, v in channels.items()}
    if r.channels is not None:
        keep = set(r.channels)
        channels = {k: v for k, v in channels.items() if k in keep}
    conditions = dict(record.conditions)
    if r.known is not None:
        conditions = {k: v for k, v in conditions.items() if k in r.known}
    if r.base_torque is not None:
        conditions[BASE_TORQUE] = r.base_torque
    return record.replace(channels=channels, conditions=conditions, units=dict(r.units))


def to_public(
    record: Record, rendering: Rendering | None = None, drive: DriveDescription | None = None
) -> dict[str, Any]:
    """A rendered record in the JSON record format, without ``event_index`` when the rendering leaves it out.

    With ``drive``, the record carries ``drive``: the description's fingerprint and content
    (:meth:`DriveDescription.provenance`), so that where it came from is kept with it.
    """
    out = record.to_dict()
    if rendering is not None and not rendering.include_event_index:
        out.pop("event_index", None)
    if drive is not None:
        out["drive"] = drive.provenance()
    return out


__all__ = [
    "MAX_RENDERED_SAMPLES",
    "Rendering",
    "check_units",
    "drive_of",
    "make_case",
    "prepare",
    "protocol_span",
    "render",
    "run",
    "to_public",
]
