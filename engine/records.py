"""The backlash-test record: the data every part of the engine exchanges.

A record holds up to five channels of ``N_SAMPLES`` samples taken every
``sample_interval`` seconds, with sample ``event_index`` at the event t_e
(MODEL.md section 2). It is the in-memory form of the service's JSON record
format (issue 3): ``{"sample_interval", "event_index", "channels", "conditions"}``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from engine.constants import CHANNELS, EVENT_INDEX, N_SAMPLES, SAMPLE_INTERVAL


class RecordError(ValueError):
    """Raised when a record is malformed; the message says what to fix."""


class ProtocolError(RecordError):
    """Raised when a well-formed record is not in the test protocol the code reads (MODEL.md section 2)."""


def require_test_protocol(record: Record, what: str) -> None:
    """Refuse a record whose time grid is not MODEL.md's, rather than misread it.

    Simulations, pattern sets and the calibration all produce records of
    ``N_SAMPLES`` samples every ``SAMPLE_INTERVAL`` with the event at sample
    ``EVENT_INDEX``; a record on another grid would be compared sample by sample
    with the wrong instants.

    Parameters
    ----------
    record : Record
        The record to be read.
    what : str
        What would read it (for the message), e.g. ``"the gap diagnosis"``.

    Raises
    ------
    ProtocolError
        ``sample_interval`` differs from ``SAMPLE_INTERVAL`` [s] (relative 1e-9) or
        ``event_index`` from ``EVENT_INDEX``; the message says what the record has.
    """
    if not math.isclose(record.sample_interval, SAMPLE_INTERVAL, rel_tol=1e-9) or record.event_index != EVENT_INDEX:
        raise ProtocolError(
            f"{what} reads records of the backlash test as MODEL.md section 2 defines them: sample_interval "
            f"{SAMPLE_INTERVAL} s, event_index {EVENT_INDEX}; this record has sample_interval "
            f"{record.sample_interval} s and event_index {record.event_index}: resample or realign it"
        )


@dataclass(frozen=True)
class Record:
    """One backlash-test record.

    Parameters
    ----------
    channels : mapping of str to ndarray
        Non-empty subset of ``CHANNELS`` (a1 [m/s^2], m_el [pu], omega1 [rad/s],
        a2 [m/s^2], v2 [m/s]); each a 1-D float array of ``N_SAMPLES`` finite values.
    sample_interval : float
        Ts [s].
    event_index : int
        Index of the sample taken at the event t_e.
    conditions : mapping of str to float
        What is known about the operating point (e.g. ``J1`` [kg m^2], ``c`` [pu],
        ``c1`` [pu], ``K`` [m]); only what is known.
    event_time : float or None
        t_e [s] since the motor was switched on, when known (simulated records).
    """

    channels: Mapping[str, np.ndarray]
    sample_interval: float = SAMPLE_INTERVAL
    event_index: int = EVENT_INDEX
    conditions: Mapping[str, float] = field(default_factory=dict)
    event_time: float | None = None

    def __post_init__(self) -> None:
        if not self.channels:
            raise RecordError("a record needs at least one channel; known channels: " + ", ".join(CHANNELS))
        clean: dict[str, np.ndarray] = {}
        for name, values in self.channels.items():
            if name not in CHANNELS:
                raise RecordError(f"unknown channel {name!r}; known channels: {', '.join(CHANNELS)}")
            arr = np.asarray(values, dtype=float)
            if arr.ndim != 1 or arr.shape[0] != N_SAMPLES:
                raise RecordError(f"channel {name!r} has shape {arr.shape}; it must hold exactly {N_SAMPLES} samples")
            if not np.all(np.isfinite(arr)):
                bad = int(np.flatnonzero(~np.isfinite(arr))[0])
                raise RecordError(f"channel {name!r} holds a non-finite value (NaN or inf) at sample {bad}")
            arr = arr.copy()
            arr.flags.writeable = False
            clean[name] = arr
        # canonical channel order
        object.__setattr__(self, "channels", {c: clean[c] for c in CHANNELS if c in clean})
        if not (np.isfinite(self.sample_interval) and self.sample_interval > 0):
            raise RecordError(f"sample_interval must be a positive number of seconds, got {self.sample_interval}")
        if not (0 <= int(self.event_index) < N_SAMPLES):
            raise RecordError(f"event_index must lie in [0, {N_SAMPLES - 1}], got {self.event_index}")
        object.__setattr__(self, "event_index", int(self.event_index))
        object.__setattr__(self, "conditions", {k: float(v) for k, v in dict(self.conditions).items()})

    @property
    def time(self) -> np.ndarray:
        """Sample times relative to the event, t - t_e [s]."""
        return (np.arange(N_SAMPLES) - self.event_index) * self.sample_interval

    def __getitem__(self, channel: str) -> np.ndarray:
        try:
            return self.channels[channel]
        except KeyError:
            raise RecordError(
                f"channel {channel!r} is not in this record; it holds: {', '.join(self.channels)}"
            ) from None

    def to_dict(self) -> dict:
        """JSON-ready dict in the service's record format."""
        out: dict = {
            "sample_interval": self.sample_interval,
            "event_index": self.event_index,
            "channels": {k: v.tolist() for k, v in self.channels.items()},
            "conditions": dict(self.conditions),
        }
        if self.event_time is not None:
            out["event_time"] = self.event_time
        return out

    @classmethod
    def from_dict(cls, data: Mapping) -> Record:
        """Build a record from the service's JSON record format."""
        if "channels" not in data:
            raise RecordError("a record needs a 'channels' object mapping channel names to sample lists")
        return cls(
            channels=dict(data["channels"]),
            sample_interval=float(data.get("sample_interval", SAMPLE_INTERVAL)),
            event_index=int(data.get("event_index", EVENT_INDEX)),
            conditions=dict(data.get("conditions") or {}),
            event_time=data.get("event_time"),
        )
