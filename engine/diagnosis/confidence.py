"""The verdict's confidence as a probability: a recalibration of the decision's score.

The decision (:func:`engine.diagnosis.decision.decide`) scores each verdict from 0 to 1: a
logistic of how far the deciding statistic lies from its threshold, times the BIC weight for an
``explained`` verdict (:mod:`engine.diagnosis.diagnose`, *Confidence*). That score is not a
probability: an ``unexplained`` verdict scores 1.0 however often such verdicts are wrong. This
module maps it to one: the probability that a verdict of that status and score is right, read off
blind validation runs (:mod:`engine.validation.reliability` says what "right" is per protocol).

The map (:data:`MAP_FILE`, committed with its provenance) is fitted per verdict status on the
score alone, by isotonic regression (:func:`fit_isotonic`: the pool-adjacent-violators fit of the
observed accuracy as a non-decreasing function of the score, blocks of fewer than
:data:`MIN_BLOCK` cases merged with a neighbour, each block's accuracy shrunk by a Jeffreys prior
so that no block states 0 or 1). Between blocks the map is linear; beyond the fitted scores it is
flat. It was fitted only on development runs and scored on held-out ones
(``docs/validation/confidence/``); a status the map does not hold keeps its score.

The locus of an ``unexplained`` or ``weak_gap`` verdict gets its own probability
(:func:`locus_confidence`, the verdict's ``locus_confidence``): the same kind of map on how well
the best locus's input fits the record (:func:`locus_feature`: ``-log10`` of the chi2 per
residual it leaves), fitted on whether the part the answer names (the best locus, or the group of
loci the record cannot tell apart) holds an effect of the record, on the blind runs of the families
kept for scoring whose runs are spent (the map's provenance names them): an unexplained gap in the
field is physics the locus method was not developed on, and on the family it was developed on it is
right more often than on any other. Each of those families left out in turn, this map was within 10
points of what it achieved in every group of 20 answers or more; a map per part the answer names,
more telling in-sample, was not (``lab/validation/locus-groups/``).

An ``explained`` verdict's probability is further multiplied by one minus the chance that its named
effect stands in for physics outside the catalogue (:mod:`engine.diagnosis.open_world`: the map's
``open_world`` part, per band of the nominal model's chi2/n, fitted on records of the families kept
for scoring whose blind runs are spent). The verdict map above was fitted on runs whose records
outside the catalogue were of the family the diagnosis was developed on, which it almost never
explains; a gap in the field owes nothing to that family.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from engine.diagnosis.open_world import OpenWorldMap

logger = logging.getLogger(__name__)

__all__ = [
    "LOCUS_FEATURE",
    "MAP_FILE",
    "MIN_BLOCK",
    "PRIOR",
    "SCORE_FEATURE",
    "ConfidenceMap",
    "IsotonicMap",
    "calibrated_confidence",
    "fit_isotonic",
    "load_map",
    "locus_confidence",
    "locus_feature",
    "stand_in_probability",
]

#: The committed map, relative to this package (``engine.diagnosis``).
MAP_FILE: str = "data/confidence_map.json"
#: Version of the map file's layout.
MAP_SCHEMA: int = 1
#: Fewest development cases behind one value of a map: the smallest group the calibration target
#: is judged on (issue 50, item 4: groups of >= 20 cases).
MIN_BLOCK: int = 20
#: Jeffreys prior Beta(1/2, 1/2) on a block's accuracy: a block of n cases all right states
#: (n + 1/2) / (n + 1), never 1 (nor 0 for none right).
PRIOR: float = 0.5
#: Smallest chi2 per residual the locus feature takes (its log is taken; a fit far below the noise
#: is as good as one at it).
LOCUS_CHI2_FLOOR: float = 1e-3
#: The verdict maps' feature: the decision's score.
SCORE_FEATURE: str = "score"
#: The locus map's feature (:func:`locus_feature`).
LOCUS_FEATURE: str = "-log10 chi2/n left by the best locus's input"


@dataclass(frozen=True)
class IsotonicMap:
    """A non-decreasing map from a feature to a probability, from an isotonic fit.

    Attributes
    ----------
    feature : str
        What the input is.
    blocks : tuple of dict
        The fit's blocks in increasing feature order: ``{"x_low", "x_high", "n", "k", "value"}``
        (the feature's range, cases, cases right, the probability stated).
    """

    feature: str
    blocks: tuple[dict[str, float], ...]

    def __post_init__(self) -> None:
        if not self.blocks:
            raise ValueError("an isotonic map needs at least one block")
        values = [b["value"] for b in self.blocks]
        lows = [b["x_low"] for b in self.blocks]
        highs = [b["x_high"] for b in self.blocks]
        if any(not 0.0 <= v <= 1.0 for v in values) or any(np.diff(values) < 0):
            raise ValueError(f"the blocks' values must be non-decreasing in [0, 1], got {values}")
        if any(lo > hi for lo, hi in zip(lows, highs, strict=True)) or any(
            h >= lo for h, lo in zip(highs[:-1], lows[1:], strict=True)
        ):
            raise ValueError("the blocks' ranges must be ordered and disjoint")

    @property
    def n(self) -> int:
        """Cases the map was fitted on."""
        return int(sum(b["n"] for b in self.blocks))

    def _knots(self) -> tuple[np.ndarray, np.ndarray]:
        xs: list[float] = []
        ys: list[float] = []
        for b in self.blocks:
            for x in (b["x_low"], b["x_high"]):
                if not xs or x > xs[-1]:
                    xs.append(float(x))
                    ys.append(float(b["value"]))
        return np.asarray(xs), np.asarray(ys)

    def __call__(self, x: float) -> float:
        """The probability at ``x``: the block's value inside a block, linear between, flat beyond."""
        if not math.isfinite(x):
            raise ValueError(f"the feature must be finite, got {x}")
        xs, ys = self._knots()
        return float(np.interp(x, xs, ys))

    def to_dict(self) -> dict[str, Any]:
        blocks = [{k: int(v) if k in ("n", "k") else v for k, v in b.items()} for b in self.blocks]
        return {"feature": self.feature, "n": self.n, "blocks": blocks}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> IsotonicMap:
        return cls(str(d["feature"]), tuple({k: float(v) for k, v in b.items()} for b in d["blocks"]))


def _merge(a: list[float], b: list[float]) -> list[float]:
    """Two adjacent blocks ``[x_low, x_high, weight, weighted sum, cases, right]`` as one."""
    return [a[0], b[1], a[2] + b[2], a[3] + b[3], a[4] + b[4], a[5] + b[5]]


def _pav(blocks: list[list[float]]) -> list[list[float]]:
    """Pool adjacent violators over ``[x_low, x_high, weight, weighted sum, cases, right]`` blocks (in
    x order) until ``weighted sum / weight`` is non-decreasing."""
    out: list[list[float]] = []
    for b in blocks:
        out.append(list(b))
        while len(out) > 1 and out[-2][3] / out[-2][2] > out[-1][3] / out[-1][2]:
            last = out.pop()
            out[-1] = _merge(out[-1], last)
    return out


def fit_isotonic(
    x: Sequence[float],
    correct: Sequence[bool],
    feature: str = SCORE_FEATURE,
    min_block: int = MIN_BLOCK,
    prior: float = PRIOR,
) -> IsotonicMap:
    """Isotonic fit of the probability of being right as a non-decreasing function of ``x``.

    Parameters
    ----------
    x : sequence of float
        The feature of each case (finite).
    correct : sequence of bool
        Whether each case was right.
    feature : str
        What ``x`` is (kept in the map).
    min_block : int
        Blocks with fewer cases are merged with the neighbour whose accuracy is closer (merging
        neighbours keeps the fit non-decreasing). Equal ``x`` are never split.
    prior : float
        Beta(prior, prior) on each block's accuracy: ``(k + prior) / (n + 2 prior)``; the blocks
        are pooled again where that shrinkage reverses their order.

    Returns
    -------
    IsotonicMap

    Raises
    ------
    ValueError
        No case, lengths differ, or a feature is not finite.
    """
    xv = np.asarray(x, dtype=float)
    yv = np.asarray(correct, dtype=bool).astype(float)
    if xv.shape != yv.shape or xv.ndim != 1 or xv.size == 0:
        raise ValueError(f"need one outcome per feature and at least one case, got {xv.shape} and {yv.shape}")
    if not np.all(np.isfinite(xv)):
        raise ValueError("every feature must be finite")
    ux, inverse = np.unique(xv, return_inverse=True)
    counts = np.bincount(inverse).astype(float)
    rights = np.bincount(inverse, weights=yv)
    blocks = _pav([[float(u), float(u), c, r, c, r] for u, c, r in zip(ux, counts, rights, strict=True)])
    while len(blocks) > 1 and min(b[4] for b in blocks) < min_block:
        i = min(range(len(blocks)), key=lambda j: blocks[j][4])
        if i == 0:
            j = 1
        elif i == len(blocks) - 1:
            j = i - 1
        else:
            acc = blocks[i][5] / blocks[i][4]
            left, right = blocks[i - 1][5] / blocks[i - 1][4], blocks[i + 1][5] / blocks[i + 1][4]
            j = i - 1 if abs(acc - left) <= abs(right - acc) else i + 1
        a, b = sorted((i, j))
        blocks[a : b + 1] = [_merge(blocks[a], blocks[b])]
    # shrink each block's accuracy, then pool again where that reversed the order (weights n + 2 prior)
    shrunk = _pav([[b[0], b[1], b[4] + 2 * prior, b[5] + prior, b[4], b[5]] for b in blocks])
    out = tuple({"x_low": b[0], "x_high": b[1], "n": b[4], "k": b[5], "value": b[3] / b[2]} for b in shrunk)
    return IsotonicMap(feature, out)


@dataclass(frozen=True)
class ConfidenceMap:
    """The committed recalibration: one map per verdict status, one for the locus, and where they come from.

    Attributes
    ----------
    verdict : dict of str to IsotonicMap
        Per status, the probability that the verdict is right given its score.
    locus : IsotonicMap or None
        The probability that an estimated locus is right given :func:`locus_feature`.
    provenance : dict
        Which runs (protocol, seed, code), when, how, and by which command it was fitted.
    open_world : OpenWorldMap or None
        How often an ``explained`` verdict is a stand-in, per band of the nominal chi2/n (None: not
        applied).
    """

    verdict: dict[str, IsotonicMap]
    locus: IsotonicMap | None
    provenance: dict[str, Any]
    open_world: OpenWorldMap | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": MAP_SCHEMA,
            "provenance": self.provenance,
            "verdict": {s: m.to_dict() for s, m in self.verdict.items()},
            "locus": None if self.locus is None else self.locus.to_dict(),
            "open_world": None if self.open_world is None else self.open_world.to_dict(),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ConfidenceMap:
        if d.get("schema") != MAP_SCHEMA:
            raise ValueError(f"confidence map of schema {d.get('schema')!r}, this code reads {MAP_SCHEMA}")
        locus, world = d.get("locus"), d.get("open_world")
        return cls(
            verdict={str(s): IsotonicMap.from_dict(m) for s, m in d["verdict"].items()},
            locus=None if locus is None else IsotonicMap.from_dict(locus),
            provenance=dict(d.get("provenance") or {}),
            open_world=None if world is None else OpenWorldMap.from_dict(world),
        )


@lru_cache(maxsize=1)
def _packaged() -> ConfidenceMap:
    text = resources.files("engine.diagnosis").joinpath(MAP_FILE).read_text(encoding="utf-8")
    return ConfidenceMap.from_dict(json.loads(text))


def load_map(path: str | Path | None = None) -> ConfidenceMap:
    """The confidence map: the committed one (:data:`MAP_FILE`), or the one in ``path``."""
    if path is None:
        return _packaged()
    return ConfidenceMap.from_dict(json.loads(Path(path).read_text(encoding="utf-8")))


def calibrated_confidence(
    status: str, score: float, cmap: ConfidenceMap | None = None, nominal_chi2: float | None = None
) -> float:
    """The probability that a verdict of ``status`` with the decision's ``score`` is right.

    Parameters
    ----------
    status : str
        The verdict's status.
    score : float
        The decision's score (0..1).
    cmap : ConfidenceMap, optional
        Default: the committed map.
    nominal_chi2 : float, optional
        The nominal calibration's chi2/n: for an ``explained`` verdict, the probability is multiplied
        by one minus :func:`stand_in_probability` (not applied when None).

    Returns
    -------
    float
        In [0, 1]; the score itself when the map holds no such status or the score is not finite.
    """
    cmap = cmap or load_map()
    m = cmap.verdict.get(status)
    if m is None or not math.isfinite(score):
        logger.debug("no confidence map for %s (score %s): the score is stated", status, score)
        return float(score)
    p = m(float(score))
    if status == "explained" and nominal_chi2 is not None:
        p *= 1.0 - (stand_in_probability(nominal_chi2, cmap) or 0.0)
    return p


def stand_in_probability(nominal_chi2: float, cmap: ConfidenceMap | None = None) -> float | None:
    """The probability that an ``explained`` verdict at this nominal chi2/n is a catalogue stand-in.

    Parameters
    ----------
    nominal_chi2 : float
        The nominal calibration's chi2/n.
    cmap : ConfidenceMap, optional
        Default: the committed map.

    Returns
    -------
    float or None
        :meth:`engine.diagnosis.open_world.OpenWorldMap.stand_in`; None when the map has no open-world
        part or the chi2/n is not finite.
    """
    world = (cmap or load_map()).open_world
    if world is None or not math.isfinite(nominal_chi2):
        return None
    return world.stand_in(float(nominal_chi2))


def locus_feature(report: Mapping[str, Any] | None) -> float | None:
    """How well the best locus's input fits: ``-log10`` of the chi2 per residual it leaves.

    Parameters
    ----------
    report : mapping or None
        A locus estimate's report (:meth:`engine.diagnosis.locus.LocusReport.to_dict`).

    Returns
    -------
    float or None
        None without a report, a best locus, its score or a finite fit.
    """
    if not report or report.get("locus") is None:
        return None
    score = (report.get("scores") or {}).get(report.get("input") or report["locus"]) or {}
    rss, n = score.get("rss"), report.get("n_data")
    if not isinstance(rss, (int, float)) or not isinstance(n, (int, float)) or n <= 0 or not math.isfinite(rss):
        return None
    return -math.log10(max(float(rss) / float(n), LOCUS_CHI2_FLOOR))


def locus_confidence(report: Mapping[str, Any] | None, cmap: ConfidenceMap | None = None) -> float | None:
    """The probability that the part the locus estimate names (its best locus, with the loci the record
    cannot tell from it) is where the missing physics acts.

    Call it where the locus is attached to the verdict (``verdict.locus_confidence``).

    Parameters
    ----------
    report : mapping or None
        The locus estimate's report (:meth:`engine.diagnosis.locus.LocusReport.to_dict`).
    cmap : ConfidenceMap, optional
        Default: the committed map.

    Returns
    -------
    float or None
        None when the report names no locus (or its fit is not finite) or the map has no locus part.
    """
    x = locus_feature(report)
    m = (cmap or load_map()).locus
    if x is None or m is None:
        return None
    return m(x)
