"""How often a blind run's diagnoses warn, by case kind and warning code (issue 50, item 3).

``python bench/warning_counts.py RUN_DIR``: RUN_DIR is a protocol-2 run directory with its answer
key. Every blind record is one the plant can produce (held-back effects included), so a
``channel_scale`` or ``sample_interval`` warning on it is a false alarm; a ``misfit`` warning on a
record no catalogue effect explains is what it is for. Prints a markdown table with Wilson 95 %
intervals.
"""

from __future__ import annotations

import argparse
import collections
import logging
import sys
from pathlib import Path

from engine.validation.layout import RunLayout
from engine.validation.stats import wilson_interval

logger = logging.getLogger(__name__)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a protocol-2 run directory with its answer key")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    layout = RunLayout(args.run)
    if not layout.key.is_file():
        logger.error("%s holds no answer key (key/answer_key.json)", args.run)
        return 2
    _, entries = layout.read_key()
    done = layout.done()
    n: collections.Counter[str] = collections.Counter()
    hits: dict[str, collections.Counter[str]] = collections.defaultdict(collections.Counter)
    codes: set[str] = set()
    for e in entries:
        if e.case_id not in done:
            continue
        warned = {w["code"] for w in layout.read_result(e.case_id).get("warnings") or ()}
        for group in ("all", e.kind):
            n[group] += 1
            for code in (*warned, "any") if warned else ():
                hits[group][code] += 1
        codes |= warned
    cols = ["any", *sorted(codes)]
    out = [
        f"Diagnoses with a warning, by case kind, on the {n['all']} diagnosed cases of {args.run} "
        "(Wilson 95 % intervals).\n",
        "| kind | n | " + " | ".join(cols) + " |",
        "|---|---|" + "---|" * len(cols),
    ]
    for group in sorted(n, key=lambda g: (g != "all", g)):
        cells = []
        for code in cols:
            k = hits[group][code]
            lo, hi = wilson_interval(k, n[group])
            cells.append(f"{k} ({100 * k / n[group]:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}])")
        out.append(f"| {group} | {n[group]} | " + " | ".join(cells) + " |")
    sys.stdout.write("\n".join(out) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
