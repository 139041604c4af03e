"""Scoring a protocol-v2 validation: the diagnoses against the answer key, once every diagnosis is done.

What a diagnosis answered is read from its result (``DiagnosisResult.to_dict()``):
``verdict.status``; ``verdict.effects``, the named effects sorted by share (a
result without that list names ``[verdict.effect]``); ``verdict.effect``, the
largest share; ``verdict.locus`` (None when absent); ``gap.before`` /
``gap.after`` ``rms_over_noise``; ``seconds``.

A named effect counts for every effect the diagnosis declared indistinguishable from it
(``verdict.effects[i].alternatives``: a measurement delay and a trigger offset give the very
same record, :func:`engine.diagnosis.space.indistinguishable`); results without that field
are scored by the names alone. Near twins (``verdict.effects[i].near_twins``: effects that only
this record cannot tell from the named one, :mod:`engine.diagnosis.ambiguity`) do not count in
the targets' metrics; the report shows how the rates read when they do (``*_near_twins``,
report only) and how many answers declared any (``near_twins_declared``).

Metrics (rates with their Wilson 95 % intervals; :data:`~engine.validation.protocol.TARGETS`):

* ``single_named``: single-effect cases answered ``explained`` with the right top effect;
* ``{pair,triple,compound}_exact``: compound cases answered ``explained`` with exactly the true set;
* ``{pair,triple,compound}_contains``: compound cases whose named set holds every true effect;
* ``held_back_unexplained``: held-back cases answered ``unexplained``;
* ``held_back_locus``: held-back cases whose ``verdict.locus`` is the held-back effect's locus;
* ``clean_false_alarm``: clean cases answered anything but ``no_gap`` (also by operating point
  on/off the catalogue's operating range and by white/coloured noise, report only);
* ``median_gap_after``: median ``gap.after.rms_over_noise`` over the cases answered
  ``explained`` (order-statistic 95 % interval);
* ``seconds_single_p90`` / ``seconds_compound_p90``: 90th percentiles of the diagnosis times
  (order-statistic 95 % interval; report only; medians alongside).
"""

from __future__ import annotations

import itertools
import math
from collections import Counter, defaultdict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from engine.validation.key import KeyEntry
from engine.validation.protocol import CASE_KINDS, COMPOUND_KINDS, TARGETS
from engine.validation.stats import MedianEstimate, QuantileEstimate, Rate, median_interval, quantile_interval, rate

__all__ = ["ROW_COLUMNS", "Answer", "Metric", "Scores", "answer_of", "score_cases"]

#: Statuses a diagnosis may give, in the order of the report's tables (``error``: it raised).
STATUSES: tuple[str, ...] = ("explained", "unexplained", "no_gap", "weak_gap", "error")


