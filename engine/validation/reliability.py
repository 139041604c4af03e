"""Whether a stated confidence is a probability: reliability tables and Brier scores of the verdicts.

A verdict stated at 80 % should be right about 80 % of the time. Given (stated confidence,
right or wrong) pairs, :func:`reliability_table` groups them by stated confidence
(:data:`RELIABILITY_EDGES`) and gives, per group, the number of cases, the mean stated confidence
and the observed accuracy with its Wilson 95 % interval (:func:`engine.validation.stats.rate`),
plus the Brier score (mean squared difference of stated and outcome) with a bootstrap 95 %
interval (:func:`brier_score`). The target of issue 50 (item 4): stated and observed agree within
:data:`TARGET_TOLERANCE` in every group of at least :data:`TARGET_MIN_N` cases.

What "right" means is each protocol's scorer's main criterion (:func:`run_outcomes`):

* protocol 2 (:mod:`engine.validation.score`): the report row's ``correct`` (a single effect
  answered ``explained`` with the right top effect, a pair or triple with exactly the true set,
  a held-back effect answered ``unexplained``, a clean record ``no_gap``; ``weak_gap`` is never
  right);
* protocol 1 (:func:`engine.diagnosis.validation.score`): an effect case answered ``explained``
  with the effect or its same-physics twin, a left-out case answered ``unexplained``, a clean or
  weak case answered ``no_gap`` (a weak draw answered ``weak_gap`` is right too).

A verdict's locus (``unexplained`` and ``weak_gap``, from the locus estimate) is right when it is
the locus of an effect in the record (none for a clean record).

:func:`read_run` reads a committed run directory (``report.json`` and ``results.tar.xz``, the
tarball read in memory; or a ``results/`` directory) into :class:`CaseOutcome` rows;
:func:`reliability_section` is the section both protocols' reports carry.
"""

from __future__ import annotations

import json
import logging
import math
import tarfile
from collections.abc import Collection, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.diagnosis.validation import SAME_PHYSICS, same_physics_names
from engine.simulation.families import locus_of
from engine.simulation.parameters import locus_group
from engine.validation.stats import CONFIDENCE, Rate, rate

logger = logging.getLogger(__name__)

__all__ = [
    "IN_CATALOGUE_KINDS",
    "RELIABILITY_EDGES",
    "TARGET_MIN_N",
    "TARGET_TOLERANCE",
    "VERDICT_STATUSES",
    "BrierScore",
    "CaseOutcome",
    "ReliabilityBin",
    "ReliabilityTable",
    "RunOutcomes",
    "brier_score",
    "explained_by_gap",
    "protocol_of",
    "read_run",
    "reliability_markdown",
    "reliability_section",
    "reliability_table",
    "run_outcomes",
    "table_markdown",
]

#: Edges of the groups of stated confidence: [0, 0.5), [0.5, 0.7), [0.7, 0.8), [0.8, 0.9),
#: [0.9, 0.95), [0.95, 1] (the last closed). Finer where verdicts are stated (most above 0.8).
RELIABILITY_EDGES: tuple[float, ...] = (0.0, 0.5, 0.7, 0.8, 0.9, 0.95, 1.0)
#: Largest difference of observed accuracy and mean stated confidence in a group (issue 50, item 4).
TARGET_TOLERANCE: float = 0.10
#: Smallest group the target is judged on (issue 50, item 4).
TARGET_MIN_N: int = 20
#: Bootstrap resamples of the Brier score's interval (the percentile interval's ends move by
#: well under 0.001 between seeds at 2000 on a few hundred cases).
BOOTSTRAP_RESAMPLES: int = 2000
#: Seed of the bootstrap (a report is reproducible).
BOOTSTRAP_SEED: int = 50
#: The verdict statuses a diagnosis gives, in the tables' order.
VERDICT_STATUSES: tuple[str, ...] = ("explained", "unexplained", "no_gap", "weak_gap")


