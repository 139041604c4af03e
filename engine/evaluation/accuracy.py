"""Held-out accuracy of the identifiers.

Three evaluations, none of which ever trains on a record it scores:

(a) ``leave-one-J1-out``: within each c group, for each of the seven J1 values,
    train on the six widths x the other six J1 values (36 records) and identify
    the six records of the held-out J1; 4 groups x 7 folds x 6 = 168 scored
    records per channel and identifier.
(b) ``random``: cases with J1 ~ U[0.75, 0.93] kg m^2, c ~ U[0.8, 1.5] pu and a
    width drawn from the six, identified with the patterns of the nearest c
    group trained on the grid; the random J1 and c are never grid values.
(c) ``random + 40 dB`` / ``random + 30 dB``: the same records with white noise
    (:func:`engine.simulation.add_white_noise`, SNR against each channel's variance).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.constants import C_GROUPS, CHANNELS
from engine.distributed import dask_client, map_cases
from engine.identification.training import make_identifier
from engine.simulation import Case, SimulationResult, add_white_noise, simulate_batch
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription

logger = logging.getLogger(__name__)


NOISE_LEVELS_DB: tuple[float, ...] = (40.0, 30.0)


@dataclass(frozen=True)
class AccuracyRow:
    identifier: str
    channel: str
    split: str
    n: int
    correct: int
    mean_epochs: float

    @property
    def accuracy(self) -> float:
        return self.correct / self.n if self.n else float("nan")


def _fit_predict(
    kind: str, channel: str, params: Mapping[str, Any], X_tr, y_tr, g_tr, X_te
) -> tuple[np.ndarray, np.ndarray]:
    est = make_identifier(kind, channel, **params).fit(X_tr, y_tr, groups=g_tr)
    res = est.identify_batch(X_te)
    return np.array([r.width for r in res]), np.array([r.epochs for r in res])


def _lojo_task(kind: str, channel: str, params: Mapping[str, Any], X, y, g) -> tuple[int, int, float]:
    correct, n, epochs = 0, 0, []
    for held in np.unique(g):
        te = np.isclose(g, held)
        pred, ep = _fit_predict(kind, channel, params, X[~te], y[~te], g[~te], X[te])
        correct += int(np.isclose(pred, y[te]).sum())
        n += int(te.sum())
        epochs.extend(ep.tolist())
    return correct, n, float(np.mean(epochs))


SPLITS_RANDOM: tuple[str, ...] = ("random", *(f"random + {db:g} dB" for db in NOISE_LEVELS_DB))


def noisy_versions(
    random: SimulationResult, channels: Sequence[str], noise_seed: int = 7
) -> dict[str, list[np.ndarray]]:
    """Per channel: the clean records, then one noisy copy per level of ``NOISE_LEVELS_DB`` (seeded).

    Every evaluation of the random cases draws its noise here, so all identifiers
    are scored on the very same noisy records.
    """
    rng = np.random.default_rng(noise_seed)
    return {
        ch: [random.channel(ch)] + [add_white_noise(random.channel(ch), db, rng) for db in NOISE_LEVELS_DB]
        for ch in channels
    }


def random_cases(n: int = 240, seed: int = 20261121, drive: DriveDescription | None = None) -> SimulationResult:
    """Held-out cases (b): J1 and c uniform over ``OPERATING_RANGE``, width uniform over the six of ``K_GRID``.

    With ``drive``: on its nominal plant, J1 and c uniform over its operating range
    (:func:`engine.validation.protocol.operating_range`, MODEL.md's scaled by the drive's nominal values) and the
    width among its six (:meth:`DriveDescription.k_grid`), within its ``t_event_max``. Without it, on MODEL.md's
    reference drive, whose range, widths and plant are ``OPERATING_RANGE``, ``K_GRID`` and ``PlantParameters``'
    defaults: the same draws and records.
    """
    from engine.validation.protocol import operating_range

    drive = drive or REFERENCE_DRIVE
    rng = np.random.default_rng(seed)
    box = operating_range(drive)
    K = rng.choice(np.asarray(drive.k_grid()), n)
    J1 = rng.uniform(*box["J1"][:2], n)
    c = rng.uniform(*box["c"][:2], n)
    plants = [drive.plant(K=float(k), J1=float(j), c=float(cc)) for k, j, cc in zip(K, J1, c, strict=True)]
    return simulate_batch([Case(p) for p in plants], solver=drive.solver())


def nearest_group_index(c: np.ndarray, groups: Sequence[float] = C_GROUPS) -> np.ndarray:
    """Index into ``groups`` of the c group nearest to each ``c`` [pu]."""
    return np.argmin(np.abs(np.asarray(c)[:, None] - np.asarray(groups)[None, :]), axis=1)


def _random_task(
    kind: str,
    channel: str,
    params: Mapping[str, Any],
    grids_X: Sequence[np.ndarray],
    grid_y: np.ndarray,
    grid_g: np.ndarray,
    X_sets: Sequence[np.ndarray],
    groups_idx: np.ndarray,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Fit one identifier per c group, then score every noise version of the random records.

    Returns, per entry of ``X_sets``, the identified widths [m] and the epochs, one per record.
    """
    ests = [make_identifier(kind, channel, **params).fit(X_k, grid_y, groups=grid_g) for X_k in grids_X]
    out = []
    for X in X_sets:
        widths = np.empty(X.shape[0])
        epochs = np.empty(X.shape[0])
        for k, est in enumerate(ests):
            sel = groups_idx == k
            if sel.any():
                res = est.identify_batch(X[sel])
                widths[sel] = [r.width for r in res]
                epochs[sel] = [r.epochs for r in res]
        out.append((widths, epochs))
    return out


