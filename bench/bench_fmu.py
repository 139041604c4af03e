"""Cost of a plant from an FMU against the native plants, in one process (issue 55).

    python bench/bench_fmu.py [--calls 15] [--diagnoses 2] [--json docs/validation/fmu/cost.json]

Per simulation: the median seconds of one simulation of each plant's example record at its nominal
values (``--calls`` timed calls after one warm-up), for

- the **baseline**, the native backlash drive (:class:`engine.plants.backlash_drive.BacklashDrivePlant`,
  the numba kernel: MODEL.md's record of 2048 samples from 4.8 ms before the event);
- the same plant as an **FMU** (``engine/plants/fmu/examples/backlash_drive``: C through FMPy, its
  record from the switch-on to 0.2 s after the event, 2325 samples at 0.1 ms);
- the **quarter car** FMU (``engine/plants/fmu/examples/quarter_car``: 2001 samples at 1 ms), run by
  its co-simulation interface (its own fixed-step solver in C) and by its **model-exchange** interface
  (its derivatives integrated by SUNDIALS' CVode on the record's grid, :mod:`engine.plants.fmu.runner`);

each also per sample, and the FMU's against the native's as a ratio. Per diagnosis: ``--diagnoses``
synthetic records of the quarter car with one catalogue effect (drawn from a fixed seed), diagnosed
by :func:`engine.diagnosis.plant_gap.diagnose_plant` twice: the **baseline** with the plant's
simulations in this process (``processes=1``), and on ``--processes`` worker processes
(:mod:`engine.plants.fmu.pool`, the default on this machine), the two in alternating order; seconds,
simulations, simulation-equivalents (the seconds over one simulation's), the ratio, and whether the
two answers are identical. Then the first record's model-exchange counterpart (synthesized by the
model-exchange plant itself, the same effect and seed) diagnosed on ``--processes`` workers: seconds,
simulations, and the verdict beside co-simulation's. (Threads alone gain nothing: two threads ran an FMU's simulations 0.68-0.98x
as fast as one, the per-sample loop holding the GIL.) Never run by the tests.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from bench_plant_diagnosis import simulation_time

from engine.atomic import write_json_atomic
from engine.diagnosis.plant_gap import diagnose_plant
from engine.plants import Plant, get_plant
from engine.plants.fmu import EXAMPLES_DIR, FmuPlant, load_description, load_plant
from engine.plants.fmu.description import parse_description
from engine.validation.provenance import code_version

logger = logging.getLogger("bench_fmu")

#: The plants timed, in order: label -> registry name or description path.
PLANTS: dict[str, str] = {
    "native backlash drive": "backlash_drive",
    "backlash drive as an FMU": str(EXAMPLES_DIR / "backlash_drive" / "plant.toml"),
    "quarter car (FMU)": str(EXAMPLES_DIR / "quarter_car" / "plant.toml"),
}
#: Label of the quarter car run by its model-exchange interface (the same description, ``interface`` changed).
MODEL_EXCHANGE = "quarter car (FMU, model exchange)"
#: Effects of the diagnosed quarter-car records: (name, value), in turn.
DIAGNOSED: tuple[tuple[str, float], ...] = (("damper_friction", 60.0), ("tyre_damping", 300.0), ("a_body_lag", 2e-3))


def model_exchange_plant(processes: int) -> FmuPlant:
    """The quarter car's plant with ``interface = "model-exchange"`` (its description otherwise as shipped)."""
    path = Path(PLANTS["quarter car (FMU)"])
    data = {**load_description(path).model_dump(), "interface": "model-exchange"}
    return FmuPlant(parse_description(data, str(path)), path.parent, processes=processes)


