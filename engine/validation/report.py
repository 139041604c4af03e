"""The report of a protocol-v2 validation: ``report.json`` and ``report.md``, small enough to commit.

The JSON holds the run's provenance (protocol, seed, mix, libraries, the code
version it was scored on and those the diagnoses ran on; ``drive``, the drive the
cases were simulated and diagnosed on, when it is not MODEL.md's reference plant), every metric with
its counts, rate, Wilson 95 % interval, target and whether it is met, the
breakdowns, the reliability of the stated confidence (``reliability``,
:func:`engine.validation.reliability.reliability_section`) and one compact row per case (a table: ``cases.columns``, ``cases.rows``). The Markdown says the same for a
reader.
"""

from __future__ import annotations

import datetime as _dt
import json
from typing import Any

from engine.atomic import write_text_atomic
from engine.validation.layout import RunLayout
from engine.validation.protocol import CASE_KINDS
from engine.validation.reliability import reliability_markdown
from engine.validation.score import STATUSES, Metric, Scores

__all__ = ["build_report", "case_rows", "dumps", "markdown", "metric_lines", "summary_markdown", "write_report"]


def build_report(scores: Scores, header: dict[str, Any]) -> dict[str, Any]:
    """The report document: ``header`` (provenance) then the scores.

    Parameters
    ----------
    scores : Scores
        The run's scores.
    header : dict
        Provenance: ``protocol``, ``seed``, ``n_cases``, ``counts``, ``library``, ``held_back``,
        ``code_version``, ``result_code_versions``, ``drive`` on a described drive (``name``,
        ``fingerprint``, ``operating_box`` and ``description``) and anything else worth keeping.

    Returns
    -------
    dict
        JSON-ready.
    """
    now = _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat()
    return {**header, "scored_at": now, **scores.to_dict()}


def _yes(x: bool | None) -> str:
    return "n/a" if x is None else "**met**" if x else "**not met**"


def _metric_cells(m: dict[str, Any]) -> tuple[str, str]:
    if "rate" in m:
        r = m["rate"]
        if r["n"] == 0:
            return "n/a (0 cases)", ""
        return f"{r['k']}/{r['n']} = {100 * r['rate']:.1f} %", f"[{100 * r['low']:.1f}, {100 * r['high']:.1f}] %"
    med = m["median"]
    if med["n"] == 0:
        return "n/a (0 cases)", ""
    est = m.get("quantile")
    if est is None:  # a median
        value = f"{med['median']:.3g} (n = {med['n']})"
        est = {**med, "value": med["median"]}
    else:  # a quantile (the interval is its own), the median beside it
        value = f"p{100 * est['q']:g} {est['value']:.3g} (n = {est['n']}; median {med['median']:.3g})"
    if est["low"] is None:
        return value, "too few cases"
    return value, f"[{est['low']:.3g}, {est['high']:.3g}] ({100 * est['coverage']:.0f} %)"


