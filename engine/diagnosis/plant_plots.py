"""PNG plots of a plant-gap report: measured against simulated, before and after, around the record's events.

matplotlib's object API (``Figure``), no pyplot: safe in a server without a display.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from engine.diagnosis.plant_gap import PlantGapReport
from engine.plants.base import Plant

__all__ = ["plot_plant_overlay"]

#: Span shown around an event [s]: before, after.
SPAN: tuple[float, float] = (-0.05, 0.25)


def plot_plant_overlay(
    plant: Plant,
    record: Any,
    report: PlantGapReport,
    path: str | Path,
    channel: str = "acceleration",
    n_panels: int = 3,
) -> Path:
    """Measured ``channel`` against the calibrated model (before) and the model with the named effects (after).

    Panels are centred on the record's events with the largest residual before (or on the largest
    residual windows of the localisation when the record has no events), plus one panel of the
    whole record.

    Parameters
    ----------
    plant, record
        The plant and the record the report is of.
    report : PlantGapReport
        The diagnosis.
    path : path
        PNG file to write.
    channel : str
        The channel plotted (one of the plant's).
    n_panels : int
        Event panels.
    """
    names = [c.name for c in plant.channels]
    if channel not in names:
        raise ValueError(f"unknown channel {channel!r}; the plant's channels are {names}")
    unit = next(c.unit for c in plant.channels if c.name == channel)
    t = np.asarray(plant.time(record), dtype=float)
    y = plant.measured(record)[channel]
    before = plant.simulate(record, report.calibration.values)[channel]
    after_values = report.named.fit.values if report.named else report.calibration.values
    after = plant.simulate(record, after_values)[channel]
    centres = np.asarray(plant.events(record), dtype=float)
    if centres.size == 0:
        centres = np.array([0.5 * (c.window[0] + c.window[1]) for c in report.where])
    res2 = (before - y) ** 2

    def energy(tc: float) -> float:
        m = (t >= tc + SPAN[0]) & (t < tc + SPAN[1])
        return float(res2[m].sum())

    picked: list[float] = []
    for tc in sorted(centres, key=energy, reverse=True):
        if all(abs(tc - p) > SPAN[1] - SPAN[0] for p in picked):
            picked.append(float(tc))
        if len(picked) == n_panels:
            break
    label_after = "+ " + ", ".join(report.named.effects) if report.named else "(no effect named)"
    from matplotlib.figure import Figure  # here: matplotlib adds about 0.6 s to every service start

    fig = Figure(figsize=(10, 2.6 * (len(picked) + 1)), layout="constrained")
    axes = fig.subplots(len(picked) + 1, 1, squeeze=False)[:, 0]
    whole = axes[0]
    whole.plot(t, y, lw=0.6, color="k", label="measured")
    whole.plot(t, before, lw=0.6, color="tab:red", alpha=0.7, label="calibrated model")
    for p in picked:
        whole.axvspan(p + SPAN[0], p + SPAN[1], color="tab:blue", alpha=0.15)
    whole.set_title(f"{plant.name}, {report.record}: {channel} [{unit}] (shaded: the panels below)")
    whole.legend(loc="upper right", fontsize=8)
    for ax, tc in zip(axes[1:], picked, strict=True):
        m = (t >= tc + SPAN[0]) & (t < tc + SPAN[1])
        ax.plot(t[m], y[m], color="k", lw=1.2, label="measured")
        ax.plot(t[m], before[m], color="tab:red", lw=1.0, label="calibrated model")
        ax.plot(t[m], after[m], color="tab:green", lw=1.0, ls="--", label=label_after)
        ax.axvline(tc, color="tab:blue", lw=0.8, ls=":")
        ax.set_ylabel(f"{channel} [{unit}]")
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("t [s]")
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    return out