@dataclass(frozen=True)
class Answer:
    """What a diagnosis answered about one case.

    Attributes
    ----------
    status : str
        ``verdict.status``.
    effects : tuple of (str, float or None)
        Named effects and their fitted values, largest share first.
    locus : str or None
        ``verdict.locus``.
    seconds : float or None
        Diagnosis time [s] (``seconds``, else the wall time around it).
    rms_before, rms_after : float or None
        ``gap.before`` / ``gap.after`` ``rms_over_noise`` [-].
    alternatives : tuple of tuple of str
        Per named effect, the effects the diagnosis declared indistinguishable from it at its
        value (``verdict.effects[i].alternatives``: the same record, e.g. a measurement delay
        and a trigger offset); a true effect among them counts as named.
    locus_group : tuple of str
        ``verdict.locus_group``: the loci the record cannot tell from ``locus`` (results written
        before it existed: none, so ``locus`` alone).
    """

    status: str
    effects: tuple[tuple[str, float | None], ...]
    locus: str | None
    seconds: float | None
    rms_before: float | None
    rms_after: float | None
    alternatives: tuple[tuple[str, ...], ...] = ()
    near_twins: tuple[tuple[str, ...], ...] = ()
    stages: tuple[tuple[str, float], ...] = ()
    locus_group: tuple[str, ...] = ()

    def names_locus(self, locus: str) -> bool:
        """Whether the part the answer names is ``locus``: its locus, or a locus of the group the
        record cannot tell from it."""
        return self.locus is not None and (locus == self.locus or locus in self.locus_group)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(n for n, _ in self.effects)

    @property
    def top(self) -> str | None:
        return self.effects[0][0] if self.effects else None

    def _could_be(self, i: int, near: bool = False) -> set[str]:
        """The i-th named effect and its declared twins (with ``near``, its near twins too)."""
        alts = self.alternatives[i] if i < len(self.alternatives) else ()
        close = self.near_twins[i] if near and i < len(self.near_twins) else ()
        return {self.effects[i][0], *alts, *close}

    def top_is(self, name: str, near: bool = False) -> bool:
        """Whether the largest-share effect is ``name`` (or declared indistinguishable from it)."""
        return bool(self.effects) and name in self._could_be(0, near)

    def names_effect(self, name: str, near: bool = False) -> bool:
        """Whether some named effect is ``name`` (or declared indistinguishable from it)."""
        return any(name in self._could_be(i, near) for i in range(len(self.effects)))

    def names_exactly(self, names: Sequence[str], near: bool = False) -> bool:
        """Whether the named effects are exactly ``names``, one each (twins count as named; with
        ``near``, near twins too)."""
        truth = list(dict.fromkeys(names))
        if len(self.effects) != len(truth):
            return False
        # match named effects to true ones (at most three each: try every order)
        return any(
            all(t in self._could_be(i, near) for i, t in enumerate(order)) for order in itertools.permutations(truth)
        )


def _number(x: Any) -> float | None:
    return float(x) if isinstance(x, (int, float)) and math.isfinite(x) else None


def _alternatives(row: dict[str, Any]) -> tuple[str, ...]:
    """A named effect's declared twins; a result that gives them as anything but a list of names is refused."""
    alts = row.get("alternatives")
    if alts is None:
        return ()
    if not isinstance(alts, list) or not all(isinstance(x, str) for x in alts):
        raise ValueError(
            f"verdict.effects[].alternatives of {row.get('effect')!r} must be a list of effect names, got {alts!r}"
        )
    return tuple(alts)


def _near_twins(row: dict[str, Any]) -> tuple[str, ...]:
    """A named effect's near twins (their names); a result that gives them as anything but a list of
    ``{"effect": name, ...}`` is refused."""
    near = row.get("near_twins")
    if near is None:
        return ()
    if not isinstance(near, list) or not all(isinstance(x, dict) and isinstance(x.get("effect"), str) for x in near):
        raise ValueError(
            f"verdict.effects[].near_twins of {row.get('effect')!r} must be a list of {{'effect': name, ...}}, "
            f"got {near!r}"
        )
    return tuple(x["effect"] for x in near)


def _stages(result: dict[str, Any]) -> tuple[tuple[str, float], ...]:
    """Where a diagnosis's time went (``stages``; none in results written before they were recorded); a
    result that gives them as anything but a list of ``{"stage": name, "seconds": finite number}`` is refused."""
    stages = result.get("stages")
    if stages is None:
        return ()
    if not isinstance(stages, list) or not all(
        isinstance(x, dict) and isinstance(x.get("stage"), str) and _number(x.get("seconds")) is not None
        for x in stages
    ):
        raise ValueError(f"stages must be a list of {{'stage': name, 'seconds': number}}, got {stages!r}")
    return tuple((x["stage"], float(x["seconds"])) for x in stages)


