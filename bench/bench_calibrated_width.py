"""Benchmark: the calibrated K as a continuous width identifier, and its 95 % interval's coverage.

``python bench/bench_calibrated_width.py [n_cases] [--offset N] [--out DIR]``: scores
:func:`engine.identification.width.estimate_width` on the main job's random held-out records
``N .. N + n_cases - 1`` (default 20 records from 0), every channel and noise level
(:func:`engine.evaluation.continuous.evaluate_continuous`), and prints the markdown table. With
``--out``, also writes ``DIR/report.md`` (the table with the command, date, code version and n)
and ``DIR/report.json`` (the same as data). Records 0-19 are the ones the interval was developed
on; the committed report (``docs/validation/continuous-width/``) is scored on others
(``--offset 20``).
"""

from __future__ import annotations

import argparse
import json
import logging
import shlex
import sys
from dataclasses import asdict
from datetime import UTC, datetime
from pathlib import Path

from engine.evaluation.continuous import channel_coverage, continuous_markdown, coverage_markdown, evaluate_continuous
from engine.validation.provenance import code_version
from engine.validation.stats import wilson_interval

logger = logging.getLogger(__name__)

#: Records the profile-likelihood interval was developed on (``--offset 0``, the first 20): a
#: report on any of them says so, as its figures are not blind.
DEVELOPMENT_RECORDS: range = range(0, 20)


def _report(rows_md: str, pooled_md: str, meta: dict[str, object]) -> str:
    records = range(int(str(meta["offset"])), int(str(meta["offset"])) + int(str(meta["n"])))
    developed = set(records) & set(DEVELOPMENT_RECORDS)
    provenance = (
        f"records {records.start}-{records.stop - 1}, of which {len(developed)} were used to develop the interval: "
        "not a blind figure"
        if developed
        else f"records {records.start}-{records.stop - 1}, none of which was used to develop the interval "
        f"(developed on {DEVELOPMENT_RECORDS.start}-{DEVELOPMENT_RECORDS.stop - 1})"
    )
    return (
        "# The calibrated K as a continuous width: accuracy and coverage of its 95 % interval\n\n"
        f"Command: `{meta['command']}`  \n"
        f"Date: {meta['date']}  \n"
        f"Code: {meta['head']}{' (with uncommitted changes)' if meta['dirty'] else ''}  \n"
        f"n = {meta['n']} records per channel and noise level: {provenance}.\n\n"
        "One channel at a time, K and J1 fitted with c and c1 known; the same random held-out records and "
        'noise draws as the identification accuracy (`engine.evaluation.accuracy`). "Inside the 95 % '
        'interval": the true K lies in `interval_95` (profile likelihood, `engine.identification.width`), '
        'with the Wilson 95 % interval of that fraction. "Within 2 sd": `sigma_K` = half the interval over '
        '1.96. "Within 2 Gauss-Newton sd (before)": the linearised sigma reported before the profile '
        "interval. Times are wall times on a shared machine.\n\n"
        "Per channel, pooled over the noise levels (issue 50's target: at least 90 % on every channel):\n\n"
        + pooled_md
        + "\nPer channel and noise level:\n\n"
        + rows_md
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n_cases", nargs="?", type=int, default=20, help="records per channel and noise level")
    parser.add_argument("--offset", type=int, default=0, help="index of the first random record scored")
    parser.add_argument("--out", type=Path, help="write report.md and report.json to this directory")
    parser.add_argument("--workers", type=int, default=None, help="local Dask workers (default one per core)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    command = " ".join(
        [".venv/bin/python bench/bench_calibrated_width.py", str(args.n_cases)]
        + (["--offset", str(args.offset)] if args.offset else [])
        + (["--out", shlex.quote(str(args.out))] if args.out else [])
        + (["--workers", str(args.workers)] if args.workers is not None else [])
    )
    rows = evaluate_continuous(n_cases=args.n_cases, offset=args.offset, n_jobs=args.workers)
    table = continuous_markdown(rows)
    pooled = coverage_markdown(rows)
    sys.stdout.write(pooled + "\n" + table)
    if args.out:
        version = code_version()
        commit = version["commit"]
        meta: dict[str, object] = {
            "command": command,
            "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
            "head": commit[:7] if isinstance(commit, str) else None,
            "dirty": version["dirty"],
            "n": args.n_cases,
            "offset": args.offset,
        }
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "report.md").write_text(_report(table, pooled, meta))
        payload = {
            **meta,
            "rows": [
                {**asdict(r), "coverage": r.coverage, "coverage_wilson_95": list(r.coverage_interval)} for r in rows
            ],
            "channels": [
                {
                    "channel": ch,
                    "covered": k,
                    "n": n,
                    "coverage_wilson_95": list(wilson_interval(k, n)),
                    "covered_noisy": k_noisy,
                    "n_noisy": n_noisy,
                    "coverage_noisy_wilson_95": list(wilson_interval(k_noisy, n_noisy)) if n_noisy else None,
                }
                for ch, k, n, k_noisy, n_noisy in channel_coverage(rows)
            ],
        }
        (args.out / "report.json").write_text(json.dumps(payload, indent=1, allow_nan=False) + "\n")
        logger.info("wrote %s and %s", args.out / "report.md", args.out / "report.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