@dataclass(frozen=True)
class BrierScore:
    """The mean squared difference of stated confidence and outcome (0 best, 0.25 a coin at 50 %).

    Attributes
    ----------
    n : int
        Cases.
    value : float or None
        The score (None when ``n == 0``).
    low, high : float or None
        Bootstrap percentile 95 % interval (cases resampled with replacement); None when ``n < 2``.
    """

    n: int
    value: float | None
    low: float | None
    high: float | None

    def to_dict(self) -> dict[str, Any]:
        return {"n": self.n, "value": _r4(self.value), "low": _r4(self.low), "high": _r4(self.high)}

    def text(self) -> str:
        """E.g. ``0.052 [0.031, 0.076] (n = 300)``."""
        if self.value is None:
            return "n/a (0 cases)"
        if self.low is None or self.high is None:
            return f"{self.value:.3f} (n = {self.n})"
        return f"{self.value:.3f} [{self.low:.3f}, {self.high:.3f}] (n = {self.n})"


def _arrays(stated: Sequence[float], correct: Sequence[bool]) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(stated, dtype=float)
    y = np.asarray(correct, dtype=bool).astype(float)
    if p.shape != y.shape or p.ndim != 1:
        raise ValueError(f"need one outcome per stated confidence, got {p.shape} and {y.shape}")
    if not np.all(np.isfinite(p)) or np.any((p < 0.0) | (p > 1.0)):
        raise ValueError("every stated confidence must lie in [0, 1]")
    return p, y


def brier_score(
    stated: Sequence[float],
    correct: Sequence[bool],
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
    confidence: float = CONFIDENCE,
) -> BrierScore:
    """The Brier score of stated confidences against outcomes, with a bootstrap percentile interval.

    Parameters
    ----------
    stated : sequence of float
        Stated confidences in [0, 1].
    correct : sequence of bool
        Whether each verdict was right.
    resamples : int
        Bootstrap resamples.
    seed : int
        Seed of the resampling.
    confidence : float
        Level of the interval.

    Returns
    -------
    BrierScore

    Raises
    ------
    ValueError
        Lengths differ, or a stated confidence lies outside [0, 1].
    """
    p, y = _arrays(stated, correct)
    n = p.size
    if n == 0:
        return BrierScore(0, None, None, None)
    sq = (p - y) ** 2
    value = float(sq.mean())
    if n < 2 or resamples < 1:
        return BrierScore(n, value, None, None)
    rng = np.random.default_rng(seed)
    means = sq[rng.integers(0, n, size=(resamples, n))].mean(axis=1)
    tail = 100.0 * (1.0 - confidence) / 2.0
    low, high = np.percentile(means, [tail, 100.0 - tail])
    return BrierScore(n, value, float(low), float(high))


@dataclass(frozen=True)
class ReliabilityBin:
    """One group of stated confidence.

    Attributes
    ----------
    low, high : float
        The group's edges (``[low, high)``; the last group includes ``high``).
    mean_stated : float or None
        Mean stated confidence of its cases (None when empty).
    observed : Rate
        Cases right, with the Wilson 95 % interval.
    """

    low: float
    high: float
    mean_stated: float | None
    observed: Rate

    @property
    def n(self) -> int:
        return self.observed.n

    @property
    def gap(self) -> float | None:
        """Observed accuracy minus mean stated confidence (positive: under-confident)."""
        if self.mean_stated is None or self.observed.value is None:
            return None
        return self.observed.value - self.mean_stated

    def within(self, tolerance: float = TARGET_TOLERANCE) -> bool | None:
        """Whether stated and observed agree within ``tolerance`` (None when empty)."""
        g = self.gap
        return None if g is None else abs(g) <= tolerance + 1e-12

    @property
    def stated_in_interval(self) -> bool | None:
        """Whether the mean stated confidence lies inside the observed accuracy's Wilson interval."""
        o = self.observed
        if self.mean_stated is None or o.low is None or o.high is None:
            return None
        return o.low <= self.mean_stated <= o.high

    def to_dict(self) -> dict[str, Any]:
        return {
            "low": self.low,
            "high": self.high,
            "n": self.n,
            "mean_stated": _r4(self.mean_stated),
            "observed": self.observed.to_dict(),
            "gap": _r4(self.gap),
            "within_tolerance": self.within(),
            "stated_in_interval": self.stated_in_interval,
        }


