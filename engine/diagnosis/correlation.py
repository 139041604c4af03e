"""How correlated a calibration's residual is: its integrated autocorrelation time, in samples.

A residual that is noise is white once the noise model has whitened it (correlation time about
1); a residual that is model error is correlated in time, and ``n`` samples then carry about
``n / tau`` independent ones. Both the diagnosis answer's width (:mod:`engine.diagnosis.width`) and
the continuous width of identification (:mod:`engine.identification.width`) scale their
uncertainty by it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from engine.diagnosis.noise import NoiseModel
from engine.diagnosis.plant_gap import correlation_time
from engine.records import Record

if TYPE_CHECKING:  # pragma: no cover
    from engine.diagnosis.calibration import CalibrationResult

__all__ = ["residual_correlation_time"]


def residual_correlation_time(record: Record, calibration: CalibrationResult) -> float:
    """Integrated autocorrelation time [samples] of the calibration's whitened residual.

    Per channel, the residual record - simulation is whitened by the calibration's noise model (in
    time for white noise; per wavelet level for coloured noise, each level's coefficients in time
    order); :func:`engine.diagnosis.plant_gap.correlation_time` averages the sequences' times
    weighted by their squared norms (the sequences that carry the misfit count most). Never below
    1; about 1 for a fit to the noise.

    Parameters
    ----------
    record : Record
        The record calibrated on (its test window, the grid of ``calibration``).
    calibration : CalibrationResult
        A fit holding its simulation on that grid.
    """
    sim = calibration.simulated_record(record)
    noise = NoiseModel.of(calibration.sigma)
    pieces: list[np.ndarray] = []
    for name, x in record.channels.items():
        ch = noise.channel(name)
        z = ch.normalise(np.asarray(x, dtype=float) - np.asarray(sim.channels[name], dtype=float))
        if ch.white:
            pieces.append(z)
            continue
        sizes = [s for s, u in zip(ch.sizes(len(x))[::-1], ch.used[::-1], strict=True) if u]  # A_L, D_L, ..., D1
        pieces += [p for p in np.split(z, np.cumsum(sizes)[:-1]) if p.size >= 4]
    return max(1.0, correlation_time(pieces))
