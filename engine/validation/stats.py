"""Interval estimates of the validation's scores: Wilson intervals of rates, order-statistic intervals of quantiles,
the inverse-variance pool of independent estimates."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import binom, chi2, norm

__all__ = [
    "MedianEstimate",
    "PooledEstimate",
    "QuantileEstimate",
    "Rate",
    "median_interval",
    "pooled_estimate",
    "quantile_interval",
    "rate",
    "wilson_interval",
]

#: Confidence level of every interval the validation reports.
CONFIDENCE: float = 0.95


def wilson_interval(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion.

    Parameters
    ----------
    k : int
        Successes, ``0 <= k <= n``.
    n : int
        Trials, ``n >= 1``.
    confidence : float
        Two-sided confidence level (0.95: z = 1.96).

    Returns
    -------
    (low, high) : tuple of float
        Bounds of the proportion, in [0, 1].

    Raises
    ------
    ValueError
        ``n < 1`` or ``k`` outside ``[0, n]``.
    """
    if n < 1 or not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n and n >= 1, got k = {k}, n = {n}")
    z = float(norm.ppf(0.5 + confidence / 2.0))
    p = k / n
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4 * n * n)) / den
    # exact at the ends (rounding would otherwise leave 1e-17 off 0 or 1)
    low = 0.0 if k == 0 else max(0.0, centre - half)
    high = 1.0 if k == n else min(1.0, centre + half)
    return low, high


@dataclass(frozen=True)
class Rate:
    """A proportion with its Wilson 95 % interval.

    Attributes
    ----------
    k, n : int
        Cases counted and cases in all.
    value : float or None
        ``k / n`` (None when ``n == 0``).
    low, high : float or None
        The interval's bounds (None when ``n == 0``).
    """

    k: int
    n: int
    value: float | None
    low: float | None
    high: float | None

    def to_dict(self) -> dict[str, float | int | None]:
        """JSON-ready copy (rates rounded to 4 decimals)."""
        r = _round4
        return {"k": self.k, "n": self.n, "rate": r(self.value), "low": r(self.low), "high": r(self.high)}

    def text(self) -> str:
        """E.g. ``95/100 = 95.0 % [88.8, 97.8]`` (``n/a`` when there is no case)."""
        if self.value is None or self.low is None or self.high is None:
            return "n/a (0 cases)"
        return f"{self.k}/{self.n} = {100 * self.value:.1f} % [{100 * self.low:.1f}, {100 * self.high:.1f}]"


def rate(outcomes: Sequence[bool]) -> Rate:
    """The share of true outcomes with its Wilson interval."""
    n, k = len(outcomes), int(sum(bool(o) for o in outcomes))
    if n == 0:
        return Rate(0, 0, None, None, None)
    low, high = wilson_interval(k, n)
    return Rate(k, n, k / n, low, high)


@dataclass(frozen=True)
class MedianEstimate:
    """A sample median with a distribution-free interval from order statistics.

    Attributes
    ----------
    n : int
        Sample size.
    median : float or None
        Sample median (None when ``n == 0``).
    low, high : float or None
        Order statistics x_(l) and x_(n-l+1) bracketing the population median.
    coverage : float or None
        Exact coverage of ``[low, high]``, at least the confidence asked for. A sample too small
        for that (n < 6 at 95 %: even its whole range covers only ``1 - 2 * 0.5**n``) has no
        interval: ``low``, ``high`` and ``coverage`` are None.
    """

    n: int
    median: float | None
    low: float | None
    high: float | None
    coverage: float | None

    def to_dict(self) -> dict[str, float | int | None]:
        """JSON-ready copy (4 significant digits)."""
        r = _sig4
        return {
            "n": self.n,
            "median": r(self.median),
            "low": r(self.low),
            "high": r(self.high),
            "coverage": _round4(self.coverage),
        }

    def text(self, unit: str = "") -> str:
        """E.g. ``1.01 [0.99, 1.05] (n = 120)``."""
        if self.median is None:
            return "n/a (0 cases)"
        if self.low is None or self.high is None:
            return f"{self.median:.3g}{unit} (n = {self.n}: too few for an interval)"
        return f"{self.median:.3g}{unit} [{self.low:.3g}, {self.high:.3g}] (n = {self.n})"


