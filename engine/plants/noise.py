"""What a plant's sensors add to a record: a channel's noise level, and the record's own estimate of it.

Every plant declares its noise model (:meth:`engine.plants.base.Plant.noise`): per channel, the
standard deviation of what the sensors add to the true signal and how long that noise stays
correlated. The gap diagnosis (:mod:`engine.diagnosis.plant_gap`) compares a fit's residual with
it: a residual at that level is noise (``no_gap``), one far above it a gap.

Two ways a plant obtains it:

- **From the record** (:func:`white_noise_level`): a channel whose noise is white and whose signal
  lies well below the Nyquist frequency holds only noise in its finest wavelet detail level D1.
  The level's robust standard deviation (:func:`robust_sigma`) is the noise's. This is the
  estimate the backlash drive's white-noise model starts from (:mod:`engine.diagnosis.noise`).
- **From the sensor chain** (e.g. an encoder's quantum through the channel's filter and
  differences): a channel whose processing removes the noise from D1 (a low-pass) needs the chain
  itself; the plant computes the chain's response to its sensors' known imperfection.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import pywt

__all__ = [
    "NOISE_FLOOR_REL",
    "NOISE_WAVELET",
    "SOKAL_WINDOW",
    "NoiseLevel",
    "finest_level_sigma",
    "integrated_time",
    "robust_sigma",
    "white_noise_level",
]

#: Clipping of the robust estimate [sigma] and the variance of a unit normal truncated there.
_CLIP = 4.0
_CLIP_VARIANCE = 1.0 - 2.0 * _CLIP * math.exp(-(_CLIP**2) / 2.0) / math.sqrt(2.0 * math.pi) / math.erf(
    _CLIP / math.sqrt(2.0)
)
#: Median absolute deviation of a unit normal (Donoho & Johnstone's 0.6745).
_MAD_NORMAL = 0.6744897501960817
#: Wavelet of the D1 estimate (Daubechies 4: short, so an edge in the signal touches few coefficients).
NOISE_WAVELET: str = "db4"
#: Smallest noise level of a channel, as a share of the channel's RMS (60 dB): a noiseless (simulated) channel
#: would otherwise weigh infinitely (every plant's, and the backlash drive's diagnosis, :mod:`engine.diagnosis.noise`).
NOISE_FLOOR_REL: float = 1e-3
#: Window constant of the integrated autocorrelation time (:func:`integrated_time`; Sokal's c, 5 for
#: a residual whose correlation decays roughly exponentially).
SOKAL_WINDOW: float = 5.0


@dataclass(frozen=True)
class NoiseLevel:
    """The noise of one channel.

    Parameters
    ----------
    sigma : float
        Standard deviation of the noise, in the channel's unit (> 0).
    tau : float
        Integrated autocorrelation time of the noise [samples] (1 for white noise): n samples carry
        about n / tau independent ones.
    source : str
        How it was obtained (reported with the answer).
    """

    sigma: float
    tau: float = 1.0
    source: str = "record"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.sigma) and self.sigma > 0.0):
            raise ValueError(f"noise level must be finite and positive, got {self.sigma!r}")
        if not (math.isfinite(self.tau) and self.tau >= 1.0):
            raise ValueError(f"noise correlation time must be >= 1 sample, got {self.tau!r}")


def robust_sigma(c: np.ndarray) -> float:
    """Robust standard deviation of zero-mean coefficients: the MAD, then the truncation-corrected
    RMS of those within 4 MADs (efficient on Gaussian noise, blind to a few large signal coefficients)."""
    c = np.asarray(c, dtype=float)
    s0 = float(np.median(np.abs(c)) / _MAD_NORMAL) if c.size else 0.0
    if s0 > 0:
        kept = c[np.abs(c) <= _CLIP * s0]
        s0 = float(np.sqrt(np.mean(kept**2) / _CLIP_VARIANCE)) if kept.size else s0
    return s0


def finest_level_sigma(y: np.ndarray) -> float:
    """Robust standard deviation of the finest wavelet detail level D1 of ``y`` (periodization
    :data:`NOISE_WAVELET`; orthonormal, so white noise of standard deviation s gives s there)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        # a copy: pywt refuses read-only buffers (a record's channels are frozen)
        d1 = pywt.wavedec(np.array(y, dtype=float), NOISE_WAVELET, mode="periodization", level=1)[1]
    return robust_sigma(d1)


def white_noise_level(y: np.ndarray, floor_rel: float = NOISE_FLOOR_REL) -> NoiseLevel:
    """The white noise of a channel, from its finest wavelet detail level (module docstring).

    Parameters
    ----------
    y : ndarray
        The channel's samples (at least 16).
    floor_rel : float
        Smallest level returned, as a share of the channel's RMS (:data:`NOISE_FLOOR_REL`).

    Raises
    ------
    ValueError
        For fewer than 16 samples, a non-finite sample or a channel that is zero throughout.
    """
    y = np.asarray(y, dtype=float)
    if y.size < 16:
        raise ValueError(f"a noise estimate needs at least 16 samples, got {y.size}")
    if not np.all(np.isfinite(y)):
        raise ValueError("a noise estimate needs finite samples")
    rms = float(np.sqrt(np.mean(y**2)))
    if rms == 0.0:
        raise ValueError("a channel that is zero throughout has no noise level")
    sigma = finest_level_sigma(y)
    floor = floor_rel * rms
    if sigma < floor:
        return NoiseLevel(floor, 1.0, "floor")
    return NoiseLevel(sigma, 1.0, "record")


def integrated_time(x: np.ndarray, c: float = SOKAL_WINDOW) -> float:
    """Integrated autocorrelation time of a residual, in samples (1 for white noise).

    ``tau = 1 + 2 sum_{k=1}^{M} rho_k``, with rho the sample autocorrelation (scipy's FFT
    correlation of the mean-removed signal) and M the smallest lag with ``M >= c tau(M)``
    (Sokal's automatic window; A. Sokal, "Monte Carlo methods in statistical mechanics", 1997,
    section 3). Never below 1.
    """
    x = np.asarray(x, dtype=float) - float(np.mean(x))
    n = x.size
    if n < 4 or not np.any(x):
        return 1.0
    from scipy.signal import correlate  # here, not at the top: scipy.signal adds 1-2 s to every process start

    acf = correlate(x, x, mode="full", method="fft")[n - 1 :]
    rho = acf / acf[0]
    taus = 1.0 + 2.0 * np.cumsum(rho[1:])
    ok = np.flatnonzero(np.arange(1, n) >= c * taus)
    tau = float(taus[ok[0]]) if ok.size else float(taus[-1])
    return max(tau, 1.0)