def _metric_table(metrics: list[dict[str, Any]], with_target: bool) -> list[str]:
    if with_target:
        lines = [
            "| metric | result | 95 % interval | target | met | interval beyond target |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
    else:
        lines = ["| quantity | result | 95 % interval |", "| --- | --- | --- |"]
    for m in metrics:
        value, interval = _metric_cells(m)
        row = f"| {m['description']} | {value} | {interval} |"
        if with_target:
            row += f" {m['target'] or ''} | {_yes(m['met'])} | {_yes(m['interval_met'])} |"
        lines.append(row)
    return lines


def _fmt_effects(effects: list[list[Any]]) -> str:
    return ", ".join(f"{n} = {v:.4g}" if v is not None else str(n) for n, v in effects) or "-"


def case_rows(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """The per-case rows of a report document as dicts (the document stores them as a table)."""
    table = doc.get("cases") or {"columns": [], "rows": []}
    return [dict(zip(table["columns"], row, strict=True)) for row in table["rows"]]


def _ran_with(ran_with: list[dict[str, Any]] | None) -> str:
    """How the diagnoses shared the machine (their times depend on it), from the results' ``ran_with``."""
    if not ran_with:
        return "how many ran at once is not recorded"

    def one(w: dict[str, Any]) -> str:
        n, t, c = w.get("at_once"), w.get("threads_each"), w.get("host_cores")
        cores = "" if c is None else f" on {c} cores"
        return f"{n} diagnos{'is' if n == 1 else 'es'} at once, {t} thread{'s' if t != 1 else ''} each{cores}"

    return "; ".join(one(w) for w in ran_with)


def _drive_line(drive: dict[str, Any] | None) -> list[str]:
    """The provenance line naming a described drive (none for MODEL.md's reference plant)."""
    if not drive:
        return []
    box = drive.get("operating_box") or {}
    where = ""
    if {"K", "J1", "c"} <= set(box):
        k, j1, c = box["K"], box["J1"], box["c"]
        where = (
            f"; operating points drawn from its plausible box K {1e3 * k[0]:.3g}-{1e3 * k[1]:.3g} mm, "
            f"J1 {j1[0]:.3g}-{j1[1]:.3g} kg m^2, c {c[0]:.3g}-{c[1]:.3g} pu"
        )
    fingerprint = str(drive.get("fingerprint"))[:12]
    return [f"- drive: {drive.get('name')}, fingerprint `{fingerprint}` (not MODEL.md's reference plant){where}"]


def summary_markdown(doc: dict[str, Any]) -> str:
    """The title, provenance and the targets table (what the CLI prints)."""
    cv = doc.get("code_version") or {}
    ran = ", ".join(doc.get("result_code_versions") or []) or "unknown"
    counts = doc.get("counts", {})
    lines = [
        f"# Blind validation, protocol {doc.get('protocol')}: {doc.get('n_cases')} cases, seed {doc.get('seed')}",
        "",
        *_drive_line(doc.get("drive")),
        f"- code scored: `{cv.get('describe') or 'unknown'}` (commit `{cv.get('commit') or 'unknown'}`); "
        f"diagnoses ran on: {ran}",
        "- cases: " + ", ".join(f"{counts.get(k, 0)} {k}" for k in CASE_KINDS),
        f"- library given to every case: the {len(doc.get('library', []))} effects of the catalogue; "
        f"held back (never in it): {', '.join(doc.get('held_back', []))}",
        f"- diagnosis times: {_ran_with(doc.get('ran_with'))}",
        f"- scored at {doc.get('scored_at')}",
        "",
        "## Targets",
        "",
        "'met' compares the point estimate with the target; 'interval beyond target' asks the whole 95 % "
        "interval (Wilson for rates, order statistics for medians) to lie on the target's side.",
        "",
        *_metric_table(doc["metrics"], with_target=True),
    ]
    return "\n".join(lines) + "\n"


def markdown(doc: dict[str, Any]) -> str:
    """The whole report as Markdown: the summary, breakdowns, answers by kind, per effect, per case."""
    lines = [summary_markdown(doc), "## Breakdown (report only)", "", *_metric_table(doc["breakdown"], False), ""]
    statuses = list(STATUSES) + sorted({s for row in doc["status_by_kind"].values() for s in row} - set(STATUSES))
    lines += ["## Answers by kind", "", "| kind | " + " | ".join(statuses) + " |", "| --- |" + " --- |" * len(statuses)]
    for kind, row in doc["status_by_kind"].items():
        lines.append(f"| {kind} | " + " | ".join(str(row.get(s, 0)) for s in statuses) + " |")
    cols = ("single_named", "compound_found", "held_back_unexplained", "held_back_locus")
    lines += ["", "## Per effect", "", "| effect | " + " | ".join(cols) + " |", "| --- |" + " --- |" * len(cols)]
    for name, cells in doc["per_effect"].items():
        vals = [f"{cells[c][0]}/{cells[c][1]}" if c in cells else "" for c in cols]
        lines.append(f"| {name} | " + " | ".join(vals) + " |")
    if doc.get("reliability"):
        lines += ["", *reliability_markdown(doc["reliability"])]
    stages = doc.get("stages_by_kind") or {}
    if stages:
        lines += [
            "",
            "## Time by stage of the work",
            "",
            "Per kind: how many diagnoses ran the stage, its median and 90th percentile [s] over them, and its "
            "share of the kind's total time.",
            "",
            "| kind | stage | n | median s | p90 s | share of time |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        for kind, by_stage in stages.items():
            total = sum(x["total"] for x in by_stage.values()) or 1.0
            for name, x in by_stage.items():
                lines.append(
                    f"| {kind} | {name} | {x['n']} | {x['median']:.1f} | {x['p90']:.1f} | {100 * x['total'] / total:.0f} % |"
                )
    lines += [
        "",
        "## Cases",
        "",
        "K in mm; noise: white or the colouring low-pass's order and cut-off; SNR range over the channels in dB; "
        "chi2/n = (gap rms_over_noise)^2 before and after the named effects.",
        "",
        "| case | kind | truth | K, J1, c | noise, SNR | channels | answer | named | locus | right | s "
        "| chi2/n before | after |",
        "| --- |" + " --- |" * 12,
    ]
    for r in case_rows(doc):
        truth = _fmt_effects(r["truth"]) + (f" ({r['true_locus']})" if r.get("true_locus") else "")
        point = f"{r['K_mm']:.2f}, {r['J1']:.3f}, {r['c']:.2f}" + ("" if r["on_box"] else " (off)")
        after = "" if r["chi2n_after"] is None else f"{r['chi2n_after']:.3g}"
        before = "" if r["chi2n_before"] is None else f"{r['chi2n_before']:.3g}"
        secs = "" if r["seconds"] is None else f"{r['seconds']:.0f}"
        lines.append(
            f"| {r['case']} | {r['kind']} | {truth} | {point} | {r['noise']}, {r['snr_db'][0]:.0f}-{r['snr_db'][1]:.0f} "
            f"| {r['channels']} | {r['status']} | {_fmt_effects(r['effects'])} | {r['locus'] or ''} "
            f"| {'yes' if r['correct'] else 'no'} | {secs} | {before} | {after} |"
        )
    return "\n".join(lines) + "\n"


def dumps(doc: dict[str, Any]) -> str:
    """The report as JSON text: indented, one line per case row (compact and diffable)."""
    body = json.dumps({k: v for k, v in doc.items() if k != "cases"}, indent=1, allow_nan=False)
    table = doc.get("cases") or {"columns": [], "rows": []}
    rows = ",\n   ".join(json.dumps(r, allow_nan=False) for r in table["rows"])
    head = body[: body.rindex("}")].rstrip()
    sep = "" if head == "{" else ","
    cases = f'{{\n  "columns": {json.dumps(table["columns"])},\n  "rows": [\n   {rows}\n  ]\n }}'
    return f'{head}{sep}\n "cases": {cases}\n}}\n'


def write_report(layout: RunLayout, doc: dict[str, Any]) -> None:
    """Write ``report.json`` and ``report.md`` to the run's directory."""
    write_text_atomic(layout.report_json, dumps(doc))
    write_text_atomic(layout.report_md, markdown(doc))


def metric_lines(metrics: list[Metric]) -> list[str]:
    """One line per metric (for logs)."""
    out = []
    for m in metrics:
        d = m.to_dict()
        value, interval = _metric_cells(d)
        out.append(f"{m.name}: {value} {interval} (target {d['target']}: {_yes(m.met).strip('*')})")
    return out