def main(argv: list[str] | None = None) -> int:
    """Time the simulations and diagnoses; print a table, write ``--json``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=15, help="timed simulations per plant (default 15)")
    ap.add_argument("--diagnoses", type=int, default=2, help="quarter-car diagnoses timed (default 2, at most 3)")
    ap.add_argument("--processes", type=int, default=2, help="worker processes of the second diagnosis (default 2)")
    ap.add_argument("--json", type=Path, help="write the figures to this file")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    rows: list[dict[str, Any]] = []
    baseline = None
    for label, name in (*PLANTS.items(), (MODEL_EXCHANGE, "")):
        plant: Plant
        if label == MODEL_EXCHANGE:
            plant = model_exchange_plant(processes=1)
        else:
            plant = get_plant(name) if name == "backlash_drive" else load_plant(name, processes=1)
        record = plant.example()
        n = len(plant.time(record))
        s = simulation_time(plant, record, args.calls)
        baseline = s if baseline is None else baseline
        rows.append(
            {"plant": label, "samples": n, "seconds": s, "us_per_sample": 1e6 * s / n, "ratio_to_native": s / baseline}
        )
        logger.info(
            "%-26s %5d samples  %7.2f ms  %5.2f us/sample  %5.2fx the native",
            label,
            n,
            1e3 * s,
            1e6 * s / n,
            s / baseline,
        )
    one_process = load_plant(PLANTS["quarter car (FMU)"], processes=1)
    pooled = load_plant(PLANTS["quarter car (FMU)"], processes=args.processes)
    record = one_process.example()
    one = next(r["seconds"] for r in rows if r["plant"] == "quarter car (FMU)")
    diagnoses = []
    for k, (effect, value) in enumerate(DIAGNOSED[: args.diagnoses]):
        synthetic = one_process.synthesize(record, {effect: value}, np.random.default_rng(100 + k))
        timed: dict[int, tuple[float, dict[str, Any]]] = {}
        for plant in (one_process, pooled) if k % 2 == 0 else (pooled, one_process):
            t0 = time.perf_counter()
            report = diagnose_plant(plant, synthetic, jobs=args.processes)
            timed[1 if plant is one_process else args.processes] = (time.perf_counter() - t0, report.to_dict(plant))
        (s1, a1), (sn, an) = timed[1], timed[args.processes]
        diagnoses.append(
            {
                "effect": effect,
                "value": value,
                "status": a1["status"],
                "named": [e["effect"] for e in a1["verdict"]["effects"]],
                "seconds": s1,
                "simulations": a1["n_simulations"],
                "simulation_equivalents": s1 / one,
                "processes": args.processes,
                "seconds_on_processes": sn,
                "ratio": sn / s1,
                "identical": json.dumps(a1, sort_keys=True, default=str) == json.dumps(an, sort_keys=True, default=str),
            }
        )
        logger.info(
            "quarter car, %s = %g: %s %s; one process %.1f s (%d simulations, %.0f sims), %d processes %.1f s (%.2fx), %s",
            effect,
            value,
            a1["status"],
            diagnoses[-1]["named"],
            s1,
            a1["n_simulations"],
            s1 / one,
            args.processes,
            sn,
            sn / s1,
            "identical" if diagnoses[-1]["identical"] else "DIFFERENT",
        )
    model_exchange = []
    if diagnoses:
        effect, value = DIAGNOSED[0]
        me_plant = model_exchange_plant(processes=args.processes)
        me_one = next(r["seconds"] for r in rows if r["plant"] == MODEL_EXCHANGE)
        synthetic = me_plant.synthesize(me_plant.example(), {effect: value}, np.random.default_rng(100))
        t0 = time.perf_counter()
        answer = diagnose_plant(me_plant, synthetic, jobs=args.processes).to_dict(me_plant)
        seconds = time.perf_counter() - t0
        model_exchange.append(
            {
                "effect": effect,
                "value": value,
                "status": answer["status"],
                "named": [e["effect"] for e in answer["verdict"]["effects"]],
                "processes": args.processes,
                "seconds": seconds,
                "simulations": answer["n_simulations"],
                "simulation_equivalents": seconds / me_one,
                "ratio_to_co_simulation": seconds / diagnoses[0]["seconds_on_processes"],
            }
        )
        logger.info(
            "quarter car by model exchange, %s = %g: %s %s; %d processes %.1f s (%d simulations), %.2fx co-simulation's",
            effect,
            value,
            answer["status"],
            model_exchange[-1]["named"],
            args.processes,
            seconds,
            answer["n_simulations"],
            model_exchange[-1]["ratio_to_co_simulation"],
        )
    if args.json is not None:
        write_json_atomic(
            args.json,
            {
                "code": code_version(),
                "command": "python bench/bench_fmu.py " + " ".join(sys.argv[1:] if argv is None else argv),
                "calls": args.calls,
                "simulations": rows,
                "diagnoses": diagnoses,
                "model_exchange_diagnoses": model_exchange,
            },
            indent=1,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