def answer_of(result: dict[str, Any]) -> Answer:
    """Read a result file's answer, tolerant of results written before ``effects`` and ``locus`` existed."""
    v = result.get("verdict") or {}
    status = str(v.get("status", "error"))
    listed = v.get("effects")
    alternatives: tuple[tuple[str, ...], ...] = ()
    near: tuple[tuple[str, ...], ...] = ()
    if isinstance(listed, list):
        rows = [e for e in listed if e.get("effect")]
        top = v.get("effect")
        if top and rows and rows[0]["effect"] != top:  # verdict.effect is the largest share: put it first
            rows.sort(key=lambda e: e["effect"] != top)
        effects = tuple((str(e["effect"]), _number(e.get("value"))) for e in rows)
        alternatives = tuple(_alternatives(e) for e in rows)
        near = tuple(_near_twins(e) for e in rows)
    elif v.get("effect"):
        effects = ((str(v["effect"]), _number(v.get("value"))),)
    else:
        effects = ()
    gap = result.get("gap") or {}
    before, after = gap.get("before") or {}, gap.get("after") or {}
    seconds = _number(result.get("seconds"))
    return Answer(
        status=status,
        effects=effects,
        locus=v.get("locus"),
        seconds=seconds if seconds is not None else _number(result.get("wall_seconds")),
        rms_before=_number(before.get("rms_over_noise")),
        rms_after=_number(after.get("rms_over_noise")),
        alternatives=alternatives,
        near_twins=near,
        stages=_stages(result),
        locus_group=tuple(str(g) for g in v.get("locus_group") or () if isinstance(g, str)),
    )


def correct(k: KeyEntry, a: Answer) -> bool:
    """Whether an answer is right by its case kind's main criterion (the named effect, the exact set,
    ``unexplained``, ``no_gap``)."""
    if k.kind == "single":
        return a.status == "explained" and a.top_is(k.effects[0].name)
    if k.kind in COMPOUND_KINDS:
        return a.status == "explained" and a.names_exactly(k.effect_names)
    return a.status == k.expected_status


@dataclass(frozen=True)
class Metric:
    """One scored quantity, with its target if it has one.

    Attributes
    ----------
    name : str
        Key of :data:`TARGETS` (or of a report-only quantity).
    description : str
        What it counts.
    rate : Rate or None
        For a rate.
    median : MedianEstimate or None
        For a median (and beside a quantile, e.g. the median time).
    quantile : QuantileEstimate or None
        For a quantile (a time target is on the 90th percentile); when set, it is the value.
    """

    name: str
    description: str
    rate: Rate | None = None
    median: MedianEstimate | None = None
    quantile: QuantileEstimate | None = None

    @property
    def _estimate(self) -> Rate | MedianEstimate | QuantileEstimate | None:
        return self.quantile if self.quantile is not None else self.rate if self.rate is not None else self.median

    @property
    def value(self) -> float | None:
        est = self._estimate
        if isinstance(est, MedianEstimate):
            return est.median
        return None if est is None else est.value

    @property
    def met(self) -> bool | None:
        """Whether the point estimate meets the target (None: no target or no case)."""
        target = TARGETS.get(self.name)
        return None if target is None or self.value is None else target.met(self.value)

    @property
    def interval_met(self) -> bool | None:
        """Whether the whole 95 % interval lies on the target's side (None: no target, case or interval)."""
        target = TARGETS.get(self.name)
        est = self._estimate
        if target is None or est is None or est.low is None or est.high is None:
            return None
        return target.met(est.low if target.direction == ">=" else est.high)

    def to_dict(self) -> dict[str, Any]:
        target = TARGETS.get(self.name)
        return {
            "name": self.name,
            "description": self.description,
            **({"rate": self.rate.to_dict()} if self.rate is not None else {}),
            **({"median": self.median.to_dict()} if self.median is not None else {}),
            **({"quantile": self.quantile.to_dict()} if self.quantile is not None else {}),
            "target": None if target is None else target.text(percent=self.rate is not None),
            "gating": None if target is None else target.gating,
            "met": self.met,
            "interval_met": self.interval_met,
        }


