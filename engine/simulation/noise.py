"""Measurement noise at a given signal-to-noise ratio: white, or coloured by a data-acquisition low-pass.

White noise is Gaussian with the standard deviation of :func:`noise_std`. Coloured noise
(:func:`coloured_noise`, :func:`add_noise` with ``lowpass_hz``) is white Gaussian noise through
a digital Butterworth low-pass of order 1 or 2 (``scipy.signal.butter``, second-order sections),
the model of a data-acquisition chain that low-passes its noise: the filter runs
:data:`WARM_UP_TIME_CONSTANTS` time constants before the record's first sample, so the noise is
stationary from the start, and the result is scaled by the filter's noise gain, so that its
standard deviation is the one asked for whatever the cut-off. Everything is drawn from the
caller's ``numpy.random.Generator``: the same seed gives the same noise.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from engine.constants import SAMPLE_INTERVAL

__all__ = ["LOWPASS_ORDERS", "WARM_UP_TIME_CONSTANTS", "add_noise", "add_white_noise", "coloured_noise", "noise_std"]

#: Samples filtered before the record starts, in time constants 1 / (2 pi f_c) of the low-pass
#: (the transient from rest has then decayed below 1e-10 of its start).
WARM_UP_TIME_CONSTANTS: float = 25.0
#: Orders of the low-pass that colours the noise.
LOWPASS_ORDERS: tuple[int, ...] = (1, 2)


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


@functools.lru_cache(maxsize=64)
def _lowpass(order: int, lowpass_hz: float, sample_interval: float) -> tuple[np.ndarray, float, int]:
    """Second-order sections of the low-pass, its noise gain (sum of h^2) and its warm-up [samples]."""
    fs = 1.0 / sample_interval
    if order not in LOWPASS_ORDERS:
        raise ValueError(f"order of the noise low-pass must be one of {LOWPASS_ORDERS}, got {order}")
    if not (math.isfinite(lowpass_hz) and 0.0 < lowpass_hz < fs / 2.0):
        raise ValueError(f"lowpass_hz must lie between 0 and the Nyquist frequency {fs / 2:g} Hz, got {lowpass_hz}")
    from scipy import signal  # here, not at the top: scipy.signal adds 1-2 s to every process start

    sos = signal.butter(order, lowpass_hz, btype="low", fs=fs, output="sos")
    warm_up = math.ceil(WARM_UP_TIME_CONSTANTS * fs / (2.0 * math.pi * lowpass_hz)) + 16
    impulse = np.zeros(4 * warm_up)
    impulse[0] = 1.0
    gain = float(np.sum(signal.sosfilt(sos, impulse) ** 2))
    return sos, gain, warm_up


def coloured_noise(
    shape: tuple[int, ...],
    rng: np.random.Generator,
    lowpass_hz: float | None = None,
    order: int = 1,
    sample_interval: float = SAMPLE_INTERVAL,
) -> np.ndarray:
    """Stationary Gaussian noise of unit standard deviation, white or low-passed along the last axis.

    Parameters
    ----------
    shape : tuple of int
        Shape of the noise; the last axis is time.
    rng : numpy.random.Generator
        Source of the draws.
    lowpass_hz : float or None
        Cut-off (-3 dB) of the Butterworth low-pass [Hz], between 0 and fs / 2; None for white noise.
    order : int
        Order of the low-pass, 1 or 2.
    sample_interval : float
        Ts [s] of the samples.

    Returns
    -------
    ndarray
        Noise of unit variance (in expectation) at every sample [-].

    Raises
    ------
    ValueError
        For an order other than 1 or 2, or a cut-off outside (0, fs / 2).
    """
    if lowpass_hz is None:
        return rng.standard_normal(shape)
    sos, gain, warm_up = _lowpass(int(order), float(lowpass_hz), float(sample_interval))
    w = rng.standard_normal((*shape[:-1], shape[-1] + warm_up))
    from scipy.signal import sosfilt

    return sosfilt(sos, w, axis=-1)[..., warm_up:] / math.sqrt(gain)


def add_noise(
    x: np.ndarray,
    snr_db: float | np.ndarray,
    rng: np.random.Generator,
    lowpass_hz: float | None = None,
    order: int = 1,
    sample_interval: float = SAMPLE_INTERVAL,
) -> np.ndarray:
    """``x`` plus Gaussian noise at ``snr_db`` per record, white or coloured by a low-pass.

    Parameters
    ----------
    x : ndarray, shape (..., n_samples)
        Records (e.g. the channels of one case, shape (n_ch, n)); time is the last axis.
    snr_db : float or array-like
        Signal-to-noise ratio [dB] (see :func:`noise_std`), one value for all records or one
        per record (broadcast against ``x.shape[:-1]``, e.g. one per channel).
    rng : numpy.random.Generator
        Source of the draws (same seed, same noise).
    lowpass_hz : float or None
        Cut-off of the Butterworth low-pass that colours the noise [Hz]; None for white noise.
        The noise's standard deviation is the SNR's whatever the cut-off.
    order : int
        Order of the low-pass, 1 or 2.
    sample_interval : float
        Ts [s] of the records.

    Returns
    -------
    ndarray
        A noisy copy of ``x`` (``x`` is not modified), in its unit.
    """
    x = np.asarray(x, dtype=float)
    snr = np.broadcast_to(np.asarray(snr_db, dtype=float), x.shape[:-1])
    if not np.all(np.isfinite(snr)):
        raise ValueError(f"snr_db must be finite, got {snr_db}")
    sd = np.sqrt(np.var(x, axis=-1) / 10.0 ** (snr / 10.0))
    return x + coloured_noise(x.shape, rng, lowpass_hz, order, sample_interval) * sd[..., None]
