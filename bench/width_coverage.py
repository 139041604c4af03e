"""Coverage of the width a diagnosis shows: is the truth inside its 95 % interval? (issue 50, item 2)

``python bench/width_coverage.py RUN_DIR [RUN_DIR ...] [--json OUT.json]``: each RUN_DIR is a protocol-2 run directory
with its answer key (``out/validation-v2-seedN``), or a committed run (``docs/validation/v2-seedN``,
the truth read from its report, rounded to 1 um); several are pooled. Prints the markdown table of
:func:`engine.validation.width_coverage.coverage_markdown`.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from dataclasses import asdict
from pathlib import Path

from engine.validation.width_coverage import coverage, coverage_markdown, truths_from_committed, truths_from_layout

logger = logging.getLogger(__name__)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "runs", type=Path, nargs="+", help="protocol-2 run directories, or committed runs in docs/validation (pooled)"
    )
    parser.add_argument("--json", type=Path, help="also write the rows as JSON here")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    truths = []
    sources = []
    for run in args.runs:
        if (run / "key" / "answer_key.json").is_file():
            truths += truths_from_layout(run)
            sources.append(f"{run} (truth from its answer key)")
        elif (run / "results.tar.xz").is_file() and (run / "report.json").is_file():
            truths += truths_from_committed(run)
            sources.append(f"{run} (truth from its report, to 1 um)")
        else:
            logger.error("%s holds neither an answer key nor report.json with results.tar.xz", run)
            return 2
    source = f"on the {len(truths)} diagnosed cases of " + ", ".join(sources)
    rows = coverage(truths)
    sys.stdout.write(coverage_markdown(rows, source))
    if args.json:
        clean = [{k: (None if isinstance(v, float) and v != v else v) for k, v in asdict(r).items()} for r in rows]
        payload = {
            "source": source,
            "rows": [{**c, "wilson_95": list(r.interval) if r.n else None} for c, r in zip(clean, rows, strict=True)],
        }
        args.json.write_text(json.dumps(payload, indent=1, allow_nan=False) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
