"""A plant from the user's own simulator: an FMI 2.0 FMU (co-simulation or model exchange) and a short description (issue 55).

:func:`load_plant` reads a TOML description (:mod:`engine.plants.fmu.description`) and returns an
:class:`FmuPlant`, a plant of :mod:`engine.plants.base` that the diagnosis reads as any other.
The FMU is run through FMPy (:mod:`engine.plants.fmu.runner`); an FMU given as C sources of the
project's framework (``engine/plants/fmu/c``) is built with the system C compiler on load
(:mod:`engine.plants.fmu.build`). ``examples/`` holds two worked examples the tests build: MODEL.md's
backlash drive and a quarter-car suspension on a test rig.
"""

from __future__ import annotations

from pathlib import Path

from engine.plants.fmu.description import DescriptionError, PlantDescription, load_description
from engine.plants.fmu.plant import FmuPlant, load_plant
from engine.plants.fmu.runner import FmuSimulationError

__all__ = [
    "EXAMPLES_DIR",
    "DescriptionError",
    "FmuPlant",
    "FmuSimulationError",
    "PlantDescription",
    "load_description",
    "load_plant",
]

#: The worked examples' folders (each a source FMU with its ``plant.toml``).
EXAMPLES_DIR: Path = Path(__file__).parent / "examples"
