"""The white-noise level of a record's channels, and how white a residual is.

The calibration normalises every channel's residual by the channel's noise
standard deviation, estimated from the record itself (:func:`estimate_noise`)
and floored by :func:`noise_weights` so that noiseless (simulated) records do
not get infinite weights. :func:`lowfreq_ratio` tells a white residual (a fit
to the noise) from a structured, mostly low-frequency one, whatever the noise
estimate's error.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping

import numpy as np
import pywt

from engine.constants import CHANNEL_WAVELETS
from engine.records import Record

__all__ = ["NOISE_FLOOR_REL", "estimate_noise", "lowfreq_ratio", "noise_weights"]

#: Relative floor of the noise level used as a weight, as a fraction of the channel's RMS
#: (60 dB SNR); keeps noiseless (simulated) records from giving infinite weights.
NOISE_FLOOR_REL: float = 1e-3

#: Clipping of the noise estimate [sigma] and the variance of a unit normal truncated there.
_CLIP = 4.0
_CLIP_VARIANCE = 1.0 - 2.0 * _CLIP * math.exp(-(_CLIP**2) / 2.0) / math.sqrt(2.0 * math.pi) / math.erf(
    _CLIP / math.sqrt(2.0)
)
#: Median absolute deviation of a unit normal (Donoho & Johnstone's 0.6745).
_MAD_NORMAL = 0.6744897501960817


def estimate_noise(record: Record) -> dict[str, float]:
    """White-noise standard deviation of every channel of a record.

    Uses the finest detail level (cD1, 1024 coefficients) of the channel's own
    wavelet (MODEL.md section 3, periodization DWT). A first, robust estimate
    is the median absolute deviation, ``sigma0 = median(|cD1|) / 0.6745``
    (Donoho & Johnstone); the result is the RMS of the coefficients within
    ``4 sigma0`` (corrected for the truncation), which keeps the median's
    immunity to the few coefficients at impacts and at the event's torque step
    but has about 1.6 times less scatter (relative standard error about 2.2 %
    instead of 3.6 % for 1024 coefficients). With 5-6 vanishing moments the
    smooth part of the record hardly reaches the finest level.

    Parameters
    ----------
    record : Record
        Any subset of channels.

    Returns
    -------
    dict of str to float
        Noise standard deviation per channel, in the channel's unit.
    """
    out: dict[str, float] = {}
    for name, x in record.channels.items():
        _, cd1 = pywt.dwt(np.array(x, dtype=float), CHANNEL_WAVELETS[name], mode="periodization")
        s0 = float(np.median(np.abs(cd1)) / _MAD_NORMAL)
        if s0 > 0:
            kept = cd1[np.abs(cd1) <= _CLIP * s0]
            s0 = float(np.sqrt(np.mean(kept**2) / _CLIP_VARIANCE)) if kept.size else s0
        out[name] = s0
    return out


def noise_weights(record: Record, noise: Mapping[str, float]) -> dict[str, float]:
    """Standard deviation used to normalise each channel's residual.

    Parameters
    ----------
    record : Record
        The record (any subset of channels).
    noise : mapping of str to float
        Noise standard deviation per channel, in the channel's unit.

    Returns
    -------
    dict of str to float
        ``max(noise, NOISE_FLOOR_REL * rms(channel))`` per channel, in the channel's unit.
    """
    out = {}
    for name, x in record.channels.items():
        rms = float(np.sqrt(np.mean(np.square(x))))
        floor = NOISE_FLOOR_REL * rms if rms > 0 else 1e-12
        out[name] = max(float(noise[name]), floor, 1e-12)
    return out


def lowfreq_ratio(r: np.ndarray, wavelet: str, level: int = 10) -> float:
    """Mean squared wavelet coefficient of a residual at low over high frequencies.

    Parameters
    ----------
    r : ndarray
        A (noise-normalised) residual, one channel.
    wavelet : str
        Wavelet of the periodization DWT.
    level : int
        Decomposition level.

    Returns
    -------
    float
        Mean squared coefficient of levels D4..D<level> and A<level> over that of
        D1 and D2 [-]: about 1 for a white residual, larger for a structured one.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"Level value of \d+ is too high", category=UserWarning)
        coeffs = pywt.wavedec(np.array(r, dtype=float), wavelet, mode="periodization", level=level)
    low = np.concatenate(coeffs[: level - 2])
    high = np.concatenate(coeffs[-2:])
    return float(np.mean(low**2) / max(np.mean(high**2), 1e-300))
