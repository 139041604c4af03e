"""PNG plots of a diagnosis: the residual map, record-versus-simulation overlays, the gap budget and the
missing term.

Uses matplotlib's object API (``Figure``), not pyplot, so it is safe in a
server without a display and keeps no global state.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from engine.constants import CHANNELS, WAVELET_LEVEL
from engine.diagnosis.diagnose import DiagnosisResult
from engine.diagnosis.localisation import DEFAULT_WINDOWS_MS, Cell, level_band
from engine.records import Record
from engine.records.units import factor

if TYPE_CHECKING:
    from matplotlib.figure import Figure


__all__ = ["plot_gap_budget", "plot_missing_term", "plot_overlays", "plot_residual_map"]


def _figure(**kwargs: Any) -> Figure:
    """A matplotlib ``Figure`` (imported here, not at the top: matplotlib adds about 0.6 s to a process start)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def _level_names(level: int = WAVELET_LEVEL) -> list[str]:
    return [f"A{level}"] + [f"D{j}" for j in range(level, 0, -1)]


def _map_level(cells: list) -> int:
    """Decomposition level of a residual map (its approximation ``A<level>``; it follows the record's interval)."""
    return max((int(c.level[1:]) for c in cells if c.level.startswith("A")), default=WAVELET_LEVEL)


def _log_excess(cell: Cell) -> float:
    """log10 of a cell's residual energy over its noise energy (the residual map's colour)."""
    return float(np.log10(max(cell.energy, 1e-12) / max(cell.noise_energy, 1e-12)))


def residual_map_limits(result: DiagnosisResult) -> tuple[float, float]:
    """The colour limits both residual maps of ``result`` share (before and after the fix)."""
    return -1.0, max(1.0, *(_log_excess(c) for c in (*result.cells, *result.cells_after)))


