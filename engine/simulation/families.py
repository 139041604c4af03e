"""The families of effects outside the catalogue, by name, for blind runs and their scorers.

A protocol-2 run hides one family from the diagnosis and draws its held-back cases from it
(``backlash validate --held-back NAME``):

* ``held_back``: :data:`~engine.simulation.held_back.HELD_BACK` (model 1.1), the default; developed
  on since issue 10, so its figures are in-family ones.
* ``development``: :data:`~engine.simulation.development.DEVELOPMENT`, the held-back five and
  three parameter drifts; open to development of the open-world step.
* ``held_out``: :data:`~engine.simulation.held_out.HELD_OUT` (model 1.2), kept for scoring (its
  rule: :data:`~engine.simulation.held_out.RULE`); its figures are the out-of-sample ones.
* ``sealed``: :data:`~engine.simulation.sealed.SEALED` (model 1.3), kept for scoring (its rule:
  :data:`~engine.simulation.sealed.RULE`); its one blind run (seed 257) is published, so it is
  spent: development data since.
* ``sealed2``: :data:`~engine.simulation.sealed2.SEALED2` (model 1.4), kept for scoring (its rule:
  :data:`~engine.simulation.sealed2.RULE`); its one blind run (seed 263) is published, so it is
  spent: development data since.
* ``sealed3``: :data:`~engine.simulation.sealed3.SEALED3` (model 1.5), kept for scoring (its rule:
  :data:`~engine.simulation.sealed3.RULE`); its one blind run (seed 269, code ada3284) is published,
  so it is spent: development data since.
* ``sealed4``: :data:`~engine.simulation.sealed4.SEALED4` (model 1.6), kept for scoring (its rule:
  :data:`~engine.simulation.sealed4.RULE`); scored once, blind (seed 281, code 55d4a47), its figures
  published: spent, development data since.
* ``sealed5``: :data:`~engine.simulation.sealed5.SEALED5` (model 1.7), kept for scoring (its rule:
  :data:`~engine.simulation.sealed5.RULE`); scored once, blind (seed 283, code 00d9c2c), its figures
  published: spent, development data since.
"""

from __future__ import annotations

from engine.simulation.development import DEVELOPMENT
from engine.simulation.effects import CATALOGUE, EffectLibrary
from engine.simulation.held_back import HELD_BACK
from engine.simulation.held_out import HELD_OUT
from engine.simulation.sealed import SEALED
from engine.simulation.sealed2 import SEALED2
from engine.simulation.sealed3 import SEALED3
from engine.simulation.sealed4 import SEALED4
from engine.simulation.sealed5 import SEALED5

__all__ = ["DEFAULT_FAMILY", "FAMILIES", "locus_of"]

#: Every family outside the catalogue, by the name a run is given.
FAMILIES: dict[str, EffectLibrary] = {
    "held_back": HELD_BACK,
    "development": DEVELOPMENT,
    "held_out": HELD_OUT,
    "sealed": SEALED,
    "sealed2": SEALED2,
    "sealed3": SEALED3,
    "sealed4": SEALED4,
    "sealed5": SEALED5,
}
#: The family a run hides unless told otherwise.
DEFAULT_FAMILY: str = "held_back"


def locus_of(name: str) -> str | None:
    """The locus of an effect of the catalogue or of any family (None for an unknown name)."""
    for library in (CATALOGUE, *FAMILIES.values()):
        if name in library:
            return str(library[name].locus)
    return None
