"""Backlash-width history of a drive: the wear trend and when the width passes a limit.

* :mod:`~engine.history.trend`: :func:`fit_trend` (weighted straight line, Birge-scaled
  covariance, Student t, Fieller interval of the crossing date) and its data types;
* :mod:`~engine.history.plots`: :func:`plot_history`, the history and its trend as a PNG.

The method, its assumptions and a worked example: docs/trend.md.
"""

from engine.history.trend import (
    DEFAULT_CONFIDENCE,
    EXTRAPOLATION_WARNING,
    MIN_DATES,
    MIN_SPAN_DAYS,
    Trend,
    TrendError,
    WidthPoint,
    fit_trend,
)

__all__ = [
    "DEFAULT_CONFIDENCE",
    "EXTRAPOLATION_WARNING",
    "MIN_DATES",
    "MIN_SPAN_DAYS",
    "Trend",
    "TrendError",
    "WidthPoint",
    "fit_trend",
]