def plot_residual_map(result: DiagnosisResult, path: str | Path, after: bool = False) -> Path:
    """Residual map: one panel per channel, wavelet level x time window, coloured by energy over noise.

    Parameters
    ----------
    result : DiagnosisResult
        The diagnosis.
    path : path
        PNG file to write.
    after : bool
        Map the residual left by the named effect's fit instead of the nominal one.

    Returns
    -------
    Path
        The written file.
    """
    cells = result.cells_after if after and result.cells_after else result.cells
    present = {c.channel for c in cells}
    channels = [c for c in CHANNELS if c in present]
    levels = _level_names(_map_level(cells))
    windows = [w[0] for w in DEFAULT_WINDOWS_MS if any(c.window == w[0] for c in cells)]
    fig = _figure(figsize=(3.2 * len(channels) + 1.5, 5.5), constrained_layout=True)
    axes = fig.subplots(1, len(channels), squeeze=False)[0]
    ts = result.before.sample_interval
    # one colour scale for the maps before and after the fix, so that a gap closed looks cold: the
    # scale spans the larger of the two (both maps of a diagnosis are drawn with the same limits)
    vmin, vmax = residual_map_limits(result)
    grids = {}
    for ch in channels:
        g = np.zeros((len(levels), len(windows)))
        for c in cells:
            if c.channel == ch and c.window in windows:
                g[levels.index(c.level), windows.index(c.window)] = _log_excess(c)
        grids[ch] = g
    im = None
    for ax, ch in zip(axes, channels, strict=True):
        im = ax.imshow(grids[ch], aspect="auto", cmap="magma", vmin=vmin, vmax=vmax, origin="upper")
        ax.set_title(ch)
        ax.set_xticks(range(len(windows)))
        ax.set_xticklabels(windows, rotation=60, fontsize=7)
        ax.set_yticks(range(len(levels)))
        labels = []
        for name in levels:
            j = int(name[1:])
            lo, hi = level_band(j, ts, approximation=name.startswith("A"))
            labels.append(f"{name} {lo:.0f}-{hi:.0f} Hz")
        ax.set_yticklabels(labels if ax is axes[0] else [], fontsize=7)
    if im is not None:
        fig.colorbar(im, ax=list(axes), label="log10(residual energy / noise energy)")
    named = " + ".join(e["effect"] for e in result.verdict.effects) or (result.verdict.effect or "")
    what = f"after adding {named}" if after and result.cells_after else "nominal calibration"
    fig.suptitle(f"Residual map ({what}); verdict: {result.verdict.status} {named}")
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def plot_overlays(record: Record, result: DiagnosisResult, path: str | Path) -> Path:
    """Record versus the calibrated simulation before and after adding the named effect.

    One row per channel of the record, in the record's own units: the record (grey), the
    nominal calibration (blue), the fit with the named effect (red, when there is one),
    and below each, the residuals in noise standard deviations.

    Returns
    -------
    Path
        The written file.
    """
    record, _ = record.test_window()  # what the diagnosis read, and what result.before/after cover
    channels = list(record.channels)
    fig = _figure(figsize=(11, 2.6 * len(channels)), constrained_layout=True)
    axes = fig.subplots(2 * len(channels), 1, sharex=True, gridspec_kw={"height_ratios": [3, 1] * len(channels)})
    t = record.time * 1e3
    sig = result.calibration.sigma
    for i, ch in enumerate(channels):
        ax, axr = axes[2 * i], axes[2 * i + 1]
        unit = record.unit(ch)
        f = factor(ch, unit, record.conditions)  # model unit per record unit
        ax.plot(t, record[ch] / f, color="0.6", lw=0.8, label="record")
        ax.plot(t, result.before[ch] / f, color="tab:blue", lw=0.9, label="calibrated nominal")
        axr.plot(t, (record[ch] - result.before[ch]) / sig[ch], color="tab:blue", lw=0.6)
        if result.after is not None:
            ax.plot(
                t,
                result.after[ch] / f,
                color="tab:red",
                lw=0.9,
                ls="--",
                label="with " + (" + ".join(e["effect"] for e in result.verdict.effects) or str(result.verdict.effect)),
            )
            axr.plot(t, (record[ch] - result.after[ch]) / sig[ch], color="tab:red", lw=0.6)
        ax.set_ylabel(f"{ch} [{unit}]")
        axr.set_ylabel("res/sigma", fontsize=7)
        if i == 0:
            ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time from the event [ms]")
    fig.suptitle(
        f"Verdict: {result.verdict.status} {' + '.join(e['effect'] for e in result.verdict.effects)} (confidence {result.verdict.confidence:.2f})"
    )
    path = Path(path)
    fig.savefig(path, dpi=100)
    return path