def _order_interval(x: np.ndarray, q: float, confidence: float) -> tuple[float, float, float] | None:
    """Equal-tailed order-statistic interval ``(low, high, coverage)`` of the population ``q``-quantile.

    ``x`` is sorted. With B ~ Binomial(n, q) the number of values below the quantile,
    ``[x_(l), x_(u)]`` (1-based order statistics) covers it with probability ``P(l <= B <= u - 1)``;
    ``l`` is the largest rank with ``P(B <= l - 1) <= alpha / 2`` and ``u`` the smallest with
    ``P(B >= u) <= alpha / 2``. None when either rank falls outside the sample (too few values).
    """
    n = x.size
    alpha = 1.0 - confidence
    l = int(binom.ppf(alpha / 2.0, n, q))  # smallest l with P(B <= l) >= alpha / 2, so P(B <= l - 1) < alpha / 2
    u = int(binom.ppf(1.0 - alpha / 2.0, n, q)) + 1  # P(B <= u - 1) >= 1 - alpha / 2
    if l < 1 or u > n:
        return None
    coverage = float(binom.cdf(u - 1, n, q) - binom.cdf(l - 1, n, q))
    return float(x[l - 1]), float(x[u - 1]), coverage


def _finite_sorted(values: Sequence[float | None]) -> np.ndarray:
    return np.sort(np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float))


def median_interval(values: Sequence[float], confidence: float = CONFIDENCE) -> MedianEstimate:
    """Sample median and the order-statistic interval of the population median.

    With B ~ Binomial(n, 1/2) the number of values below the median, the interval
    ``[x_(l), x_(n-l+1)]`` (1-based order statistics) covers the median with probability
    ``P(l <= B <= n - l)``; ``l`` is the largest rank keeping that at least ``confidence``.

    Parameters
    ----------
    values : sequence of float
        The sample (non-finite values are dropped).
    confidence : float
        Smallest coverage wanted.

    Returns
    -------
    MedianEstimate
    """
    x = _finite_sorted(values)
    if x.size == 0:
        return MedianEstimate(0, None, None, None, None)
    bounds = _order_interval(x, 0.5, confidence)
    if bounds is None:  # even [min, max] covers less than asked
        return MedianEstimate(x.size, float(np.median(x)), None, None, None)
    return MedianEstimate(x.size, float(np.median(x)), *bounds)


@dataclass(frozen=True)
class QuantileEstimate:
    """A sample quantile with a distribution-free interval from order statistics.

    Attributes
    ----------
    q : float
        The quantile's level (0.9: the 90th percentile).
    n : int
        Sample size.
    value : float or None
        Sample quantile (linear interpolation, ``numpy.quantile``'s default; None when ``n == 0``).
    low, high : float or None
        Order statistics bracketing the population quantile (equal tails). A sample too small for
        that has no interval (for the 90th percentile at 95 %: n < 36, since even the largest
        value lies below it with probability ``0.9**n`` > 2.5 %): ``low``, ``high`` and
        ``coverage`` are then None.
    coverage : float or None
        Exact coverage of ``[low, high]``, at least the confidence asked for.
    """

    q: float
    n: int
    value: float | None
    low: float | None
    high: float | None
    coverage: float | None

    def to_dict(self) -> dict[str, float | int | None]:
        """JSON-ready copy (4 significant digits)."""
        r = _sig4
        return {
            "q": self.q,
            "n": self.n,
            "value": r(self.value),
            "low": r(self.low),
            "high": r(self.high),
            "coverage": _round4(self.coverage),
        }

    def text(self, unit: str = "") -> str:
        """E.g. ``p90 12.1 [9.8, 15.0] (n = 75)``."""
        name = f"p{100 * self.q:g}"
        if self.value is None:
            return f"{name} n/a (0 cases)"
        if self.low is None or self.high is None:
            return f"{name} {self.value:.3g}{unit} (n = {self.n}: too few for an interval)"
        return f"{name} {self.value:.3g}{unit} [{self.low:.3g}, {self.high:.3g}] (n = {self.n})"


