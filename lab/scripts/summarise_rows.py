"""Summary of the per-case rows of ``lab/scripts/rediagnose.py``: how many right, and the time budgets of issue 10.

Each input file holds one JSON row per case (``case``, ``kind``, ``correct``, ``seconds``), as
``lab/scripts/rediagnose.py`` prints them. Files are read in order and a later row of the same case
replaces an earlier one, so a lever that changes only the records reaching one stage is scored
as the run before it with those records' new rows on top::

    T=lab/validation/v2-seed173/time-levers
    python lab/scripts/summarise_rows.py $T/seeded-fd-1e-5-default-compound.jsonl \\
        $T/seeded-fd-1e-5-compound-rest.jsonl $T/first-exchange-compound.jsonl

For each group (single; compound = pair and triple; then each kind present): the records right
(the case kind's main criterion: for a pair or triple, exactly the true set) and, for pairs and
triples whose rows hold their answer, every true effect named, each with the Wilson 95 % interval (:func:`engine.validation.stats.wilson_interval`), the median and the
90th percentile of the seconds with their order-statistic 95 % intervals
(:func:`engine.validation.stats.quantile_interval`), and how many exceed the group's budget
(one diagnosis on 2 cores: 10 s for a single, 60 s for a compound). The rows say on what machine
and load they were taken only where their files' README says so.

One JSON line on stdout; the same in words on stderr.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from _runs import BUDGET_P90_S, GROUPS

from engine.validation.rows import json_rows

logger = logging.getLogger("lab.summarise_rows")


def read_rows(paths: Iterable[Path]) -> dict[str, dict[str, Any]]:
    """The rows of every file by case id, a later file's row replacing an earlier one's.

    Raises
    ------
    ValueError
        On a line that is not a JSON object with ``case``, ``kind``, ``correct`` and ``seconds``
        (the file and line are named).
    """
    rows: dict[str, dict[str, Any]] = {}
    for path in paths:
        try:
            for _, row in json_rows(path, ("kind", "correct", "seconds")):
                rows[str(row["case"])] = row
        except ValueError as exc:
            raise ValueError(f"{exc} (rows of lab/scripts/rediagnose.py)") from None
    return rows


def all_true_named(row: Mapping[str, Any]) -> bool | None:
    """Whether an explained row names every effect of its ``truth`` (twins count, as the scorer's
    "every true effect named" counts them: :meth:`engine.validation.score.Answer.names_effect`);
    None for a row without ``truth``, ``status``, ``effects`` or ``alternatives``."""
    from engine.validation.score import Answer

    if not all(k in row for k in ("truth", "status", "effects", "alternatives")):
        return None
    answer = Answer(
        status=str(row["status"]),
        effects=tuple((str(e), None) for e in row["effects"]),
        locus=row.get("locus"),
        seconds=None,
        rms_before=None,
        rms_after=None,
        alternatives=tuple(tuple(a) for a in row["alternatives"]),
        near_twins=tuple(tuple(a) for a in row.get("near_twins", [])),
    )
    return answer.status == "explained" and all(answer.names_effect(str(n)) for n in row["truth"])


def summarise(rows: Mapping[str, Mapping[str, Any]], kinds: tuple[str, ...], budget: float | None) -> dict[str, Any]:
    """Rate right and the time quantiles of the rows of the given kinds (None when there are none)."""
    from engine.validation.stats import quantile_interval, wilson_interval

    chosen = [r for r in rows.values() if r["kind"] in kinds]
    if not chosen:
        return {"n": 0}
    n = len(chosen)
    k = sum(bool(r["correct"]) for r in chosen)
    lo, hi = wilson_interval(k, n)
    seconds = [float(r["seconds"]) for r in chosen]
    out: dict[str, Any] = {"n": n, "right": k, "rate": k / n, "rate_interval": [lo, hi]}
    for name, q in (("median", 0.5), ("p90", 0.9)):
        est = quantile_interval(seconds, q)
        out[f"{name}_s"] = est.value
        out[f"{name}_interval_s"] = [est.low, est.high]
    named = [all_true_named(r) for r in chosen]
    if all(x is not None for x in named) and any(r["kind"] in ("pair", "triple") for r in chosen):
        k_all = sum(bool(x) for x in named)
        out["all_true_named"] = k_all
        out["all_true_named_interval"] = list(wilson_interval(k_all, n))
    if budget is not None:
        out["budget_p90_s"] = budget
        out["over_budget"] = sum(s > budget for s in seconds)
    return out


def _interval(bounds: list[float | None]) -> str:
    """``[lo, hi]``, or why there is none (too few records for an order-statistic interval)."""
    lo, hi = bounds
    return "(too few for an interval)" if lo is None or hi is None else f"[{lo:.1f}, {hi:.1f}]"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "rows", nargs="+", type=Path, help="JSON-lines files of lab/scripts/rediagnose.py, later ones on top"
    )
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stderr)
    try:
        rows = read_rows(args.rows)
    except (OSError, ValueError) as exc:
        ap.error(str(exc))
    present = sorted({str(r["kind"]) for r in rows.values()})
    groups: dict[str, tuple[tuple[str, ...], float | None]] = {
        g: (kinds, BUDGET_P90_S[g]) for g, kinds in GROUPS.items() if set(kinds) & set(present)
    }
    groups.update({k: ((k,), None) for k in present if k not in groups})
    summary = {name: summarise(rows, kinds, budget) for name, (kinds, budget) in groups.items()}
    for name, s in summary.items():
        if not s["n"]:
            continue
        over = f"  over {s['budget_p90_s']:.0f} s: {s['over_budget']}" if "budget_p90_s" in s else ""
        if "all_true_named" in s:
            pct = [100 * v for v in s["all_true_named_interval"]]
            over += f"  every true effect named {s['all_true_named']}/{s['n']} {_interval(pct)}"
        logger.info(
            "%-9s n=%3d  right %d/%d = %.1f %% %s  median %.1f s %s  p90 %.1f s %s%s",
            name,
            s["n"],
            s["right"],
            s["n"],
            100 * s["rate"],
            _interval([100 * v for v in s["rate_interval"]]),
            s["median_s"],
            _interval(s["median_interval_s"]),
            s["p90_s"],
            _interval(s["p90_interval_s"]),
            over,
        )
    print(json.dumps({"files": [str(p) for p in args.rows], "cases": len(rows), "groups": summary}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
