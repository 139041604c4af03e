"""Does any flexible transmission explain the pulse record? A sweep of the documented choices.

The catalogue's ``flexibility`` effect fixes the carriage's share of the mass (0.5) and the
damping ratio (0.05) and fits the natural frequency. This script relaxes both: for every pair of
choices it scans the frequency over 5-200 Hz (25 values, log-spaced) with the calibration from
DATA_EMPS held, and prints the best cost relative to the rigid model's on DATA_EMPS_PULSES.

    .venv/bin/python docs/real-data/flexibility_sweep.py
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import numpy as np

from engine.diagnosis.plant_gap import PlantObjective, calibrate
from engine.plants.emps import EmpsPlant, load_mat

DATA = Path(__file__).resolve().parents[2] / "engine" / "plants" / "emps" / "data"


def main() -> None:
    logging.basicConfig(level=logging.WARNING)
    plant = EmpsPlant()
    cal = calibrate(plant, load_mat(DATA / "DATA_EMPS.mat")).values
    pulses = load_mat(DATA / "DATA_EMPS_PULSES.mat")
    sys.stdout.write(
        "| carriage share | damping ratio | best cost / rigid | at [Hz] |\n| ---: | ---: | ---: | ---: |\n"
    )
    for rho in (0.1, 0.3, 0.5, 0.7, 0.9):
        for zeta in (0.01, 0.05, 0.2):
            obj = PlantObjective(EmpsPlant(fixed={"rho_flex": rho, "zeta_flex": zeta}), pulses)
            r0 = obj.vector(cal)
            costs = []
            for f in np.geomspace(5.0, 200.0, 25):
                try:
                    r = obj.vector({**cal, "flexibility": float(f)})
                    costs.append((float(r @ r) / float(r0 @ r0), float(f)))
                except FloatingPointError:
                    costs.append((np.inf, float(f)))
            best, at = min(costs)
            sys.stdout.write(f"| {rho} | {zeta} | {best:.3f} | {at:.1f} |\n")


if __name__ == "__main__":
    main()
