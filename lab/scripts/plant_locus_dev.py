"""Development replay of the plant locus estimate on held-back records (development seeds only).

    PYTHONPATH=. .venv/bin/python lab/scripts/plant_locus_dev.py --plant brfd --seed 111 --cases 8 [--record R]

Draws held-back effects as the synthetic check does, diagnoses, and prints the locus estimate per case.
Development data: figures from here are in-family, never the scored ones.
"""

from __future__ import annotations

import argparse
import logging
import time

import numpy as np

from engine.diagnosis.plant_gap import diagnose_plant
from engine.plants import get_plant
from engine.validation.plant_check import _perturbed

logger = logging.getLogger("plant_locus_dev")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--plant", default="brfd")
    ap.add_argument("--seed", type=int, default=111)
    ap.add_argument("--cases", type=int, default=8)
    ap.add_argument("--record", default=None)
    ap.add_argument("--seconds", type=float, default=None)
    ap.add_argument("--only", default=None, help="draw this effect only")
    a = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    plant = get_plant(a.plant)
    record = plant.example(a.record, a.seconds)
    rng = np.random.default_rng(a.seed)
    names = list(plant.held_back)
    for i in range(a.cases):
        name = a.only or names[i % len(names)]
        e = plant.held_back[name].as_parameter()
        cal = _perturbed(plant, record, rng)
        value = float(e.value(float(rng.uniform(0.0, 1.0))))
        syn = plant.synthesize(record, {**cal, name: value}, rng)
        t0 = time.perf_counter()
        rep = diagnose_plant(plant, syn)
        t1 = time.perf_counter()
        loc = rep.locus
        if loc is None:
            print(f"{i} {name}={value:.4g}: {rep.status}, no locus ({t1 - t0:.1f} s)", flush=True)
            continue
        test = rep.extra.get("stand_in_test")  # the open world's test of the named set, as it ran
        extra = f" [stand-in test: {test}]" if test else ""
        sc = " ".join(f"{k}:{s.explained:.2f}/{s.weight:.2f}" for k, s in loc.scores.items())
        print(
            f"{i} {name}={value:.4g} ({plant.held_back[name].locus}): {rep.status} "
            f"named={rep.named.effects if rep.named else None} -> locus {loc.locus} ({loc.confidence:.2f}) "
            f"ties={loc.ties} [{sc}] term: {loc.term.get('description', '')} "
            f"({t1 - t0:.1f} s, {loc.n_simulations} sims) disp {loc.dispersion:.3g} {loc.note[:40]} "
            f"| {rep.to_dict(plant)['verdict']['reason']}{extra}",
            flush=True,
        )


if __name__ == "__main__":
    main()