def plot_gap_budget(result: DiagnosisResult, path: str | Path) -> Path:
    """The gap budget of the named effects, and the gap per channel before and after them.

    Left: one bar per named effect, its share of the nominal model's excess residual energy (beyond
    noise; ``verdict.effects[i]["share"]``, largest first, labelled with its value, uncertainty and
    locus), and one for what is left (``verdict.left``); together they make 1. Right: per channel of the
    record, the residual RMS over the noise of the calibrated nominal model and of the fit with the
    effects (log scale; 1 is the noise).

    Raises
    ------
    ValueError
        When the verdict names no effect (``no_gap``, ``weak_gap``, ``unexplained``).
    """
    effects = result.verdict.effects
    if not effects:
        raise ValueError(f"a {result.verdict.status!r} verdict names no effect, so it has no gap budget")
    fig = _figure(figsize=(11, 0.9 + 0.55 * max(len(effects) + 1, 5)), layout="constrained")
    ax, bx = fig.subplots(1, 2, width_ratios=(1.6, 1))
    names, shares, colours = [], [], []
    palette = ("tab:red", "tab:orange", "tab:green", "tab:purple")
    for i, e in enumerate(effects):
        share = e.get("share")
        names.append(
            f"{e['effect']} = {_value_text(e.get('value'), e.get('uncertainty'), e.get('unit'))}"
            + (f" ({e['locus']})" if e.get("locus") else "")
        )
        shares.append(float(share) if share is not None else np.nan)
        colours.append(palette[i % len(palette)])
    left = result.verdict.left
    names.append("left")
    shares.append(float(left) if left is not None else np.nan)
    colours.append("0.6")
    y = np.arange(len(names))
    ax.barh(y, np.nan_to_num(shares), color=colours)
    for yi, v in zip(y, shares, strict=True):
        ax.text(
            min(np.nan_to_num(v), 1.0) + 0.01, yi, "n/a" if np.isnan(v) else f"{100 * v:.1f} %", va="center", fontsize=8
        )
    ax.set_yticks(y, names, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(0.0, 1.15)
    ax.set_xlabel("share of the nominal model's excess residual energy [-]")
    ax.set_title("Gap budget (Shapley split of the energy each effect removes)", fontsize=9)
    before = result.gap_before.per_channel
    after = result.gap_after.per_channel if result.gap_after is not None else {}
    channels = list(before)
    yc = np.arange(len(channels))
    rb = [float(before[c]["rms_over_noise"]) for c in channels]
    ra = [float(after[c]["rms_over_noise"]) if c in after else np.nan for c in channels]
    bx.barh(yc - 0.2, rb, height=0.4, color="tab:blue", label="calibrated nominal")
    bx.barh(yc + 0.2, np.nan_to_num(ra), height=0.4, color="tab:red", label="with the effects")
    bx.axvline(1.0, color="k", lw=0.8, ls=":")
    bx.set_xscale("log")
    bx.set_yticks(yc, channels, fontsize=8)
    bx.invert_yaxis()
    bx.set_xlabel("residual RMS / noise [-]")
    bx.legend(fontsize=7, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=2, frameon=False)
    fig.suptitle(
        f"Verdict: {result.verdict.status} {' + '.join(e['effect'] for e in effects)}"
        f" (confidence {result.verdict.confidence:.2f})"
    )
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def _value_text(value: float | None, uncertainty: float | None, unit: str | None) -> str:
    """``1.39980 +- 0.00011 x``: a fitted value to the second significant digit of its uncertainty."""
    if value is None:
        return "?"
    u = f" {unit}" if unit else ""
    if uncertainty is None or not np.isfinite(uncertainty) or uncertainty <= 0:
        return f"{value:.4g}{u}"
    digits = max(0, -int(np.floor(np.log10(uncertainty))) + 1)
    return f"{value:.{digits}f} +- {uncertainty:.2g}{u}"


def plot_missing_term(result: DiagnosisResult, path: str | Path) -> Path:
    """The missing term of an unexplained (or weak) gap: its time series, and how well each locus explains it.

    Left: the estimated unknown input at the best locus against time from the event [ms], in its
    unit (pu torque, rad angle, relative voltage), with the one-sentence description as title.
    Right: per locus, the fraction of the residual energy its input explains.

    Raises
    ------
    ValueError
        When the result carries no locus estimate (an explained or no-gap verdict).
    """
    loc = result.locus
    if not loc or not loc.get("term"):
        raise ValueError("this diagnosis has no missing-term estimate (only unexplained and weak gaps have one)")
    term = loc["term"]
    fig = _figure(figsize=(10, 3.6), layout="constrained")
    ax, bx = fig.subplots(1, 2, width_ratios=(3, 1.3))
    t_ms = np.asarray(term["t"], dtype=float) * 1e3
    ax.plot(t_ms, np.asarray(term["series"], dtype=float), color="tab:purple", lw=1.0)
    ax.axvline(0.0, color="0.6", lw=0.7, ls=":")
    ax.set_xlabel("time from the event [ms]")
    ax.set_ylabel(f"{term['kind']} [{term['unit']}]")
    ax.set_title(term["description"], fontsize=9)
    scores = loc.get("scores", {})
    names = list(scores)
    vals = [float(scores[n].get("explained") or 0.0) for n in names]
    colours = ["tab:purple" if n == loc.get("locus") else "0.7" for n in names]
    bx.barh(names, vals, color=colours)
    bx.set_xlim(0.0, 1.0)
    bx.set_xlabel("residual energy explained [-]")
    bx.tick_params(axis="y", labelsize=8)
    bx.invert_yaxis()
    fig.suptitle(f"Missing term, locus {loc.get('locus')} (confidence {loc.get('confidence', float('nan')):.2f})")
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path
