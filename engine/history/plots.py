"""PNG plot of a drive's backlash-width history and its trend; the worked example of docs/trend.md.

Uses matplotlib's object API (``Figure``, Agg canvas), not pyplot, so it is safe in a server
without a display and keeps no global state (as :mod:`engine.diagnosis.plots`).

``python -m engine.history.plots [--plot PATH]`` prints docs/trend.md's worked example (Markdown)
and optionally draws its figure.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.dates import date2num
from matplotlib.figure import Figure
from scipy import stats

from engine.history.trend import Trend, TrendError, WidthPoint, fit_trend, worked_example

__all__ = ["main", "plot_history"]

logger = logging.getLogger(__name__)

#: The trend is drawn at most this many observed spans past the last estimate [-] (a crossing further
#: out is named in the subtitle, not drawn).
_MAX_SPANS_DRAWN = 20.0
_DAYS_PER_YEAR = 365.25


def _horizon(points: Sequence[WidthPoint], trend: Trend) -> datetime:
    """Last date the trend is drawn to: the crossing interval's far end, or a span past the last estimate."""
    first, last = points[0].measured_at, points[-1].measured_at
    span = last - first
    ends = [e for e in (trend.crossing_date, *trend.crossing_interval) if e is not None]
    end = max([last, *ends])
    if trend.crossing_interval[1] is None:
        end = max(end, last + span)
    end = min(end, last + _MAX_SPANS_DRAWN * span)
    return end + 0.05 * (end - first)


def _day(when: datetime | None) -> str:
    return "open" if when is None else when.date().isoformat()


