"""Render the measurement tables of README.md and docs/ from the committed reports.

A table that reports a measurement is never typed: it sits in a marked region of a Markdown file,

    <!-- gen:NAME -->
    ...
    <!-- /gen:NAME -->

and this script writes the region's body from the committed report (JSON, CSV or JSON-lines rows)
that the renderer ``NAME`` reads (:data:`RENDERERS`). Every region ends with a line naming its
sources, so a reader can open them.

Usage (from the repository root, with the project's venv)::

    .venv/bin/python docs/gen.py            # rewrite every region of README.md and docs/**/*.md
    .venv/bin/python docs/gen.py --check    # exit 1 naming every stale region (tests/test_docs_figures.py)
    .venv/bin/python docs/gen.py --list     # the renderers and the files they read

A region whose renderer is unknown is an error (exit 2). The statistics (Wilson intervals,
order-statistic intervals of quantiles) are those of :mod:`engine.validation.stats`, the module the
scorers use.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
VALIDATION = "docs/validation"

#: An unformatted f-string placeholder that calls a function (``{pooled_rate(``) in a rendered region (a
#: bare ``{name}`` is not one: route templates such as ``/v1/assets/{a}/history`` are shown so).
PLACEHOLDER = re.compile(r"\{[A-Za-z_][A-Za-z0-9_.]*\(")
#: A marked region: the opening marker, the generated body, the closing marker of the same name, each
#: marker alone on its line (a marker quoted inside a line of text is not one).
REGION = re.compile(
    r"^(?P<open><!-- gen:(?P<name>[A-Za-z0-9_-]+) -->\n)(?P<body>.*?)^(?P<close><!-- /gen:(?P=name) -->)$", re.S | re.M
)
#: Any opening or closing marker alone on its line (to find a marker without its partner).
MARKER = re.compile(r"^<!-- (/?)gen:([A-Za-z0-9_-]+) -->$", re.M)


# --- reading ------------------------------------------------------------------------------------


def read_json(path: str) -> Any:
    """The JSON document at ``path`` (relative to the repository root)."""
    return json.loads((ROOT / path).read_text())


def read_csv(path: str) -> list[dict[str, str]]:
    """The rows of the CSV file at ``path`` (relative to the repository root)."""
    with (ROOT / path).open(newline="") as f:
        return list(csv.DictReader(f))


def read_rows(paths: Iterable[str]) -> list[dict[str, Any]]:
    """The JSON-lines rows of the files at ``paths``, a later row of the same case replacing an earlier one
    (as ``lab/scripts/summarise_rows.py`` reads them)."""
    rows: dict[str, dict[str, Any]] = {}
    for path in paths:
        for line in (ROOT / path).read_text().splitlines():
            if line.strip():
                row = json.loads(line)
                rows[str(row["case"])] = row
    return list(rows.values())


# --- formatting ---------------------------------------------------------------------------------


def wilson(k: int, n: int) -> tuple[float, float]:
    """Wilson 95 % interval of ``k`` in ``n`` (the scorers' :func:`engine.validation.stats.wilson_interval`)."""
    from engine.validation.stats import wilson_interval

    return wilson_interval(k, n)


def pct(x: float, digits: int = 1) -> str:
    """A fraction as a percentage: ``0.9731 -> '97.3 %'``."""
    return f"{100 * x:.{digits}f} %"


def interval(low: float | None, high: float | None, digits: int = 1, scale: float = 100.0) -> str:
    """``[low, high]`` scaled (percent by default), or a dash when there is none."""
    if low is None or high is None:
        return "[–]"
    return f"[{scale * low:.{digits}f}, {scale * high:.{digits}f}]"


def rate(k: int, n: int, low: float | None = None, high: float | None = None) -> str:
    """``k/n = r % [low, high]``: the interval given, else Wilson's."""
    if n == 0:
        return "0/0"
    if low is None or high is None:
        low, high = wilson(k, n)
    return f"{k}/{n} = {pct(k / n)} {interval(low, high)}"


def rate_of(r: Mapping[str, Any]) -> str:
    """A scorer's rate object (``k``, ``n``, ``low``, ``high``) as :func:`rate`."""
    return rate(int(r["k"]), int(r["n"]), r.get("low"), r.get("high"))


def seconds(x: float | None) -> str:
    """A time in seconds, three significant figures."""
    return "–" if x is None else f"{x:.3g} s"


def table(head: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(head) + " |", "| " + " | ".join("---" for _ in head) + " |"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


@dataclass(frozen=True)
class Page:
    """The Markdown file a region is rendered into: links are written relative to it."""

    path: Path

    @property
    def in_docs(self) -> bool:
        """Whether the file is a page of the documentation site (under ``docs/``)."""
        return DOCS in self.path.resolve().parents

    def link(self, target: str, text: str | None = None) -> str:
        """A link to ``target`` (a path from the repository root) that works where the file is read.

        From README.md (and any file outside ``docs/``) a relative link, which GitHub-like viewers
        follow. From a page of the site, a relative link when the target is inside ``docs/`` (the
        site copies it; ``mkdocs build --strict`` checks it), else the path as code: a site page must
        not link outside the site.
        """
        label = text or target
        inside = (ROOT / target).resolve().is_relative_to(DOCS)
        if self.in_docs and not inside:
            return f"`{target}`" if text is None else f"{label} (`{target}`)"
        rel = os.path.relpath(ROOT / target, self.path.resolve().parent)
        return f"[{label}]({Path(rel).as_posix()})"


def sources(page: Page, paths: Sequence[str], command: str | None = None) -> str:
    """The closing line of a region: what it was generated from."""
    links = ", ".join(page.link(p) for p in paths)
    how = f"; the report's own command: `{command}`" if command else ""
    return f"\n\n<sub>Generated by `python docs/gen.py` from {links}{how}.</sub>"


# --- protocol 2 ---------------------------------------------------------------------------------

P2_RUNS = (191, 223, 229, 239)
#: The blind run on the held-out family (model 1.2), kept apart from development.
HELD_OUT_RUN = "v2-heldout-seed241"
#: The blind run on the sealed family (model 1.3), defined after the locus work that HELD_OUT's run led to.
SEALED_RUN = "v2-sealed-seed257"
#: The blind run on the second sealed family (model 1.4), defined before the locus work that seed 257's run led to.
SEALED2_RUN = "v2-sealed2-seed263"
#: The blind run on the third sealed family (model 1.5), defined before the open-world work was scored on it.
SEALED3_RUN = "v2-sealed3-seed269"
#: The blind run on the fourth sealed family (model 1.6), defined before the work seed 269's run led to was scored.
SEALED4_RUN = "v2-sealed4-seed281"
#: The blind run on the fifth sealed family (model 1.7), defined before the work seed 281's run led to was committed.
SEALED5_RUN = "v2-sealed5-seed283"
#: The protocol-2 blind run on the described drive of docs/examples/drive-60hz-conveyor.toml (issue 52).
DRIVE_RUN = "v2-conveyor-seed311"
#: The time budgets of issue 10 (90th percentile of one diagnosis at a time on 2 cores).
BUDGET_S = {"single": 10.0, "compound": 60.0}


def p2_report(seed: int) -> dict[str, Any]:
    """The scorer's report of the protocol-2 run of ``seed``."""
    return dict(read_json(f"{VALIDATION}/v2-seed{seed}/report.json"))


def p2_metric(report: Mapping[str, Any], name: str) -> dict[str, Any]:
    """One target's entry of a protocol-2 report."""
    return next(m for m in report["metrics"] if m["name"] == name)


def _met_word(target: Any, m: Mapping[str, Any]) -> str:
    """``met`` or ``not met`` by the point estimate, ``not by the whole interval`` when only it meets."""
    r = m["rate"]
    if r["rate"] is None:
        return "n/a"
    if not target.met(r["rate"]):
        return "not met"
    edge = r["low"] if target.direction == ">=" else r["high"]
    return "met" if edge is not None and target.met(edge) else "met, not by the whole interval"


def p2_single_locus(report: Mapping[str, Any]) -> dict[str, Any]:
    """The held-back records whose verdict's single locus is the effect's: ``held_back_locus_single``, or, in
    reports scored before the loci the record cannot tell apart were named together, ``held_back_locus``
    (which was that)."""
    for m in (*report["metrics"], *report.get("breakdown", ())):
        if m["name"] == "held_back_locus_single":
            return m
    return p2_metric(report, "held_back_locus")


def p2_cell(m: Mapping[str, Any]) -> str:
    """A protocol-2 target's result: a rate, a median, or a time quantile (throughput) with its interval."""
    if "rate" in m:
        return rate_of(m["rate"])
    if "quantile" in m:
        q, med = m["quantile"], m["median"]
        return f"{seconds(q['value'])} {interval(q['low'], q['high'], 1, 1.0)} (median {seconds(med['median'])})"
    med = m["median"]
    return f"{med['median']:.3f} (n = {med['n']}) {interval(med['low'], med['high'], 3, 1.0)}"


def met(m: Mapping[str, Any]) -> str:
    """Whether a target is met: by the whole interval, at the point estimate, or not."""
    if m["met"] and m["interval_met"]:
        return "yes (whole interval)"
    return "yes (point)" if m["met"] else "**no**"


def p2_code(report: Mapping[str, Any]) -> str:
    """The commit a protocol-2 run's diagnoses ran on."""
    return str(report["code_version"]["describe"]).removesuffix("-dirty")


def render_p2_runs(page: Page) -> str:
    """The targets of the last protocol-2 blind runs, one column per run, and whether the newest met them."""
    reports = {s: p2_report(s) for s in P2_RUNS}
    newest = reports[P2_RUNS[-1]]
    head = ["metric (target)"] + [
        f"seed {s}, code {p2_code(r)}, {r['n_cases']} cases" + (" (newest)" if s == P2_RUNS[-1] else "")
        for s, r in reports.items()
    ]
    head.append(f"met ({P2_RUNS[-1]})")
    rows = []
    for m in newest["metrics"]:
        name = m["name"]
        target = m["target"].replace(" (report only)", "; throughput, report only")
        cells = [p2_cell(p2_metric(r, name)) for r in reports.values()]
        rows.append([f"{m['description']} ({target})", *cells, met(m)])
    paths = [f"{VALIDATION}/v2-seed{s}/report.json" for s in P2_RUNS]
    return table(head, rows) + sources(page, paths)


def idle_summary(rows: Sequence[Mapping[str, Any]], kinds: tuple[str, ...], budget: float) -> list[str]:
    """Right, median and p90 time with their intervals, and the records over the budget."""
    from engine.validation.stats import quantile_interval

    chosen = [r for r in rows if r["kind"] in kinds]
    n, k = len(chosen), sum(bool(r["correct"]) for r in chosen)
    t = [float(r["seconds"]) for r in chosen]
    med, p90 = quantile_interval(t, 0.5), quantile_interval(t, 0.9)
    return [
        str(n),
        rate(k, n),
        f"{seconds(med.value)} {interval(med.low, med.high, 1, 1.0)}",
        f"**{seconds(p90.value)}** {interval(p90.low, p90.high, 1, 1.0)} ({budget:.0f} s)",
        str(sum(x > budget for x in t)),
    ]


def render_p2_time_idle(page: Page) -> str:
    """The time budgets measured one diagnosis at a time on the idle machine, on each run's own records."""
    rows, paths = [], []
    for seed in (191, 223, 229):
        folder = f"lab/validation/v2-seed{seed}/time"
        files = [f"{folder}/{k}.jsonl" for k in ("single", "pair", "triple")]
        paths += files
        data = read_rows(files)
        code = p2_code(p2_report(seed))
        rows.append([f"seed {seed} (code {code})", "single", *idle_summary(data, ("single",), BUDGET_S["single"])])
        rows.append(
            [
                f"seed {seed} (code {code})",
                "pair or triple",
                *idle_summary(data, ("pair", "triple"), BUDGET_S["compound"]),
            ]
        )
    head = ["records", "kind", "n", "right", "median", "p90 (budget)", "over budget"]
    note = (
        "\n\nRows of `lab/scripts/rediagnose.py` (development data: the runs had been scored), summarised as "
        "`lab/scripts/summarise_rows.py` does; order-statistic 95 % intervals of the median and the 90th percentile."
    )
    return table(head, rows) + note + sources(page, paths)


def render_p2_families(page: Page) -> str:
    """Effects outside the catalogue: the family the open-world step was developed on against one kept apart."""
    runs = [
        (
            "v2-seed229",
            "held-back five (developed on), seed 229",
            "docs/validation/width/held-out-seed229.json",
            "rule",
        ),
        (
            "v2-seed239",
            "held-back five (developed on), seed 239",
            f"{VALIDATION}/v2-seed239/width-coverage.json",
            "answer",
        ),
        (
            HELD_OUT_RUN,
            "held-out seven (model 1.2, never developed on), seed 241",
            f"{VALIDATION}/{HELD_OUT_RUN}/width-coverage.json",
            "answer",
        ),
        (
            SEALED_RUN,
            "sealed seven (model 1.3, defined after the locus work; never developed on), seed 257",
            f"{VALIDATION}/{SEALED_RUN}/width-coverage.json",
            "answer",
        ),
        (
            SEALED2_RUN,
            "second sealed seven (model 1.4, defined before the work seed 257 led to; never developed on), seed 263",
            f"{VALIDATION}/{SEALED2_RUN}/width-coverage.json",
            "answer",
        ),
        (
            SEALED3_RUN,
            "third sealed seven (model 1.5, defined before the work seed 263 led to was scored; never developed on), "
            "seed 269",
            f"{VALIDATION}/{SEALED3_RUN}/width-coverage.json",
            "answer",
        ),
        (
            SEALED4_RUN,
            "fourth sealed seven (model 1.6, defined before the work seed 269 led to was scored; never developed on), "
            "seed 281",
            f"{VALIDATION}/{SEALED4_RUN}/width-coverage.json",
            "answer",
        ),
        (
            SEALED5_RUN,
            "fifth sealed seven (model 1.7, defined before the work seed 281 led to was committed; never developed "
            "on), seed 283",
            f"{VALIDATION}/{SEALED5_RUN}/width-coverage.json",
            "answer",
        ),
    ]
    rows, paths = [], []
    for run, label, cov_path, rule in runs:
        report = read_json(f"{VALIDATION}/{run}/report.json")
        cov = coverage_row(cov_path, rule, "status unexplained")
        paths += [f"{VALIDATION}/{run}/report.json", cov_path]
        rows.append(
            [
                f"{label}, code {p2_code(report)}",
                rate_of(p2_metric(report, "held_back_unexplained")["rate"]),
                rate_of(p2_metric(report, "held_back_locus")["rate"]),
                rate_of(p2_single_locus(report)["rate"]),
                f"{cov['covered']}/{cov['n']} = {coverage_cell(cov)}"
                + (" (rebuilt from the stored fits)" if rule == "rule" else ""),
            ]
        )
    head = [
        "records of effects outside the catalogue",
        "answered `unexplained` (>= 80 %; >= 90 % for a family kept for scoring, issue 50)",
        "part named right (>= 80 %): the locus, or the loci the record cannot tell apart",
        "single locus right",
        "width of `unexplained` answers: truth inside the 95 % interval",
    ]
    return table(head, rows) + sources(page, paths)


def render_drive_p2(page: Page) -> str:
    """Protocol 2 on the described drive of docs/examples (issue 52): every target, and the width's coverage."""
    path, cov_path = f"{VALIDATION}/{DRIVE_RUN}/report.json", f"{VALIDATION}/{DRIVE_RUN}/width-coverage.json"
    report = read_json(path)
    drive = report["drive"]
    rows = [
        [
            f"{m['description']} ({m['target'].replace(' (report only)', '; throughput, report only')})",
            p2_cell(m),
            met(m),
        ]
        for m in report["metrics"]
    ]
    for group in ("all", "status explained", "status no_gap", "status unexplained"):
        r = coverage_row(cov_path, "answer", group)
        missing = f", {r['not_identifiable']} not identifiable" if r["not_identifiable"] else ""
        label = "every verdict" if group == "all" else f"`{group.removeprefix('status ')}`"
        rows.append(
            [
                f"the answer's width: truth inside the stated 95 % interval, {label}{missing} (>= 90 %)",
                f"{r['covered']}/{r['n']} = {coverage_cell(r)}",
                "yes (point)" if r["n"] and r["covered"] / r["n"] >= 0.9 else "**no**",
            ]
        )
    head = [
        f"metric (target); drive {drive['name']!r} ({str(drive['fingerprint'])[:12]}), seed {report['seed']}, "
        f"code {p2_code(report)}, {report['n_cases']} cases",
        "result",
        "met",
    ]
    return table(head, rows) + sources(page, [path, cov_path])


# --- the width after a diagnosis ------------------------------------------------------------------


def coverage_row(path: str, rule: str, group: str) -> dict[str, Any]:
    """One row of a width-coverage report (``bench/width_coverage.py --json``)."""
    rows = read_json(path)["rows"]
    return dict(next(r for r in rows if r["rule"] == rule and r["group"] == group))


def coverage_cell(r: Mapping[str, Any]) -> str:
    """Coverage with its Wilson interval."""
    lo, hi = r["wilson_95"]
    return f"{pct(r['covered'] / r['n'])} {interval(lo, hi)}"


def render_width_coverage(page: Page) -> str:
    """Truth inside the stated 95 % interval of the width: before (the nominal fit) and the answer's width."""
    dev, held = "docs/validation/width/development.json", "docs/validation/width/held-out-seed229.json"
    blind, rescored = f"{VALIDATION}/v2-seed239/width-coverage.json", "docs/validation/width/seed239-rescored.json"
    out241 = f"{VALIDATION}/{HELD_OUT_RUN}/width-coverage.json"
    spent = "docs/validation/width/spent-families-rescored.json"
    spec = [
        ("development, seeds 97-223 (chose the constants): every verdict", dev, "all", "rule"),
        ("held out, seed 229: every verdict", held, "all", "rule"),
        ("seed 229: `explained`", held, "status explained", "rule"),
        ("seed 229: `no_gap`", held, "status no_gap", "rule"),
        ("seed 229: `unexplained`", held, "status unexplained", "rule"),
        ("blind run seed 239 (code 1e0908a, the widths as answered, factor 3): every verdict", blind, "all", "answer"),
        ("seed 239: `explained`", blind, "status explained", "answer"),
        ("seed 239: `no_gap`", blind, "status no_gap", "answer"),
        ("seed 239: `unexplained`", blind, "status unexplained", "answer"),
        ("seed 239 re-scored by today's rule (factor 4.5; not blind for it): every verdict", rescored, "all", "rule"),
        ("seed 239 re-scored: `unexplained`", rescored, "status unexplained", "rule"),
        ("held-out family, seed 241 (code 9878c7f, factor 4.5, out of sample): every verdict", out241, "all", "answer"),
        ("seed 241: `unexplained`", out241, "status unexplained", "answer"),
        (
            "the three spent families (seeds 241, 257, 263) re-scored by today's rule, stand-in term included "
            "(development: chosen looking at them): every verdict",
            spent,
            "all",
            "rule",
        ),
        ("the three spent families re-scored: `explained` (every one a stand-in)", spent, "status explained", "rule"),
        ("the three spent families as answered: `explained`", spent, "status explained", "answer"),
    ]
    rows = []
    for label, path, group, rule in spec:
        nominal, answer = coverage_row(path, "nominal", group), coverage_row(path, rule, group)
        missing = f" ({answer['not_identifiable']} not identifiable)" if answer["not_identifiable"] else ""
        rows.append(
            [
                label + missing,
                f"{nominal['n']} / {answer['n']}",
                coverage_cell(nominal),
                f"{answer['covered']}/{answer['n']} = {coverage_cell(answer)}",
                f"{answer['median_half_width_um']:.3g}",
            ]
        )
    head = [
        "protocol-2 records",
        "n (before / answer)",
        "the width shown before (nominal fit)",
        "the answer's width",
        "median 95 % half-width [um]",
    ]
    return table(head, rows) + sources(page, [dev, held, blind, rescored, out241, spent])


# --- confidence -----------------------------------------------------------------------------------


def render_open_world(page: Page) -> str:
    """The committed map's open-world part: per band of the nominal chi2/n, the counts and the stand-in chance."""
    path = "engine/diagnosis/data/confidence_map.json"
    cmap = read_json(path)
    world, prov = cmap["open_world"], cmap["provenance"]
    edges = [0.0, *world["edges"], math.inf]
    rows = []
    for i, ((k_in, n_in), (k_out, n_out)) in enumerate(zip(world["explained_in"], world["explained_out"], strict=True)):
        band = f"{edges[i]:g} to {edges[i + 1]:g}" if math.isfinite(edges[i + 1]) else f">= {edges[i]:g}"
        rows.append([band, rate(k_in, n_in), rate(k_out, n_out), f"{world['stand_in'][i]:.2f}"])
    head = [
        f"{world['feature']}",
        "in-catalogue records answered `explained` there (development runs)",
        "records of new physics answered `explained` there ("
        + ", ".join(r["run"] for r in prov.get("open_world_fitted_on", []))
        + ")",
        "chance that such an answer is a stand-in",
    ]
    note = (
        f"\n\nShare of gaps taken to be of physics outside the catalogue: {world['share']:.3f} (protocol 2's mix, an "
        "assumption); Bayes' rule with a Beta(1/2, 1/2) prior on each rate."
    )
    return table(head, rows) + note + sources(page, [path])


def render_confidence(page: Page) -> str:
    """Stated against observed accuracy on the held-out runs, before and after the map."""
    path = "docs/validation/confidence/report.json"
    report = read_json(path)
    rows = []
    for g in report["groups"]:
        if g["split"] not in ("held_out", "held_out_outside_the_catalogue"):
            continue
        outside = g["split"] != "held_out"
        runs = ", ".join(f"{r['run']} ({r['code_version']})" for r in g["runs"])
        runs += " (outside the catalogue)" if outside else ""
        parts: list[tuple[str, Mapping[str, Any], Mapping[str, Any]]] = [
            ("every verdict", g["before"]["verdict"], g["after"]["verdict"])
        ]
        # a family outside the catalogue: its explained answers (all stand-ins) are the point, however few
        parts += [
            (f"`{s}`", g["before"]["by_status"][s], g["after"]["by_status"][s])
            for s in g["before"]["by_status"]
            if g["before"]["by_status"][s]["n"] >= report["target"]["min_n"]
            or (outside and s == "explained" and g["before"]["by_status"][s]["n"])
        ]
        parts.append(("locus", g["before"]["locus"], g["after"]["locus"]))
        for label, b, a in parts:
            if not b["n"]:
                continue
            rows.append(
                [
                    f"{g['protocol']}: {runs}",
                    label,
                    str(b["n"]),
                    f"{pct(b['mean_stated'])}, {rate_of(b['accuracy'])}, {b['brier']['value']:.3f}",
                    f"{pct(a['mean_stated'])}, {a['brier']['value']:.3f} "
                    f"{interval(a['brier']['low'], a['brier']['high'], 3, 1.0)}",
                    "no group of 20" if a["target_met"] is None else "yes" if a["target_met"] else "**no**",
                ]
            )
    head = [
        "protocol: held-out run",
        "verdicts",
        "n",
        "before the map: stated, observed [Wilson 95 %], Brier",
        "after: stated, Brier [bootstrap 95 %]",
        "target met after",
    ]
    note = (
        f"\n\nTarget: observed within {100 * report['target']['tolerance']:.0f} points of stated in every group of "
        f"stated confidence with at least {report['target']['min_n']} verdicts; statuses with fewer verdicts are "
        "left out of the rows but not of *every verdict*. The observed accuracy is the same before and after "
        "(the map changes what is stated, not the verdicts)."
    )
    return table(head, rows) + note + sources(page, [path])


# --- identification -------------------------------------------------------------------------------

ACCURACY = "docs/validation/identification/accuracy.csv"


def render_identification_accuracy(page: Page) -> str:
    """Exact-width accuracy of both identifiers per channel and held-out split (``make run``'s table)."""
    data = read_csv(ACCURACY)
    splits = list(dict.fromkeys(r["split"] for r in data))
    n = {r["split"]: r["n"] for r in data}
    head = ["identifier", "channel"] + [f"{s} (n={n[s]})" for s in splits]
    rows = []
    for kind, ch in dict.fromkeys((r["identifier"], r["channel"]) for r in data):
        cells = {r["split"]: r for r in data if r["identifier"] == kind and r["channel"] == ch}
        out = []
        for s in splits:
            k, m = int(cells[s]["correct"]), int(cells[s]["n"])
            out.append(f"{pct(k / m)} {interval(*wilson(k, m))}")
        rows.append([kind, ch, *out])
    note = "\n\nExact width identified (chance 16.7 %), Wilson 95 % intervals."
    return table(head, rows) + note + sources(page, [ACCURACY, "docs/validation/identification/README.md"])


KERNEL_SPEED = "docs/validation/kernel-speed/report.json"


def render_kernel_speed(page: Page) -> str:
    """The simulator kernel against solve_ivp on the 168-case grid, per core (``bench/bench_simulator.py``)."""
    r = read_json(KERNEL_SPEED)
    threads = r["numba_threads"]
    rows = [
        [
            "numba kernel",
            f"{r['kernel_records_per_s']:.1f}",
            f"{r['kernel_seconds']:.3f} s (best of "
            + (f"{r['kernel_runs']} runs between the baseline's chunks" if "kernel_runs" in r else "3")
            + ", compiled)",
        ],
        ["solve_ivp LSODA, rtol 1e-8", f"{r['baseline_records_per_s']:.1f}", f"{r['baseline_seconds']:.2f} s"],
    ]
    note = (
        f"\n\n**{r['speedup']:.1f}x** in the same process, the kernel on {threads} numba thread"
        f"{'s' if threads != 1 else ''} ({r['cpus']} cores), the baseline on one; agreement: max error "
        f"{100 * r['max_rel_error']:.4f} % of peak-to-peak (limit 0.5 %), max |t_e difference| "
        f"{r['max_event_time_error_s']:.2e} s (limit 1e-6 s). Code {r['commit']}; "
        f"`{r['command']}`."
    )
    return table(["simulator", "records/s", "168 cases in"], rows) + note + sources(page, [KERNEL_SPEED])


#: Repeated runs of the kernel bench, two codes alternating (``docs/validation/kernel-speed/runs/<code>-<i>.json``).
KERNEL_SPEED_RUNS = "docs/validation/kernel-speed/runs"


def render_kernel_speed_runs(page: Page) -> str:
    """Each committed run of the kernel bench: the ratio to solve_ivp and both rates (``bench/bench_simulator.py``)."""
    paths = sorted(str(p) for p in Path(KERNEL_SPEED_RUNS).glob("*.json"))
    rows = []
    for path in paths:
        r = read_json(path)
        rows.append(
            [
                Path(path).stem,
                r["commit"],
                f"{r['speedup']:.1f}x",
                f"{r['kernel_records_per_s']:.0f}",
                f"{r['baseline_records_per_s']:.1f}",
            ]
        )
    head = ["run", "code", "against solve_ivp", "kernel, records/s", "solve_ivp, records/s"]
    return table(head, rows) + sources(page, paths)


DIAGNOSIS_COST = [
    "docs/validation/diagnosis-cost/cost.json",
    "docs/validation/diagnosis-cost/left-out-37/cost.json",
    "docs/validation/diagnosis-cost/kernel-53b8207/cost.json",
    "docs/validation/diagnosis-cost/exchange-a571475/cost.json",
]


def render_diagnosis_cost(page: Page) -> str:
    """Each committed diagnosis-cost run: p50/p90 per kind and code, with intervals (``bench/bench_diagnosis_cost.py``)."""

    def q(est: dict) -> str:
        lo, hi = est.get("low"), est.get("high")
        span = f" [{lo:.1f}, {hi:.1f}]" if lo is not None and hi is not None else " (n too small for an interval)"
        return f"{est['value']:.1f} s{span}"

    rows = []
    for path in DIAGNOSIS_COST:
        r = read_json(path)
        codes = r["meta"]["codes"]
        for kind, by_code in r["summary"].items():
            for code in ("current", "baseline"):
                if code not in by_code:
                    continue
                x = by_code[code]
                ratio = by_code.get("ratio", {}).get("per_case_median_s")
                rows.append(
                    [
                        kind,
                        f"{codes[code]['describe']} ({code})",
                        str(x["n"]),
                        f"{x['right']}/{x['n']}",
                        q(x["seconds"]["p50"]),
                        q(x["seconds"]["p90"]),
                        f"{ratio:.2f}x" if code == "current" and ratio is not None else "",
                    ]
                )
    head = ["kind", "code", "n", "right", "p50", "p90 (target 10 s)", "per-case median time, current / baseline"]
    note = (
        "\n\nOne diagnosis at a time on 2 cores, the two codes alternating record by record; 95 % order-statistic "
        "intervals. Verdicts that differ between the two codes in a run: "
        + "; ".join(str(len(read_json(p)["verdict_changes"])) for p in DIAGNOSIS_COST)
        + " (in the order of the sources)."
    )
    return table(head, rows) + note + sources(page, DIAGNOSIS_COST)


MEMORY = "docs/validation/memory/report.json"


def render_memory(page: Page) -> str:
    """Peak memory of reading and diagnosing a CSV record against its length (``bench/bench_memory.py``)."""
    r = read_json(MEMORY)
    rows = r["rows"]
    base = next(x for x in rows if x["samples"] == r["baseline_samples"])

    def cell(x: dict, key: str) -> str:
        if key not in x:
            return "-"
        return f"{x[key]:.1f} ({x[key] / base[key]:.2f}x)" if base.get(key) else f"{x[key]:.1f}"

    out = []
    for x in rows:
        answer = x.get("verdict", "-") + (f", K {x['K_mm']} mm" if x.get("K_mm") is not None else "")
        out.append(
            [
                f"{x['samples']:.0e}",
                f"{x['file_mb']:.0f}",
                cell(x, "read_peak_mb"),
                cell(x, "read_rss_mb"),
                cell(x, "api_peak_mb"),
                cell(x, "diagnose_peak_mb"),
                cell(x, "arrays_peak_mb"),
                answer,
            ]
        )
    head = [
        "samples",
        "file [MB]",
        "CLI read, peak [MB]",
        "CLI read, resident [MB]",
        "API CSV read, peak [MB]",
        "diagnosis, peak [MB]",
        "JSON-like arrays, peak [MB]",
        "answer",
    ]
    v = r["code_version"]
    note = (
        f"\n\nRatios against the {r['baseline_samples']:.0e}-sample record in the same run; code "
        f"{v.get('describe') or v.get('commit')}, {r['cores']} cores; `{r['command']}`."
    )
    return table(head, out) + note + sources(page, [MEMORY])


CONTINUOUS = "docs/validation/continuous-width/report.json"


def render_continuous_channels(page: Page) -> str:
    """The continuous width's 95 % interval: coverage per channel, pooled over the noise levels."""
    report = read_json(CONTINUOUS)
    rows = []
    for ch in report["channels"]:
        lo, hi = ch["coverage_wilson_95"]
        lo_n, hi_n = ch["coverage_noisy_wilson_95"]
        rows.append(
            [
                ch["channel"],
                rate(ch["covered"], ch["n"], lo, hi),
                rate(ch["covered_noisy"], ch["n_noisy"], lo_n, hi_n),
            ]
        )
    head = ["channel", "true K inside the 95 % interval, every split", "noisy splits only (40 and 30 dB)"]
    return table(head, rows) + sources(page, [CONTINUOUS], report["command"])


def render_continuous_splits(page: Page) -> str:
    """The continuous width per channel and noise level: accuracy, error, coverage, interval, time."""
    report = read_json(CONTINUOUS)
    rows = []
    for r in report["rows"]:
        lo, hi = r["coverage_wilson_95"]
        rows.append(
            [
                r["channel"],
                r["split"],
                str(r["n"]),
                pct(r["correct"] / r["n"], 0),
                f"{r['median_abs_error_um']:.2f}",
                f"{r['covered']}/{r['n']} = {pct(r['coverage'], 0)} {interval(lo, hi, 0)}",
                f"{r['median_interval_um']:.2f}",
                pct(r["within_2sigma"], 0),
                pct(r["within_2sigma_gn"], 0),
                str(r["not_identifiable"]),
                f"{r['median_seconds']:.1f}",
            ]
        )
    head = [
        "channel",
        "split",
        "n",
        "accuracy (nearest width)",
        "median abs K error [um]",
        "true K inside the 95 % interval [Wilson 95 %]",
        "median interval width [um]",
        "true K within 2 sd",
        "within 2 Gauss-Newton sd (before)",
        "not identifiable",
        "median time [s]",
    ]
    return table(head, rows) + sources(page, [CONTINUOUS], report["command"])


# --- protocol 1 -----------------------------------------------------------------------------------

P1_RUNS = (193, 199, 211, 227)


def p1_codes() -> dict[int, str]:
    """The code each protocol-1 run's diagnoses ran on, as the confidence report lists them."""
    runs = read_json("docs/validation/confidence/report.json")["per_run"]
    return {int(r["run"].split("seed")[1]): r["code_version"] for r in runs if r["run"].startswith("v1-")}


def render_p1_runs(page: Page) -> str:
    """Protocol 1's targets on the committed runs (seeds 193-227)."""
    codes = p1_codes()
    reports = {s: read_json(f"{VALIDATION}/v1-seed{s}/report.json") for s in P1_RUNS}
    idents = {s: read_json(f"{VALIDATION}/v1-seed{s}/identification.json") for s in P1_RUNS}

    def n_exp(s: int) -> int:
        return int(reports[s]["n_by_expected"]["explained"])

    def count(share: float, n: int) -> str:
        return rate(round(share * n), n)

    def ident(s: int) -> str:
        p = idents[s]["paired"]
        share = ""
        if "after_minus_oracle" in p:
            share = f" (the diagnosis's share {p['after_minus_oracle']:+.1f} +- {p['after_minus_oracle_stderr']:.1f})"
        return f"{p['after_minus_twin']:+.1f} +- {p['stderr']:.1f}{share}"

    spec: list[tuple[str, Callable[[int], str]]] = [
        (
            "cases: explained / unexplained / no_gap expected",
            lambda s: " / ".join(str(reports[s]["n_by_expected"][k]) for k in ("explained", "unexplained", "no_gap")),
        ),
        ("top-1: verdict names the effect (>= 90 %)", lambda s: count(reports[s]["top1"], n_exp(s))),
        ("top-2: effect among the two best-ranked (>= 97 %)", lambda s: count(reports[s]["top2"], n_exp(s))),
        ("median gap shrinkage of the true effect (>= 5x)", lambda s: f"{reports[s]['shrinkage']['median']:,.0f}x"),
        ("share of those cases with shrinkage >= 5x", lambda s: count(reports[s]["shrinkage"]["share_ge_5"], n_exp(s))),
        (
            "median value error / range width",
            lambda s: pct(reports[s]["value_error"]["median_rel_range"], 3),
        ),
        (
            "abstention on left-out effects (>= 80 %)",
            lambda s: count(reports[s]["abstention"], reports[s]["n_by_expected"]["unexplained"]),
        ),
        (
            "false alarms on clean and weak cases (<= 5 %)",
            lambda s: count(reports[s]["false_alarm"], reports[s]["n_by_expected"]["no_gap"]),
        ),
        ("identification after the fix minus clean twins, paired, points (within 2)", ident),
    ]

    head = ["metric (target)"] + [f"seed {s} (code {codes[s]})" for s in P1_RUNS]
    rows = [[label, *(f(s) for s in P1_RUNS)] for label, f in spec]
    paths = [f"{VALIDATION}/v1-seed{s}/{f}" for s in P1_RUNS for f in ("report.json", "identification.json")]
    paths.append("docs/validation/confidence/report.json")
    return table(head, rows) + sources(page, paths)


def render_p1_identification(page: Page) -> str:
    """Identification before and after the fix on the committed protocol-1 runs, paired with clean twins."""
    rows = []
    for s in P1_RUNS:
        d = read_json(f"{VALIDATION}/v1-seed{s}/identification.json")
        acc, p, n = d["accuracy"], d["paired"], d["n"]
        rows.append(
            [
                str(s),
                str(n["after"]),
                pct(acc["before"]["mean"]),
                pct(acc["after"]["mean"]),
                pct(acc["twin"]["mean"]),
                f"{p['after_minus_twin']:+.1f} +- {p['stderr']:.1f}",
                f"{pct(acc['clean']['mean'])} (n = {n['clean']})",
            ]
        )
    head = [
        "seed",
        "effect records",
        "nominal patterns",
        "after the fix",
        "clean twins",
        "paired difference, points (standard error)",
        "clean cases (unpaired)",
    ]
    note = "\n\nTemplate identifier, mean accuracy over the five channels (exact width)."
    paths = [f"{VALIDATION}/v1-seed{s}/identification.json" for s in P1_RUNS]
    return table(head, rows) + note + sources(page, paths)


# --- real data ------------------------------------------------------------------------------------

EMPS_RUNS = ("emps", "pulses", "emps_cross", "pulses_self")


def render_emps_diagnosis(page: Page) -> str:
    """The diagnosis of both EMPS records: named effects with their share of the gap, errors before and after."""
    rows, paths = [], []
    for name in EMPS_RUNS:
        path = f"docs/real-data/runs/{name}.json"
        paths.append(path)
        d = read_json(path)
        cal = d["calibration"]
        held = ", held" if not cal.get("refitted_with_effects", True) else ""
        source = "itself" if cal["from"] == d["record"] else cal["from"].removesuffix(".mat") + held
        named = []
        for e in d["verdict"]["effects"]:
            sigma = "" if e["uncertainty"] is None else f" +- {e['uncertainty']:.2g}"
            named.append(f"{e['effect']} {e['value']:.3g}{sigma} {e['unit']} ({pct(e['share'])})")
        err = d["relative_error"]
        rows.append(
            [
                f"{d['record'].removesuffix('.mat')} ({source})",
                f"`{d['status']}`: " + " + ".join(named),
                *(
                    f"{err['before'][c]:.3g} -> {err['after'][c]:.3g} %"
                    for c in ("position", "velocity", "acceleration", "force")
                ),
            ]
        )
    head = [
        "record (calibrated on)",
        "verdict: named (share of the gap closed)",
        "position",
        "velocity",
        "acceleration",
        "force",
    ]
    note = "\n\nRelative error `100 ||y - y_sim|| / ||y||` per channel, before -> after the named effects."
    return table(head, rows) + note + sources(page, paths)


#: The synthetic checks of the noise gate (issue 52, item 2), blind for the code of their commit.
PLANT_CHECK_RUNS = (
    "brfd-seed21",
    "brfd-seed22",
    "emps-seed23",
    "emps-seed24",
    "backlash_drive-seed25",
    "backlash_drive-seed26",
    "backlash_drive-seed27",
)
#: Runs of code since changed for their plant: in the table, left out of the README's pooled line.
PLANT_CHECK_SUPERSEDED: dict[str, str] = {
    "backlash_drive-seed25": "before the drive's calibration started from its global search",
}
#: The rates the gate's table shows, in order.
PLANT_CHECK_MEASURES = (
    "clean_no_gap",
    "clean_false_alarm",
    "strong_top1",
    "weak_ok",
    "absorbed",
    "named_where_absorbed",
)


def check_measure_rows(runs: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> list[list[str]]:
    """Rows of a table of synthetic checks (``engine.validation.plant_check`` reports): per measure of ``keys``
    its label, then its rate in each run (a dash where a run lacks it); measures no run has are left out."""
    labels: dict[str, str] = {}
    cells: dict[str, list[str]] = {key: [] for key in keys}
    for r in runs:
        by_key = {m["key"]: m for m in r["measures"]}
        for key in keys:
            m = by_key.get(key)
            if m is not None:
                labels.setdefault(key, m["label"])
            cells[key].append("-" if m is None else rate(m["k"], m["n"], m["low"], m["high"]))
    return [[labels[key], *cells[key]] for key in keys if key in labels]


def render_plant_checks(page: Page) -> str:
    """The synthetic checks through the plant interface: clean cases, strong and weak effects, per run."""
    paths = [
        f"docs/real-data/check/{name}.json"
        for name in PLANT_CHECK_RUNS
        if (ROOT / f"docs/real-data/check/{name}.json").exists()
    ]
    runs = [read_json(p) for p in paths]
    names = [Path(p).stem for p in paths]
    head = [
        "measure",
        *(
            f"{r['run']['plant']}, {r['run']['record'] or 'reference test'}, seed {r['run']['seed']}"
            + (f" ({PLANT_CHECK_SUPERSEDED[n]})" if n in PLANT_CHECK_SUPERSEDED else "")
            for r, n in zip(runs, names, strict=True)
        ),
    ]
    rows = check_measure_rows(runs, PLANT_CHECK_MEASURES)
    rows.append(
        [
            "seconds per diagnosis, median / max",
            *(f"{r['seconds']['median']:.0f} / {r['seconds']['max']:.0f}" if r["seconds"] else "-" for r in runs),
        ]
    )
    note = (
        f"\n\nStrong: the true effect moves the record by more than {runs[0]['min_strength_noise_rms']:g} noise RMS "
        "(computed from the truth after the diagnosis); Wilson 95 % intervals."
        if runs
        else ""
    )
    return table(head, rows) + note + sources(page, paths)


#: The synthetic checks of the open world through the plant interface (issue 52 item 2), in order:
#: report stem -> what the family was to the code (developed on, or sealed and scored once).
PLANT_LOCUS_RUNS: dict[str, str] = {
    "brfd-seed28": "held-back four (developed on)",
    "brfd-seed29": "held-back four (developed on)",
    "emps-seed32": "held-back five (developed on)",
    "brfd-seed30": "sealed four (scored once)",
    "brfd-seed31": "sealed four (scored once)",
    "emps-seed33": "sealed five (scored once)",
    "brfd-seed34": "held-back four (developed on), weak gaps with a locus",
    "brfd-seed35": "held-back four (developed on), weak gaps with a locus",
    "emps-seed36": "held-back five (developed on), weak gaps with a locus",
}
#: Runs the README's pooled line leaves out: the held-back runs of the code before weak gaps carried a
#: locus (kept in the tables; the sealed runs are the only scoring of their families and stay).
PLANT_LOCUS_SUPERSEDED: frozenset[str] = frozenset({"brfd-seed28", "brfd-seed29", "emps-seed32"})
#: The open world's rates, in order.
PLANT_LOCUS_MEASURES = (
    "held_back_locus",
    "held_back_abstained",
    "held_back_unexplained",
    "held_back_weak_ok",
    "clean_false_alarm",
    "strong_top1",
)


#: The answers that attribute nothing (:data:`engine.validation.plant_check.QUIET`).
_QUIET = ("no_gap", "weak_gap")


def _locus_runs() -> list[tuple[str, str, dict[str, Any]]]:
    """The committed open-world runs, in :data:`PLANT_LOCUS_RUNS`'s order: (path, family, report)."""
    out = []
    for name, what in PLANT_LOCUS_RUNS.items():
        path = f"docs/real-data/check/{name}.json"
        if (ROOT / path).exists():
            out.append((path, "sealed" if what.startswith("sealed") else "held-back", read_json(path)))
    return out


def _strong_held_back(report: Mapping[str, Any]) -> list[dict[str, Any]]:
    """A check's cases of an effect outside the catalogue that moves the record beyond ``min_strength``."""
    return [
        c for c in report["cases"] if c.get("held_back") and c["strength_noise_rms"] > report["min_strength_noise_rms"]
    ]


def _answered_locus_counts(report: Mapping[str, Any]) -> tuple[int, int]:
    """Of a check's strong held-back cases answered with a gap (not quiet), how many at the true locus."""
    answered = [c for c in _strong_held_back(report) if c["status"] not in _QUIET]
    return sum(c["locus"] == c["true_locus"] for c in answered), len(answered)


def _quiet_misses(report: Mapping[str, Any]) -> tuple[int, int]:
    """Of a check's strong held-back cases whose answer's locus is wrong or missing, how many were quiet."""
    misses = [c for c in _strong_held_back(report) if c["locus"] != c["true_locus"]]
    return sum(c["status"] in _QUIET for c in misses), len(misses)


def render_plant_locus_checks(page: Page) -> str:
    """The open world on EMPS and BRFD: effects outside the catalogue, their locus, per run."""
    runs = _locus_runs()
    paths = [p for p, _, _ in runs]
    if not runs:
        return "(no run committed yet)"
    labels: dict[str, str] = {}
    rows = []
    for p, _, r in runs:
        by_key = {m["key"]: m for m in r["measures"]}
        for key in PLANT_LOCUS_MEASURES:
            if key in by_key:
                labels.setdefault(key, by_key[key]["label"])
        run = r["run"]
        k, n = _answered_locus_counts(r)
        rows.append(
            [
                f"{run['plant']}, {run['record']}, seed {run['seed']}",
                PLANT_LOCUS_RUNS[Path(p).stem],
                (run.get("code") or {}).get("describe") or "-",
                *(
                    rate(by_key[k]["k"], by_key[k]["n"], by_key[k]["low"], by_key[k]["high"]) if k in by_key else "-"
                    for k in PLANT_LOCUS_MEASURES
                ),
                rate(k, n) if n else "-",
            ]
        )
    head = [
        "run",
        "family",
        "code",
        *(labels.get(k, k) for k in PLANT_LOCUS_MEASURES),
        "held-back, strong, answered with a gap (not `no_gap`/`weak_gap`): locus right",
    ]
    note = (
        f"\n\nStrong: the true effect moves the record by more than {runs[0][2]['min_strength_noise_rms']:g} noise "
        "RMS (from the truth, after the diagnosis). The answer's locus is the first named effect's, or the locus "
        "estimate's when nothing is named. Wilson 95 % intervals."
    )
    return table(head, rows) + note + sources(page, paths)


def render_plant_locus_real(page: Page) -> str:
    """The real records re-diagnosed with the open world (``docs/real-data/locus_real.py``)."""
    path = "docs/real-data/runs/locus-real.json"
    if not (ROOT / path).exists():
        return "(not run yet)"
    data = read_json(path)
    rows = []
    for r in data["records"]:
        loc = r["locus"]
        named = " + ".join(f"{e} ({100 * share:.0f} %)" for e, share in r["named"]) or "-"
        if loc is None:
            where, explained, term = "-", "-", "-"
        else:
            where = f"{loc['locus'] or 'none'}" + (f" ({loc['confidence']:.2f})" if loc["locus"] else "")
            explained = ", ".join(f"{k} {100 * v:.0f} %" for k, v in loc["explained"].items())
            term = (loc["term"] or "-") + (" (first guess)" if "first guess" in (loc["note"] or "") else "")
        if "warnings" in r:  # answers before the plausibility warnings did not record them
            codes: dict[str, list[str]] = {}
            for code, channel in r["warnings"]:
                codes.setdefault(code, []).append(channel or "record")
            warned = "; ".join(f"`{c}` ({', '.join(chs)})" for c, chs in codes.items()) or "none"
        else:
            warned = "(not recorded)"
        rows.append(
            [f"{r['plant']} {r['record']}", r["status"], named, where, explained, term, warned, f"{r['seconds']:.0f}"]
        )
    head = [
        "record",
        "answer",
        "named (share of the gap)",
        "locus of what is left (confidence)",
        "gap explained by each locus's term",
        "term",
        "warnings (channels)",
        "s",
    ]
    code = (data.get("code") or {}).get("describe") or "-"
    return (
        table(head, rows) + f"\n\nCode {code}; `.venv/bin/python docs/real-data/locus_real.py`." + sources(page, [path])
    )


def render_plant_diagnosis_cost(page: Page) -> str:
    """A plant's diagnosis on threads against one thread (``bench/bench_plant_diagnosis.py``, issue 54), per run."""
    paths = ["docs/real-data/runs/plant-cost.json", "docs/real-data/runs/plant-cost-5873047.json"]
    parts = []
    for path in paths:
        data = read_json(path)
        rows = [
            [
                f"{r['plant']} {r['record']}",
                f"{1e3 * r['sim_s']:.1f}",
                f"{r['baseline_seconds']:.1f} ({r['baseline_sims']:.0f})",
                f"{r['threads_seconds']:.1f} ({r['threads_sims']:.0f})",
                f"{r['ratio']:.2f}x",
                str(r["baseline_n_eval"]),
                "yes" if r["identical"] else "**no**",
            ]
            for r in data["rows"]
        ]
        head = [
            "record",
            "one simulation [ms]",
            "one thread: s (sims)",
            f"{data['rows'][0]['jobs']} threads: s (sims)" if data["rows"] else "threads: s (sims)",
            "threads / one",
            "simulations",
            "same answer",
        ]
        code = (data.get("code") or {}).get("describe") or "-"
        lines = "".join(f"\n- {line}" for line in data.get("summary", []))
        plants = " ".join(dict.fromkeys(r["plant"] for r in data["rows"]))
        parts.append(
            f"**Code {code}**\n\n"
            + table(head, rows)
            + f"\n{lines}\n\nOne diagnosis at a time, the two settings alternating record by record; "
            f"`NUMBA_NUM_THREADS=2 .venv/bin/python bench/bench_plant_diagnosis.py --plants {plants} --json {path}`."
        )
    return "\n\n".join(parts) + sources(page, paths)


def render_emps_kernel(page: Page) -> str:
    """The EMPS kernel against an earlier commit's (``bench/bench_emps_kernel.py``, issue 54)."""
    path = "docs/real-data/runs/emps-kernel.json"
    if not (ROOT / path).exists():
        return "(not run yet)"
    data = read_json(path)
    rows = [
        [
            r["record"],
            str(r["samples"]),
            f"{r['identical']}/{r['draws']}",
            f"{1e3 * r['baseline_s']:.1f}",
            f"{1e3 * r['current_s']:.1f}",
            f"{r['ratio']:.2f}x",
        ]
        for r in data["rows"]
    ]
    head = [
        "record",
        "samples",
        "draws bit for bit",
        f"one simulation, {data['baseline']} [ms]",
        "current [ms]",
        "current / baseline",
    ]
    code = (data.get("code") or {}).get("describe") or "-"
    return (
        table(head, rows)
        + f"\n\nCode {code}, one core; `NUMBA_NUM_THREADS=1 .venv/bin/python bench/bench_emps_kernel.py "
        + f"--baseline {data['baseline']} --json {path}`."
        + sources(page, [path])
    )


def render_plant_locus_reliability(page: Page) -> str:
    """Whether the plants' stated locus confidence is a probability, per family, over the open-world runs."""
    from engine.validation.reliability import TARGET_MIN_N, reliability_table, table_markdown

    runs = [r for r in _locus_runs() if Path(r[0]).stem not in PLANT_LOCUS_SUPERSEDED]
    if not runs:
        return "(no run committed yet)"
    out: list[str] = []
    for family in ("held-back", "sealed"):
        cases = [
            c
            for _, f, report in runs
            if f == family
            for c in _strong_held_back(report)
            if c["locus"] is not None and c.get("locus_confidence") is not None
        ]
        t = reliability_table(
            [float(c["locus_confidence"]) for c in cases], [c["locus"] == c["true_locus"] for c in cases]
        )
        out += table_markdown(f"{family} family, strong cases answered with a locus", t.to_dict(), TARGET_MIN_N)
    note = (
        "Right: the answer's locus is the part the effect acts at. The stated confidence is the locus's "
        "dispersion-scaled BIC weight (capped at 0.5 for a first guess); groups of at least "
        f"{TARGET_MIN_N} cases are judged against issue 50's 10 points. Brier score with a bootstrap 95 % "
        "interval, rates with Wilson's."
    )
    return "\n".join(out) + "\n" + note + sources(page, [p for p, _, _ in runs])


def render_plant_locus_effects(page: Page) -> str:
    """Per effect outside the catalogue: how its strong cases were answered, over the open-world runs."""
    runs = _locus_runs()
    paths = [p for p, _, _ in runs]
    if not runs:
        return "(no run committed yet)"
    tally: dict[tuple[str, str, str, str], dict[str, Any]] = {}
    for _, family, report in runs:
        for c in _strong_held_back(report):
            key = (report["run"]["plant"], family, c["effect"], c["true_locus"])
            t = tally.setdefault(key, {"n": 0, "right": 0, "quiet": 0, "explained": 0, "wrong": {}})
            t["n"] += 1
            t["right"] += c["locus"] == c["true_locus"]
            t["quiet"] += c["status"] in _QUIET
            t["explained"] += c["status"] == "explained"
            if c["locus"] not in (None, c["true_locus"]):
                t["wrong"][c["locus"]] = t["wrong"].get(c["locus"], 0) + 1
    rows = [
        [
            plant,
            family,
            f"`{effect}`",
            locus,
            str(t["n"]),
            str(t["right"]),
            str(t["quiet"]),
            str(t["explained"]),
            ", ".join(f"{k} {v}" for k, v in sorted(t["wrong"].items())) or "-",
        ]
        for (plant, family, effect, locus), t in sorted(tally.items())
    ]
    head = [
        "plant",
        "family",
        "effect",
        "its locus",
        "strong cases",
        "locus right",
        "answered `no_gap`/`weak_gap`",
        "claimed `explained` by a catalogue set",
        "placed instead at",
    ]
    return table(head, rows) + sources(page, paths)


def _run_code(report: Mapping[str, Any]) -> str:
    """The commit a plant check ran on (its ``run.code``), without a dirty mark."""
    return str(((report.get("run") or {}).get("code") or {}).get("describe") or "-").removesuffix("-dirty")


def render_plant_locus_summary(page: Page) -> str:
    """One line for the README: the open world on EMPS and BRFD, the held-back and the sealed families pooled apart."""
    pooled: dict[str, dict[str, list[int]]] = {"held-back": {}, "sealed": {}}
    answered = {"held-back": [0, 0], "sealed": [0, 0]}
    quiet = {"held-back": [0, 0], "sealed": [0, 0]}
    runs = [r for r in _locus_runs() if Path(r[0]).stem not in PLANT_LOCUS_SUPERSEDED]
    paths = [p for p, _, _ in runs]
    codes = {f: sorted({_run_code(rep) for _, fam, rep in runs if fam == f}) for f in ("held-back", "sealed")}
    for _, family, report in runs:
        k_ans, n_ans = _answered_locus_counts(report)
        answered[family] = [answered[family][0] + k_ans, answered[family][1] + n_ans]
        k_q, n_q = _quiet_misses(report)
        quiet[family] = [quiet[family][0] + k_q, quiet[family][1] + n_q]
        for m in report["measures"]:
            k, n = pooled[family].get(m["key"], [0, 0])
            pooled[family][m["key"]] = [k + m["k"], n + m["n"]]
    if not runs:
        return "(no run committed yet)"
    strong = f"{runs[0][2]['min_strength_noise_rms']:g} noise RMS"

    def pooled_rate(family: str, key: str) -> str:
        k, n = pooled[family].get(key, [0, 0])
        return rate(k, n) if n else "none drawn"

    def answered_rate(family: str) -> str:
        k, n = answered[family]
        return rate(k, n) if n else "none"

    text = (
        "- **Gaps no catalogue effect explains, on EMPS and BRFD** (blind synthetic checks through the plant "
        f"interface): an effect of the held-back families (developed on; code {', '.join(codes['held-back'])}) "
        f"beyond {strong} is answered at its "
        f"own part of the machine in {pooled_rate('held-back', 'held_back_locus')} (of the answers that report a "
        f"gap: {answered_rate('held-back')}) and claimed by no catalogue set in "
        f"{pooled_rate('held-back', 'held_back_abstained')}; of the sealed families (never developed on, scored "
        f"once, code {', '.join(codes['sealed'])}) in {pooled_rate('sealed', 'held_back_locus')} (of those reporting a gap: {answered_rate('sealed')}) "
        f"and {pooled_rate('sealed', 'held_back_abstained')}. Of the misses, {quiet['held-back'][0]} of "
        f"{quiet['held-back'][1]} and {quiet['sealed'][0]} of {quiet['sealed'][1]} were answered `weak_gap`/`no_gap`: "
        f"effects the calibration absorbs down to a misfit of at most {strong}, which the answer does not attribute "
        "(a weak gap's locus, where the current code gives one, was not the effect's); "
        "the other misses are placed at the wrong part, out of sample mostly effects that follow a signal no part of "
        f"the plant declares ({page.link('docs/real-data.md', 'real data, section 7')}, per effect)."
    )
    return text + sources(page, paths)


def pooled_measures(runs: list[dict[str, Any]]) -> Callable[[str], str]:
    """A function of a measure's key: its successes over trials pooled over the ``runs``' ``measures``, as a rate."""
    pooled: dict[str, list[int]] = {}
    for r in runs:
        for m in r["measures"]:
            k, n = pooled.setdefault(m["key"], [0, 0])
            pooled[m["key"]] = [k + m["k"], n + m["n"]]

    def pooled_rate(key: str) -> str:
        k, n = pooled.get(key, [0, 0])
        return rate(k, n)

    return pooled_rate


def render_plant_checks_summary(page: Page) -> str:
    """One line for the README: the gate's checks pooled over every plant's runs of the current code."""
    paths = [
        f"docs/real-data/check/{n}.json"
        for n in PLANT_CHECK_RUNS
        if n not in PLANT_CHECK_SUPERSEDED and (ROOT / f"docs/real-data/check/{n}.json").exists()
    ]
    runs = [read_json(p) for p in paths]
    pooled_rate = pooled_measures(runs)
    plants = sorted({r["run"]["plant"] for r in runs})

    text = (
        f"- **Clean and weak records on every plant** ({', '.join(plants)}; {len(runs)} blind synthetic checks of the "
        f"current code through the plant interface, pooled): a record the model already fits is answered `no_gap` in "
        f"{pooled_rate('clean_no_gap')}, with a false alarm in {pooled_rate('clean_false_alarm')}; an effect "
        f"beyond 3 noise RMS is named first in {pooled_rate('strong_top1')}; a weaker one is answered `no_gap`/"
        f"`weak_gap` or named right in {pooled_rate('weak_ok')} ({page.link('docs/real-data.md', 'real data, section 6')})."
    )
    return text + sources(page, paths)


#: The logs of ``time ./.ci/run`` on fresh clones: ``YYYY-MM-DD-HHMM-COMMIT-WHERE.log`` (UTC, when the
#: run ended), so that they sort oldest first.
TEST_RUN_LOGS = "docs/validation/test-run"
#: pytest's closing line: ``51 passed, 1 xfailed in 1554.69s``, any outcomes in any order.
_PYTEST_SUMMARY = re.compile(r"^(?P<counts>(?:\d+ [a-z]+(?:, )?)+) in (?P<s>[\d.]+)s", re.M)


def pytest_runs(text: str) -> list[tuple[dict[str, int], float]]:
    """Every pytest closing line of a log: its counts by outcome and its seconds."""
    out = []
    for m in _PYTEST_SUMMARY.finditer(text):
        counts = {word: int(k) for k, word in (item.split() for item in m["counts"].split(", "))}
        out.append((counts, float(m["s"])))
    return out


_TIME_LINE = re.compile(r"^(?P<what>real|user)\s+(?P<m>\d+)m(?P<s>[\d.]+)s$", re.M)


def test_run(path: Path) -> dict[str, Any]:
    """One fresh-clone run from its log: the two pytest parts, wall and CPU time, exit status."""
    text = path.read_text()
    fields = path.stem.split("-")
    date = "-".join(fields[:3]) + f" {fields[3][:2]}:{fields[3][2:]}"
    commit, where = fields[4], " ".join(fields[5:])
    parts = [
        {"passed": counts.get("passed", 0), "failed": counts.get("failed", 0), "seconds": sec}
        for counts, sec in pytest_runs(text)
    ]
    times = {m["what"]: 60 * int(m["m"]) + float(m["s"]) for m in _TIME_LINE.finditer(text)}
    rc = re.search(r"^rc (\d+)$", text, re.M)
    return {"date": date, "commit": commit, "where": where, "parts": parts, **times, "rc": int(rc[1]) if rc else None}


def _min_s(x: float | None) -> str:
    return "-" if x is None else f"{int(x // 60)} min {x % 60:.0f} s"


def render_test_run_times(page: Page) -> str:
    """The default run's time from fresh clones (set-up, linters, docs, warm-up and both pytest parts)."""
    logs = sorted((ROOT / TEST_RUN_LOGS).glob("*.log"))
    rows = []
    for log in logs:
        r = test_run(log)
        parts = r["parts"]
        cells = [
            f"{p['passed'] + p['failed']} tests in {_min_s(p['seconds'])}"
            + (f" ({p['failed']} failed)" if p["failed"] else "")
            for p in parts[:2]
        ] + ["-"] * (2 - len(parts[:2]))
        rows.append(
            [
                r["date"],
                f"`{r['commit']}`",
                r["where"],
                _min_s(r.get("real")),
                *cells,
                _min_s(r.get("user")),
                str(r["rc"]),
            ]
        )
    head = [
        "ended (UTC)",
        "commit",
        "where",
        "wall time",
        "on two workers",
        "alone (serial)",
        "user CPU",
        "exit status",
    ]
    paths = [log.relative_to(ROOT).as_posix() for log in logs]
    return table(head, rows) + sources(page, paths)


#: The logs of ``make test-slow``'s command on the working tree of a commit: ``YYYY-MM-DD-HHMM-COMMIT.log``
#: (UTC, when the run started).
SLOW_RUN_LOGS = "docs/validation/test-run/slow"


def render_slow_suite_times(page: Page) -> str:
    """The slow suite's runs: tests by outcome and wall time (two workers, one numba thread each)."""
    logs = sorted((ROOT / SLOW_RUN_LOGS).glob("*.log"))
    rows = []
    for log in logs:
        fields = log.stem.split("-")
        text = log.read_text()
        runs = pytest_runs(text)
        rc = re.search(r"^rc (\d+)$", text, re.M)
        rows.append(
            [
                "-".join(fields[:3]) + f" {fields[3][:2]}:{fields[3][2:]}",
                f"`{fields[4]}`",
                ", ".join(f"{k} {word}" for word, k in runs[-1][0].items()) if runs else "-",
                _min_s(runs[-1][1]) if runs else "-",
                rc[1] if rc else "-",
            ]
        )
    head = ["started (UTC)", "commit", "tests", "time", "exit status"]
    return table(head, rows) + sources(page, [log.relative_to(ROOT).as_posix() for log in logs])


# --- the headline ---------------------------------------------------------------------------------


def render_validation_summary(page: Page) -> str:
    """The one table of what the product has been validated on (README and the site's home page)."""
    from engine.validation.protocol import SEALED_TARGETS

    newest, previous = P2_RUNS[-1], P2_RUNS[-2]
    r2, r2p = p2_report(newest), p2_report(previous)
    p2 = f"{VALIDATION}/v2-seed{newest}/report.md"
    p2p = f"{VALIDATION}/v2-seed{previous}/report.md"
    kinds = {
        "single_named": "single-effect",
        "compound_contains": "pair and triple",
        "held_back_unexplained": "held-back",
        "held_back_locus": "held-back",
        "clean_false_alarm": "clean",
    }
    rows: list[list[str]] = []
    for name, what in (
        ("single_named", "diagnosis: one unmodelled effect named right"),
        ("compound_contains", "diagnosis: two or three effects at once, every true effect named"),
        ("held_back_unexplained", "diagnosis: an effect outside the catalogue answered `unexplained`"),
        ("held_back_locus", "... and the part of the plant it acts on named right"),
        ("clean_false_alarm", "diagnosis: false alarms on clean records"),
    ):
        m, mp = p2_metric(r2, name), p2_metric(r2p, name)
        rows.append(
            [
                what,
                f"**{rate_of(m['rate'])}** ({rate_of(mp['rate'])})",
                f"{m['rate']['n']} {kinds[name]} records of seed {newest} ({mp['rate']['n']} of seed {previous}); "
                f"target {m['target']}",
                f"{page.link(p2, f'seed {newest}')}, {page.link(p2p, f'seed {previous}')}",
            ]
        )
    r241 = read_json(f"{VALIDATION}/{HELD_OUT_RUN}/report.json")
    r257 = read_json(f"{VALIDATION}/{SEALED_RUN}/report.json")
    r263 = read_json(f"{VALIDATION}/{SEALED2_RUN}/report.json")
    r269 = read_json(f"{VALIDATION}/{SEALED3_RUN}/report.json")
    r281 = read_json(f"{VALIDATION}/{SEALED4_RUN}/report.json")
    r283 = read_json(f"{VALIDATION}/{SEALED5_RUN}/report.json")

    for what, now, before in (
        (
            "diagnosis: an effect of a family never developed on answered `unexplained`",
            p2_metric(r283, "held_back_unexplained"),
            p2_metric(r281, "held_back_unexplained"),
        ),
        (
            "... and the part of the plant it acts on named right (the locus, or the supply and the motor's "
            "electrics together, which the record cannot tell apart)",
            p2_metric(r283, "held_back_locus"),
            p2_single_locus(r281),
        ),
        ("... the single locus named right", p2_single_locus(r283), p2_single_locus(r281)),
    ):
        target = SEALED_TARGETS.get(now["name"])
        rows.append(
            [
                what,
                f"**{rate_of(now['rate'])}** ({rate_of(before['rate'])})",
                f"{now['rate']['n']} records of the fifth sealed family (model 1.7), seed 283, code {p2_code(r283)}: "
                f"out of sample ({before['rate']['n']} of the fourth sealed family of model 1.6, seed 281, code "
                f"{p2_code(r281)}, whose answers named single loci)"
                + (
                    f"; target {target.text(percent=True)} (issue 50, item 5): {_met_word(target, now)}"
                    if target
                    else ""
                ),
                f"{page.link(f'{VALIDATION}/{SEALED5_RUN}/report.md', 'seed 283')}, "
                f"{page.link(f'{VALIDATION}/{SEALED4_RUN}/report.md', 'seed 281')}",
            ]
        )
    v1 = read_json(f"{VALIDATION}/v1-seed227/report.json")
    n_exp, n_un = v1["n_by_expected"]["explained"], v1["n_by_expected"]["unexplained"]
    rows.append(
        [
            "protocol 1: a catalogue effect named first / a left-out one abstained on",
            f"**{rate(round(v1['top1'] * n_exp), n_exp)}** / **{rate(round(v1['abstention'] * n_un), n_un)}**",
            f"blind run seed 227: {v1['n_cases']} simulated records, code {p1_codes()[227]}",
            page.link(f"{VALIDATION}/v1-seed227/report.md", "seed 227"),
        ]
    )
    w = coverage_row(f"{VALIDATION}/v2-seed239/width-coverage.json", "answer", "all")
    rows.append(
        [
            "the width after a diagnosis: truth inside its stated 95 % interval",
            f"**{w['covered']}/{w['n']} = {coverage_cell(w)}**",
            f"the answers of seed {newest} with a width ({w['not_identifiable']} more reported not identifiable)",
            page.link(f"{VALIDATION}/v2-seed239/width-coverage.md", "width coverage"),
        ]
    )
    conf = read_json("docs/validation/confidence/report.json")
    g = next(g for g in conf["groups"] if g["split"] == "held_out" and g["protocol"] == 2)
    a = g["after"]["verdict"]
    rows.append(
        [
            "the verdict's confidence: stated against observed",
            f"stated {pct(a['mean_stated'])}, observed **{rate_of(a['accuracy'])}**",
            f"held out: protocol-2 seed {g['runs'][0]['seed']}, {g['n']} simulated records (map fitted on other runs)",
            page.link("docs/validation/confidence/report.md", "reliability"),
        ]
    )
    cw = read_json(CONTINUOUS)
    k, n = sum(r["covered"] for r in cw["rows"]), sum(r["n"] for r in cw["rows"])
    rows.append(
        [
            "the width from identification (continuous): truth inside its 95 % interval",
            f"**{rate(k, n)}**",
            f"{n} estimates: held-out simulated records {cw['offset']}-{cw['offset'] + cw['n'] - 1}, 5 channels, "
            "3 noise levels (none, 40, 30 dB)",
            page.link("docs/validation/continuous-width/report.md", "continuous width"),
        ]
    )
    acc = {(r["identifier"], r["channel"], r["split"]): r for r in read_csv(ACCURACY)}
    for kind, ch, split, what in (
        (
            "template",
            "v2",
            "random + 30 dB",
            "identification of the width (our template method), channel v2: exact width",
        ),
        ("paper", "m_el", "random + 30 dB", "the paper's wavelet-neural method, its best channel m_el: exact width"),
    ):
        r = acc[(kind, ch, split)]
        rows.append(
            [
                what,
                f"**{rate(int(r['correct']), int(r['n']))}**",
                f"{r['n']} held-out simulated records, J1 and c off the training grid, {split.split('+ ')[1]} noise",
                page.link("docs/validation/identification/accuracy.md", "identification"),
            ]
        )
    head = ["what", "result [Wilson 95 %]", "evaluated on", "report"]
    note = (
        f"\n\nEvery record here is simulated (the reference plant of MODEL.md with unmodelled effects, noise and "
        f"operating points drawn by the protocol); a blind run is blind only for the code it ran on. Seed {newest}: "
        f"protocol 2 (the open world), {r2['n_cases']} records, code {p2_code(r2)}; seed {previous}: "
        f"{r2p['n_cases']} records, code {p2_code(r2p)} (in brackets); both hold back five effects outside the "
        "catalogue that the open-world step was developed on. Seeds 283 and 281: the same protocol on families "
        f"kept apart for scoring: the fifth sealed family of model 1.7, {r283['n_cases']} records, code "
        f"{p2_code(r283)}; the fourth of model 1.6, {r281['n_cases']} records, code {p2_code(r281)}; before them "
        f"seed 269 on the third of model 1.5 ({r269['n_cases']} records, code {p2_code(r269)}), "
        f"seed 263 on the second of model 1.4 ({r263['n_cases']} records, code {p2_code(r263)}), defined "
        f"before the work that seed 257's run (the sealed family of model 1.3, {r257['n_cases']} records, code "
        f"{p2_code(r257)}) led to; earlier, seed 241 on the held-out family of "
        f"model 1.2 ({r241['n_cases']} records, code {p2_code(r241)}). Real measurements are not in this table: see "
        "the real-data pages."
    )
    paths = [
        f"{VALIDATION}/v2-seed{newest}/report.json",
        f"{VALIDATION}/v2-seed{previous}/report.json",
        f"{VALIDATION}/{SEALED5_RUN}/report.json",
        f"{VALIDATION}/{SEALED4_RUN}/report.json",
        f"{VALIDATION}/{SEALED3_RUN}/report.json",
        f"{VALIDATION}/{SEALED2_RUN}/report.json",
        f"{VALIDATION}/{SEALED_RUN}/report.json",
        f"{VALIDATION}/{HELD_OUT_RUN}/report.json",
        f"{VALIDATION}/v1-seed227/report.json",
        f"{VALIDATION}/v2-seed239/width-coverage.json",
        "docs/validation/confidence/report.json",
        CONTINUOUS,
        ACCURACY,
    ]
    return table(head, rows) + note + sources(page, paths)


# --- the service ----------------------------------------------------------------------------------

#: The load benchmark's committed summary (``bench/bench_load.py --out``).
LOAD_REPORT = f"{VALIDATION}/service/load.json"
#: The long schemathesis run's committed counts (``FUZZ_REPORT`` of tests/app/test_schema_fuzz.py).
FUZZ_REPORT = f"{VALIDATION}/service/fuzz.json"
LOAD_COMMAND = "python bench/bench_load.py --clients 20 --seconds 60 --out docs/validation/service/load.json"
FUZZ_COMMAND = (
    "FUZZ_EXAMPLES=100 FUZZ_REPORT=docs/validation/service/fuzz.json python -m pytest -q tests/app/test_schema_fuzz.py"
)


def _ms_cell(x: float | None) -> str:
    return "-" if x is None else f"{x:.0f}"


def retention_words(report: str | dict[str, Any] | None) -> str:
    """What a retention run (``backlash store prune``'s JSON, or its text) deleted and how it compacted."""
    if report is None:
        return "no retention run"
    r = json.loads(report) if isinstance(report, str) else report
    deleted = ", ".join(f"{n} {what}" for what, n in r["deleted"].items())
    return f"`backlash store prune` deleted {deleted}, then {r['compaction']}"


def render_service_load(page: Page) -> str:
    """The load benchmark: every route under 20 clients, 20 MB bodies and abandoned diagnoses among them."""
    r = read_json(LOAD_REPORT)
    b, m, f, jobs = r["baseline"], r["memory"], r["file_bytes"], r["jobs"]
    rows = [
        [
            op,
            str(s["count"]),
            _ms_cell(s["p50_ms"]),
            _ms_cell(s["p99_ms"]),
            str(s["server_errors"]),
            ", ".join(f"{k}: {v}" for k, v in s["errors"].items()) or "-",
        ]
        for op, s in r["operations"].items()
    ]
    mib = {k: "-" if v is None else f"{v / 2**20:.1f} MiB" for k, v in f.items()}
    lines = [
        f"{r['clients']} clients for {r['seconds']:g} s, every route (weights "
        f"{', '.join(f'{op} {w:g}' for op, w in r['mix'].items())}), "
        f"{r['large_bodies']} bodies of {r['large_body_bytes'] / 1e6:.0f} MB and {r['abandoned']} synchronous "
        f"diagnoses abandoned after {r['abandon_after_s']:g} s among them; one run on 2 cores (code "
        f"{r['code']}), no interval.",
        "",
        f"- **5xx: {r['server_errors']}** (limit 0); **lost jobs: {jobs['lost']}** of {jobs['submitted']} "
        f"submitted (limit 0; final states {jobs['final_states']}).",
        f"- **`GET /healthz` under load: p99 {_ms_cell(b['under_load_p99_ms'])} ms** (limit 1000 ms), maximum "
        f"{_ms_cell(b['under_load_max_ms'])} ms over {b['under_load_n']} requests; p50 "
        f"{b['under_load_p50_ms']:.1f} ms against {b['before_p50_ms']:.1f} ms before the load (ratio "
        f"{b['ratio_p50']:.1f}x).",
        f"- A synchronous diagnosis after the load: {r['sync_after_load']} (the abandoned ones gave their slots back).",
        f"- Peak resident memory of the server (its process and every worker): {m['peak_total_mib']:.0f} MiB in "
        f"all, {m['peak_process_mib']:.0f} MiB in one process.",
        f"- Database file: {mib['before_the_load']} before the load, {mib['after_the_load']} after it, "
        f"{mib['after_the_retention_run']} after the retention run ({retention_words(r['retention'])}).",
        "",
        table(["operation", "count", "p50 ms", "p99 ms", "5xx", "other answers"], rows),
    ]
    return "\n".join(lines) + sources(page, [LOAD_REPORT], LOAD_COMMAND)


def render_service_fuzz(page: Page) -> str:
    """The long schemathesis run: requests per operation, 5xx and failed checks."""
    r = read_json(FUZZ_REPORT)
    ops = r["operations"]
    counts = sorted(o["requests"] for o in ops.values())
    fewest = [op for op, o in ops.items() if o["requests"] == counts[0]]
    line = (
        f"{len(ops)} operations, {r['requests']} requests (at most {r['max_examples']} random ones per operation "
        f"besides its examples and the coverage phase's boundary cases; from {counts[0]} requests ({', '.join(fewest)}) "
        f"to {counts[-1]} per operation, median {counts[len(counts) // 2]}): **{r['server_errors']} 5xx, "
        f"{r['failed']} failed checks** ({', '.join(r['checks'])}; code {r['code']})."
    )
    return line + sources(page, [FUZZ_REPORT], FUZZ_COMMAND)


def render_service_summary(page: Page) -> str:
    """Two lines for the README: the load benchmark's limits and the long schemathesis run's counts."""
    load, fuzz = read_json(LOAD_REPORT), read_json(FUZZ_REPORT)
    b, jobs = load["baseline"], load["jobs"]
    counts = sorted(o["requests"] for o in fuzz["operations"].values())
    lines = [
        f"- **Load** ({load['clients']} clients x {load['seconds']:g} s over every route, {load['large_bodies']} "
        f"bodies of 20 MB and {load['abandoned']} abandoned synchronous diagnoses among them, one run on 2 cores): "
        f"**{load['server_errors']} 5xx, {jobs['lost']} lost jobs** of {jobs['submitted']}, `GET /healthz` p99 "
        f"**{_ms_cell(b['under_load_p99_ms'])} ms**; `{LOAD_COMMAND}`.",
        f"- **Contract** (schemathesis, every one of {len(fuzz['operations'])} operations, at most "
        f"{fuzz['max_examples']} random requests each besides the examples and boundary cases: {fuzz['requests']} "
        f"requests, {counts[0]} to {counts[-1]} per operation): **{fuzz['server_errors']} 5xx, {fuzz['failed']} "
        f"schema violations**; `{FUZZ_COMMAND}`.",
    ]
    return "\n".join(lines) + sources(page, [LOAD_REPORT, FUZZ_REPORT])


#: The synthetic checks of the FMU plants' catalogues (issue 55): report paths, oldest first.
FMU_CHECKS: tuple[str, ...] = (
    "docs/validation/fmu/quarter_car-seed43.json",
    "docs/validation/fmu/quarter_car-seed47.json",
)
#: The rates the FMU checks' table shows, in order.
FMU_CHECK_MEASURES: tuple[str, ...] = (
    "strong_top1",
    "top1",
    "weak_ok",
    "absorbed",
    "named_where_absorbed",
    "clean_no_gap",
    "clean_false_alarm",
    "clean_warned",
    "scale_warned",
)
#: The FMU cost bench's report (``bench/bench_fmu.py --json``).
FMU_COST = "docs/validation/fmu/cost.json"


def _fmu_check_runs() -> list[tuple[str, dict[str, Any]]]:
    return [(p, read_json(p)) for p in FMU_CHECKS if (ROOT / p).exists()]


def render_fmu_checks(page: Page) -> str:
    """The FMU plants' synthetic checks: per run, the catalogue's rates, every case's effect, and the time."""
    runs = _fmu_check_runs()
    if not runs:
        return "No committed check yet."
    head = [
        "measure",
        *(f"{Path(r['run']['plant']).parent.name or r['run']['plant']}, seed {r['run']['seed']}" for _, r in runs),
    ]
    rows = check_measure_rows([r for _, r in runs], FMU_CHECK_MEASURES)
    rows.append(
        [
            "seconds per diagnosis, median / max",
            *(f"{r['seconds']['median']:.0f} / {r['seconds']['max']:.0f}" for _, r in runs),
        ]
    )
    misses = []
    for _, r in runs:
        for c in r["cases"]:
            if c["effect"] is None or c["held_back"] or c["absorbed"]:
                continue
            if (c["named"] or [None])[0] != c["effect"]:
                misses.append(
                    f"`{c['effect']}` = {c['value']:.4g} ({c['strength_noise_rms']:.1f} noise RMS): "
                    f"{c['status']}{' ' + ', '.join(c['named']) if c['named'] else ''}"
                )
    note = (
        f"\n\nStrong: the true effect moves the record by more than {runs[0][1]['min_strength_noise_rms']:g} noise RMS "
        "(computed from the truth after the diagnosis); Wilson 95 % intervals; the code of each run is in its report. "
        + ("Cases whose first named effect is not the truth: " + "; ".join(misses) + "." if misses else "")
    )
    return table(head, rows) + note + sources(page, [p for p, _ in runs])


def render_fmu_cost(page: Page) -> str:
    """One simulation of each plant (FMU and native) and the quarter car's diagnoses, from ``bench/bench_fmu.py``."""
    r = read_json(FMU_COST)
    rows = [
        [
            s["plant"],
            str(s["samples"]),
            f"{1e3 * s['seconds']:.2f}",
            f"{s['us_per_sample']:.2f}",
            f"{s['ratio_to_native']:.2f}x",
        ]
        for s in r["simulations"]
    ]
    lines = [table(["plant", "samples", "ms per simulation", "us per sample", "against the native drive"], rows)]
    if r["diagnoses"]:
        d_rows = [
            [
                f"`{d['effect']}` = {d['value']:g}",
                f"{d['status']} {', '.join(d['named'])}".strip(),
                f"{d['seconds']:.1f}",
                str(d["simulations"]),
                f"{d['simulation_equivalents']:.0f}",
                f"{d['seconds_on_processes']:.1f} ({d['ratio']:.2f}x)",
                "yes" if d["identical"] else "**no**",
            ]
            for d in r["diagnoses"]
        ]
        head = ["quarter car, one effect", "answer", "seconds, one process", "simulations", "simulation-equivalents"]
        head += [f"seconds on {r['diagnoses'][0]['processes']} processes", "same answer"]
        lines.append("\n\n" + table(head, d_rows))
    if r.get("model_exchange_diagnoses"):
        co = {d["effect"]: d for d in r["diagnoses"]}
        m_rows = [
            [
                f"`{d['effect']}` = {d['value']:g}",
                f"{d['status']} {', '.join(d['named'])}".strip(),
                f"{d['seconds']:.1f}",
                str(d["simulations"]),
                f"{d['simulation_equivalents']:.0f}",
                f"{d['ratio_to_co_simulation']:.1f}x"
                + (f" ({co[d['effect']]['seconds_on_processes']:.1f} s)" if d["effect"] in co else ""),
            ]
            for d in r["model_exchange_diagnoses"]
        ]
        head = [
            "quarter car by model exchange, one effect",
            "answer",
            f"seconds on {r['model_exchange_diagnoses'][0]['processes']} processes",
            "simulations",
            "simulation-equivalents",
            "against co-simulation",
        ]
        lines.append("\n\n" + table(head, m_rows))
    code = r["code"]["describe"] if isinstance(r["code"], Mapping) else r["code"]
    lines.append(f"\n\nCode {code}, {r['calls']} timed calls of one simulation per plant; `{r['command']}`.")
    return "".join(lines) + sources(page, [FMU_COST])


#: Synthetic checks that count the plausibility warnings of ``engine.diagnosis.plant_plausibility`` (one per
#: plant, each run once on the code its report names).
PLANT_WARNING_RUNS: tuple[str, ...] = (
    "docs/validation/fmu/quarter_car-seed47.json",
    "docs/real-data/check/brfd-seed37.json",
    "docs/real-data/check/emps-seed38.json",
)


def render_plant_warnings(page: Page) -> str:
    """The plausibility warnings on synthetic records of each plant (all in their declared units)."""
    paths = [p for p in PLANT_WARNING_RUNS if (ROOT / p).exists()]
    if not paths:
        return "No committed check yet."
    runs = [read_json(p) for p in paths]
    head = [
        "measure",
        *(f"{Path(r['run']['plant']).parent.name or r['run']['plant']}, seed {r['run']['seed']}" for r in runs),
    ]
    rows = check_measure_rows(runs, ("clean_warned", "scale_warned", "clean_no_gap", "strong_top1"))
    codes = ", ".join(f"`{r['run']['code']['describe']}`" for r in runs)
    note = (
        f"\n\nCode {codes} (in order); Wilson 95 % intervals; each run once, on a seed not used before, "
        "nothing changed after it."
    )
    return table(head, rows) + note + sources(page, paths)


#: The committed measurements of the generic plants' sample-interval check (``bench/interval_check.py``).
PLANT_INTERVAL_RUNS: tuple[str, ...] = (
    "docs/validation/plausibility/interval-quarter_car-seed53.json",
    "docs/validation/plausibility/interval-brfd-seed51.json",
    "docs/validation/plausibility/interval-backlash_drive-seed52.json",
)


def render_plant_interval(page: Page) -> str:
    """The sample-interval check per plant: false warnings at the true interval, detection at wrong ones."""
    paths = [p for p in PLANT_INTERVAL_RUNS if (ROOT / p).exists()]
    if not paths:
        return "No committed measurement yet."
    runs = [read_json(p) for p in paths]
    head = [
        "records",
        *(f"{Path(r['run']['plant']).parent.name or r['run']['plant']}, seed {r['run']['seed']}" for r in runs),
    ]
    labels = {
        "clean": "at the true interval, clean: a warning",
        "catalogue": "at the true interval, a catalogue effect: a warning",
        "held_back": "at the true interval, a held-back effect: a warning",
    }

    def cell(r: Mapping[str, Any]) -> str:
        return rate(r["k"], r["n"], r["low"], r["high"]) if r else "-"

    rows = [[label, *(cell(run["summary"]["false_warning"].get(k, {})) for run in runs)] for k, label in labels.items()]
    factors = sorted({a for run in runs for a in run["summary"]["detected"]}, key=float)
    rows += [
        [
            f"declared {a}x the true interval: warned, the right reading named",
            *(cell(run["summary"]["detected"].get(a, {})) for run in runs),
        ]
        for a in factors
    ]
    codes = ", ".join(f"`{r['run']['code']['describe']}`" for r in runs)
    note = (
        f"\n\nCode {codes} (in order); Wilson 95 % intervals; each run once, on a seed not used before, nothing "
        "changed after it; `-`: no such record (the plant has no held-back family, or cannot be read at that "
        "interval: the drive's records take 10 us to 1 ms and must cover the test window)."
    )
    return table(head, rows) + note + sources(page, paths)


def render_fmu_summary(page: Page) -> str:
    """One line for the README: the FMU checks pooled (the catalogue named first, clean records answered)."""
    runs = _fmu_check_runs()
    if not runs:
        return "No committed check yet."
    pooled_rate = pooled_measures([r for _, r in runs])
    plants = ", ".join(sorted({Path(r["run"]["plant"]).parent.name for _, r in runs}))
    text = (
        f"- **A plant from an FMU** ({plants}; {len(runs)} blind synthetic {'check' if len(runs) == 1 else 'checks'} of its "
        f"catalogue through the plant interface, of the code its report names): an effect beyond 3 noise RMS is named "
        f"first in {pooled_rate('strong_top1')}; "
        f"a clean record is answered `no_gap` in {pooled_rate('clean_no_gap')}, with a false alarm in "
        f"{pooled_rate('clean_false_alarm')} ({page.link('docs/fmu-plant.md', 'your own simulator')})."
    )
    return text + sources(page, [p for p, _ in runs])


#: Every renderer by the name its region bears.
RENDERERS: dict[str, Callable[[Page], str]] = {
    "validation-summary": render_validation_summary,
    "p2-runs": render_p2_runs,
    "p2-time-idle": render_p2_time_idle,
    "p2-families": render_p2_families,
    "width-coverage": render_width_coverage,
    "drive-p2": render_drive_p2,
    "confidence": render_confidence,
    "open-world": render_open_world,
    "identification-accuracy": render_identification_accuracy,
    "kernel-speed": render_kernel_speed,
    "kernel-speed-runs": render_kernel_speed_runs,
    "memory": render_memory,
    "diagnosis-cost": render_diagnosis_cost,
    "continuous-width-channels": render_continuous_channels,
    "continuous-width-splits": render_continuous_splits,
    "p1-runs": render_p1_runs,
    "p1-identification": render_p1_identification,
    "emps-diagnosis": render_emps_diagnosis,
    "plant-checks": render_plant_checks,
    "plant-checks-summary": render_plant_checks_summary,
    "plant-locus-checks": render_plant_locus_checks,
    "plant-locus-summary": render_plant_locus_summary,
    "plant-locus-real": render_plant_locus_real,
    "plant-locus-effects": render_plant_locus_effects,
    "plant-locus-reliability": render_plant_locus_reliability,
    "emps-kernel": render_emps_kernel,
    "plant-diagnosis-cost": render_plant_diagnosis_cost,
    "test-run-times": render_test_run_times,
    "slow-suite-times": render_slow_suite_times,
    "service-load": render_service_load,
    "service-fuzz": render_service_fuzz,
    "service-summary": render_service_summary,
    "fmu-checks": render_fmu_checks,
    "fmu-cost": render_fmu_cost,
    "fmu-summary": render_fmu_summary,
    "plant-warnings": render_plant_warnings,
    "plant-interval": render_plant_interval,
}


# --- the regions ----------------------------------------------------------------------------------


class RegionError(ValueError):
    """A marker without its partner, or a region whose renderer is unknown."""


def default_files() -> list[Path]:
    """README.md and every Markdown file under docs/ that holds a region."""
    files = [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]
    return [f for f in files if MARKER.search(f.read_text())]


def render_file(path: Path) -> tuple[str, list[str]]:
    """The file's text with every region rendered, and the regions whose body changed (``LINE: gen:NAME``).

    Raises
    ------
    RegionError
        An unknown renderer, or a marker that does not pair up.
    """
    text = path.read_text()
    paired = {m.start("open") for m in REGION.finditer(text)} | {m.start("close") for m in REGION.finditer(text)}
    for m in MARKER.finditer(text):
        if m.start() not in paired:
            line = text.count("\n", 0, m.start()) + 1
            raise RegionError(f"{path}:{line}: marker {m.group(0)} has no partner")
    changed: list[str] = []
    page = Page(path)

    def replace(m: re.Match[str]) -> str:
        name = m.group("name")
        if name not in RENDERERS:
            line = text.count("\n", 0, m.start()) + 1
            raise RegionError(f"{path}:{line}: no renderer for region gen:{name} (known: {', '.join(RENDERERS)})")
        body = "\n" + RENDERERS[name](page).rstrip("\n") + "\n\n"
        left = PLACEHOLDER.search(body)
        if left is not None:  # an f-string's prefix forgotten: the code would be shown instead of the figure
            raise RegionError(f"{path}: region gen:{name} shows an unformatted placeholder {left.group(0)!r}")
        if body != m.group("body"):
            changed.append(f"{text.count(chr(10), 0, m.start()) + 1}: gen:{name}")
        return m.group("open") + body + m.group("close")

    return REGION.sub(replace, text), changed


def used_regions(files: Iterable[Path]) -> set[str]:
    """The region names the files hold."""
    return {m.group("name") for f in files for m in REGION.finditer(f.read_text())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="*", type=Path, help="Markdown files (default: README.md and docs/**/*.md)")
    ap.add_argument("--check", action="store_true", help="change nothing; exit 1 naming every stale region")
    ap.add_argument("--list", action="store_true", help="list the renderers and where their regions are")
    args = ap.parse_args(argv)
    files = [f.resolve() for f in args.files] or default_files()
    if args.list:
        for name, fn in RENDERERS.items():
            where = [str(f.relative_to(ROOT)) for f in files if name in used_regions([f])]
            sys.stdout.write(f"{name}: {(fn.__doc__ or '').splitlines()[0]} [{', '.join(where) or 'unused'}]\n")
        return 0
    stale: list[str] = []
    try:
        for path in files:
            new, changed = render_file(path)
            shown = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
            stale += [f"{shown}:{where}" for where in changed]
            if changed and not args.check:
                path.write_text(new)
    except RegionError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    if args.check:
        if stale:
            sys.stderr.write(
                "stale generated figures (their committed reports say otherwise; run `python docs/gen.py`):\n"
            )
            sys.stderr.writelines(f"  {s}\n" for s in stale)
            return 1
        sys.stdout.write(f"{len(files)} files, every generated region up to date\n")
        return 0
    sys.stdout.writelines(f"rewrote {s}\n" for s in stale)
    sys.stdout.write(f"{len(files)} files, {len(stale)} regions rewritten\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
