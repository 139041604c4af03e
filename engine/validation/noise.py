"""Measurement noise of the validation's records: what is drawn per case, and its rendering per channel.

White, or coloured: white Gaussian noise through a Butterworth low-pass of order 1 or 2,
stationary from the record's first sample and of the standard deviation asked for
(:func:`engine.simulation.noise.coloured_noise`). The diagnosis assumes white noise (it
estimates the noise from the finest wavelet detail), so coloured noise is part of the
open world the validation tests.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.simulation.noise import coloured_noise

__all__ = ["NoiseSpec", "render_noise"]


@dataclass(frozen=True)
class NoiseSpec:
    """How a record's noise is made.

    Attributes
    ----------
    snr_db : dict of str to float
        Signal-to-noise ratio per recorded channel [dB] (noise standard deviation = channel
        standard deviation * 10^(-SNR/20), :func:`engine.simulation.noise.noise_std`).
    order : int
        0 for white noise, else the order of the Butterworth low-pass that colours it.
    cutoff_hz : float or None
        The low-pass's -3 dB cut-off [Hz] (None for white noise).
    """

    snr_db: dict[str, float]
    order: int = 0
    cutoff_hz: float | None = None

    @property
    def colour(self) -> str:
        """``white`` or ``coloured``."""
        return "white" if self.order == 0 else "coloured"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {
            "colour": self.colour,
            "order": self.order,
            "cutoff_hz": self.cutoff_hz,
            "snr_db": {k: round(v, 3) for k, v in self.snr_db.items()},
        }

    def text(self) -> str:
        """E.g. ``coloured (2nd-order, 1200 Hz), 31-39 dB``."""
        lo, hi = min(self.snr_db.values()), max(self.snr_db.values())
        what = "white" if self.order == 0 else f"coloured (order {self.order}, {self.cutoff_hz:.0f} Hz)"
        return f"{what}, {lo:.0f}-{hi:.0f} dB"


def render_noise(
    shape: tuple[int, int], std: np.ndarray, spec: NoiseSpec, sample_interval: float, rng: np.random.Generator
) -> np.ndarray:
    """Noise for a record's channels (:func:`engine.simulation.noise.coloured_noise` scaled per channel).

    Parameters
    ----------
    shape : (n_channels, n_samples)
        Shape of the channels.
    std : ndarray, shape (n_channels,)
        Standard deviation of each channel's noise, in its unit.
    spec : NoiseSpec
        White or coloured (order and cut-off).
    sample_interval : float
        Ts [s].
    rng : numpy.random.Generator
        Source of the white noise.

    Returns
    -------
    ndarray, shape ``shape``
        The noise, stationary, of standard deviation ``std`` per channel (in expectation).
    """
    n_ch, _ = shape
    std = np.asarray(std, dtype=float).reshape(n_ch, 1)
    if spec.order == 0:
        return coloured_noise(shape, rng, None, sample_interval=sample_interval) * std
    if spec.cutoff_hz is None:
        raise ValueError("coloured noise needs a cut-off")
    return coloured_noise(shape, rng, spec.cutoff_hz, spec.order, sample_interval) * std