@dataclass(frozen=True)
class ReliabilityTable:
    """Stated confidence against observed accuracy, per group of stated confidence.

    Attributes
    ----------
    bins : tuple of ReliabilityBin
        One per group of :data:`RELIABILITY_EDGES` (or the edges given), empty ones included.
    accuracy : Rate
        Every case: right, with the Wilson interval.
    mean_stated : float or None
        Mean stated confidence over every case.
    brier : BrierScore
        Over every case.
    """

    bins: tuple[ReliabilityBin, ...]
    accuracy: Rate
    mean_stated: float | None
    brier: BrierScore

    @property
    def n(self) -> int:
        return self.accuracy.n

    def target_met(self, min_n: int = TARGET_MIN_N, tolerance: float = TARGET_TOLERANCE) -> bool | None:
        """Whether every group of at least ``min_n`` cases agrees within ``tolerance`` (None: no such group)."""
        judged = [b.within(tolerance) for b in self.bins if b.n >= min_n]
        return None if not judged else all(bool(w) for w in judged)

    def to_dict(self) -> dict[str, Any]:
        return {
            "n": self.n,
            "mean_stated": _r4(self.mean_stated),
            "accuracy": self.accuracy.to_dict(),
            "brier": self.brier.to_dict(),
            "target_met": self.target_met(),
            "bins": [b.to_dict() for b in self.bins],
        }


def reliability_table(
    stated: Sequence[float],
    correct: Sequence[bool],
    edges: Sequence[float] = RELIABILITY_EDGES,
    resamples: int = BOOTSTRAP_RESAMPLES,
) -> ReliabilityTable:
    """Group (stated confidence, outcome) pairs by stated confidence and compare.

    Parameters
    ----------
    stated : sequence of float
        Stated confidences in [0, 1].
    correct : sequence of bool
        Whether each verdict was right.
    edges : sequence of float
        Increasing group edges from 0 to 1 (the last group includes its upper edge).
    resamples : int
        Bootstrap resamples of the Brier score's interval.

    Returns
    -------
    ReliabilityTable

    Raises
    ------
    ValueError
        Lengths differ, a stated confidence lies outside [0, 1], or the edges do not run
        increasing from 0 to 1.
    """
    e = np.asarray(edges, dtype=float)
    if e.size < 2 or e[0] != 0.0 or e[-1] != 1.0 or np.any(np.diff(e) <= 0):
        raise ValueError(f"the edges must increase from 0 to 1, got {list(edges)}")
    p, y = _arrays(stated, correct)
    # group i holds e[i] <= p < e[i+1]; p == 1 goes to the last group
    idx = np.clip(np.searchsorted(e, p, side="right") - 1, 0, e.size - 2)
    bins = []
    for i in range(e.size - 1):
        sel = idx == i
        bins.append(
            ReliabilityBin(
                low=float(e[i]),
                high=float(e[i + 1]),
                mean_stated=float(p[sel].mean()) if sel.any() else None,
                observed=rate([bool(v) for v in y[sel]]),
            )
        )
    return ReliabilityTable(
        bins=tuple(bins),
        accuracy=rate([bool(v) for v in y]),
        mean_stated=float(p.mean()) if p.size else None,
        brier=brier_score(p.tolist(), [bool(v) for v in y], resamples),
    )


