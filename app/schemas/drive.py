"""The ``drive`` object of a request and of an answer: a drive description (engine.simulation.drive).

The schema states the description's sections and keys (each a number); whether the values are possible is the
engine's to say (:class:`engine.simulation.drive.DriveDescription`, 422 with its message).
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, Field

from engine.simulation.drive import SECTIONS

_DRIVE_DOC = (
    "A description of the user's own drive (docs/drive-description.md): sections supply, motor, base, mechanics "
    "and protocol of MODEL.md's parameters by the project's names, the base values that convert per unit to SI and "
    "the test protocol where it differs; every key left out keeps MODEL.md's value. The records are simulated on "
    "this drive's nominal plant (K, J1, c, c1 of the request override its nominal values) and its protocol's grid, "
    "and carry its fingerprint and content."
)


def _drive_schema() -> dict[str, Any]:
    """Every section with its keys, unknown ones refused (by the engine, with the list of the known ones)."""
    sections: dict[str, Any] = {
        section: {"type": "object", "properties": {k: {"type": "number"} for k in keys}, "additionalProperties": False}
        for section, keys in SECTIONS.items()
    }
    return {"properties": {"name": {"type": "string"}, **sections}, "additionalProperties": False}


#: A request's drive description: a JSON object of sections (checked by the engine).
DriveIn = Annotated[dict[str, Any], Field(description=_DRIVE_DOC, json_schema_extra=_drive_schema())]


class DrivePublic(BaseModel):
    """The drive a record was simulated on, kept with it."""

    fingerprint: str = Field(description="SHA-256 of the description's values (its name left out).")
    description: dict[str, Any] = Field(description="Every value of the description, by section.")


__all__ = ["DriveIn", "DrivePublic"]