@dataclass
class Scores:
    """Every score of a run.

    Attributes
    ----------
    metrics : list of Metric
        The targets' metrics, in the report's order.
    breakdown : list of Metric
        Report-only rates: the overall and per-kind main criterion, false alarms by operating
        point and noise colour.
    status_by_kind : dict
        ``status_by_kind[kind][status]`` counts.
    per_effect : dict
        Per effect: single cases named, compound cases found in the set, held-back cases
        answered unexplained and located (each ``[k, n]``).
    stages_by_kind : dict
        ``stages_by_kind[kind][stage]``: how many of the kind's diagnoses ran that stage of the work
        and its wall time over them (``n``, ``median``, ``p90``, ``total`` [s]), from the results'
        ``stages`` (empty for results written before they were recorded).
    rows : list of dict
        One row per case (keys :data:`ROW_COLUMNS`); :meth:`to_dict` writes them as a table
        (``cases.columns`` and ``cases.rows``) to keep the report small.
    """

    metrics: list[Metric]
    breakdown: list[Metric]
    status_by_kind: dict[str, dict[str, int]]
    per_effect: dict[str, dict[str, list[int]]]
    rows: list[dict[str, Any]]
    stages_by_kind: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "metrics": [m.to_dict() for m in self.metrics],
            "breakdown": [m.to_dict() for m in self.breakdown],
            "status_by_kind": self.status_by_kind,
            "per_effect": self.per_effect,
            "stages_by_kind": self.stages_by_kind,
            "cases": {
                "columns": list(ROW_COLUMNS),
                "rows": [[r[c] for c in ROW_COLUMNS] for r in self.rows],
            },
        }


#: Columns of a per-case row: id, kind, the true effects ``[name, value]`` and the held-back locus,
#: operating point (K [mm], J1 [kg m^2], c [pu]) and whether it is on the operating range, noise
#: (``white`` or the colouring low-pass), its SNR range over the channels [dB], the channels, the
#: answer (status, ``[name, value]`` named, locus), whether it is right by the kind's main
#: criterion, the diagnosis time [s], chi2/n (the gap's rms_over_noise squared) before and after.
ROW_COLUMNS: tuple[str, ...] = (
    "case",
    "kind",
    "truth",
    "true_locus",
    "K_mm",
    "J1",
    "c",
    "on_box",
    "noise",
    "snr_db",
    "channels",
    "status",
    "effects",
    "locus",
    "correct",
    "seconds",
    "chi2n_before",
    "chi2n_after",
)


def _sig(x: float | None, digits: int = 4) -> float | None:
    return None if x is None or not math.isfinite(x) else float(f"{x:.{digits}g}")


def _p90(xs: Sequence[float]) -> float | None:
    return float(np.percentile(xs, 90)) if xs else None


def _time_metric(name: str, what: str, seconds: list[float]) -> Metric:
    return Metric(name, what, median=median_interval(seconds), quantile=quantile_interval(seconds, 0.9))


def _row(k: KeyEntry, a: Answer, ok: bool) -> dict[str, Any]:
    noise = k.noise
    snr = list(noise["snr_db"].values())
    colour = "white" if noise["order"] == 0 else f"o{noise['order']} {noise['cutoff_hz']:.0f} Hz"
    return {
        "case": k.case_id,
        "kind": k.kind,
        "truth": [[e.name, _sig(e.value)] for e in k.effects],
        "true_locus": k.effects[0].locus if k.kind == "held_back" else None,
        "K_mm": round(1e3 * k.K, 3),
        "J1": round(k.J1, 4),
        "c": round(k.c, 3),
        "on_box": k.on_box,
        "noise": colour,
        "snr_db": [round(min(snr), 1), round(max(snr), 1)],
        "channels": "all" if len(k.channels) == 5 else ",".join(k.channels),
        "status": a.status,
        "effects": [[n, _sig(v)] for n, v in a.effects],
        "locus": a.locus,
        "correct": ok,
        "seconds": _sig(a.seconds, 3),
        "chi2n_before": _sig(None if a.rms_before is None else a.rms_before**2),
        "chi2n_after": _sig(None if a.rms_after is None else a.rms_after**2),
    }


