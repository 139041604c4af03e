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


def get_plant(name: str) -> Plant:
    """The plant registered as ``name``.

    Raises
    ------
    KeyError
        For an unknown name, listing the known ones.
    """
    try:
        return PLANTS[name]()
    except KeyError:
        raise KeyError(f"unknown plant {name!r}; known plants: {', '.join(PLANTS)}") from None
