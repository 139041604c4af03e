"""White measurement noise at a given signal-to-noise ratio."""

from __future__ import annotations

import numpy as np


def noise_std(x: np.ndarray, snr_db: float, axis: int = -1) -> np.ndarray:
    """Noise standard deviation giving ``snr_db`` on each record of ``x``.

    SNR is taken against the record's *variance* (its power about the mean), not
    its mean square: a channel with a large offset (omega1) is not made to look
    cleaner than it is. Units are the channel's.
    """
    if not np.isfinite(snr_db):
        raise ValueError(f"snr_db must be finite, got {snr_db}")
    return np.sqrt(np.var(x, axis=axis, keepdims=True) / 10.0 ** (snr_db / 10.0))


def add_white_noise(x: np.ndarray, snr_db: float, rng: np.random.Generator, axis: int = -1) -> np.ndarray:
    """``x`` plus Gaussian white noise at ``snr_db`` (see :func:`noise_std`); ``x`` is not modified."""
    x = np.asarray(x, dtype=float)
    return x + rng.standard_normal(x.shape) * noise_std(x, snr_db, axis)
