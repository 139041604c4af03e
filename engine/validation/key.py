"""The answer key of a protocol-v2 validation: the truth about every case, read only by the scorer."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.validation.protocol import operating_range

__all__ = ["EXPECTED_STATUS", "KeyEntry", "TrueEffect", "on_operating_range"]

#: The answer the diagnosis should give, per case kind.
EXPECTED_STATUS: dict[str, str] = {
    "single": "explained",
    "pair": "explained",
    "triple": "explained",
    "held_back": "unexplained",
    "clean": "no_gap",
}


def on_operating_range(K: float, J1: float, c: float, drive: DriveDescription = REFERENCE_DRIVE) -> bool:
    """Whether an operating point lies in a drive's operating range.

    Parameters
    ----------
    K : float
        Backlash zone width [m].
    J1 : float
        Motor-side inertia [kg m^2].
    c : float
        Apparent viscosity of the absorber [pu].
    drive : DriveDescription
        The drive (default MODEL.md's reference plant, whose range is
        :data:`engine.constants.OPERATING_RANGE`; :func:`engine.validation.protocol.operating_range`).
    """
    box = operating_range(drive)
    point = {"K": K, "J1": J1, "c": c}
    return all(box[k][0] <= v <= box[k][1] for k, v in point.items())


@dataclass(frozen=True)
class TrueEffect:
    """One effect put into a case.

    Attributes
    ----------
    name : str
        Effect name (in the catalogue, or in the held-back family).
    value : float
        Its value, in ``unit``.
    unit : str
        Unit of the value.
    locus : str
        Where it acts (one of :data:`engine.simulation.LOCI`).
    strength : float
        Largest RMS change of a recorded channel it causes on its own (noiseless record with it
        alone minus the record without any effect), in noise standard deviations.
    strength_in_set : float
        The same for the record with every effect of the case minus the record with the others
        (equal to ``strength`` for a single effect).
    strength_refit : float
        The same for the record with every effect minus the best local refit of the model
        without this one (K, J1, c and the case's other effects refitted; the absorption rule,
        :func:`engine.validation.cases.absorbed_strength`); NaN in keys written before the rule.
    """

    name: str
    value: float
    unit: str
    locus: str
    strength: float
    strength_in_set: float
    strength_refit: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {
            "name": self.name,
            "value": self.value,
            "unit": self.unit,
            "locus": self.locus,
            "strength": round(self.strength, 3),
            "strength_in_set": round(self.strength_in_set, 3),
            "strength_refit": round(self.strength_refit, 3) if math.isfinite(self.strength_refit) else None,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrueEffect:
        return cls(
            str(d["name"]),
            float(d["value"]),
            str(d["unit"]),
            str(d["locus"]),
            float(d["strength"]),
            float(d["strength_in_set"]),
            float(d["strength_refit"]) if d.get("strength_refit") is not None else math.nan,
        )


@dataclass(frozen=True)
class KeyEntry:
    """The truth about one case.

    Attributes
    ----------
    case_id : str
        The case (its record is ``cases/<case_id>.json``).
    kind : {"single", "pair", "triple", "held_back", "clean"}
        What the case holds.
    effects : tuple of TrueEffect
        The effects in the record (none for a clean case).
    K, J1, c : float
        Operating point [m], [kg m^2], [pu] (unknown to the diagnosis; c1 is the record's condition).
    channels : tuple of str
        The recorded channels.
    noise : dict
        :meth:`engine.validation.noise.NoiseSpec.to_dict`: colour, low-pass order and cut-off [Hz],
        SNR per channel [dB].
    draws : int
        Draws it took to make every effect strong enough (1: the first draw).
    on_range : bool or None
        Whether the operating point lies in the operating range of the drive the case was simulated
        on (:func:`on_operating_range`, decided when the case is drawn); None: the reference
        drive's range, decided from K, J1, c.
    """

    case_id: str
    kind: str
    effects: tuple[TrueEffect, ...]
    K: float
    J1: float
    c: float
    channels: tuple[str, ...]
    noise: dict[str, Any]
    draws: int = 1
    on_range: bool | None = None

    @property
    def expected_status(self) -> str:
        """The answer the diagnosis should give."""
        return EXPECTED_STATUS[self.kind]

    @property
    def effect_names(self) -> tuple[str, ...]:
        """Names of the effects in the record."""
        return tuple(e.name for e in self.effects)

    @property
    def on_box(self) -> bool:
        """Whether the operating point lies in the operating range of the case's drive (:attr:`on_range`)."""
        return on_operating_range(self.K, self.J1, self.c) if self.on_range is None else self.on_range

    @property
    def colour(self) -> str:
        """``white`` or ``coloured`` noise."""
        return str(self.noise["colour"])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {
            "case_id": self.case_id,
            "kind": self.kind,
            "expected_status": self.expected_status,
            "effects": [e.to_dict() for e in self.effects],
            "K": self.K,
            "J1": self.J1,
            "c": self.c,
            "on_operating_range": self.on_box,
            "channels": list(self.channels),
            "noise": self.noise,
            "draws": self.draws,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> KeyEntry:
        return cls(
            case_id=str(d["case_id"]),
            kind=str(d["kind"]),
            effects=tuple(TrueEffect.from_dict(e) for e in d["effects"]),
            K=float(d["K"]),
            J1=float(d["J1"]),
            c=float(d["c"]),
            channels=tuple(d["channels"]),
            noise=dict(d["noise"]),
            draws=int(d.get("draws", 1)),
            on_range=bool(d["on_operating_range"]) if d.get("on_operating_range") is not None else None,
        )
