"""How large the sim-to-real gap left by a fit is, and how much a fit shrinks it.

A calibration that fits to the noise leaves a residual energy chi2 of about
n (the number of residuals, in noise variances); anything beyond is the gap.
:func:`gap_of` measures it in total and per channel, :func:`shrinkage_ratio`
compares the gap of two fits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from engine.diagnosis.calibration import CalibrationResult

__all__ = ["Gap", "closed_fraction", "gap_of", "shrinkage_ratio"]


@dataclass(frozen=True)
class Gap:
    """Size of the sim-to-real gap left by a fitted model.

    Attributes
    ----------
    rms_over_noise : float
        Residual RMS divided by the noise level (1 when the model fits to the noise) [-].
    excess_energy : float
        Residual energy beyond the noise, ``max(chi2 - n, 0)`` [noise variances].
    excess_fraction : float
        ``excess_energy`` over the residual energy expected from noise alone, n
        (0 when the model fits to the noise) [-].
    per_channel : dict
        The same three numbers per channel.
    """

    rms_over_noise: float
    excess_energy: float
    excess_fraction: float
    per_channel: dict[str, dict[str, float]]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {
            "rms_over_noise": self.rms_over_noise,
            "excess_energy": self.excess_energy,
            "excess_fraction": self.excess_fraction,
            "per_channel": {k: dict(v) for k, v in self.per_channel.items()},
        }


def gap_of(cal: CalibrationResult) -> Gap:
    """The gap a calibration leaves, total and per channel.

    Parameters
    ----------
    cal : CalibrationResult
        The fit.

    Returns
    -------
    Gap
    """
    n_ch = len(cal.chi2_per_channel)
    n_per = cal.n_data // max(n_ch, 1)
    per = {}
    for ch, c2 in cal.chi2_per_channel.items():
        per[ch] = {
            "rms_over_noise": math.sqrt(c2 / n_per),
            "excess_energy": max(c2 - n_per, 0.0),
            "excess_fraction": max(c2 - n_per, 0.0) / n_per,
        }
    ex = max(cal.chi2 - cal.n_data, 0.0)
    return Gap(math.sqrt(cal.chi2 / cal.n_data), ex, ex / cal.n_data, per)


def shrinkage_ratio(before: CalibrationResult, after: CalibrationResult) -> float:
    """How many times the gap shrinks: excess energy before over excess energy after.

    Both excesses (``chi2 - n``, in noise variances) are floored at their
    resolution, ``3 sqrt(2 n)`` (three standard deviations of a chi-square of
    n degrees of freedom), so a fit to the noise gives a large but finite
    ratio, and a gap below the resolution gives 1.

    Parameters
    ----------
    before, after : CalibrationResult
        The fits compared (e.g. the nominal calibration and a candidate's).

    Returns
    -------
    float
        The ratio [-].
    """
    floor = 3.0 * math.sqrt(2.0 * after.n_data)
    ex_before = max(before.chi2 - before.n_data, floor)
    ex_after = max(after.chi2 - after.n_data, floor)
    return ex_before / ex_after


def closed_fraction(before: CalibrationResult, after: CalibrationResult) -> float:
    """Fraction of ``before``'s excess residual energy (``chi2 - n``) that ``after`` removes, in [0, 1].

    Parameters
    ----------
    before, after : CalibrationResult
        The fits compared (e.g. the nominal calibration and a candidate's).

    Returns
    -------
    float
        ``(E_before - E_after) / E_before`` with ``E = max(chi2 - n, 0)``, clipped to [0, 1]
        (0 when ``before`` leaves no excess) [-].
    """
    e0 = max(before.chi2 - before.n_data, 0.0)
    if e0 <= 0.0:
        return 0.0
    e1 = max(after.chi2 - after.n_data, 0.0)
    return min(max((e0 - e1) / e0, 0.0), 1.0)
