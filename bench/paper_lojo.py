"""Leave-one-J1-out accuracy of the paper's identifier at c = 1.0 (docs/paper-notes.md, section F).

For every channel and every J1 of ``J1_GRID`` (7 folds): fit ``PaperIdentifier``
on the 36 records of the other six J1 values (6 J1 x 6 widths), identify the
6 records of the held-out J1, count the correct widths. Nothing is tuned: the
identifier runs with the parameters given on the command line (default: its
own defaults).

Run from the repository root::

    .venv/bin/python bench/paper_lojo.py                      # current defaults
    .venv/bin/python bench/paper_lojo.py --target as_printed --test-rows single \
        --max-epochs 2000                                     # the faithful-as-printed reading

Columns: accuracy over the 42 held-out records; the min..max epochs of the
pattern networks and of the test networks ("cap" = never converged); ties =
held-out records whose D has a tie at its minimum; fit = median wall time of
one ``fit`` (36 records, 6 networks); identify = median wall time of one
``identify`` call (one record). Times include the wavelet transform. The first
fit of a session also pays numba's compilation (or cache load); it is run
once before timing.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time

import numpy as np

from engine.constants import CHANNELS, J1_GRID
from engine.identification import PaperIdentifier
from engine.simulation import paper_grid, simulate_batch


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--c", type=float, default=1.0, help="apparent viscosity group (default 1.0)")
    ap.add_argument("--channels", nargs="*", default=list(CHANNELS))
    ap.add_argument("--target", default=None, help="PaperIdentifier target (default: the identifier's)")
    ap.add_argument("--test-rows", default=None, help="PaperIdentifier test_rows (default: the identifier's)")
    ap.add_argument("--max-epochs", type=int, default=None)
    ap.add_argument("--learning-rate", type=float, default=None)
    ap.add_argument("--delta1", type=float, default=None)
    args = ap.parse_args(argv)
    logging.getLogger("engine.identification").setLevel(logging.ERROR)  # cap / tie warnings are counted below

    params = {
        k: v
        for k, v in {
            "target": args.target,
            "test_rows": args.test_rows,
            "max_epochs": args.max_epochs,
            "learning_rate": args.learning_rate,
            "delta1": args.delta1,
        }.items()
        if v is not None
    }
    grid = simulate_batch(paper_grid(args.c))
    y = np.asarray([c.plant.K for c in grid.cases])
    g = np.asarray([c.plant.J1 for c in grid.cases])
    shown = PaperIdentifier(CHANNELS[0], **params).get_params()
    print(f"c = {args.c}, params: " + ", ".join(f"{k}={shown[k]!r}" for k in shown if k != "channel"))
    print("| channel | accuracy | pattern epochs | test epochs | ties | fit [s] | identify [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    total = 0
    for ch in args.channels:
        X = grid.channel(ch)
        PaperIdentifier(ch, **params).fit(X[g != J1_GRID[0]], y[g != J1_GRID[0]])  # warm-up (JIT / cache load)
        correct, ties, fit_t, id_t, pe, te, pcap, tcap = 0, 0, [], [], [], [], 0, 0
        for J in J1_GRID:
            tr, te_mask = g != J, g == J
            t0 = time.perf_counter()
            ident = PaperIdentifier(ch, **params).fit(X[tr], y[tr])
            fit_t.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            ident.identify(X[te_mask][0])
            id_t.append(time.perf_counter() - t0)
            res = ident.identify_batch(X[te_mask])
            for r, k in zip(res, y[te_mask], strict=True):
                correct += int(np.isclose(r.width, k))
                ties += int(np.count_nonzero(r.D.min() == r.D) > 1)
                te.append(r.epochs)
                tcap += int(not r.converged)
            pe.extend(ident.epochs_.tolist())
            pcap += int(np.count_nonzero(ident.pattern_rms_ >= ident.delta1))
        n = int(np.count_nonzero(np.isin(g, J1_GRID)))
        total += correct

        def rng(v: list[int], cap: int) -> str:
            s = f"{min(v)}..{max(v)}" if min(v) != max(v) else f"{min(v)}"
            return s + (f" ({cap} cap)" if cap else "")

        print(
            f"| {ch} | {correct}/{n} | {rng(pe, pcap)} | {rng(te, tcap)} | {ties} | "
            f"{np.median(fit_t):.3g} | {np.median(id_t):.3g} |"
        )
        sys.stdout.flush()
    print(f"total: {total}/{len(args.channels) * len(y)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
