"""Plants the gap diagnosis can work on, behind one interface (:mod:`engine.plants.base`).

``backlash_drive`` is the reference plant of MODEL.md; ``emps`` is the EMPS benchmark's
positioning axis, real measurements (:mod:`engine.plants.emps`); ``brfd`` a friction damper with
a real play, real measurements (:mod:`engine.plants.brfd`).
"""

from __future__ import annotations

from collections.abc import Callable

from engine.plants.base import CalibratedParameter, CandidateEffect, Channel, Plant, relative_error

__all__ = [
    "DEFAULT_PLANT",
    "PLANTS",
    "CalibratedParameter",
    "CandidateEffect",
    "Channel",
    "Plant",
    "get_plant",
    "is_description",
    "relative_error",
]

#: The plant a request names when it names none.
DEFAULT_PLANT: str = "backlash_drive"


def _backlash_drive() -> Plant:
    from engine.plants.backlash_drive import BacklashDrivePlant

    return BacklashDrivePlant()


def _brfd() -> Plant:
    from engine.plants.brfd import BrfdPlant

    return BrfdPlant()


def _emps() -> Plant:
    from engine.plants.emps import EmpsPlant

    return EmpsPlant()


#: Registry: plant name -> constructor (imported lazily, so one plant's kernel is compiled only when used).
PLANTS: dict[str, Callable[[], Plant]] = {"backlash_drive": _backlash_drive, "brfd": _brfd, "emps": _emps}


def is_description(name: str) -> bool:
    """Whether ``name`` names a plant description file (a ``.toml`` path) rather than a registered plant."""
    return name.lower().endswith(".toml")


def get_plant(name: str) -> Plant:
    """The plant registered as ``name``, or the plant a description file ``name`` (``*.toml``) describes.

    A description is a plant from the user's own simulator, an FMU (:mod:`engine.plants.fmu`).

    Raises
    ------
    KeyError
        For an unknown name, listing the known ones.
    engine.plants.fmu.DescriptionError
        For a description (or its FMU) the plant cannot use, saying what to fix.
    """
    if is_description(name):
        from engine.plants.fmu import load_plant

        return load_plant(name)
    try:
        return PLANTS[name]()
    except KeyError:
        raise KeyError(f"unknown plant {name!r}; known plants: {', '.join(PLANTS)}") from None
