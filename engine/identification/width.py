"""The calibrated K as a continuous backlash-width identifier.

The other identifiers of :mod:`engine.identification` pick one of the paper's
six widths from trained patterns. :func:`estimate_width` instead fits the
plant to the record (the gap diagnosis's calibration,
:func:`engine.diagnosis.calibration.calibrate`) with K free and the record's
other conditions known, and reports the calibrated K with its one-sigma
uncertainty; :func:`nearest_grid_width` gives the paper's width class it falls
in. It needs no training, works on any subset of channels (a single channel
included), and costs a calibration (hundreds of simulations) per record.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from engine.constants import K_GRID
from engine.diagnosis.calibration import CalibrationResult, CalibrationSettings, calibrate
from engine.records import Record

__all__ = ["WIDTH_SETTINGS", "WidthEstimate", "estimate_width", "nearest_grid_width"]

#: Search settings of the continuous width estimate (two or three free parameters): the ones
#: README's "calibrated K as a continuous width" table was measured with (with the optimiser's
#: difference step of that time, 2e-3; the diagnosis's default is smaller since 2026-11-24).
WIDTH_SETTINGS = CalibrationSettings(n_global=128, n_starts=2, fd_step=2e-3)


@dataclass(frozen=True)
class WidthEstimate:
    """The calibrated K offered as a continuous backlash-width estimate.

    Attributes
    ----------
    K : float
        Estimated backlash zone width [m].
    sigma_K : float
        One standard deviation of K [m] (Gauss-Newton, measurement noise only;
        too small on a1 under noise, see docs/diagnosis.md section 8).
    calibration : CalibrationResult
        The fit behind it (every fitted parameter, chi2, noise).
    """

    K: float
    sigma_K: float
    calibration: CalibrationResult = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the calibration without arrays)."""
        return {"K": self.K, "sigma_K": self.sigma_K, "calibration": self.calibration.to_dict()}


def estimate_width(record: Record, settings: CalibrationSettings = WIDTH_SETTINGS) -> WidthEstimate:
    """Continuous backlash-width estimate: the calibrated K and its one-sigma uncertainty.

    The record's other conditions (J1, c, c1) are used as known; a ``K``
    condition is ignored (K is what is estimated). Works on any subset of
    channels, a single channel included.

    Parameters
    ----------
    record : Record
        The measured record, on any grid (its test window is fitted on its own instants; a
        located event's instant is fitted too).
    settings : CalibrationSettings
        Search settings (default :data:`WIDTH_SETTINGS`).

    Returns
    -------
    WidthEstimate

    Raises
    ------
    engine.diagnosis.calibration.CalibrationError
        When the record cannot be fitted.
    """
    if "K" in record.conditions:
        record = record.replace(conditions={k: v for k, v in record.conditions.items() if k != "K"})
    cal = calibrate(record, settings=settings)
    return WidthEstimate(cal.values["K"], cal.uncertainties["K"], cal)


def nearest_grid_width(K: float) -> float:
    """The paper's width nearest to ``K`` [m] (the class a continuous width belongs to), in m."""
    return float(min(K_GRID, key=lambda w: abs(w - K)))
