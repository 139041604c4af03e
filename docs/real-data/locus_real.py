"""The real records re-diagnosed with the open world: the answer and the locus of the gap it leaves.

    .venv/bin/python docs/real-data/locus_real.py [--out docs/real-data/runs/locus-real.json]

Every shipped real record of the EMPS and BRFD plants, calibrated on itself, through
:func:`engine.diagnosis.plant_gap.diagnose_plant` (the CLI's ``backlash diagnose --plant P FILE``):
the status, the named set, the plausibility warnings (code and channel), and the ``locus`` block (the part of the machine the gap the answer's
model leaves lies at, its confidence, each locus's share of the gap explained, the term). The
table in ``docs/real-data.md`` section 7 is generated from the JSON this writes.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path
from typing import Any

from engine.atomic import write_json_atomic
from engine.diagnosis.plant_gap import diagnose_plant
from engine.plants import get_plant
from engine.validation.provenance import code_version

PLANTS: tuple[str, ...] = ("emps", "brfd")

logger = logging.getLogger("locus_real")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/real-data/runs/locus-real.json"))
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    rows: list[dict[str, Any]] = []
    for name in PLANTS:
        plant = get_plant(name)
        for record_name in plant.examples:
            t0 = time.perf_counter()
            answer = diagnose_plant(plant, plant.example(record_name)).to_dict(plant)
            locus = answer["locus"]
            rows.append(
                {
                    "plant": name,
                    "record": answer["record"],
                    "status": answer["status"],
                    "named": [(e["effect"], e["share"]) for e in answer["verdict"]["effects"]],
                    "verdict_locus": answer["verdict"]["locus"],
                    "reason": answer["verdict"]["reason"],
                    "warnings": [(w["code"], w["channel"]) for w in answer["warnings"]],
                    "locus": None
                    if locus is None
                    else {
                        "locus": locus["locus"],
                        "confidence": locus["confidence"],
                        "ties": locus["ties"],
                        "explained": {k: v["explained"] for k, v in locus["scores"].items()},
                        "term": locus["term"].get("description"),
                        "note": locus["note"],
                    },
                    "seconds": time.perf_counter() - t0,
                }
            )
            logger.info("%s %s: %s, locus %s", name, record_name, answer["status"], locus and locus["locus"])
    write_json_atomic(args.out, {"code": code_version(), "records": rows}, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
