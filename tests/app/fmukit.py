"""The quarter-car FMU as a user's plant of the service: its reduced description, records synthesized from it.

Shared by the service's FMU tests (test_app_fmu_plants.py) and the report page's (test_browser.py).
"""

from __future__ import annotations

import io
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from engine.plants.fmu import EXAMPLES_DIR, FmuPlant
from engine.plants.fmu.record import FmuRecord, load_record

EXAMPLE = EXAMPLES_DIR / "quarter_car"
OCTET = {"Content-Type": "application/octet-stream"}
#: The calibrated parameters' values of the synthetic records (off nominal: the calibration has work to do).
TRUE = {"m_s": 320.0, "c_s": 1400.0}


def small_description(sha: str) -> dict[str, Any]:
    """The quarter car with three effects and no generic ones (a diagnosis of a few seconds)."""
    d = tomllib.loads((EXAMPLE / "plant.toml").read_text())
    d.update(fmu=f"sha256:{sha}", examples=[], held_back=[], generic={"sensors": False, "actuators": False})
    d["name"] = "quarter_car_small"
    d["effects"] = [e for e in d["effects"] if e["name"] in ("damper_friction", "progressive_spring", "tyre_stiffness")]
    d["inputs"] = d["inputs"][:2]
    return d


def synthetic(local: FmuPlant, effects: dict[str, float], seed: int) -> FmuRecord:
    base = load_record(EXAMPLE / "record.csv", local.description)
    return local.synthesize(base, {**TRUE, **effects}, np.random.default_rng(seed))


def as_json(record: FmuRecord, local: FmuPlant) -> dict[str, Any]:
    return {
        "columns": {local.description.time: record.t.tolist(), **{k: v.tolist() for k, v in record.columns.items()}}
    }


def as_csv(record: FmuRecord, local: FmuPlant, header_units: bool = True) -> bytes:
    d = local.description
    names = [d.time, *record.columns]
    units = {d.time: "s", **{str(i.column): i.unit for i in d.driven}, **{c.name: c.unit for c in d.channels}}
    head = ",".join(f"{n} [{units[n]}]" if header_units else n for n in names)
    table = np.column_stack([record.t, *record.columns.values()])
    out = io.StringIO()
    np.savetxt(out, table, delimiter=",", header=head, comments="", fmt="%.10g")
    return out.getvalue().encode()


def local_plant(fmu: Path) -> FmuPlant:
    """The reduced plant in this process (the FMU file ``fmu``), to synthesize records with."""
    from engine.plants.fmu.description import parse_description

    d = small_description("0" * 64)
    d["fmu"] = fmu.name
    return FmuPlant(parse_description(d), fmu.parent, processes=1)