def plot_history(
    points: Sequence[WidthPoint],
    trend: Trend | None,
    limit: float | None,
    path: Path,
    *,
    title: str | None = None,
) -> Path:
    """Width history over date with its fitted trend, confidence band, limit and crossing.

    The estimates in mm with their one-sigma error bars (none when unknown); the fitted line and its
    ``trend.confidence`` band from the first estimate to past the crossing interval (or one observed
    span past the last estimate when the latest end is open; at most 20 spans); the limit as a
    horizontal line; the crossing date as a vertical line and its interval shaded (an open end
    shaded to the edge of the plot and labelled "open").

    Parameters
    ----------
    points : sequence of WidthPoint
        The history (any order; at least one estimate).
    trend : Trend or None
        The fit of :func:`engine.history.trend.fit_trend`; ``None`` draws the estimates alone.
    limit : float or None
        Width limit [m]; ``None`` uses ``trend.limit`` when there is a trend, else draws none.
    path : Path
        PNG file to write.
    title : str, optional
        Figure title [default: "Backlash width history"].

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    ValueError
        When there are no points.
    """
    pts = sorted(points, key=lambda p: p.measured_at)
    if not pts:
        raise ValueError("no width estimates to plot")
    if limit is None and trend is not None:
        limit = trend.limit
    fig = Figure(figsize=(9.0, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    dates = [float(date2num(p.measured_at)) for p in pts]
    k_mm = np.array([p.K for p in pts]) * 1e3
    err = np.array([p.K_sigma or 0.0 for p in pts]) * 1e3
    has_err = any(p.K_sigma is not None for p in pts)
    ax.errorbar(
        dates,
        k_mm,
        yerr=err if has_err else None,
        fmt="o",
        color="black",
        ms=4,
        capsize=3,
        lw=1.0,
        label="estimates" + (" (1 sigma)" if has_err else ""),
        zorder=3,
    )
    subtitle = ""
    if trend is not None:
        end = _horizon(pts, trend)
        first = pts[0].measured_at
        grid_dates = [first + (end - first) * f for f in np.linspace(0.0, 1.0, 200)]
        grid = date2num(grid_dates)
        k, _ = trend.predict(grid_dates)
        lo, hi = trend.band(grid_dates)
        ax.plot(grid, k * 1e3, color="tab:blue", lw=1.2, label="fitted line")
        ax.fill_between(
            grid,
            lo * 1e3,
            hi * 1e3,
            color="tab:blue",
            alpha=0.18,
            lw=0,
            label=f"{100 * trend.confidence:.3g} % band of the line",
        )
        earliest, latest = trend.crossing_interval
        if trend.crossing_date is not None and trend.crossing_date <= end:
            ax.axvline(
                float(date2num(trend.crossing_date)),
                color="tab:red",
                lw=1.0,
                label=f"crossing {_day(trend.crossing_date)}",
            )
        if earliest is not None or latest is not None:
            left = earliest if earliest is not None else first - 0.05 * (end - first)
            right = latest if latest is not None and latest <= end else end
            ax.axvspan(
                float(date2num(left)),
                float(date2num(right)),
                color="tab:red",
                alpha=0.10,
                lw=0,
                label=f"crossing interval [{_day(earliest)}, {_day(latest)}]",
            )
            if latest is None:
                ax.annotate(
                    "latest: open",
                    xy=(float(date2num(end)), float(limit or np.nanmax(hi)) * 1e3),
                    xytext=(-6, 6),
                    textcoords="offset points",
                    ha="right",
                    fontsize=8,
                    color="tab:red",
                )
        ax.set_xlim(float(date2num(first - 0.05 * (end - first))), float(date2num(end)))
        r_year = trend.rate_m_per_day * 1e3 * _DAYS_PER_YEAR
        s_year = trend.rate_sigma_m_per_day * 1e3 * _DAYS_PER_YEAR
        subtitle = f"rate {r_year:.3g} ± {s_year:.2g} mm/year (1 sigma), {trend.n_points} estimates"
        if trend.scatter_factor is not None:
            subtitle += f", Birge ratio {trend.scatter_factor:.2f}"
        if trend.crossing_date is not None and trend.crossing_date > end:
            subtitle += f"; crossing {_day(trend.crossing_date)} (beyond the plot)"
    if limit is not None:
        ax.axhline(limit * 1e3, color="tab:red", ls="--", lw=1.0, label=f"limit {limit * 1e3:.3g} mm")
    ax.xaxis_date(UTC)
    ax.set_xlabel("date (UTC)")
    ax.set_ylabel("backlash width K [mm]")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(fontsize=7, loc="upper left")
    fig.autofmt_xdate()
    fig.suptitle(title or "Backlash width history")
    if subtitle:
        ax.set_title(subtitle, fontsize=9)
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


# --- docs/trend.md's worked example ----------------------------------------------------------------
def _fmt(v: object) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def coverage_table(n_sim: int = 800, seed: int = 2024) -> list[str]:
    """Simulated coverage of the 95 % rate and crossing intervals, as Markdown table rows.

    ``n_sim`` histories of 6 estimates (days 0, 45, 120, 170, 260, 365) of a width growing from
    5 mm by 4 um/day (limit 7 mm, reached on day 500) with Gaussian noise of 0.2 mm, for four ways
    the stated sigmas can relate to the true noise. Coverage with its Wilson 95 % interval.
    """
    rng = np.random.default_rng(seed)
    offsets = np.array([0.0, 45.0, 120.0, 170.0, 260.0, 365.0])
    k0, rate, noise, limit = 5e-3, 4e-6, 2e-4, 7e-3
    start = datetime(2024, 1, 1, tzinfo=UTC)
    truth = start + timedelta(days=(limit - k0) / rate)
    rows = [
        f"| stated sigma ({n_sim} histories) | rate covered | Wilson 95 % | crossing covered | Wilson 95 % |",
        "| --- | --- | --- | --- | --- |",
    ]
    for label, factor in (
        ("none (equal weights)", None),
        ("right", 1.0),
        ("3x too small", 1 / 3),
        ("3x too large", 3.0),
    ):
        hits = np.zeros(2, dtype=int)
        for _ in range(n_sim):
            k = k0 + rate * offsets + noise * rng.standard_normal(offsets.size)
            sigma = None if factor is None else noise * factor
            pts = [
                WidthPoint(start + timedelta(days=float(o)), float(v), sigma) for o, v in zip(offsets, k, strict=True)
            ]
            t = fit_trend(pts, limit)
            lo, hi = t.rate_interval_m_per_day
            e, l = t.crossing_interval
            hits += [lo <= rate <= hi, (e is None or e <= truth) and (l is None or truth <= l)]
        cells = []
        for h in hits:
            ci = stats.binomtest(int(h), n_sim).proportion_ci(confidence_level=0.95, method="wilson")
            cells += [f"{h / n_sim:.3f}", f"[{ci.low:.3f}, {ci.high:.3f}]"]
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    return rows


def example_markdown(plot: Path | None = None) -> str:
    """docs/trend.md's worked example as Markdown (the history, the fit, a short and a refused history).

    Parameters
    ----------
    plot : Path, optional
        Also draw the example's figure there (PNG).
    """
    example = worked_example()
    points, limit = example.points, example.limit
    out = ["| date | K [mm] | sigma [mm] |", "| --- | --- | --- |"]
    out += [
        f"| {p.measured_at.date().isoformat()} | {p.K * 1e3:.3f} | {(p.K_sigma or 0.0) * 1e3:.3f} |" for p in points
    ]
    trend = fit_trend(points, limit)
    d = trend.to_dict()
    out += ["", f"Limit {limit * 1e3:g} mm, confidence {trend.confidence:g}. `Trend.to_dict()` (excerpt):", "", "```"]
    keys = (
        "rate_m_per_day",
        "rate_sigma_m_per_day",
        "crossing_date",
        "crossing_interval",
        "n_points",
        "dof",
        "quantile",
        "scatter_factor",
        "reference_date",
        "intercept_m",
        "message",
        "method",
    )
    out += [f"{key}: {_fmt(d[key])}" for key in keys]
    out += ["```"]
    rate = trend.rate_m_per_day * 1e3 * _DAYS_PER_YEAR
    out += [
        "",
        f"In mm/year: {rate:.3f} ± {trend.rate_sigma_m_per_day * 1e3 * _DAYS_PER_YEAR:.3f} (1 sigma). "
        f"The truth the history was drawn from: {example.rate_m_per_day * 1e3 * _DAYS_PER_YEAR:.3f} mm/year, "
        f"crossing on {example.crossing_date.date().isoformat()}.",
    ]
    for n in (4, 3):
        short = fit_trend(points[:n], limit)
        span = (points[n - 1].measured_at - points[0].measured_at).days
        out += ["", f"The first {n} estimates alone ({span} days):", "", "```"]
        out += [
            f"rate [mm/year]: {short.rate_m_per_day * 1e3 * _DAYS_PER_YEAR:.3f} "
            f"± {short.rate_sigma_m_per_day * 1e3 * _DAYS_PER_YEAR:.3f}, t = {short.quantile:.3f}",
            f"crossing_date: {_fmt(short.to_dict()['crossing_date'])}",
            f"crossing_interval: {short.to_dict()['crossing_interval']}",
            f"message: {short.message}",
            "```",
        ]
    try:
        fit_trend(points[:2], limit)
    except TrendError as exc:
        out += ["", "The first two estimates alone:", "", "```", f"TrendError: {exc}", "```"]
    out += ["", "Coverage of the 95 % intervals in synthetic histories (`coverage_table()`):", "", *coverage_table()]
    late = fit_trend(points, limit, now=points[-1].measured_at + timedelta(days=900))
    out += ["", "The full history judged 900 days after the last estimate (`now=`):", "", "```"]
    out += [f"message: {late.message}", "```"]
    if plot is not None:
        plot_history(points, trend, limit, plot, title="Worked example (docs/trend.md)")
        logger.info("wrote %s", plot)
    return "\n".join(out) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print docs/trend.md's worked example (Markdown); ``--plot PATH`` also draws it."""
    p = argparse.ArgumentParser(prog="python -m engine.history.plots", description="docs/trend.md's worked example")
    p.add_argument("--plot", type=Path, help="also write the example's figure (PNG) here")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    sys.stdout.write(example_markdown(args.plot))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
