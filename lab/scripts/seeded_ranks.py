"""Where the true effect of a single-effect record ranks among the seeded single fits (development, not blind).

The singles' escalation gives the global search to the best seeded candidates, in BIC order, until one
fits to the noise; ``SetSettings.n_escalate_first`` of them before the first pairs and
``SetSettings.n_escalate_singles`` (None: all) after them. A cap is safe for a single-effect record
only when its true effect ranks within it. For each chosen single-effect case of a protocol-2 run,
this fits the nominal model and the seeded single candidates as the diagnosis does (no escalation,
the front runners refined) and prints one JSON line: the truth, whether any seeded single already
fits to the noise (then no escalation runs), and the rank of the true effect (or of an exact twin
of it) among the seeded fits, best BIC first. The summary gives, over the records that need the
escalation, the share whose true effect ranks within the first N, with Wilson 95 % intervals.

Example (the single-effect cases of the seed-131 progress run; the cases are drawn from the seed
when the directory holds none)::

    python lab/scripts/seeded_ranks.py out/s131 --seed 131 --cases 80

The cases of a scored run are development data once read.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path, help="run directory (made from --seed and --cases when it holds no cases)")
    ap.add_argument("--seed", type=int, required=True, help="seed of the run's case generator")
    ap.add_argument("--cases", dest="n_cases", type=int, required=True, help="number of cases of the run")
    ap.add_argument("--ids", default="", help="case ids, comma-separated (default: every single-effect case)")
    ap.add_argument("--within", default="2,4,6,8", help="ranks N of the summary, comma-separated")
    ap.add_argument("--log-level", default="WARNING", help="log level (default WARNING)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)

    from _seeded import open_run, seeded_singles

    from engine.diagnosis.candidates import needs_escalation
    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.diagnosis.space import indistinguishable
    from engine.simulation import CATALOGUE
    from engine.validation.stats import wilson_interval

    layout = open_run(args.run, args.n_cases, args.seed)
    try:
        within = [int(x) for x in args.within.split(",") if x]
    except ValueError:
        ap.error(f"--within: whole ranks, comma-separated (got {args.within!r})")
    ids = [c for c in args.ids.split(",") if c]
    try:
        entries = layout.key_entries(ids or layout.case_ids())
    except KeyError as e:
        ap.error(str(e.args[0]))
    others = [k.case_id for k in entries if k.kind != "single"]
    if ids and others:  # a rank among single fits means nothing for them: refuse rather than skip
        ap.error(f"not single-effect cases: {', '.join(others)}")
    entries = [k for k in entries if k.kind == "single"]
    ds = DiagnosisSettings()
    ranks: list[int | None] = []  # of the records that need the escalation
    for k in entries:
        (truth,) = k.effects
        t0 = time.perf_counter()
        cands = seeded_singles(layout, k.case_id, ds).singles
        fitted = [c for c in cands if c.calibration is not None]
        twins = {truth.name, *indistinguishable(truth.name, truth.value, CATALOGUE)}
        rank = next((i + 1 for i, c in enumerate(fitted) if c.effect in twins), None)
        escalates = needs_escalation(cands, ds.candidates)
        if escalates:
            ranks.append(rank)
        row = {
            "case": k.case_id,
            "truth": truth.name,
            "value": truth.value,
            "needs_escalation": escalates,
            "rank": rank,
            "of": len(fitted),
            "seconds": round(time.perf_counter() - t0, 1),
        }
        print(json.dumps(row), flush=True)
    n = len(ranks)
    print(f"{n} of {len(entries)} single-effect records need the escalation; true effect's seeded rank: {ranks}")
    for cap in within:
        hits = sum(r is not None and r <= cap for r in ranks)
        low, high = wilson_interval(hits, n) if n else (0.0, 1.0)
        print(f"within the first {cap}: {hits}/{n}, Wilson 95 % [{100 * low:.1f}, {100 * high:.1f}] %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