@dataclass(frozen=True)
class CaseOutcome:
    """One diagnosis of a scored run: what it stated and whether it was right.

    Attributes
    ----------
    run : str
        The run's name (its directory's name, e.g. ``v2-seed229``).
    protocol : int
        1 or 2.
    case : str
        Case id.
    kind : str
        The case's kind (protocol 2: single, pair, triple, held_back, clean; protocol 1: effect,
        left_out, clean).
    status : str
        ``verdict.status``.
    confidence : float or None
        ``verdict.confidence`` as stated.
    score : float or None
        The uncalibrated score (``verdict.score``; for results written before it existed, the
        stated confidence, which was that score).
    correct : bool
        Right by the protocol's main criterion (module notes).
    true_loci : tuple of str
        Loci of the effects in the record (none for a clean record).
    locus : str or None
        ``verdict.locus``.
    locus_confidence : float or None
        ``verdict.locus_confidence`` when stated; else the locus estimate's own ``confidence``
        (results written before the verdict stated one); None without a locus estimate.
    locus_estimate : dict or None
        The result's ``locus`` (the locus estimate's report) without the missing term.
    nominal_chi2 : float or None
        The nominal calibration's chi2/n (the open-world map's feature,
        :mod:`engine.diagnosis.open_world`); None when the result holds no calibration.
    """

    run: str
    protocol: int
    case: str
    kind: str
    status: str
    confidence: float | None
    score: float | None
    correct: bool
    true_loci: tuple[str, ...]
    locus: str | None
    locus_confidence: float | None
    locus_estimate: dict[str, Any] | None
    nominal_chi2: float | None = None

    @property
    def locus_correct(self) -> bool | None:
        """Whether the part the verdict names, from a locus estimate, is where an effect of the record acts
        (None when the verdict states no estimated locus).

        The part is the locus with the loci the record cannot tell from it: the estimate's ``group``,
        or, for a result written before it existed, :func:`~engine.simulation.parameters.locus_group`
        of its locus (the group is a function of the best locus alone, so this is what the current
        code would answer with the same best locus).
        """
        if self.locus_estimate is None or self.locus is None:
            return None
        group = self.locus_estimate.get("group") or locus_group(self.locus)
        return any(g in self.true_loci for g in group)


@dataclass(frozen=True)
class RunOutcomes:
    """The outcomes of one scored run.

    Attributes
    ----------
    name : str
        The directory's name.
    protocol : int
        1 or 2.
    seed : int or None
        The run's seed (from ``report.json`` or the directory's name).
    code_version : str or None
        What the diagnoses ran on (protocol 2: the report's ``result_code_versions``; protocol 1
        results do not say, so None).
    outcomes : tuple of CaseOutcome
        One per case scored.
    excluded : tuple of (str, str)
        Cases left out, with why.
    """

    name: str
    protocol: int
    seed: int | None
    code_version: str | None
    outcomes: tuple[CaseOutcome, ...]
    excluded: tuple[tuple[str, str], ...] = ()


#: Case kinds whose records hold catalogue effects only (protocol 2's and protocol 1's).
IN_CATALOGUE_KINDS: frozenset[str] = frozenset({"single", "pair", "triple", "effect"})


def explained_by_gap(outcomes: Iterable[CaseOutcome], kinds: Collection[str] | None = None) -> list[tuple[float, bool]]:
    """``(nominal chi2/n, answered explained)`` of every outcome of ``kinds`` (all kinds when None) that holds a
    nominal chi2/n: the rows :func:`engine.diagnosis.open_world.fit_open_world` counts."""
    return [
        (o.nominal_chi2, o.status == "explained")
        for o in outcomes
        if o.nominal_chi2 is not None and (kinds is None or o.kind in kinds)
    ]


def _locus_of(name: str) -> str | None:
    locus = locus_of(name)
    if locus is None:
        logger.warning("effect %s is in neither the catalogue nor a family outside it: no locus", name)
    return locus


def _float(x: Any) -> float | None:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) else None


def _stated(result: Mapping[str, Any]) -> dict[str, Any]:
    """What a result states: status, confidence, score, locus, locus confidence and the locus estimate."""
    v = result.get("verdict") or {}
    est = result.get("locus")
    est = {k: x for k, x in est.items() if k != "term"} if isinstance(est, dict) else None
    conf = _float(v.get("confidence"))
    score = _float(v.get("score")) if "score" in v else conf
    loc_conf = _float(v.get("locus_confidence")) if "locus_confidence" in v else None
    if loc_conf is None and "locus_confidence" not in v and est is not None:
        loc_conf = _float(est.get("confidence"))
    return {
        "status": str(v.get("status", "error")),
        "effect": v.get("effect"),
        "confidence": conf,
        "score": score,
        "locus": v.get("locus"),
        "locus_confidence": loc_conf,
        "locus_estimate": est,
        "nominal_chi2": _float((result.get("calibration") or {}).get("reduced_chi2")),
    }


