"""The BRFD as a plant: a 20 kN banded rotary friction damper with a play, real measurements.

Data: D. Coble, P. Huggins, L. Cao, J. Ricles, A. Downey, "Dataset-Friction-Damper-with-Backlash"
(ARTS Lab, University of South Carolina, 2022), CC BY-SA 4.0; the device: A. Downey et al., "High
capacity variable friction damper based on band brake technology", Engineering Structures 113
(2016) 287-298. Three records ship in ``engine/plants/brfd/data/`` with that citation and licence.
"""

from engine.plants.brfd.catalogue import CATALOGUE, LOCI
from engine.plants.brfd.model import CALIBRATED, CHANNELS, EXAMPLES, BrfdParameters, BrfdPlant
from engine.plants.brfd.record import BrfdRecord, load_csv, load_json, load_record

__all__ = [
    "CALIBRATED",
    "CATALOGUE",
    "CHANNELS",
    "EXAMPLES",
    "LOCI",
    "BrfdParameters",
    "BrfdPlant",
    "BrfdRecord",
    "load_csv",
    "load_json",
    "load_record",
]
