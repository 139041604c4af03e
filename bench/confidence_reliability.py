"""Is the verdict's confidence a probability? Reliability tables of committed blind runs, and the map's fit.

Measure (``--out``): read each run directory (``report.json`` and ``results.tar.xz``, in memory;
:func:`engine.validation.reliability.read_run`), then per protocol and per split (held out: runs the
confidence map was not fitted on; development: runs it was) write the reliability of the
confidence *before* (the decision's score, which every committed run states as its confidence;
for the locus, the locus estimate's own confidence) and *after* (the committed map applied to the
same scores, :mod:`engine.diagnosis.confidence`): every verdict, per verdict status, and the locus
of unexplained and weak-gap verdicts; per group of stated confidence the cases, mean stated and
observed accuracy with its Wilson 95 % interval, and the Brier score with a bootstrap 95 % interval.
"After" on the development runs is in-sample (the map was fitted on them) and says so.

Fit (``--fit``): fit the map on the given runs (development only: a run of :data:`HELD_OUT_RUNS`
is refused) and write it with its provenance. With ``--open-world-runs`` (runs of families outside
the catalogue whose blind figures are spent) the map's open-world part is fitted too
(:mod:`engine.diagnosis.open_world`): per band of the nominal chi2/n, how often the given runs'
in-catalogue records and those runs' records were answered ``explained``.

Runs whose every case is of a family outside the catalogue (``held_back``) are measured as a split
of their own ("outside the catalogue"), held out or development as above.

Examples (from the repository root)::

    python bench/confidence_reliability.py --fit engine/diagnosis/data/confidence_map.json \\
        docs/validation/v2-seed{97,151,163,173,191,223} docs/validation/v1-seed{193,199,211} \\
        --open-world-runs docs/validation/v2-heldout-seed241 docs/validation/v2-sealed-seed257 \\
        --locus-runs docs/validation/v2-heldout-seed241 docs/validation/v2-sealed-seed257 \\
        docs/validation/v2-sealed2-seed263 docs/validation/v2-sealed3-seed269 docs/validation/v2-sealed4-seed281
    python bench/confidence_reliability.py --out docs/validation/confidence \\
        docs/validation/v2-seed{97,151,163,173,191,223,229} docs/validation/v1-seed{193,199,211,227}
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import logging
import re
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from engine.atomic import write_text_atomic
from engine.diagnosis.confidence import (
    LOCUS_FEATURE,
    MAP_FILE,
    MIN_BLOCK,
    PRIOR,
    SCORE_FEATURE,
    ConfidenceMap,
    IsotonicMap,
    calibrated_confidence,
    fit_isotonic,
    load_map,
    locus_confidence,
    locus_feature,
)
from engine.diagnosis.open_world import fit_open_world
from engine.validation.provenance import code_version
from engine.validation.reliability import (
    IN_CATALOGUE_KINDS,
    TARGET_MIN_N,
    TARGET_TOLERANCE,
    VERDICT_STATUSES,
    CaseOutcome,
    RunOutcomes,
    explained_by_gap,
    read_run,
    reliability_markdown,
    reliability_section,
)
from engine.validation.rows import json_rows

logger = logging.getLogger("confidence_reliability")

#: The runs of the current diagnosis code, kept out of every fit: protocol-2 seed 229 (code
#: 99405d2) and protocol-1 seed 227 (code 1b3904d, the diagnosis of 99405d2); ``git diff 99405d2
#: HEAD -- engine/diagnosis`` changes no decision (the later-pass helper, the same fd step).
HELD_OUT_RUNS: tuple[str, ...] = ("v2-seed229", "v1-seed227")
#: The commit a protocol-1 run's README names in its title ("..., code 1b3904d ..."); its results
#: do not stamp one.
README_CODE = re.compile(r"\bcode ([0-9a-f]{7,40})\b")


def _readme_code(run_dir: Path) -> str | None:
    readme = run_dir / "README.md"
    if not readme.is_file():
        return None
    first = readme.read_text(encoding="utf-8").splitlines()[:1]
    m = README_CODE.search(first[0]) if first else None
    return m.group(1) if m else None


def _read(paths: Sequence[Path]) -> list[tuple[RunOutcomes, str | None]]:
    runs = []
    for p in paths:
        run = read_run(p)
        code = run.code_version or _readme_code(p)
        logger.info(
            "%s: protocol %d, %d cases, %d left out, code %s",
            run.name,
            run.protocol,
            len(run.outcomes),
            len(run.excluded),
            code,
        )
        runs.append((run, code))
    return runs


def _command(argv: Sequence[str]) -> str:
    return "python bench/confidence_reliability.py " + " ".join(argv)


def read_locus_rows(path: Path) -> list[tuple[float, bool]]:
    """(feature, right) of each case row of a locus re-run (``lab/scripts/locus_cases.py``'s JSON lines).

    Rows without a located answer (no ``locus_feature``) are left out, as the runs' are.

    Raises
    ------
    ValueError
        A row is not JSON or a case row lacks ``right``.
    """
    out: list[tuple[float, bool]] = []
    for _, row in json_rows(path, ("right",)):
        x = row.get("locus_feature")
        if isinstance(x, (int, float)):
            out.append((float(x), bool(row["right"])))
    return out


def fit_map(
    runs: Sequence[tuple[RunOutcomes, str | None]],
    command: str,
    locus_rows: Sequence[tuple[Path, list[tuple[float, bool]]]] = (),
    open_world_runs: Sequence[tuple[RunOutcomes, str | None]] = (),
    locus_runs: Sequence[tuple[RunOutcomes, str | None]] = (),
) -> ConfidenceMap:
    """The map fitted on ``runs``: per verdict status on the score, and the locus on :func:`locus_feature`.

    With ``locus_rows`` (files of a locus re-run and their (feature, right) pairs) the locus's map is
    fitted on those instead of the runs' unexplained and weak-gap verdicts. With ``open_world_runs``
    (runs of families outside the catalogue) the open-world part is fitted on their records against the
    in-catalogue records of ``runs``. With ``locus_runs`` (blind runs of families outside the catalogue)
    the locus's map is fitted on their located verdicts instead (the command line takes one of the two), right
    when the part the answer names holds an effect of the record.
    """
    outcomes = [o for run, _ in runs for o in run.outcomes]
    verdict: dict[str, IsotonicMap] = {}
    for status in VERDICT_STATUSES:
        xy = [(o.score, o.correct) for o in outcomes if o.status == status and o.score is not None]
        if xy:
            verdict[status] = fit_isotonic([x for x, _ in xy], [ok for _, ok in xy], SCORE_FEATURE)
    loc = [(locus_feature(o.locus_estimate), o.locus_correct) for o in outcomes if o.locus_correct is not None]
    loc_xy = [(x, bool(ok)) for x, ok in loc if x is not None]
    if locus_rows:
        loc_xy = [xy for _, rows in locus_rows for xy in rows]
    located = [o for run, _ in locus_runs for o in run.outcomes if o.locus_correct is not None]
    if located:
        loc_xy = [(x, bool(o.locus_correct)) for o in located if (x := locus_feature(o.locus_estimate)) is not None]
    locus = fit_isotonic([x for x, _ in loc_xy], [ok for _, ok in loc_xy], LOCUS_FEATURE) if loc_xy else None
    world = None
    if open_world_runs:
        inside = explained_by_gap(outcomes, IN_CATALOGUE_KINDS)
        outside = explained_by_gap(o for run, _ in open_world_runs for o in run.outcomes)
        world = fit_open_world(inside, outside)
    provenance = {
        "fitted_on": [
            {
                "run": run.name,
                "protocol": run.protocol,
                "seed": run.seed,
                "code_version": code,
                "n": len(run.outcomes),
                "excluded": [list(x) for x in run.excluded],
            }
            for run, code in runs
        ],
        "held_out": list(HELD_OUT_RUNS),
        "locus_fitted_on": (
            [
                {
                    "run": run.name,
                    "seed": run.seed,
                    "code_version": code,
                    "n": sum(o.locus_correct is not None for o in run.outcomes),
                }
                for run, code in locus_runs
            ]
            if locus_runs
            else [{"rows": str(p), "n": len(rows)} for p, rows in locus_rows]
            if locus_rows
            else "the unexplained and weak-gap verdicts of the runs above"
        ),
        "open_world_fitted_on": [
            {"run": run.name, "protocol": run.protocol, "seed": run.seed, "code_version": code, "n": len(run.outcomes)}
            for run, code in open_world_runs
        ],
        "fitted_at": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "fitted_by": command,
        "fitting_code": code_version().get("describe"),
        "method": (
            f"isotonic regression (pool adjacent violators) of 'right by the protocol's main criterion' on the "
            f"decision's score, per verdict status, over the pooled cases of the runs above; blocks of fewer than "
            f"{MIN_BLOCK} cases merged with the neighbour of closer accuracy; each block's accuracy shrunk by a "
            f"Beta({PRIOR:g}, {PRIOR:g}) prior; linear between blocks, flat beyond. Locus: the same on "
            f"{LOCUS_FEATURE}, on whether the verdict's locus is where an effect of the record acts "
            f"(engine.validation.reliability: the part the answer names, the locus with the loci the record "
            f"cannot tell from it)."
        ),
        "score": (
            "the decision's score (engine/diagnosis/decision.py; its formula and thresholds are the same in the "
            "code of every run above, d1e2cd2 to 99405d2, only the searches that feed it differ): the confidence "
            "those runs state"
        ),
    }
    return ConfidenceMap(verdict=verdict, locus=locus, provenance=provenance, open_world=world)


def _calibrated(o: CaseOutcome, cmap: ConfidenceMap) -> CaseOutcome:
    """The outcome as the map would state it: the score's calibrated probability, the locus's."""
    conf = calibrated_confidence(o.status, o.score, cmap, o.nominal_chi2) if o.score is not None else o.confidence
    loc = locus_confidence(o.locus_estimate, cmap) if o.locus_estimate is not None else None
    return replace(o, confidence=conf, locus_confidence=loc)


def _raw(o: CaseOutcome) -> CaseOutcome:
    """The outcome stating the decision's score (the confidence of every committed run)."""
    return replace(o, confidence=o.score)


def measure(
    runs: Sequence[tuple[RunOutcomes, str | None]], cmap: ConfidenceMap, command: str, map_name: str
) -> dict[str, Any]:
    """The measurement document: per protocol and split, the reliability before and after the map."""
    fitted = {r["run"] for r in cmap.provenance.get("fitted_on", [])}
    fitted |= {r["run"] for r in cmap.provenance.get("open_world_fitted_on", [])}
    locus_on = cmap.provenance.get("locus_fitted_on")
    fitted |= {r["run"] for r in locus_on if "run" in r} if isinstance(locus_on, list) else set()

    def split_of(r: RunOutcomes) -> str:
        outside = bool(r.outcomes) and all(o.kind == "held_back" for o in r.outcomes)
        return ("development" if r.name in fitted else "held_out") + ("_outside_the_catalogue" if outside else "")

    groups = []
    for split in ("held_out", "development", "held_out_outside_the_catalogue", "development_outside_the_catalogue"):
        for protocol in (2, 1):
            sel = [(r, c) for r, c in runs if r.protocol == protocol and split_of(r) == split]
            if not sel:
                continue
            outcomes = [o for r, _ in sel for o in r.outcomes]
            groups.append(
                {
                    "protocol": protocol,
                    "split": split,
                    "runs": [
                        {
                            "run": r.name,
                            "seed": r.seed,
                            "code_version": c,
                            "n": len(r.outcomes),
                            "excluded": len(r.excluded),
                        }
                        for r, c in sel
                    ],
                    "n": len(outcomes),
                    "before": reliability_section([_raw(o) for o in outcomes]),
                    "after": reliability_section([_calibrated(o, cmap) for o in outcomes]),
                    "after_in_sample": split.startswith("development"),
                }
            )
    per_run = []
    for r, c in runs:
        sec = reliability_section([_raw(o) for o in r.outcomes], resamples=0)
        per_run.append(
            {
                "run": r.name,
                "protocol": r.protocol,
                "code_version": c,
                "split": split_of(r),
                "n": sec["verdict"]["n"],
                "mean_stated": sec["verdict"]["mean_stated"],
                "accuracy": sec["verdict"]["accuracy"],
                "brier": sec["verdict"]["brier"]["value"],
            }
        )
    return {
        "command": command,
        "date": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "code_version": code_version(),
        "map": {"file": map_name, "provenance": cmap.provenance},
        "target": {"tolerance": TARGET_TOLERANCE, "min_n": TARGET_MIN_N},
        "groups": groups,
        "per_run": per_run,
    }


def _line(t: dict[str, Any] | None) -> str:
    if t is None:
        return "| 0 | | | | |"
    a, b = t["accuracy"], t["brier"]
    met = t["target_met"]
    brier = f"{b['value']:.3f}" + ("" if b["low"] is None else f" [{b['low']:.3f}, {b['high']:.3f}]")
    return (
        f"| {t['n']} | {100 * t['mean_stated']:.1f} | {a['k']}/{a['n']} = {100 * a['rate']:.1f} % "
        f"[{100 * a['low']:.1f}, {100 * a['high']:.1f}] | {brier} | "
        f"{'no group >= ' + str(TARGET_MIN_N) if met is None else 'yes' if met else '**no**'} |"
    )


def markdown(doc: dict[str, Any]) -> str:
    """The measurement as Markdown."""
    prov = doc["map"]["provenance"]
    fitted = ", ".join(f"{r['run']} ({r['code_version']})" for r in prov.get("fitted_on", []))
    lines = [
        "# Reliability of the verdict's confidence (issue 50, item 4)",
        "",
        f"- command: `{doc['command']}`",
        f"- date: {doc['date']}; code: `{doc['code_version'].get('describe')}`",
        f"- map: `{doc['map']['file']}`, fitted on {fitted} only (development), at {prov.get('fitted_at')}; "
        f"held out: {', '.join(prov.get('held_out', []))}",
        f"- method: {prov.get('method')}",
        "- before: the confidence every committed run states (the decision's score; for the locus, the locus "
        "estimate's own confidence); after: the committed map applied to the same scores and locus estimates.",
        "- right: by the protocol's main criterion (engine/validation/reliability.py); a locus is right when an "
        "effect of the record acts there.",
        f"- target: observed within {100 * doc['target']['tolerance']:g} points of stated in every group of >= "
        f"{doc['target']['min_n']} cases (groups of stated confidence [0, 0.5), [0.5, 0.7), [0.7, 0.8), [0.8, 0.9), "
        "[0.9, 0.95), [0.95, 1]); Wilson 95 % intervals, Brier with a bootstrap 95 % interval.",
        "",
        "## Summary",
        "",
        "| split | protocol | verdicts | when | n | mean stated % | observed (Wilson 95 %) | Brier (95 %) | target met |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for g in doc["groups"]:
        split = g["split"].replace("_", " ") + (" (after: in-sample)" if g["after_in_sample"] else "")
        for which in ("every", *VERDICT_STATUSES, "locus"):
            for when in ("before", "after"):
                sec = g[when]
                t = (
                    sec["verdict"]
                    if which == "every"
                    else sec["locus"]
                    if which == "locus"
                    else sec["by_status"].get(which)
                )
                if t is None:
                    continue
                lines.append(f"| {split} | {g['protocol']} | {which} | {when} " + _line(t))
    lines += [
        "",
        "## Per run (before: the confidence as stated)",
        "",
        "| run | protocol | code | split | n | mean stated % | observed | Brier |",
        "| --- |" + " --- |" * 7,
    ]
    for r in doc["per_run"]:
        a = r["accuracy"]
        lines.append(
            f"| {r['run']} | {r['protocol']} | {r['code_version']} | {r['split'].replace('_', ' ')} | {r['n']} | "
            f"{100 * r['mean_stated']:.1f} | {a['k']}/{a['n']} = {100 * a['rate']:.1f} % "
            f"[{100 * a['low']:.1f}, {100 * a['high']:.1f}] | {r['brier']:.3f} |"
        )
    for g in doc["groups"]:
        runs = ", ".join(r["run"] for r in g["runs"])
        for when in ("after", "before"):
            label = "after the map" + (" (in-sample: the map was fitted on these runs)" if g["after_in_sample"] else "")
            label = label if when == "after" else "before (as stated)"
            lines += [
                "",
                f"# {g['split'].replace('_', ' ').capitalize()}, protocol {g['protocol']} ({runs}): {label}",
                "",
            ]
            lines += [x.replace("## ", "### ", 1) if x.startswith("## ") else x for x in reliability_markdown(g[when])]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="+", help="run directories (report.json and results.tar.xz)")
    what = ap.add_mutually_exclusive_group(required=True)
    what.add_argument("--out", type=Path, help="write report.json and report.md of the measurement here")
    what.add_argument("--fit", type=Path, help="fit the map on the runs (development only) and write it here")
    ap.add_argument("--map", type=Path, default=None, help=f"the map to measure (default: the committed {MAP_FILE})")
    ap.add_argument(
        "--locus-rows",
        type=Path,
        nargs="+",
        default=(),
        help="with --fit: fit the locus's map on these rows of lab/scripts/locus_cases.py (development data: "
        "families whose blind run is spent) instead of the runs' unexplained verdicts",
    )
    ap.add_argument(
        "--locus-runs",
        type=Path,
        nargs="+",
        default=(),
        help="with --fit: blind runs of families outside the catalogue whose figures are spent; fits the locus's "
        "map on their located verdicts (instead of --locus-rows)",
    )
    ap.add_argument(
        "--open-world-runs",
        type=Path,
        nargs="+",
        default=(),
        help="with --fit: runs of families outside the catalogue whose blind figures are spent; fits the map's "
        "open-world part (engine.diagnosis.open_world)",
    )
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    for p in args.runs:
        if not (p / "report.json").is_file():
            ap.error(f"{p} holds no report.json: not a scored run")
    names = [p.name for p in args.runs]
    if args.fit is not None:
        held = sorted((set(names) | {p.name for p in (*args.open_world_runs, *args.locus_runs)}) & set(HELD_OUT_RUNS))
        if held:
            ap.error(f"refusing to fit on held-out runs: {', '.join(held)}")
        if args.locus_rows and args.locus_runs:
            ap.error("give the locus's map either --locus-rows or --locus-runs, not both")
        try:
            rows = [(p, read_locus_rows(p)) for p in args.locus_rows]
        except (OSError, ValueError) as e:
            ap.error(str(e))
        cmap = fit_map(_read(args.runs), _command(argv), rows, _read(args.open_world_runs), _read(args.locus_runs))
        write_text_atomic(args.fit, json.dumps(cmap.to_dict(), indent=1) + "\n")
        logger.info("wrote the map to %s", args.fit)
        return 0
    cmap = load_map(args.map)
    map_name = str(args.map) if args.map is not None else f"engine/diagnosis/{MAP_FILE}"
    doc = measure(_read(args.runs), cmap, _command(argv), map_name)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "report.json", json.dumps(doc, indent=1) + "\n")
    write_text_atomic(args.out / "report.md", markdown(doc))
    logger.info("wrote %s and %s", args.out / "report.json", args.out / "report.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