def _table_rows(doc: Mapping[str, Any]) -> list[dict[str, Any]]:
    table = doc.get("cases") or {"columns": [], "rows": []}
    return [dict(zip(table["columns"], row, strict=True)) for row in table["rows"]]


def _v2_outcomes(name: str, doc: Mapping[str, Any], results: Mapping[str, Mapping[str, Any]]) -> list[CaseOutcome]:
    out = []
    for row in _table_rows(doc):
        s = _stated(results[row["case"]])
        names = [t[0] for t in row["truth"]]
        loci: tuple[str, ...]
        if row["kind"] == "held_back":
            loci = (str(row["true_locus"]),)
        else:
            loci = tuple(dict.fromkeys(x for x in (_locus_of(n) for n in names) if x is not None))
        out.append(
            CaseOutcome(
                run=name,
                protocol=2,
                case=str(row["case"]),
                kind=str(row["kind"]),
                status=s["status"],
                confidence=s["confidence"],
                score=s["score"],
                correct=bool(row["correct"]),
                true_loci=loci,
                locus=s["locus"],
                locus_confidence=s["locus_confidence"],
                locus_estimate=s["locus_estimate"],
                nominal_chi2=s["nominal_chi2"],
            )
        )
    return out


def _v1_correct(row: Mapping[str, Any], status: str, named: str | None) -> bool:
    """Protocol 1's main criterion (:func:`engine.diagnosis.validation.score`)."""
    expected = row["expected"]
    if expected == "explained":
        return status == "explained" and named is not None and same_physics_names(named, str(row["effect"]))
    if expected == "unexplained":
        return status == "unexplained"
    return status == "no_gap" or (row["kind"] != "clean" and status == "weak_gap")


def _v1_outcomes(
    name: str, doc: Mapping[str, Any], results: Mapping[str, Mapping[str, Any]]
) -> tuple[list[CaseOutcome], list[tuple[str, str]]]:
    out, excluded = [], []
    for row in doc["per_case"]:
        cid = str(row["case_id"])
        s = _stated(results[cid])
        effect = row.get("effect")
        named = s["effect"]
        if (
            row["kind"] == "left_out"
            and s["status"] == "explained"
            and named is not None
            and named != effect
            and any(effect in g and named in g for g in SAME_PHYSICS)
        ):
            # only before protocol 1's revision of 2026-11-26 could the library hold a left-out
            # effect's same-physics twin: not a case of the protocol as it is
            excluded.append((cid, f"left-out {effect} answered with its same-physics twin {named} (library held it)"))
            continue
        loci = (_locus_of(str(effect)),) if effect and row["kind"] != "clean" else ()
        out.append(
            CaseOutcome(
                run=name,
                protocol=1,
                case=cid,
                kind=str(row["kind"]),
                status=s["status"],
                confidence=s["confidence"],
                score=s["score"],
                correct=_v1_correct(row, s["status"], named),
                true_loci=tuple(x for x in loci if x is not None),
                locus=s["locus"],
                locus_confidence=s["locus_confidence"],
                locus_estimate=s["locus_estimate"],
                nominal_chi2=s["nominal_chi2"],
            )
        )
    return out, excluded


def protocol_of(doc: Mapping[str, Any]) -> int:
    """The protocol of a report document (2: rows in ``cases``; 1: ``per_case``)."""
    if doc.get("protocol") == 2 and "cases" in doc:
        return 2
    if "per_case" in doc:
        return 1
    raise ValueError("not a validation report: neither protocol 2's cases table nor protocol 1's per_case rows")


def run_outcomes(
    name: str, doc: Mapping[str, Any], results: Mapping[str, Mapping[str, Any]]
) -> tuple[list[CaseOutcome], list[tuple[str, str]]]:
    """The outcomes of a scored run from its report document and its results (by case id).

    Parameters
    ----------
    name : str
        The run's name.
    doc : mapping
        ``report.json`` (either protocol).
    results : mapping of str to mapping
        Every case's result (``DiagnosisResult.to_dict()`` shape).

    Returns
    -------
    outcomes : list of CaseOutcome
    excluded : list of (case id, why)

    Raises
    ------
    KeyError
        A case of the report has no result.
    ValueError
        ``doc`` is not a report of either protocol.
    """
    if protocol_of(doc) == 2:
        return _v2_outcomes(name, doc, results), []
    return _v1_outcomes(name, doc, results)


