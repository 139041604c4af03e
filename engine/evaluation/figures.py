"""PNG figures of the main job (matplotlib, Agg backend)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from engine.constants import CHANNEL_UNITS, CHANNELS, EVENT_INDEX, K_GRID, N_SAMPLES, SAMPLE_INTERVAL
from engine.evaluation.accuracy import AccuracyRow
from engine.evaluation.paper_tables import TableRow
from engine.simulation import SimulationResult

_T_MS = (np.arange(N_SAMPLES) - EVENT_INDEX) * SAMPLE_INTERVAL * 1e3


def plot_channels_by_width(grid: SimulationResult, J1: float, path: Path) -> Path:
    """The five channels for the grid's widths (the six of K_GRID, or a drive's) at the grid's J1 nearest ``J1``
    [kg m^2] (time relative to the event)."""
    fig, axes = plt.subplots(len(CHANNELS), 1, figsize=(10, 12), sharex=True)
    widths = sorted({case.plant.K for case in grid.cases})
    J1 = min({case.plant.J1 for case in grid.cases}, key=lambda j: abs(j - J1))
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(widths)))
    for i, case in enumerate(grid.cases):
        if case.plant.J1 != J1:
            continue
        k = widths.index(case.plant.K)
        for ax, ch in zip(axes, CHANNELS, strict=True):
            ax.plot(_T_MS, grid.channel(ch)[i], color=colors[k], lw=0.8, label=f"K = {case.plant.K * 1e3:g} mm")
    for ax, ch in zip(axes, CHANNELS, strict=True):
        ax.set_ylabel(f"{ch} [{CHANNEL_UNITS[ch]}]")
        ax.axvline(0.0, color="k", lw=0.5, ls=":")
        ax.grid(alpha=0.3)
    axes[0].legend(ncol=3, fontsize=8)
    axes[0].set_title(f"Backlash test records, J1 = {J1:.4g} kg m^2, c = {grid.cases[0].plant.c:.4g} (event at t = 0)")
    axes[-1].set_xlabel("time from the event [ms]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_table_d_vectors(rows: Sequence[TableRow], path: Path) -> Path:
    """Our D vectors beside the paper's for the table cases (each scaled to its maximum)."""
    n = len(rows)
    cols = 4
    fig, axes = plt.subplots(int(np.ceil(n / cols)), cols, figsize=(14, 2.6 * np.ceil(n / cols)), squeeze=False)
    x = np.arange(1, len(K_GRID) + 1)
    for ax, r in zip(axes.ravel(), rows, strict=False):  # the grid may have spare axes
        paper = np.asarray(r.case.D) / max(r.case.D)
        ours = r.D / r.D.max() if r.D.max() > 0 else r.D
        ax.bar(x - 0.2, paper, 0.4, label="paper", color="0.6")
        ax.bar(x + 0.2, ours, 0.4, label="ours", color="C0" if r.correct else "C3")
        ax.axvline(K_GRID.index(r.case.K) + 1, color="k", ls=":", lw=0.8)
        ax.set_title(f"T{r.case.table} {r.case.channel} K={r.case.K} l={r.case.l} d1={r.case.delta1}", fontsize=8)
        ax.set_xticks(x)
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("D vectors of the paper's table cases (scaled to max; dotted line: true width; red: we misidentify)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_accuracy_vs_noise(rows: Sequence[AccuracyRow], path: Path) -> Path:
    """Accuracy on the random held-out cases versus noise, per identifier and channel."""
    splits = [s for s in dict.fromkeys(r.split for r in rows) if s.startswith("random")]
    kinds = list(dict.fromkeys(r.identifier for r in rows))
    fig, axes = plt.subplots(1, len(kinds), figsize=(6 * len(kinds), 4), sharey=True, squeeze=False)
    for ax, kind in zip(axes[0], kinds, strict=True):
        for ch in CHANNELS:
            acc = [
                next(
                    (100 * r.accuracy for r in rows if r.identifier == kind and r.channel == ch and r.split == s),
                    np.nan,
                )
                for s in splits
            ]
            ax.plot(range(len(splits)), acc, marker="o", label=ch)
        ax.set_xticks(range(len(splits)))
        ax.set_xticklabels(["clean" if s == "random" else s.replace("random + ", "") for s in splits])
        ax.set_title(f"{kind} identifier")
        ax.set_ylim(0, 102)
        ax.axhline(100 / 6, color="k", ls=":", lw=0.8)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("accuracy on held-out random J1, c [%] (dotted: chance)")
    axes[0][0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