def quantile_interval(values: Sequence[float], q: float, confidence: float = CONFIDENCE) -> QuantileEstimate:
    """Sample ``q``-quantile and the equal-tailed order-statistic interval of the population's.

    The binomial argument of :func:`median_interval` with ``P(value below the quantile) = q``;
    exact for any continuous distribution, conservative (coverage at least ``confidence``).

    Parameters
    ----------
    values : sequence of float
        The sample (non-finite values are dropped).
    q : float
        Level, ``0 < q < 1``.
    confidence : float
        Smallest coverage wanted.

    Returns
    -------
    QuantileEstimate

    Raises
    ------
    ValueError
        ``q`` outside (0, 1).
    """
    if not 0.0 < q < 1.0:
        raise ValueError(f"the quantile's level must lie in (0, 1), got {q}")
    x = _finite_sorted(values)
    if x.size == 0:
        return QuantileEstimate(q, 0, None, None, None, None)
    value = float(np.quantile(x, q))
    bounds = _order_interval(x, q, confidence)
    if bounds is None:
        return QuantileEstimate(q, x.size, value, None, None, None)
    return QuantileEstimate(q, x.size, value, *bounds)


@dataclass(frozen=True)
class PooledEstimate:
    """Independent estimates of one quantity pooled by inverse variance, with the test of their agreement.

    Attributes
    ----------
    value : float
        Weighted mean, weights ``1 / stderr**2``.
    stderr : float
        Its standard error, ``sum(weights) ** -0.5``.
    low, high : float
        The normal interval ``value -+ z * stderr`` at the confidence asked for.
    chi2 : float
        Cochran's Q: ``sum(weights * (values - value) ** 2)``.
    dof : int
        Its degrees of freedom, one less than the estimates.
    p_value : float
        Probability of a Q this large when every estimate has the same mean (chi-square with
        ``dof`` degrees of freedom); a small one says the pool mixes different quantities.
    """

    value: float
    stderr: float
    low: float
    high: float
    chi2: float
    dof: int
    p_value: float

    @property
    def birge_ratio(self) -> float:
        """``sqrt(chi2 / dof)``: about 1 when the estimates scatter as their standard errors say; well above 1
        when the stated errors are too small for the scatter (or the estimates measure different quantities)."""
        return float(np.sqrt(self.chi2 / self.dof))


def pooled_estimate(
    values: Sequence[float], stderrs: Sequence[float], confidence: float = CONFIDENCE
) -> PooledEstimate:
    """Inverse-variance (fixed-effect) pool of independent estimates with normal errors.

    Parameters
    ----------
    values : sequence of float
        The estimates (e.g. one paired difference per validation run, in points).
    stderrs : sequence of float
        Their standard errors, same units, each finite and positive.
    confidence : float
        Level of the interval.

    Returns
    -------
    PooledEstimate

    Raises
    ------
    ValueError
        Fewer than two estimates, sequences of different lengths, or a standard error that is not
        finite and positive (an estimate without an error cannot be weighted).
    """
    v = np.asarray(values, dtype=float)
    s = np.asarray(stderrs, dtype=float)
    if v.ndim != 1 or v.shape != s.shape or v.size < 2:
        raise ValueError(f"give two or more estimates with one standard error each, got {v.size} and {s.size}")
    if not (np.isfinite(v).all() and np.isfinite(s).all() and (s > 0).all()):
        raise ValueError("every estimate must be finite and every standard error finite and positive")
    w = 1.0 / s**2
    mean = float(np.sum(w * v) / np.sum(w))
    se = float(np.sum(w) ** -0.5)
    z = float(norm.ppf(0.5 + confidence / 2.0))
    q = float(np.sum(w * (v - mean) ** 2))
    dof = int(v.size - 1)
    return PooledEstimate(mean, se, mean - z * se, mean + z * se, q, dof, float(chi2.sf(q, dof)))


def _round4(x: float | None) -> float | None:
    return None if x is None else round(float(x), 4)


def _sig4(x: float | None) -> float | None:
    return None if x is None else float(f"{x:.4g}")