def _results_in(run_dir: Path) -> Iterator[tuple[str, dict[str, Any]]]:
    """``(case id, result)`` of a run: from ``results.tar.xz`` read in memory, else from ``results/``."""
    tar = run_dir / "results.tar.xz"
    if tar.exists():
        with tarfile.open(tar, "r:xz") as tf:
            for member in tf:
                if not (member.isfile() and member.name.endswith(".json")):
                    continue
                f = tf.extractfile(member)
                if f is None:
                    continue
                result = json.loads(f.read())
                yield str(result.get("case_id") or Path(member.name).stem), _slim(result)
        return
    folder = run_dir / "results"
    if not folder.is_dir():
        raise FileNotFoundError(f"{run_dir} has neither results.tar.xz nor results/")
    for path in sorted(folder.glob("*.json")):
        result = json.loads(path.read_text())
        yield str(result.get("case_id") or path.stem), _slim(result)


def _slim(result: Mapping[str, Any]) -> dict[str, Any]:
    """The parts of a result the outcomes read (a result with its records is large)."""
    est = result.get("locus")
    if isinstance(est, dict):
        est = {k: v for k, v in est.items() if k != "term"}
    chi2 = (result.get("calibration") or {}).get("reduced_chi2")
    return {
        "verdict": result.get("verdict"),
        "locus": est,
        "code_version": result.get("code_version"),
        "calibration": {"reduced_chi2": chi2},
    }


def read_run(run_dir: str | Path) -> RunOutcomes:
    """Read a scored run's directory: ``report.json`` and its diagnoses.

    Parameters
    ----------
    run_dir : path
        Holds ``report.json`` and ``results.tar.xz`` (read in memory, nothing extracted) or a
        ``results/`` directory.

    Returns
    -------
    RunOutcomes

    Raises
    ------
    FileNotFoundError
        No report or no results.
    KeyError
        A case of the report has no result.
    """
    d = Path(run_dir)
    doc = json.loads((d / "report.json").read_text())
    results = dict(_results_in(d))
    outcomes, excluded = run_outcomes(d.name, doc, results)
    protocol = protocol_of(doc)
    seed = doc.get("seed")
    if seed is None and "seed" in d.name:
        tail = d.name.rsplit("seed", 1)[-1]
        seed = int(tail) if tail.isdigit() else None
    versions = doc.get("result_code_versions") or sorted(
        {str((r.get("code_version") or {}).get("describe")) for r in results.values() if r.get("code_version")}
    )
    for cid, why in excluded:
        logger.info("%s: %s left out: %s", d.name, cid, why)
    return RunOutcomes(
        name=d.name,
        protocol=protocol,
        seed=int(seed) if seed is not None else None,
        code_version=", ".join(versions) if versions else None,
        outcomes=tuple(outcomes),
        excluded=tuple(excluded),
    )


def _pairs(outcomes: Iterable[CaseOutcome], locus: bool = False) -> tuple[list[float], list[bool]]:
    """(stated, right) of the verdicts (or their loci) that state a confidence in [0, 1]."""
    stated, right = [], []
    for o in outcomes:
        ok = o.locus_correct if locus else o.correct if o.status in VERDICT_STATUSES else None
        p = o.locus_confidence if locus else o.confidence
        if ok is None or p is None:
            continue
        if not 0.0 <= p <= 1.0:
            logger.warning("%s %s: stated confidence %r is not in [0, 1]: left out of the table", o.run, o.case, p)
            continue
        stated.append(p)
        right.append(ok)
    return stated, right


