"""The BRFD's own figure: force against displacement, measured and model, before and after.

A friction damper is read as a loop: force against the imposed displacement. The backlash regime
is the near-zero stretch of force after each reversal. matplotlib's object API (no pyplot).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from matplotlib.figure import Figure

from engine.plants.brfd.model import BrfdPlant, input_displacement
from engine.plants.brfd.record import BrfdRecord

__all__ = ["plot_force_displacement"]

#: Length of the time panel after the first reversal past the settle time [s].
ZOOM: float = 1.0


def plot_force_displacement(
    plant: BrfdPlant,
    record: BrfdRecord,
    before: Mapping[str, float],
    after: Mapping[str, float] | None,
    path: str | Path,
    after_label: str = "with the named effects",
) -> Path:
    """Measured force vs displacement beside the model at ``before`` and at ``after``; and the same in time.

    Parameters
    ----------
    plant, record
        The plant and one of its records.
    before, after : mapping
        Parameter and effect values of the two models (``after`` may be None).
    path
        PNG file written.
    """
    path = Path(path)
    sl = plant.scored(record)
    x = record.x[sl] * 1e3
    f_meas = record.force[sl] / 1e3
    f_before = plant.simulate(record, before)["force"][sl] / 1e3
    f_after = plant.simulate(record, after)["force"][sl] / 1e3 if after is not None else None
    fig = Figure(figsize=(12, 4.8))
    ax1, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.0, 1.3]})
    ax1.plot(x, f_meas, color="black", lw=0.6, label="measured")
    ax1.plot(x, f_before, color="tab:red", lw=0.8, label="nominal model (no play)")
    if f_after is not None:
        ax1.plot(x, f_after, color="tab:green", lw=0.8, ls="--", label=after_label)
    ax1.set_xlabel("displacement [mm]")
    ax1.set_ylabel("friction force [kN]")
    ax1.legend(loc="upper left", fontsize=8)
    ax1.grid(alpha=0.3)
    t = record.t[sl]
    rev = plant.events(record)
    t0 = float(rev[0]) - 0.1 if rev.size else float(t[0])
    win = (t >= t0) & (t <= t0 + ZOOM)
    ax2.plot(t[win], f_meas[win], color="black", lw=0.8, label="measured")
    ax2.plot(t[win], f_before[win], color="tab:red", lw=0.9, label="nominal")
    if f_after is not None:
        ax2.plot(t[win], f_after[win], color="tab:green", lw=0.9, ls="--", label=after_label)
    for te in rev[(rev >= t0) & (rev <= t0 + ZOOM)]:
        ax2.axvline(te, color="grey", ls=":", lw=0.8)
    twin = ax2.twinx()
    twin.plot(t[win], input_displacement(record)[sl][win] * 1e3, color="tab:blue", lw=0.6, alpha=0.5)
    twin.set_ylabel("displacement [mm]", color="tab:blue")
    ax2.set_xlabel("time [s] (dotted: reversals)")
    ax2.set_ylabel("friction force [kN]")
    ax2.grid(alpha=0.3)
    fig.suptitle(f"BRFD {record.name}: force against displacement, measured and model", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path
