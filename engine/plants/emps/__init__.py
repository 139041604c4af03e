"""The EMPS benchmark as a plant: a real electro-mechanical positioning axis in its PD loop.

Data and reference model: A. Janot, M. Gautier, M. Brunot, "Data Set and Reference Models of
EMPS" (ONERA / LS2N), a nonlinear system identification benchmark; the two records ship in
``engine/plants/emps/data/`` with that citation.
"""

from engine.plants.emps.catalogue import CATALOGUE, HELD_BACK, LOCI, SEALED
from engine.plants.emps.model import CALIBRATED, CHANNELS, ENTRIES, PUBLISHED, EmpsParameters, EmpsPlant
from engine.plants.emps.record import EmpsRecord, load_csv, load_mat, load_record

__all__ = [
    "CALIBRATED",
    "CATALOGUE",
    "CHANNELS",
    "ENTRIES",
    "HELD_BACK",
    "LOCI",
    "PUBLISHED",
    "SEALED",
    "EmpsParameters",
    "EmpsPlant",
    "EmpsRecord",
    "load_csv",
    "load_mat",
    "load_record",
]
