"""Pool the paired identification figure of several protocol-1 runs by inverse variance.

Each run's ``identification.json`` (written by ``backlash validate --protocol 1``) holds
``paired.after_minus_twin``: identification accuracy after the fix minus the same records' clean
twins, in points, mean over the effect records, with its standard error ``paired.stderr``. Runs of
different seeds draw independent records, so their figures pool
(:func:`engine.validation.stats.pooled_estimate`): the weighted mean, its standard error and 95 %
interval, and Cochran's Q with its p-value (a small one: the runs do not measure one quantity).
Pool only runs whose identifier is the same code; the script cannot check that.

Example (the four protocol-1 runs of the open-world code, whose identifier is unchanged)::

    python bench/pool_identification.py docs/validation/v1-seed{193,199,211,227}/identification.json

One JSON line on stdout.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from engine.validation.stats import pooled_estimate


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", type=Path, nargs="+", help="identification.json of each run (two or more)")
    args = ap.parse_args(argv)
    values, stderrs = [], []
    for path in args.files:
        paired = json.loads(path.read_text()).get("paired") if path.is_file() else None
        if not isinstance(paired, dict) or "after_minus_twin" not in paired or "stderr" not in paired:
            ap.error(f"{path} holds no paired figure (paired.after_minus_twin and paired.stderr): not a scored run")
        values.append(float(paired["after_minus_twin"]))
        stderrs.append(float(paired["stderr"]))
    try:
        pool = pooled_estimate(values, stderrs)
    except ValueError as exc:
        ap.error(str(exc))
    out = {
        "runs": [str(p) for p in args.files],
        "after_minus_twin": [round(v, 3) for v in values],
        "stderr": [round(s, 3) for s in stderrs],
        "pooled": round(pool.value, 2),
        "pooled_stderr": round(pool.stderr, 2),
        "interval_95": [round(pool.low, 2), round(pool.high, 2)],
        "cochran_q": round(pool.chi2, 2),
        "dof": pool.dof,
        "p_value": round(pool.p_value, 3),
    }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