def score_cases(key: Sequence[KeyEntry], results: dict[str, dict[str, Any]]) -> Scores:
    """Score every case of the key against its diagnosis result.

    Parameters
    ----------
    key : sequence of KeyEntry
        The answer key.
    results : dict of str to dict
        Result per case id (``DiagnosisResult.to_dict()`` shape, see :func:`answer_of`).

    Returns
    -------
    Scores

    Raises
    ------
    KeyError
        A case of the key has no result (score only once every diagnosis is done).
    """
    missing = [k.case_id for k in key if k.case_id not in results]
    if missing:
        raise KeyError(f"{len(missing)} case(s) have no result yet (e.g. {missing[0]}): finish the diagnoses first")
    answers = {k.case_id: answer_of(results[k.case_id]) for k in key}
    by_kind: dict[str, list[tuple[KeyEntry, Answer]]] = defaultdict(list)
    for k in key:
        by_kind[k.kind].append((k, answers[k.case_id]))
    compound = [p for kind in COMPOUND_KINDS for p in by_kind[kind]]

    def exact(pairs: list[tuple[KeyEntry, Answer]], near: bool = False) -> Rate:
        return rate([a.status == "explained" and a.names_exactly(k.effect_names, near) for k, a in pairs])

    def contains(pairs: list[tuple[KeyEntry, Answer]], near: bool = False) -> Rate:
        return rate(
            [a.status == "explained" and all(a.names_effect(n, near) for n in k.effect_names) for k, a in pairs]
        )

    singles, held, clean = by_kind["single"], by_kind["held_back"], by_kind["clean"]
    explained_after = [a.rms_after for a in answers.values() if a.status == "explained" and a.rms_after is not None]
    # a diagnosis that raised has no diagnosis time
    secs_single = [a.seconds for _, a in singles if a.seconds is not None and a.status != "error"]
    secs_compound = [a.seconds for _, a in compound if a.seconds is not None and a.status != "error"]
    metrics = [
        Metric(
            "single_named",
            "single effect: explained, top effect right",
            rate([a.status == "explained" and a.top_is(k.effects[0].name) for k, a in singles]),
        ),
        Metric("compound_exact", "pair or triple: explained, exactly the true set", exact(compound)),
        Metric("pair_exact", "pair: explained, exactly the true set", exact(by_kind["pair"])),
        Metric("triple_exact", "triple: explained, exactly the true set", exact(by_kind["triple"])),
        Metric("compound_contains", "pair or triple: every true effect named", contains(compound)),
        Metric("pair_contains", "pair: every true effect named", contains(by_kind["pair"])),
        Metric("triple_contains", "triple: every true effect named", contains(by_kind["triple"])),
        Metric(
            "held_back_unexplained",
            "held back: answered unexplained",
            rate([a.status == "unexplained" for _, a in held]),
        ),
        Metric(
            "held_back_locus",
            "held back: the part the verdict names (verdict.locus, with the loci the record cannot tell "
            "from it) is the effect's locus",
            rate([a.names_locus(k.effects[0].locus) for k, a in held]),
        ),
        Metric(
            "held_back_locus_single",
            "held back: verdict.locus itself is the effect's locus",
            rate([a.locus == k.effects[0].locus for k, a in held]),
        ),
        Metric("clean_false_alarm", "clean: any answer but no_gap", rate([a.status != "no_gap" for _, a in clean])),
        Metric(
            "median_gap_after",
            "answered explained: median gap.after.rms_over_noise",
            median=median_interval(explained_after),
        ),
        _time_metric("seconds_single_p90", "single effect: diagnosis time [s], 90th percentile", secs_single),
        _time_metric("seconds_compound_p90", "pair or triple: diagnosis time [s], 90th percentile", secs_compound),
    ]
    # near twins (this record cannot tell them from the named effect) are not counted above: how the
    # rates read when they are, and how often an answer declared any
    breakdown = [
        Metric(
            "single_named_near_twins",
            "single effect: top effect right, near twins counted",
            rate([a.status == "explained" and a.top_is(k.effects[0].name, near=True) for k, a in singles]),
        ),
        Metric(
            "compound_exact_near_twins",
            "pair or triple: exactly the true set, near twins counted",
            exact(compound, True),
        ),
        Metric(
            "compound_contains_near_twins",
            "pair or triple: every true effect named, near twins counted",
            contains(compound, True),
        ),
        Metric(
            "near_twins_declared",
            "answered explained: some named effect has near twins",
            rate([any(a.near_twins) for a in answers.values() if a.status == "explained"]),
        ),
    ]
    breakdown += [
        Metric(
            "all_correct",
            "every case: right by its kind's main criterion",
            rate([correct(k, answers[k.case_id]) for k in key]),
        )
    ]
    breakdown += [
        Metric(
            f"{kind}_correct", f"{kind}: right by the main criterion", rate([correct(k, a) for k, a in by_kind[kind]])
        )
        for kind in CASE_KINDS
    ]
    for on_box in (True, False):
        for colour in ("white", "coloured"):
            sel = [a.status != "no_gap" for k, a in clean if k.on_box == on_box and k.colour == colour]
            where = "on" if on_box else "off"
            breakdown.append(
                Metric(
                    f"clean_false_alarm_{where}_box_{colour}",
                    f"clean, operating point {where} the operating range, {colour} noise: false alarms",
                    rate(sel),
                )
            )
    for where, on_box in (("on", True), ("off", False)):
        breakdown.append(
            Metric(
                f"clean_false_alarm_{where}_box",
                f"clean, operating point {where} the operating range: false alarms",
                rate([a.status != "no_gap" for k, a in clean if k.on_box == on_box]),
            )
        )
    for colour in ("white", "coloured"):
        breakdown.append(
            Metric(
                f"clean_false_alarm_{colour}",
                f"clean, {colour} noise: false alarms",
                rate([a.status != "no_gap" for k, a in clean if k.colour == colour]),
            )
        )
    secs_all = [a.seconds for a in answers.values() if a.seconds is not None and a.status != "error"]
    breakdown.append(
        Metric("seconds_all_median", "every case: diagnosis time [s], median", median=median_interval(secs_all))
    )
    breakdown.append(_time_metric("seconds_all_p90", "every case: diagnosis time [s], 90th percentile", secs_all))

    status_by_kind: dict[str, dict[str, int]] = {}
    for kind in CASE_KINDS:
        counts = Counter(a.status for _, a in by_kind[kind])
        status_by_kind[kind] = {s: counts.get(s, 0) for s in (*STATUSES, *sorted(set(counts) - set(STATUSES)))}
    per_effect: dict[str, dict[str, list[int]]] = defaultdict(lambda: defaultdict(lambda: [0, 0]))
    for k, a in singles:
        cell = per_effect[k.effects[0].name]["single_named"]
        cell[0] += int(a.status == "explained" and a.top_is(k.effects[0].name))
        cell[1] += 1
    for k, a in compound:
        for e in k.effects:
            cell = per_effect[e.name]["compound_found"]
            cell[0] += int(a.status == "explained" and a.names_effect(e.name))
            cell[1] += 1
    for k, a in held:
        name, locus = k.effects[0].name, k.effects[0].locus
        cell = per_effect[name]["held_back_unexplained"]
        cell[0] += int(a.status == "unexplained")
        cell[1] += 1
        cell = per_effect[name]["held_back_locus"]
        cell[0] += int(a.names_locus(locus))
        cell[1] += 1
    rows = [_row(k, answers[k.case_id], correct(k, answers[k.case_id])) for k in key]
    return Scores(
        metrics=metrics,
        breakdown=breakdown,
        status_by_kind=status_by_kind,
        per_effect={n: dict(v) for n, v in sorted(per_effect.items())},
        rows=rows,
        stages_by_kind=_stages_by_kind(by_kind),
    )


def _stages_by_kind(by_kind: Mapping[str, list[tuple[KeyEntry, Answer]]]) -> dict[str, dict[str, dict[str, float]]]:
    """Per kind and stage of the work: how many diagnoses ran it and its wall time (median, p90, total [s])."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for kind in CASE_KINDS:
        times: dict[str, list[float]] = defaultdict(list)
        for _, a in by_kind.get(kind, []):
            for name, secs in a.stages:
                times[name].append(secs)
        if times:
            out[kind] = {
                name: {"n": len(t), "median": float(np.median(t)), "p90": _p90(t) or 0.0, "total": sum(t)}
                for name, t in times.items()
            }
    return out