def reliability_section(outcomes: Sequence[CaseOutcome], resamples: int = BOOTSTRAP_RESAMPLES) -> dict[str, Any]:
    """The reports' section: the verdicts' reliability (all and per status) and the locus's.

    Parameters
    ----------
    outcomes : sequence of CaseOutcome
        The run's cases.
    resamples : int
        Bootstrap resamples of the Brier scores' intervals.

    Returns
    -------
    dict
        JSON-ready: ``verdict`` (every verdict), ``by_status`` (one table per status with a
        verdict), ``locus`` (verdicts with an estimated locus), the target's tolerance and
        smallest group.
    """
    by_status = {}
    for status in VERDICT_STATUSES:
        stated, right = _pairs(o for o in outcomes if o.status == status)
        if stated:
            by_status[status] = reliability_table(stated, right, resamples=resamples).to_dict()
    loc_stated, loc_right = _pairs(outcomes, locus=True)
    return {
        "edges": list(RELIABILITY_EDGES),
        "tolerance": TARGET_TOLERANCE,
        "min_n": TARGET_MIN_N,
        "verdict": reliability_table(*_pairs(outcomes), resamples=resamples).to_dict(),
        "by_status": by_status,
        "locus": reliability_table(loc_stated, loc_right, resamples=resamples).to_dict() if loc_stated else None,
    }


def _pct(x: float | None) -> str:
    return "" if x is None else f"{100 * x:.1f}"


def table_markdown(title: str, t: Mapping[str, Any], min_n: int = TARGET_MIN_N) -> list[str]:
    """One reliability table (:meth:`ReliabilityTable.to_dict`) as Markdown lines under a bold ``title``."""
    acc, brier = t["accuracy"], t["brier"]
    met = t["target_met"]
    verdict = "no group large enough" if met is None else "met" if met else "**not met**"
    brier_text = "n/a" if brier["value"] is None else f"{brier['value']:.3f}"
    if brier["low"] is not None:
        brier_text += f" [{brier['low']:.3f}, {brier['high']:.3f}]"
    lines = [
        f"**{title}**: n = {t['n']}, mean stated {_pct(t['mean_stated'])} %, observed "
        f"{acc['k']}/{acc['n']} = {_pct(acc['rate'])} % [{_pct(acc['low'])}, {_pct(acc['high'])}], "
        f"Brier {brier_text}; groups of >= {min_n} within tolerance: {verdict}",
        "",
        "| stated | n | mean stated % | observed | 95 % interval | observed - stated (points) |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for b in t["bins"]:
        close = "]" if b["high"] == 1.0 else ")"
        o = b["observed"]
        if b["n"] == 0:
            lines.append(f"| [{b['low']:g}, {b['high']:g}{close} | 0 | | | | |")
            continue
        flag = "" if b["n"] < min_n or b["within_tolerance"] else " (beyond tolerance)"
        lines.append(
            f"| [{b['low']:g}, {b['high']:g}{close} | {b['n']} | {_pct(b['mean_stated'])} | {o['k']}/{o['n']} = "
            f"{_pct(o['rate'])} % | [{_pct(o['low'])}, {_pct(o['high'])}] | {100 * b['gap']:+.1f}{flag} |"
        )
    return [*lines, ""]


def reliability_markdown(section: Mapping[str, Any]) -> list[str]:
    """The reports' section as Markdown lines (see :func:`reliability_section`)."""
    min_n, tol = section["min_n"], section["tolerance"]
    lines = [
        "## Reliability of the stated confidence",
        "",
        "Verdicts grouped by stated confidence: per group the cases, their mean stated confidence and the observed "
        f"accuracy (right by the protocol's main criterion) with its Wilson 95 % interval; the Brier score with a "
        f"bootstrap 95 % interval. Target (issue 50): observed within {100 * tol:g} points of stated in every "
        f"group of >= {min_n} cases.",
        "",
        *table_markdown("Every verdict", section["verdict"], min_n),
    ]
    for status, t in section["by_status"].items():
        lines += table_markdown(f"Verdicts {status}", t, min_n)
    if section.get("locus") is not None:
        lines += table_markdown(
            "Locus of unexplained and weak-gap verdicts (right: an effect of the record acts there)",
            section["locus"],
            min_n,
        )
    return lines


def _r4(x: float | None) -> float | None:
    return None if x is None else round(float(x), 4)
