"""Identification accuracy before and after the diagnosed fix, scored against a blind validation's answer key.

Runs after :func:`engine.diagnosis.validation.run_validation` has finished
every diagnosis: it reads the answer key (``key/answer_key.json``), which the
diagnosis itself never sees, and identifies every counting record with
nominal patterns and with patterns retrained with the *diagnosed* effect
(:func:`engine.diagnosis.identification.identify_before_after`). Scoring code
only: the service never imports it.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from engine.constants import C_NOMINAL
from engine.diagnosis.identification import identify_before_after
from engine.identification.training import DEFAULT_KIND
from engine.identification.width import nearest_grid_width
from engine.records import Record
from engine.simulation import Case, PlantParameters, simulate_batch

__all__ = ["clean_twins", "identification_markdown", "score_identification"]

#: A progress callback: called with (records done, records in all).
Progress = Callable[[int, int], object]


def clean_twins(truths: Sequence[dict[str, Any]], records: Sequence[Record]) -> list[Record]:
    """The records without their effect: same operating point, same noise realisation.

    The noise is recovered exactly as record - noiseless simulation with the
    effect (operating point and effect from the answer key; the validation's
    generator simulates with the same defaults), and added to the noiseless
    simulation without the effect.

    Parameters
    ----------
    truths : sequence of dict
        Answer-key entries: ``K`` [m], ``J1`` [kg m^2], ``c`` [pu], ``effect`` and ``value``.
    records : sequence of Record
        The records, in the same order.

    Returns
    -------
    list of Record
        The clean twins (same channels and conditions).
    """
    cases = [Case(PlantParameters(K=t["K"], J1=t["J1"], c=t["c"])) for t in truths]
    if not cases:
        return []
    with_eff = simulate_batch(cases, effects=[{t["effect"]: t["value"]} for t in truths])
    clean = simulate_batch(cases)
    out = []
    for i, rec in enumerate(records):
        noiseless, twin = with_eff.record(i).channels, clean.record(i).channels
        ch = {name: np.asarray(x) - noiseless[name] + twin[name] for name, x in rec.channels.items()}
        out.append(Record(ch, rec.sample_interval, rec.event_index, conditions=dict(rec.conditions)))
    return out


def score_identification(
    out_dir: str | Path, kind: str = DEFAULT_KIND, at_groups: bool = True, progress: Progress | None = None
) -> dict[str, Any]:
    """Identification accuracy before and after the diagnosed fix, over a finished blind validation.

    Reads ``cases/`` and ``results/`` of :func:`engine.diagnosis.validation.run_validation`'s
    output and, like the scorer, the answer key only once every diagnosis is done.
    A record counts as identified when the identified width is the paper's
    width nearest to its true K.

    * ``clean``: cases without an effect, identified with nominal patterns;
    * ``twin``: the counting effect cases' *clean twins* (the same operating
      point and the same noise realisation, effect removed; see
      :func:`clean_twins`), nominal patterns: the accuracy on clean data
      paired case by case with ``after``, so the comparison is free of the
      sampling error between different operating points;
    * ``before``: counting effect cases, nominal patterns;
    * ``after``: the same cases, patterns retrained with the *diagnosed* effect at its
      fitted value (nominal patterns where the diagnosis named none);
    * ``oracle``: the same cases, patterns retrained with the *true* effect at its true
      value (from the answer key): the best any diagnosis could do for the identifier.
      ``after - oracle`` is the diagnosis's share of the loss against the clean twins,
      ``oracle - twin`` the identifier's own (the effect makes the width harder to read
      even when it is known exactly).

    Patterns are trained at the *calibrated* c (never the true c), or at the
    nearest paper group with ``at_groups``.

    Parameters
    ----------
    out_dir : str or Path
        Output directory of a finished blind validation.
    kind : str
        Identifier kind.
    at_groups : bool
        Train at the paper's c group nearest to the calibrated c (as stored pattern sets are).
    progress : callable, optional
        Called with (records done, records in all) after each record.

    Raises
    ------
    ValueError
        When ``out_dir`` holds a protocol-2 run (its answer key is a document, not a list of cases).

    Returns
    -------
    dict
        ``{"kind", "n": {...}, "accuracy": {split: {channel: fraction, "mean": fraction}},
        "paired": {"after_minus_twin": points, "stderr": points, "after_minus_oracle": points,
        "after_minus_oracle_stderr": points, "oracle_minus_twin": points, "oracle_minus_twin_stderr": points},
        "by_effect": {effect: {"n", "after_minus_twin", "oracle_minus_twin"}}}``.
    """
    out = Path(out_dir)
    entries = json.loads((out / "key" / "answer_key.json").read_text())
    if not isinstance(entries, list):  # protocol 2 writes a document with its cases under "cases"
        raise ValueError(
            f"{out} is not a protocol-1 run: its answer key is not a list of cases (protocol 2 scores "
            "no identification)"
        )
    key = {e["case_id"]: e for e in entries}
    hits: dict[str, dict[str, list[bool]]] = {"clean": {}, "twin": {}, "before": {}, "after": {}, "oracle": {}}
    effect_of: list[str] = []  # the true effect of each effect record, in the order of the hits
    ids = [i for i in sorted(key) if key[i]["expected_status"] == "explained" or key[i]["kind"] == "clean"]
    records = {i: Record.from_dict(json.loads((out / "cases" / f"{i}.json").read_text())["record"]) for i in ids}
    effect_ids = [i for i in ids if key[i]["expected_status"] == "explained"]
    twins = dict(
        zip(effect_ids, clean_twins([key[i] for i in effect_ids], [records[i] for i in effect_ids]), strict=True)
    )
    for n_done, case_id in enumerate(ids):
        truth = key[case_id]
        clean = truth["kind"] == "clean"
        record = records[case_id]
        result = json.loads((out / "results" / f"{case_id}.json").read_text())
        cal = result["calibration"]
        c = cal["values"].get("c", cal["fixed"].get("c", C_NOMINAL))
        v = result["verdict"]
        named = (v["effect"], v["value"]) if v["status"] == "explained" else (None, None)
        ident = identify_before_after(record, named[0], named[1], c=c, kind=kind, at_groups=at_groups)
        want = nearest_grid_width(truth["K"])
        if not clean:
            twin = identify_before_after(twins[case_id], None, None, c=c, kind=kind, at_groups=at_groups)
            oracle = identify_before_after(
                record, truth["effect"], truth["value"], c=c, kind=kind, at_groups=at_groups
            )["channels"]
            effect_of.append(truth["effect"])
        for ch, entry in ident["channels"].items():
            ok_before = bool(np.isclose(entry["before"]["width"], want))
            if clean:
                hits["clean"].setdefault(ch, []).append(ok_before)
            else:
                ok_after = bool(np.isclose((entry["after"] or entry["before"])["width"], want))
                hits["before"].setdefault(ch, []).append(ok_before)
                hits["after"].setdefault(ch, []).append(ok_after)
                hits["twin"].setdefault(ch, []).append(bool(np.isclose(twin["channels"][ch]["before"]["width"], want)))
                hits["oracle"].setdefault(ch, []).append(bool(np.isclose(oracle[ch]["after"]["width"], want)))
        if progress:
            progress(n_done + 1, len(ids))
    accuracy: dict[str, dict[str, float]] = {}
    for split, by_ch in hits.items():
        acc = {ch: float(np.mean(v)) for ch, v in by_ch.items()}
        acc["mean"] = float(np.mean(list(acc.values()))) if acc else float("nan")
        accuracy[split] = acc
    n = {split: (len(next(iter(by_ch.values()))) if by_ch else 0) for split, by_ch in hits.items()}
    paired: dict[str, float] = {}
    by_effect: dict[str, dict[str, float]] = {}
    if hits["after"]:
        # per case: mean over channels of (a - b); their mean and standard error, in points
        chans = list(hits["after"])
        per_case = {
            (a, b): np.mean([np.array(hits[a][ch], float) - np.array(hits[b][ch], float) for ch in chans], axis=0)
            for a, b in (("after", "twin"), ("after", "oracle"), ("oracle", "twin"))
        }
        for (a, b), d in per_case.items():
            name = f"{a}_minus_{b}"
            paired[name] = float(100 * d.mean())
            err = float(100 * d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("nan")
            paired["stderr" if name == "after_minus_twin" else f"{name}_stderr"] = err
        # the same paired differences by true effect (points; a reading, no target)
        names = np.array(effect_of)
        by_effect = {
            str(e): {
                "n": int((names == e).sum()),
                "after_minus_twin": float(100 * per_case["after", "twin"][names == e].mean()),
                "oracle_minus_twin": float(100 * per_case["oracle", "twin"][names == e].mean()),
            }
            for e in sorted(set(effect_of))
        }
    return {
        "kind": kind,
        "at_groups": at_groups,
        "n": n,
        "accuracy": accuracy,
        "paired": paired,
        "by_effect": by_effect,
    }


def identification_markdown(score: dict[str, Any]) -> str:
    """Table of :func:`score_identification`'s accuracies (per channel and mean), and the paired difference."""
    acc = score["accuracy"]
    channels = [ch for ch in acc["clean"] if ch != "mean"] + ["mean"]
    head = "| split | n | " + " | ".join(channels) + " |\n|---|---|" + "---|" * len(channels) + "\n"
    label = {
        "clean": "clean cases, nominal patterns",
        "twin": "effect cases' clean twins (same point and noise, effect removed), nominal patterns",
        "before": "effect cases, nominal patterns",
        "after": "effect cases, patterns retrained with the diagnosed effect",
        "oracle": "effect cases, patterns retrained with the true effect at its true value",
    }
    rows = (
        "\n".join(
            f"| {label[s]} | {score['n'][s]} | "
            + " | ".join(f"{100 * acc[s].get(ch, float('nan')):.1f} %" for ch in channels)
            + " |"
            for s in ("clean", "twin", "before", "after", "oracle")
            if s in acc
        )
        + "\n"
    )
    p = score.get("paired") or {}
    if p:
        rows += (
            f"\nAfter the fix minus clean twin, paired per case (mean over channels): "
            f"{p['after_minus_twin']:+.1f} points (standard error {p['stderr']:.1f}).\n"
        )
    if "after_minus_oracle" in p:
        rows += (
            f"Of it, the diagnosis's share (after the fix minus the true effect's patterns): "
            f"{p['after_minus_oracle']:+.1f} points (standard error {p['after_minus_oracle_stderr']:.1f}); "
            f"the identifier's (true effect's patterns minus clean twin): {p['oracle_minus_twin']:+.1f} points "
            f"(standard error {p['oracle_minus_twin_stderr']:.1f}).\n"
        )
    by_effect = score.get("by_effect") or {}
    if by_effect:
        rows += "\n| true effect | n | after the fix minus clean twin | true effect's patterns minus clean twin |\n"
        rows += "|---|---|---|---|\n"
        for e, r in by_effect.items():
            rows += f"| {e} | {r['n']} | {r['after_minus_twin']:+.1f} | {r['oracle_minus_twin']:+.1f} |\n"
    return head + rows
