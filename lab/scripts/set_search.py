"""The set search alone on cases of a protocol-2 run, with chosen settings (development, not blind).

Draws the run's cases from its seed when the directory does not hold them yet (the cases only, no
diagnosis: :func:`engine.validation.run.prepare_cases`), then for each chosen case fits the nominal
model and the seeded single candidates (no escalation) and runs :func:`engine.diagnosis.sets.search_sets`
with the default :class:`~engine.diagnosis.sets.SetSettings` updated by ``--settings``. It prints
one JSON line per case (truth, best set, its chi2/n, whether the true set fits to the noise, seconds)
and a summary with a Wilson interval. This is the comparison behind docs/diagnosis.md 8b (*Two
bases*, *Scans of a time shift*); the cases of a scored run are development data once read.

Examples::

    python lab/scripts/set_search.py out/s117 --seed 117 --cases 40 case0038 --settings '{"n_base": 1}'
    python lab/scripts/set_search.py out/s107 --seed 107 --cases 100 case0086,case0042

To compare code versions rather than settings, run this file with another checkout's engine first
on the path (``PYTHONPATH=/path/to/checkout python lab/scripts/set_search.py ...``).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from dataclasses import replace
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path, help="run directory (made from --seed and --cases when it holds no cases)")
    ap.add_argument("cases", help="case ids, comma-separated")
    ap.add_argument("--seed", type=int, required=True, help="seed of the run's case generator")
    ap.add_argument("--cases", dest="n_cases", type=int, required=True, help="number of cases of the run")
    ap.add_argument("--settings", default="{}", help="SetSettings fields as JSON, e.g. '{\"n_base\": 1}'")
    ap.add_argument("--log-level", default="WARNING", help="log level (default WARNING)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)

    from _seeded import open_run, seeded_singles

    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.diagnosis.sets import search_sets
    from engine.diagnosis.space import indistinguishable
    from engine.simulation import CATALOGUE
    from engine.validation.stats import wilson_interval

    layout = open_run(args.run, args.n_cases, args.seed)
    try:
        entries = layout.key_entries([c for c in args.cases.split(",") if c])
    except KeyError as e:
        ap.error(str(e.args[0]))
    ds = DiagnosisSettings()
    ss = replace(ds.set_search(), **json.loads(args.settings))
    hits = 0
    for k in entries:
        cid, truth = k.case_id, {e.name for e in k.effects}
        t0 = time.perf_counter()
        fit = seeded_singles(layout, cid, ds)
        sets = search_sets(fit.record, fit.nominal, fit.space, CATALOGUE, fit.singles, ds.candidates, ss)
        best = sets[0] if sets else None
        named: set[str] = set()
        if best is not None:
            for n, v in best.values.items():
                named |= {n, *indistinguishable(n, v, CATALOGUE)}
        chi2n = best.calibration.reduced_chi2 if best is not None and best.calibration is not None else None
        ok = best is not None and chi2n is not None and chi2n <= ss.escalate_above and len(best.effects) == len(truth)
        ok = ok and truth <= named
        hits += ok
        row = {
            "case": cid,
            "truth": sorted(truth),
            "best": list(best.effects) if best is not None else None,
            "chi2n": chi2n,
            "true_set_at_noise": ok,
            "seconds": round(time.perf_counter() - t0, 1),
        }
        print(json.dumps(row), flush=True)
    low, high = wilson_interval(hits, len(entries))
    print(f"true set fitted to the noise: {hits}/{len(entries)}, Wilson 95 % [{100 * low:.1f}, {100 * high:.1f}] %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
