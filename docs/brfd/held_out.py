"""Held-out prediction on the BRFD: fit on the 36 lb sine tests, predict the two earthquake histories.

    .venv/bin/python docs/brfd/held_out.py [--out docs/brfd/held_out.md]

Runs on the shipped records only. The earthquake tests ran at 36 lb band tension (upstream README;
the same files are also listed upstream under a 30 lb series), so the 36 lb sine tests are the
training records. Every effect set is fitted on the training records (the calibration and the
effects' scalars shared), then the earthquake records are simulated with it.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from engine.diagnosis.plant_transfer import held_out
from engine.plants import get_plant

TRAIN = ("dataset-2_1Hz36lbtension1amplitude", "dataset-2_0.5Hz36lbtension1amplitude")
TEST = ("dataset-2_ImperialValleyDBE", "dataset-2_KocaeliDBE")
#: The effect sets carried over: the play alone, and the play with what the diagnosis of the
#: training records named beside it (sensor_offset), or with the makers' self-energizing.
SETS: tuple[tuple[str, ...], ...] = (("backlash",), ("backlash", "sensor_offset"), ("backlash", "self_energizing"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    plant = get_plant("brfd")
    train = [plant.example(n) for n in TRAIN]
    test = [plant.example(n) for n in TEST]
    lines = [
        "| effects carried over | fitted on the sine tests | "
        + " | ".join(f"{n}: nominal -> with effects (own calibration) [%]" for n in TEST)
        + " | sine tests in-sample: nominal -> with effects [%] |",
        "| --- | --- | " + " | ".join("---" for _ in TEST) + " | --- |",
    ]
    for effects in SETS:
        r = held_out(plant, train, test, list(effects))
        fitted = ", ".join(f"{k} = {v:.4g}" for k, v in r.with_effects.items())
        cells = []
        for n in TEST:
            e = r.relative_error[n]
            cells.append(
                f"{e['nominal']['force']:.1f} -> {e['with_effects']['force']:.1f} ({e['own_calibration']['force']:.1f})"
            )
        ins = "; ".join(
            f"{e['nominal']['force']:.1f} -> {e['with_effects']['force']:.1f}" for e in r.train_error.values()
        )
        lines.append(f"| {', '.join(effects)} | {fitted} | " + " | ".join(cells) + f" | {ins} |")
    text = "\n".join(lines) + "\n"
    if args.out:
        args.out.write_text(text)
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
