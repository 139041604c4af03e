"""Score the identification before and after the fix again over a finished protocol-1 run.

``backlash validate --protocol 1`` scores the identification once, when the run ends
(``<run>/identification.md``). This scores it again with the current scorer
(:func:`engine.evaluation.identification.score_identification`), for example to add a split the
run's scorer did not have, and writes ``identification.md`` and ``identification.json`` to
``--to`` (never into the run, whose files are its record)::

    python lab/scripts/rescore_identification.py out/validation-v1-seed211 --to lab/validation/v1-seed211/rescored

It reads the run's answer key, as the scorer does once every diagnosis is done. A few minutes
for 200 cases on one core (it trains patterns for each effect record's diagnosed and true effect).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from engine.evaluation.identification import identification_markdown, score_identification

logger = logging.getLogger("lab.rescore_identification")


def main(argv: list[str] | None = None) -> int:
    """Score ``run`` and write the two files to ``--to``; 2 on a run that is not a finished protocol-1 run."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="output directory of a finished protocol-1 run")
    ap.add_argument("--to", type=Path, required=True, help="directory for identification.md and .json")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    missing = [p for p in ("key/answer_key.json", "cases", "results") if not (args.run / p).exists()]
    if missing:
        logger.error("%s is not a finished protocol-1 run: %s missing", args.run, ", ".join(missing))
        return 2
    if args.to.resolve() == args.run.resolve():
        logger.error("--to must not be the run itself (its identification files are the run's record)")
        return 2

    def progress(done: int, total: int) -> None:
        if done % 20 == 0 or done == total:
            logger.info("%d of %d records scored", done, total)

    try:
        scored = score_identification(args.run, progress=progress)
    except ValueError as exc:
        logger.error("%s", exc)
        return 2
    args.to.mkdir(parents=True, exist_ok=True)
    text = identification_markdown(scored)
    (args.to / "identification.md").write_text(text)
    (args.to / "identification.json").write_text(json.dumps(scored, indent=1))
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
