"""Tests for the width-history trend (engine.history).

Each test checks one promise of :func:`engine.history.trend.fit_trend`: exact recovery without
noise, agreement with an independent fit, the Birge scaling, the nominal coverage of the rate and
crossing intervals (by simulation), Fieller's open end when the slope is not significant, the
refusals, the JSON form, the plot, and that docs/trend.md shows what the code computes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import engine
from engine.history import MIN_DATES, MIN_SPAN_DAYS, Trend, TrendError, WidthPoint, fit_trend
from engine.history.plots import example_markdown, plot_history

REPO_ROOT = Path(engine.__file__).resolve().parent.parent
START = datetime(2024, 1, 1, 6, 30, tzinfo=UTC)
DAY = timedelta(days=1)


def history(
    offsets: np.ndarray,
    *,
    k0: float,
    rate: float,
    noise: float,
    stated: float | None,
    rng: np.random.Generator,
) -> list[WidthPoint]:
    """Widths k0 + rate * day + N(0, noise^2) at START + offsets [day], stated sigma ``stated``."""
    k = k0 + rate * offsets + noise * rng.standard_normal(offsets.size)
    return [WidthPoint(START + timedelta(days=float(o)), float(v), stated) for o, v in zip(offsets, k, strict=True)]


def true_crossing(k0: float, rate: float, limit: float) -> datetime:
    return START + timedelta(days=(limit - k0) / rate)


def wilson(hits: int, n: int) -> tuple[float, float]:
    ci = stats.binomtest(hits, n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)


def covers(interval: tuple[datetime | None, datetime | None], when: datetime) -> bool:
    lo, hi = interval
    return (lo is None or lo <= when) and (hi is None or when <= hi)


# --- exact recovery and agreement with independent fits --------------------------------------------
@pytest.mark.parametrize("stated", [2e-4, None])
def test_noiseless_history_is_recovered_exactly(stated: float | None) -> None:
    offsets = np.array([0.0, 30.0, 95.0, 180.0, 365.0])
    k0, rate, limit = 5e-3, 4e-6, 7e-3
    pts = history(offsets, k0=k0, rate=rate, noise=0.0, stated=stated, rng=np.random.default_rng(0))
    t = fit_trend(pts, limit)
    assert t.rate_m_per_day == pytest.approx(rate, rel=1e-9)
    k_ref, _ = t.predict(t.reference_date)
    assert k_ref[0] == pytest.approx(t.intercept_m, rel=1e-12)
    assert t.intercept_m == pytest.approx(k0 + rate * (t.reference_date - START) / DAY, rel=1e-9)
    truth = true_crossing(k0, rate, limit)
    assert t.crossing_date is not None
    assert abs(t.crossing_date - truth) <= DAY / 2  # rounded to a UTC midnight
    assert t.significant and t.n_points == 5 and t.dof == 3
    lo, hi = t.crossing_interval
    assert lo is not None and hi is not None and lo <= truth <= hi
    if stated is None:
        # No scatter, no stated uncertainty: the line is exact and the interval collapses to a day.
        assert t.rate_sigma_m_per_day == pytest.approx(0.0, abs=1e-15)
        assert hi - lo <= 2 * DAY
        assert t.scatter_factor is None and t.weighting == "equal"
    else:
        # chi2 = 0: the stated sigmas are kept (max(1, chi2/dof)), never shrunk.
        x = np.array([(p.measured_at - START) / DAY for p in pts])
        expected = stated / math.sqrt(float(np.sum((x - x.mean()) ** 2)))
        assert t.rate_sigma_m_per_day == pytest.approx(expected, rel=1e-9)
        assert t.scatter_factor == pytest.approx(0.0, abs=1e-6) and t.weighting == "stated"


def test_equal_weights_match_scipy_linregress() -> None:
    rng = np.random.default_rng(1)
    offsets = np.sort(rng.uniform(0.0, 400.0, 9))
    pts = history(offsets, k0=4e-3, rate=3e-6, noise=1e-4, stated=None, rng=rng)
    t = fit_trend(pts, 8e-3)
    ref = stats.linregress(offsets, [p.K for p in pts])
    assert t.rate_m_per_day == pytest.approx(ref.slope, rel=1e-9)
    assert t.rate_sigma_m_per_day == pytest.approx(ref.stderr, rel=1e-9)
    assert t.quantile == pytest.approx(stats.t.ppf(0.975, 7), rel=1e-12)
    k_first, _ = t.predict(START)
    assert k_first[0] == pytest.approx(ref.intercept, rel=1e-9)


def test_birge_ratio_inflates_but_never_shrinks() -> None:
    rng = np.random.default_rng(2)
    offsets = np.linspace(0.0, 300.0, 10)
    base = history(offsets, k0=5e-3, rate=3e-6, noise=3e-4, stated=None, rng=rng)
    equal = fit_trend(base, 9e-3)
    # Stated sigmas 3x too small: the scatter wins and the result equals the unweighted fit's.
    small = fit_trend([WidthPoint(p.measured_at, p.K, 1e-4) for p in base], 9e-3)
    assert small.scatter_factor is not None and small.scatter_factor > 1.5
    assert small.rate_m_per_day == pytest.approx(equal.rate_m_per_day, rel=1e-9)
    assert small.rate_sigma_m_per_day == pytest.approx(equal.rate_sigma_m_per_day, rel=1e-9)
    assert "inflated" in small.method
    # Stated sigmas 3x too large: they are kept, the intervals stay wide.
    large = fit_trend([WidthPoint(p.measured_at, p.K, 9e-4) for p in base], 9e-3)
    assert large.scatter_factor is not None and large.scatter_factor < 1.0
    x = offsets - offsets.mean()
    assert large.rate_sigma_m_per_day == pytest.approx(9e-4 / math.sqrt(float(np.sum(x * x))), rel=1e-9)
    assert large.rate_sigma_m_per_day > equal.rate_sigma_m_per_day


# --- coverage by simulation ----------------------------------------------------------------------
N_SIM = 400
OFFSETS = np.array([0.0, 45.0, 120.0, 170.0, 260.0, 365.0])
K0, RATE, NOISE, LIMIT = 5e-3, 4e-6, 2e-4, 7e-3  # the true crossing is 500 days after the first estimate


def _coverage(stated_factor: float | None, seed: int) -> tuple[int, int]:
    """Hits of the rate interval and of the crossing interval over N_SIM histories."""
    rng = np.random.default_rng(seed)
    stated = None if stated_factor is None else NOISE * stated_factor
    truth = true_crossing(K0, RATE, LIMIT)
    rate_hits = crossing_hits = 0
    for _ in range(N_SIM):
        t = fit_trend(history(OFFSETS, k0=K0, rate=RATE, noise=NOISE, stated=stated, rng=rng), LIMIT)
        lo, hi = t.rate_interval_m_per_day
        rate_hits += lo <= RATE <= hi
        crossing_hits += covers(t.crossing_interval, truth)
    return rate_hits, crossing_hits


@pytest.mark.parametrize(
    ("stated_factor", "seed"),
    [(None, 11), (1.0 / 3.0, 12)],
    ids=["sigmas-unknown", "sigmas-understated-3x"],
)
def test_rate_and_crossing_intervals_cover_at_the_nominal_rate(stated_factor: float | None, seed: int) -> None:
    """Unknown or understated sigmas: the scatter sets the intervals, and Student t makes them exact.

    With 4 degrees of freedom a normal quantile would cover only about 88 %, outside the Wilson
    interval: the test fails for that mistake, and for a covariance not scaled by the scatter. The
    crossing interval with understated sigmas is exact up to the max(1, chi2/dof) floor and the
    outward rounding to days (about 0.956 in 10000 histories, docs/trend.md): never below nominal.
    """
    rate_hits, crossing_hits = _coverage(stated_factor, seed)
    lo, hi = wilson(rate_hits, N_SIM)
    assert lo <= 0.95 <= hi, f"rate coverage {rate_hits / N_SIM:.3f}, Wilson [{lo:.3f}, {hi:.3f}]"
    lo, hi = wilson(crossing_hits, N_SIM)
    assert hi >= 0.95 and crossing_hits / N_SIM <= 0.98, f"crossing coverage {crossing_hits / N_SIM:.3f}"
    if stated_factor is None:
        assert lo <= 0.95, f"crossing coverage {crossing_hits / N_SIM:.3f}, Wilson [{lo:.3f}, {hi:.3f}]"


def test_correct_stated_sigmas_give_at_least_nominal_coverage() -> None:
    """Right sigmas: max(1, chi2/dof) with Student t is conservative (documented), never too narrow."""
    rate_hits, crossing_hits = _coverage(1.0, 13)
    for hits in (rate_hits, crossing_hits):
        assert wilson(hits, N_SIM)[1] >= 0.95
        assert hits / N_SIM >= 0.95


# --- Fieller's interval ----------------------------------------------------------------------------
def test_crossing_interval_ends_are_where_the_band_meets_the_limit() -> None:
    rng = np.random.default_rng(3)
    pts = history(np.linspace(0.0, 400.0, 8), k0=5e-3, rate=4e-6, noise=1.5e-4, stated=1.5e-4, rng=rng)
    t = fit_trend(pts, 7.5e-3)
    lo, hi = t.crossing_interval
    assert t.significant and lo is not None and hi is not None and t.crossing_date is not None
    assert lo < t.crossing_date < hi
    # Ends rounded outwards to a day: the upper band reaches the limit within the day after ``lo``,
    # the lower band within the day before ``hi``.
    assert t.band(lo)[1][0] <= t.limit <= t.band(lo + DAY)[1][0]
    assert t.band(hi - DAY)[0][0] <= t.limit <= t.band(hi)[0][0]


def test_non_significant_slope_leaves_the_latest_end_open() -> None:
    rng = np.random.default_rng(4)
    pts = history(np.array([0.0, 20.0, 50.0, 90.0]), k0=5e-3, rate=5e-7, noise=2e-4, stated=2e-4, rng=rng)
    t = fit_trend(pts, 7e-3)
    lo_r, hi_r = t.rate_interval_m_per_day
    assert not t.significant and lo_r < 0.0 < hi_r
    earliest, latest = t.crossing_interval
    assert latest is None
    assert "not growing significantly" in t.message and "unbounded" in t.message
    # The width is confidently below the limit now, so the earliest end is where the upper band
    # first reaches the limit after now.
    assert earliest is not None and earliest > t.now
    assert t.band(earliest)[1][0] <= t.limit <= t.band(earliest + DAY)[1][0]
    d = t.to_dict()
    assert d["crossing_interval"][1] is None


def test_falling_but_not_significant_history_predicts_no_crossing() -> None:
    wiggle = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0]) * 1e-4
    offsets = np.linspace(0.0, 200.0, 6)
    pts = [
        WidthPoint(START + timedelta(days=float(o)), 5e-3 + w - 1e-7 * o, None)
        for o, w in zip(offsets, wiggle, strict=True)
    ]
    t = fit_trend(pts, 8e-3)
    assert t.rate_m_per_day < 0.0 and not t.significant
    assert t.crossing_date is None
    assert "not growing significantly" in t.message and "no crossing predicted" in t.message
    earliest, latest = t.crossing_interval
    assert latest is None and earliest is not None and earliest > t.now


def test_significant_decrease_is_reported_as_inconsistent_with_wear() -> None:
    rng = np.random.default_rng(6)
    pts = history(np.linspace(0.0, 300.0, 7), k0=6e-3, rate=-5e-6, noise=5e-5, stated=5e-5, rng=rng)
    t = fit_trend(pts, 8e-3)
    assert t.significant and t.rate_m_per_day < 0.0
    assert t.crossing_date is None and t.crossing_interval == (None, None)
    assert "decreases significantly" in t.message


def test_history_already_past_the_limit_says_so() -> None:
    rng = np.random.default_rng(7)
    pts = history(np.linspace(0.0, 300.0, 7), k0=6e-3, rate=5e-6, noise=5e-5, stated=5e-5, rng=rng)
    t = fit_trend(pts, 6.5e-3)
    lo, hi = t.crossing_interval
    assert lo is not None and hi is not None and hi < t.now
    assert t.crossing_date is not None and t.crossing_date < t.now
    assert "Already past the limit" in t.message


# --- refusals ------------------------------------------------------------------------------------
def _pts(days: list[float], k: float = 5e-3, sigma: float | None = 1e-4) -> list[WidthPoint]:
    return [WidthPoint(START + timedelta(days=d), k + 1e-6 * d, sigma) for d in days]


@pytest.mark.parametrize(
    ("make", "limit", "match"),
    [
        (lambda: [], 7e-3, "no width estimates"),
        (lambda: _pts([0.0, 100.0]), 7e-3, "too little history: 2 width estimate"),
        (lambda: _pts([0.0, 0.1, 0.2]), 7e-3, "all 3 width estimates are from one date"),
        (lambda: _pts([0.0, 100.0, 100.1, 100.2]), 7e-3, "on 2 date"),
        (lambda: _pts([0.0, 1.0, 2.0, 3.0]), 7e-3, f"less than {MIN_SPAN_DAYS:g}"),
        (lambda: _pts([0.0, 50.0, 100.0]), 0.0, "finite number > 0"),
        (lambda: _pts([0.0, 50.0, 100.0]), -1e-3, "finite number > 0"),
        (lambda: _pts([0.0, 50.0, 100.0]), math.nan, "finite number > 0"),
    ],
    ids=["empty", "two-points", "one-date", "two-dates", "short-span", "limit-0", "limit-negative", "limit-nan"],
)
def test_too_little_history_or_bad_limit_is_refused(
    make: Callable[[], list[WidthPoint]], limit: float, match: str
) -> None:
    with pytest.raises(TrendError, match=match):
        fit_trend(make(), limit)


def test_bad_points_are_refused_with_what_to_do() -> None:
    with pytest.raises(TrendError, match="no time zone"):
        WidthPoint(datetime(2024, 1, 1), 5e-3, 1e-4)  # a naive date
    with pytest.raises(TrendError, match="finite"):
        WidthPoint(START, math.nan, 1e-4)
    with pytest.raises(TrendError, match="finite"):
        WidthPoint(START, math.inf, None)
    with pytest.raises(TrendError, match="finite and > 0"):
        WidthPoint(START, 5e-3, math.nan)
    with pytest.raises(TrendError, match="finite and > 0"):
        WidthPoint(START, 5e-3, 0.0)
    with pytest.raises(TrendError, match="strictly between 0 and 1"):
        fit_trend(_pts([0.0, 50.0, 100.0]), 7e-3, confidence=1.5)
    with pytest.raises(TrendError, match="timezone-aware"):
        fit_trend(_pts([0.0, 50.0, 100.0]), 7e-3, now=datetime(2025, 1, 1))
    assert issubclass(TrendError, ValueError)
    assert MIN_DATES == 3


# --- form of the answer ----------------------------------------------------------------------------
def test_to_dict_is_json_ready_and_carries_the_api_keys() -> None:
    rng = np.random.default_rng(8)
    pts = history(np.linspace(0.0, 360.0, 6), k0=5e-3, rate=4e-6, noise=1e-4, stated=1e-4, rng=rng)
    t = fit_trend(pts, 7e-3)
    d = json.loads(json.dumps(t.to_dict(), allow_nan=False))
    for key in ("rate_m_per_day", "rate_sigma_m_per_day", "crossing_date", "crossing_interval", "n_points", "method"):
        assert key in d
    assert d["n_points"] == 6 and len(d["crossing_interval"]) == 2
    assert datetime.fromisoformat(d["crossing_date"]) == t.crossing_date
    assert [datetime.fromisoformat(s) for s in d["crossing_interval"]] == list(t.crossing_interval)
    assert "Fieller" in d["method"] and "linearly" in d["method"] and d["message"]


def test_order_and_time_zones_do_not_matter_and_missing_sigmas_mean_equal_weights() -> None:
    rng = np.random.default_rng(9)
    pts = history(np.linspace(0.0, 360.0, 6), k0=5e-3, rate=4e-6, noise=1e-4, stated=1e-4, rng=rng)
    tz = timezone(timedelta(hours=-7))
    shuffled = [WidthPoint(p.measured_at.astimezone(tz), p.K, p.K_sigma) for p in reversed(pts)]
    a, b = fit_trend(pts, 7e-3), fit_trend(shuffled, 7e-3)
    assert a.to_dict() == b.to_dict()
    mixed = [WidthPoint(p.measured_at, p.K, None if i == 2 else p.K_sigma) for i, p in enumerate(pts)]
    m = fit_trend(mixed, 7e-3)
    assert m.weighting == "equal" and "1 of 6 estimates had no uncertainty" in m.method


# --- plot and docs ---------------------------------------------------------------------------------
def test_plot_writes_png(tmp_path: Path) -> None:
    rng = np.random.default_rng(10)
    pts = history(np.linspace(0.0, 360.0, 6), k0=5e-3, rate=4e-6, noise=1e-4, stated=1e-4, rng=rng)
    flat = history(np.array([0.0, 20.0, 50.0, 90.0]), k0=5e-3, rate=5e-7, noise=2e-4, stated=None, rng=rng)
    cases: list[tuple[list[WidthPoint], Trend | None, float | None]] = [
        (pts, fit_trend(pts, 7e-3), 7e-3),
        (flat, fit_trend(flat, 7e-3), None),
        (pts, None, None),
    ]
    for i, (p, t, limit) in enumerate(cases):
        out = plot_history(p, t, limit, tmp_path / f"h{i}.png", title="test")
        data = out.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000


def test_docs_show_what_the_code_computes() -> None:
    """docs/trend.md's worked example is the output of ``python -m engine.history.plots``."""
    doc = (REPO_ROOT / "docs" / "trend.md").read_text(encoding="utf-8")
    assert example_markdown() in doc
