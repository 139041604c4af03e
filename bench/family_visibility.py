"""Visibility of a family's effects: the table of the bounds' rule (docs/model-changes.md, 1.2 to 1.7).

Simulation only: nothing is diagnosed, calibrated or validated, so the script may be run on a
family kept for scoring. For every effect of the family at ``--fraction`` of its upper bound, on
the nominal plant (K 5 mm, J1 0.87 kg m^2, c 1.0), the change of each channel's record against the
plain record: its RMS over the record in units of the noise standard deviation at ``--snr`` dB
(:func:`engine.simulation.noise_std` of the plain record), the largest single-sample change in
brackets, then the shift of the event time t_e. The bounds' rule asks, at half the upper bound,
for at least two channels above 3 noise RMS (one for an effect of the measurement chain that acts
on one channel only), and for the event at the upper bound. Any family of
:data:`engine.simulation.families.FAMILIES` (``--family``; the newest, ``sealed5`` of model 1.7,
by default).

Run from the repository root::

    .venv/bin/python bench/family_visibility.py --family sealed5           # half the upper bound
    .venv/bin/python bench/family_visibility.py --family sealed5 --fraction 1
    .venv/bin/python bench/family_visibility.py --family sealed4           # model 1.6's table

Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import sys
from typing import NamedTuple

import numpy as np

from engine.constants import CHANNELS
from engine.simulation import Case, PlantParameters, noise_std, simulate_batch
from engine.simulation.families import FAMILIES

#: The nominal plant of the rule.
NOMINAL = PlantParameters(K=0.005, J1=0.87, c=1.0)


class Row(NamedTuple):
    """One effect's change: value, per-channel RMS and largest change [noise RMS], event shift [s]."""

    name: str
    value: float
    rms: np.ndarray
    largest: np.ndarray
    event_shift: float


def visibility(family: str, fraction: float = 0.5, snr_db: float = 40.0) -> list[Row]:
    """The rows of ``FAMILIES[family]`` at ``fraction`` of each effect's upper bound."""
    library = FAMILIES[family]
    base = Case(NOMINAL)
    cases = [base] + [e.apply(base, fraction * e.bounds[1]) for e in library.values()]
    res = simulate_batch(cases)
    plain = res.channels[0]
    sd = noise_std(plain, snr_db)[:, 0]
    rows = []
    for i, (name, e) in enumerate(library.items(), 1):
        diff = res.channels[i] - plain
        rows.append(
            Row(
                name,
                fraction * e.bounds[1],
                np.sqrt(np.mean(diff**2, axis=1)) / sd,
                np.max(np.abs(diff), axis=1) / sd,
                float(res.event_times[i] - res.event_times[0]),
            )
        )
    return rows


def cell(rms: float, largest: float) -> str:
    """A channel's cell: ``0`` for no change at all, ``< 0.1 (0)`` below a tenth, else ``RMS (largest)``."""
    if rms == 0.0:
        return "0"
    if rms < 0.05:
        return f"< 0.1 ({largest:.0f})"
    return f"{rms:.1f} ({largest:.0f})"


def table(rows: list[Row], fraction: float) -> str:
    """The Markdown table of ``rows``."""
    what = "half bound" if fraction == 0.5 else f"{fraction:g} x bound"
    lines = [
        f"| effect, value ({what}) | {' | '.join(CHANNELS)} | t_e shift |",
        "| --- |" + " --- |" * (len(CHANNELS) + 1),
    ]
    for r in rows:
        cells = " | ".join(cell(a, m) for a, m in zip(r.rms, r.largest, strict=True))
        lines.append(f"| {r.name} {r.value:g} | {cells} | {1e3 * r.event_shift:+.3f} ms |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--family", choices=sorted(FAMILIES), default="sealed5")
    ap.add_argument("--fraction", type=float, default=0.5, help="of each effect's upper bound (default 0.5)")
    ap.add_argument("--snr", type=float, default=40.0, help="noise level [dB] (default 40)")
    args = ap.parse_args(argv)
    sys.stdout.write(table(visibility(args.family, args.fraction, args.snr), args.fraction) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
