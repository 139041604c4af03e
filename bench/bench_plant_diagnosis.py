"""Cost of a plant's diagnosis (EMPS, BRFD) in seconds and simulation-equivalents, threads against one (issue 54).

    python bench/bench_plant_diagnosis.py [--plants emps brfd] [--records NAME ...] [--jobs 2] [--json FILE]

Every shipped real record of each plant (or those named) is diagnosed by
:func:`engine.diagnosis.plant_gap.diagnose_plant`, calibrated on itself, twice in this process:
with ``jobs=1`` (the **baseline**: every simulation one after another, the order of the code before
the simulation pool) and with ``--jobs`` threads (the **current** setting, the default of the CLI
and the service on this machine: numba's thread count). The two alternate record by record (the
baseline first on even records, the threads first on odd ones) so that they share the machine's
load.

Each diagnosis's time is also given in **simulation-equivalents** (sims): its seconds over the
median time of one simulation of the same record at the plant's nominal values (:data:`SIM_CALLS`
calls, timed in this process before the record's diagnoses), so that figures taken on different
machines compare. The simulations each diagnosis reports (``n_eval``) are printed beside them, and
whether the two answers are identical (every field of the JSON answer but the simulation counts;
the threads must change no answer).

Printed: one line per record, then per plant the median of the per-record ratios threads /
baseline and the sums. ``--json FILE`` holds the rows (rewritten after every record). Never run by
the tests; about 12 min for every shipped record on 2 idle cores.
"""

from __future__ import annotations

import argparse
import json
import logging
import statistics
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from engine.atomic import write_json_atomic
from engine.diagnosis.plant_gap import diagnose_plant
from engine.plants import get_plant
from engine.validation.provenance import code_version

logger = logging.getLogger("bench_plant_diagnosis")

#: Timed calls of one simulation per record (their median is the unit of sims).
SIM_CALLS: int = 7
#: Fields of an answer that count work, not the answer: left out of the identity check.
COUNTS: frozenset[str] = frozenset({"n_eval", "n_simulations"})


def _answer(d: Any) -> Any:
    """An answer without its work counts (:data:`COUNTS`)."""
    if isinstance(d, Mapping):
        return {k: _answer(v) for k, v in d.items() if k not in COUNTS}
    if isinstance(d, list | tuple):
        return [_answer(x) for x in d]
    return d


def simulation_time(plant: Any, record: Any, calls: int = SIM_CALLS) -> float:
    """Median seconds of one simulation of ``record`` at the plant's nominal values (after one warm-up call)."""
    plant.simulate(record, {})
    times = []
    for _ in range(calls):
        t0 = time.perf_counter()
        plant.simulate(record, {})
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench_record(plant: Any, name: str, jobs: int, order: int) -> dict[str, Any]:
    """Both diagnoses of one record (``order`` even: the baseline first) and their comparison."""
    record = plant.example(name)
    unit = simulation_time(plant, record)
    runs: dict[str, dict[str, Any]] = {}
    codes = ("baseline", "threads") if order % 2 == 0 else ("threads", "baseline")
    for code in codes:
        t0 = time.perf_counter()
        answer = diagnose_plant(plant, record, jobs=1 if code == "baseline" else jobs).to_dict(plant)
        seconds = time.perf_counter() - t0
        runs[code] = {
            "seconds": seconds,
            "sims": seconds / unit,
            "n_eval": answer.get("n_simulations"),
            "status": answer["status"],
            "answer": _answer(answer),
        }
    same = json.dumps(runs["baseline"].pop("answer"), sort_keys=True, default=str) == json.dumps(
        runs["threads"].pop("answer"), sort_keys=True, default=str
    )
    return {
        "plant": plant.name,
        "record": name,
        "sim_s": unit,
        "jobs": jobs,
        "first": codes[0],
        **{f"{code}_{k}": v for code, run in runs.items() for k, v in run.items()},
        "ratio": runs["threads"]["seconds"] / runs["baseline"]["seconds"],
        "identical": same,
    }


def summary(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Per plant: the median per-record ratio, the sums of seconds and sims, identical answers."""
    lines = []
    for name in dict.fromkeys(r["plant"] for r in rows):
        mine = [r for r in rows if r["plant"] == name]
        base = sum(r["baseline_seconds"] for r in mine)
        thr = sum(r["threads_seconds"] for r in mine)
        lines.append(
            f"{name}: {len(mine)} records; threads / baseline per record, median {statistics.median(r['ratio'] for r in mine):.2f}x; "
            f"sum {thr:.1f} s / {base:.1f} s = {thr / base:.2f}x "
            f"({sum(r['threads_sims'] for r in mine):.0f} / {sum(r['baseline_sims'] for r in mine):.0f} sims); "
            f"identical answers {sum(r['identical'] for r in mine)}/{len(mine)}"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plants", nargs="+", default=["emps", "brfd"])
    ap.add_argument("--records", nargs="*", default=None, help="record names (default: every shipped one)")
    ap.add_argument("--jobs", type=int, default=2, help="threads of the current setting (default 2)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    rows: list[dict[str, Any]] = []
    order = 0
    for name in args.plants:
        plant = get_plant(name)
        for record in args.records or plant.examples:
            if record not in plant.examples:
                continue
            row = bench_record(plant, record, args.jobs, order)
            order += 1
            rows.append(row)
            print(
                f"{name} {record}: baseline {row['baseline_seconds']:.1f} s ({row['baseline_sims']:.0f} sims, "
                f"{row['baseline_n_eval']} simulations), {args.jobs} threads {row['threads_seconds']:.1f} s "
                f"({row['threads_sims']:.0f} sims); ratio {row['ratio']:.2f}; one simulation {1e3 * row['sim_s']:.1f} ms; "
                f"{'identical' if row['identical'] else 'DIFFERENT'} answers ({row['baseline_status']})",
                flush=True,
            )
            if args.json:
                write_json_atomic(args.json, {"code": code_version(), "rows": rows}, indent=1)
    for line in summary(rows):
        print(line)
    if args.json:
        write_json_atomic(args.json, {"code": code_version(), "rows": rows, "summary": summary(rows)}, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