def evaluate(
    grids: Mapping[float, SimulationResult],
    random: SimulationResult,
    kinds: Mapping[str, Mapping[str, Any]],
    channels: Sequence[str] = CHANNELS,
    noise_seed: int = 7,
    n_jobs: int | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    scheduler: str | None = None,
) -> list[AccuracyRow]:
    """Run evaluations (a), (b) and (c) for every identifier kind and channel.

    Parameters
    ----------
    grids : mapping of c group to SimulationResult
        The paper grid of each c group (six widths x seven J1, width-major).
    random : SimulationResult
        Held-out random cases, see :func:`random_cases`.
    kinds : mapping of kind to hyper-parameters
        Identifier kinds to evaluate, e.g. ``{"template": {}, "paper": {"max_epochs": 500}}``.
    n_jobs : int, optional
        Single-threaded workers of the local Dask cluster (default: one per core).
    progress : callable, optional
        Called with (tasks done, tasks, task) as tasks finish.
    scheduler : str, optional
        An existing Dask scheduler (default ``$BACKLASH_DASK_SCHEDULER``, else a local cluster).
    """
    groups = sorted(grids)
    y = np.array([c.plant.K for c in grids[groups[0]].cases])
    g = np.array([c.plant.J1 for c in grids[groups[0]].cases])
    truth = np.array([c.plant.K for c in random.cases])
    gidx = nearest_group_index(np.array([c.plant.c for c in random.cases]), groups)
    splits = list(SPLITS_RANDOM)
    X_random = noisy_versions(random, channels, noise_seed)
    lojo_inputs: dict[str, tuple[Any, ...]] = {}
    random_inputs: dict[str, tuple[Any, ...]] = {}
    for kind, params in kinds.items():
        for ch in channels:
            for cg in groups:
                lojo_inputs[f"lojo/{kind}/{ch}/{cg}"] = (kind, ch, dict(params), grids[cg].channel(ch), y, g)
            grids_X = [grids[cg].channel(ch) for cg in groups]
            random_inputs[f"random/{kind}/{ch}"] = (kind, ch, dict(params), grids_X, y, g, X_random[ch], gidx)
    n_tasks = len(lojo_inputs) + len(random_inputs)
    results: dict[str, Any] = {}
    with dask_client(scheduler, n_jobs) as client:
        for key, res in map_cases(client, _lojo_task, lojo_inputs, "accuracy", 0, n_tasks):
            results[key] = res
            if progress:
                progress(len(results), n_tasks, key)
        for key, widths_epochs in map_cases(client, _random_task, random_inputs, "accuracy", len(lojo_inputs), n_tasks):
            results[key] = widths_epochs
            if progress:
                progress(len(results), n_tasks, key)
    lojo: dict[tuple[str, str], list[tuple[int, int, float]]] = {}
    rows: list[AccuracyRow] = []
    for key in lojo_inputs:  # submission order: the report does not depend on which task finished first
        _, kind, ch, _ = key.split("/")
        lojo.setdefault((kind, ch), []).append(results[key])
    for key in random_inputs:
        _, kind, ch = key.split("/")
        for split, (widths, epochs) in zip(splits, results[key], strict=True):
            n_right = int(np.isclose(widths, truth).sum())
            rows.append(AccuracyRow(kind, ch, split, len(truth), n_right, float(epochs.mean())))
    for (kind, ch), parts in lojo.items():
        n = sum(p[1] for p in parts)
        rows.append(
            AccuracyRow(
                kind,
                ch,
                "leave-one-J1-out",
                n,
                sum(p[0] for p in parts),
                float(np.average([p[2] for p in parts], weights=[p[1] for p in parts])),
            )
        )
    order = {s: i for i, s in enumerate(["leave-one-J1-out", *splits])}
    rows.sort(key=lambda r: (r.identifier, CHANNELS.index(r.channel), order[r.split]))
    return rows


def accuracy_markdown(rows: Sequence[AccuracyRow]) -> str:
    """Accuracy table: one row per identifier and channel, one column per split."""
    splits = list(dict.fromkeys(r.split for r in rows))
    n_by_split = {r.split: r.n for r in rows}
    head = "| identifier | channel | " + " | ".join(f"{s} (n={n_by_split[s]})" for s in splits) + " |\n"
    head += "|---|---|" + "---|" * len(splits) + "\n"
    body = []
    for kind, ch in dict.fromkeys((r.identifier, r.channel) for r in rows):
        cells = {r.split: r for r in rows if r.identifier == kind and r.channel == ch}
        body.append(f"| {kind} | {ch} | " + " | ".join(f"{100 * cells[s].accuracy:.1f} %" for s in splits) + " |")
    return head + "\n".join(body) + "\n"
