"""The calibrated K as a continuous width estimate, scored like the other identifiers.

For each held-out random record (the same records and the same noise draws as
:mod:`engine.evaluation.accuracy`, via :func:`noisy_versions`), one channel at
a time, the gap diagnosis's calibration fits K and J1 with c and c1 known, as
they are to the other identifiers (which pick their patterns by c). The
estimate counts as correct when the paper's width nearest to K_hat is the true
width; we also report the K error and how often the true K lies within two
reported standard deviations.

Each estimate is a calibration (hundreds of simulations), so this runs as a
benchmark (``bench/bench_calibrated_width.py``) on the first ``n_cases`` of
the random records, not in the main job.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from engine.constants import CHANNELS
from engine.distributed import dask_client, map_cases
from engine.evaluation.accuracy import SPLITS_RANDOM, noisy_versions, random_cases
from engine.identification.width import estimate_width, nearest_grid_width
from engine.records import Record

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class ContinuousRow:
    channel: str
    split: str
    n: int
    correct: int
    median_abs_error_mm: float
    within_2sigma: float
    median_seconds: float

    @property
    def accuracy(self) -> float:
        return self.correct / self.n


def calibrated_width(x: np.ndarray, channel: str, c: float, c1: float = 0.2) -> tuple[float, float, float]:
    """K_hat [m], its standard deviation [m] and the time [s] for one single-channel record."""
    t0 = time.perf_counter()
    est = estimate_width(Record(channels={channel: x}, conditions={"c": c, "c1": c1}))
    return est.K, est.sigma_K, time.perf_counter() - t0


def _task(channel: str, X: np.ndarray, c: np.ndarray) -> list[tuple[float, float, float]]:
    return [calibrated_width(x, channel, float(cc)) for x, cc in zip(X, c, strict=True)]


def evaluate_continuous(
    n_cases: int = 20,
    channels: Sequence[str] = CHANNELS,
    n_jobs: int | None = None,
    n_random: int = 240,
    scheduler: str | None = None,
) -> list[ContinuousRow]:
    """Score the calibrated width on the first ``n_cases`` random held-out records, per channel and noise level.

    The fits run on Dask (:mod:`engine.distributed`): ``n_jobs`` local single-threaded workers (default
    one per core), or the cluster of ``scheduler`` / ``$BACKLASH_DASK_SCHEDULER``.
    """
    random = random_cases(n_random)
    truth = np.array([c.plant.K for c in random.cases])[:n_cases]
    c = np.array([c.plant.c for c in random.cases])[:n_cases]
    versions = noisy_versions(random, channels)
    rows = []
    inputs = {
        f"{ch}/{split}": (ch, versions[ch][s][:n_cases], c) for ch in channels for s, split in enumerate(SPLITS_RANDOM)
    }
    with dask_client(scheduler, n_jobs) as client:
        results = dict(map_cases(client, _task, inputs, "continuous"))
    for key in inputs:  # submission order
        ch, split = key.split("/")
        est = np.array(results[key])
        K_hat, sd, sec = est[:, 0], est[:, 1], est[:, 2]
        correct = int(sum(np.isclose(nearest_grid_width(k), t) for k, t in zip(K_hat, truth, strict=True)))
        rows.append(
            ContinuousRow(
                ch,
                split,
                n_cases,
                correct,
                float(np.median(np.abs(K_hat - truth)) * 1e3),
                float(np.mean(np.abs(K_hat - truth) <= 2 * sd)),
                float(np.median(sec)),
            )
        )
        logger.info("calibrated width %s %s: %d/%d", ch, split, correct, n_cases)
    return rows


def continuous_markdown(rows: Sequence[ContinuousRow]) -> str:
    head = (
        "| channel | split | n | accuracy (nearest width) | median abs K error [mm] | true K within 2 sd | "
        "median time [s] |\n|---|---|---|---|---|---|---|\n"
    )
    return (
        head
        + "\n".join(
            f"| {r.channel} | {r.split} | {r.n} | {100 * r.accuracy:.1f} % | {r.median_abs_error_mm:.3f} | "
            f"{100 * r.within_2sigma:.0f} % | {r.median_seconds:.1f} |"
            for r in rows
        )
        + "\n"
    )
