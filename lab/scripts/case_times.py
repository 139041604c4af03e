"""Time budget of issue 10: one diagnosis at a time on this machine's cores, on a validation run's cases.

The blind run's times are throughput figures (``--workers 2``: two diagnoses at once, one core
each). The issue's budgets are for one diagnosis on 2 cores (90th percentile <= 10 s for a
single-effect record, <= 60 s for a pair or triple). This takes the first ``--per-kind`` cases
of each kind (in id order: no choice by outcome) of a finished run, diagnoses them one after the
other in this process with every core (numba's threads; ``--threads`` to limit them), and prints
the median and 90th percentile per group (single; compound = pair and triple) with the
order-statistic 95 % intervals of :func:`engine.validation.stats.quantile_interval`.

Baseline, in the same process: ``--baseline-threads 1`` diagnoses the same cases again with one
thread and prints the ratio of the times (per group, of the medians and the 90th percentiles);
``--baseline-sets JSON`` instead diagnoses them again with other :class:`SetSettings` fields, e.g.
the order before the early escalation came before pass 1b (docs/diagnosis.md 8b)::

    python lab/scripts/case_times.py out/validation-v2-seed223 --seed 223 --cases 300 --per-kind 75 \\
        --kinds single --baseline-sets '{"escalate_before_reseed": false}'

Also printed: the run's own recorded times of the same cases (another process and machine load;
for reference only).

The run's cases are development data once the run is scored; the times do not depend on the
answers, but they do depend on what else the machine runs (the load average is printed).

Example (about 25 min on 2 cores)::

    python lab/scripts/case_times.py out/validation-v2-seed97 --seed 97 --cases 300 --per-kind 20

One JSON line per case, then one summary line, on stdout; progress on stderr.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time
from typing import Any

from _runs import BUDGET_P90_S, GROUPS, add_run_arguments, chosen_entries, run_drive, run_library, updated

logger = logging.getLogger("lab.case_times")


def _time_cases(
    layout: Any, library: Any, ids: list[str], threads: int, settings: Any = None, drive: Any = None
) -> dict[str, float]:
    """Wall seconds of the diagnosis of each case with ``threads`` numba threads, the run's library
    and ``settings`` (a ``DiagnosisSettings``; None: the default), on the run's ``drive`` (None: the reference)."""
    import numba

    from engine.diagnosis import diagnose

    numba.set_num_threads(threads)
    out = {}
    for i, cid in enumerate(ids):
        rec = layout.read_case(cid)
        t0 = time.perf_counter()
        if drive is None:
            diagnose(rec, library, settings=settings)
        else:
            diagnose(rec, library, settings=settings, drive=drive)
        out[cid] = time.perf_counter() - t0
        logger.info(
            "%d/%d %s, %d threads: %.1f s (load %.2f)", i + 1, len(ids), cid, threads, out[cid], os.getloadavg()[0]
        )
    return out


def _summary(times: list[float]) -> dict[str, Any]:
    from engine.validation.stats import quantile_interval

    return {"median": quantile_interval(times, 0.5).to_dict(), "p90": quantile_interval(times, 0.9).to_dict()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(ap, "(not used: the cases are the first --per-kind of each kind)")
    ap.add_argument("--per-kind", type=int, default=20, help="cases of each kind (single, pair, triple)")
    ap.add_argument("--kinds", default="single,pair,triple", help="kinds timed, comma-separated")
    ap.add_argument("--threads", type=int, default=0, help="numba threads (default: every core)")
    ap.add_argument("--baseline-threads", type=int, default=0, help="also time the same cases with this many threads")
    ap.add_argument(
        "--baseline-sets",
        default="",
        help="also time the same cases with these SetSettings fields (JSON, same threads), "
        "e.g. '{\"escalate_before_reseed\": false}'",
    )
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)
    logger.setLevel(logging.INFO)
    if args.per_kind < 1:
        ap.error("--per-kind must be at least 1")
    if args.baseline_threads and args.baseline_sets:
        ap.error("give --baseline-threads or --baseline-sets, not both")
    baseline_settings = None
    if args.baseline_sets:
        from dataclasses import replace

        from engine.diagnosis.diagnose import DiagnosisSettings

        ds = DiagnosisSettings()
        try:
            baseline_settings = replace(ds, sets=updated(ds.sets, json.loads(args.baseline_sets)))
        except (TypeError, ValueError) as exc:
            ap.error(f"--baseline-sets: {exc}")
    import numba

    threads = args.threads or numba.get_num_threads()
    layout, entries = chosen_entries(ap, args, None)
    kinds = {k for k in args.kinds.split(",") if k}
    if not kinds <= {k for g in GROUPS.values() for k in g}:
        ap.error(f"--kinds: give some of {', '.join(k for g in GROUPS.values() for k in g)}")
    chosen: dict[str, list[str]] = {k: [] for k in kinds}
    for e in sorted(entries, key=lambda e: e.case_id):
        if e.kind in chosen and len(chosen[e.kind]) < args.per_kind:
            chosen[e.kind].append(e.case_id)
    ids = [c for k in sorted(chosen) for c in chosen[k]]
    kind_of = {e.case_id: e.kind for e in entries}
    from engine.simulation import Case, PlantParameters, simulate_batch

    simulate_batch([Case(PlantParameters())] * 2)  # JIT (cached) before the first timing
    library = run_library(ap, layout)
    run_on = run_drive(ap, layout)
    drive = None if run_on.is_reference else run_on
    times = _time_cases(layout, library, ids, threads, drive=drive)
    base: dict[str, float] = {}
    if args.baseline_threads:
        base = _time_cases(layout, library, ids, args.baseline_threads, drive=drive)
    elif baseline_settings is not None:
        base = _time_cases(layout, library, ids, threads, baseline_settings, drive)
    baseline_name = f"{args.baseline_threads}_threads" if args.baseline_threads else "sets"
    recorded = {c: float(layout.read_result(c)["seconds"]) for c in ids if c in layout.done()}
    for c in ids:
        row = {"case": c, "kind": kind_of[c], "seconds": round(times[c], 2), "threads": threads}
        if base:
            row["baseline_seconds"] = round(base[c], 2)
        if c in recorded:
            row["run_recorded_seconds"] = round(recorded[c], 2)
        print(json.dumps(row), flush=True)
    summary: dict[str, Any] = {"threads": threads, "load_average_1min_end": os.getloadavg()[0]}
    for g, ks in GROUPS.items():
        g_ids = [c for c in ids if kind_of[c] in ks]
        if not g_ids:
            continue
        s = _summary([times[c] for c in g_ids])
        s["budget_p90_s"] = BUDGET_P90_S[g]
        s["n"] = len(g_ids)
        if base:
            b = _summary([base[c] for c in g_ids])
            s[f"baseline_{baseline_name}"] = b
            s["ratio_median"] = s["median"]["value"] / b["median"]["value"]
            s["ratio_p90"] = s["p90"]["value"] / b["p90"]["value"]
        rec = [recorded[c] for c in g_ids if c in recorded]
        if rec:
            s["run_recorded"] = _summary(rec)
        summary[g] = s
    print(json.dumps({"summary": summary}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
