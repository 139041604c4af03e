"""Wavelet features of backlash-test records (paper section 3).

The paper decomposes every recorded channel with a discrete wavelet transform
of level 10 (sym5 for a1, omega1, v2; db6 for m_el, a2) and feeds the
coefficients of one record, 2048 numbers, to the identifier's network (its
matrix ``N[7, 2048]``). This module produces exactly that vector.

Layout
------
For a record of ``n = 2048`` samples and ``level = 10`` the output is the
PyWavelets ``wavedec`` list concatenated along the transformed axis::

    [cA10 (2), cD10 (2), cD9 (4), cD8 (8), ..., cD2 (512), cD1 (1024)]

i.e. coarsest first. :func:`level_slices` gives the slice of each block and
the frequency band it covers for a sample interval Ts.

Why ``mode="periodization"``
----------------------------
The paper says nothing about signal extension, but its matrix ``N`` has 2048
columns for records of 2048 samples, so the transform it used kept the length.
Of the PyWavelets modes only ``periodization`` does that: every level halves
the length exactly (``n`` must be a multiple of ``2**level``), so 2048 samples
give 2048 coefficients. With an orthogonal wavelet (sym5, db6 both are) the
periodized transform is an orthogonal change of basis: energy is preserved
(Parseval, ``sum(x**2) == sum(c**2)``) and the inverse is exact. The other
modes add ``filter_length - 1`` boundary coefficients per level (2048 samples
would give over 2100 coefficients with sym5 at level 10) and are neither
length-preserving nor orthogonal. The price of periodization is that the end
of the record wraps onto its start; at level 10 the coarse filters are longer
than the coarse signals anyway (see below), so every coarse coefficient is a
"boundary" coefficient whichever mode is chosen.

Level 10 and PyWavelets' warning
--------------------------------
``pywt.dwt_max_level(2048, "sym5")`` is 7: beyond level 7 the (length 10 or
12) filters are longer than the signal they filter and PyWavelets warns that
"all coefficients will experience boundary effects". The paper asks for level
10, and with periodization the deeper levels are still well defined and
orthogonal (the filter simply wraps around the short periodic signal), so we
keep level 10 and silence exactly that one warning (see
:func:`_wavedecn_quiet`); every other warning still surfaces. Levels above
``log2(n)`` are impossible and raise :class:`ValueError`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pywt

from engine.constants import CHANNEL_WAVELETS, N_SAMPLES, SAMPLE_INTERVAL, WAVELET_LEVEL

__all__ = [
    "Band",
    "channel_features",
    "level_slices",
    "wavelet_coefficients",
    "wavelet_reconstruct",
]

#: Message of the PyWavelets warning we silence on purpose (level above dwt_max_level).
_LEVEL_WARNING = r"Level value of \d+ is too high"


@dataclass(frozen=True)
class Band:
    """One block of the coefficient layout.

    Attributes
    ----------
    name : str
        ``"cA<level>"`` for the approximation, ``"cD<j>"`` for detail level j.
    kind : {"approximation", "detail"}
        Which kind of coefficients the block holds.
    level : int
        Decomposition level j of the block (the approximation has ``level``).
    slice : slice
        Position of the block in the layout of :func:`wavelet_coefficients`.
    f_low, f_high : float
        Nominal frequency band covered by the block [Hz].
    """

    name: str
    kind: Literal["approximation", "detail"]
    level: int
    slice: slice
    f_low: float
    f_high: float

    @property
    def size(self) -> int:
        """Number of coefficients in the block."""
        return self.slice.stop - self.slice.start


def _check_level(n: int, level: int) -> None:
    if not isinstance(level, (int, np.integer)) or isinstance(level, bool) or level < 1:
        raise ValueError(f"level must be a positive integer, got {level!r}")
    if n < 2 or level > int(math.log2(n)):
        raise ValueError(f"level {level} is impossible for {n} samples: at most floor(log2(n))")
    if n % (2**level) != 0:
        raise ValueError(
            f"records of {n} samples cannot be decomposed to level {level} without changing length: "
            f"the length must be a multiple of 2**level = {2**level}"
        )


def _normalise_axis(axis: int, ndim: int) -> int:
    if not -ndim <= axis < ndim:
        raise ValueError(f"axis {axis} is out of range for a {ndim}-D array")
    return axis % ndim


def _wavedecn_quiet(x: np.ndarray, wavelet: pywt.Wavelet, mode: str, level: int, axis: int) -> list:
    """``pywt.wavedecn`` along one axis, without the 'level too high' warning.

    The paper's level 10 exceeds ``pywt.dwt_max_level`` for 2048 samples (7 for
    sym5/db6). That is a deliberate choice of the method, not an accident of
    the caller, so only this one warning is suppressed; anything else PyWavelets
    says is passed on.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_LEVEL_WARNING, category=UserWarning)
        return pywt.wavedecn(x, wavelet, mode=mode, level=level, axes=(axis,))


def _as_wavelet(wavelet: str | pywt.Wavelet) -> pywt.Wavelet:
    try:
        w = wavelet if isinstance(wavelet, pywt.Wavelet) else pywt.Wavelet(wavelet)
    except ValueError as exc:
        raise ValueError(
            f"unknown wavelet {wavelet!r}; use a PyWavelets discrete wavelet name such as 'sym5' or 'db6'"
        ) from exc
    return w


def wavelet_coefficients(
    x: np.ndarray,
    wavelet: str | pywt.Wavelet,
    mode: str = "periodization",
    level: int = WAVELET_LEVEL,
    axis: int = -1,
) -> np.ndarray:
    """Multilevel DWT of one or many records, as one coefficient vector per record.

    Parameters
    ----------
    x : array_like, shape (n,) or (n_records, n)
        Time-domain samples (any unit; the coefficients carry the same unit).
        The length ``n`` along ``axis`` must be a multiple of ``2**level``.
    wavelet : str or pywt.Wavelet
        Discrete wavelet, e.g. ``"sym5"`` or ``"db6"``.
    mode : str, default "periodization"
        PyWavelets signal-extension mode. Only ``"periodization"`` maps ``n``
        samples onto ``n`` coefficients and is orthogonal (see module notes);
        other modes give a longer vector.
    level : int, default 10
        Decomposition level.
    axis : int, default -1
        Axis holding the samples.

    Returns
    -------
    ndarray
        Coefficients laid out as ``[cA_level, cD_level, ..., cD1]`` along
        ``axis``; the other axes are unchanged.

    Raises
    ------
    ValueError
        Non-finite samples, wrong dimensionality, impossible level or a length
        that is not a multiple of ``2**level``.
    """
    arr = np.asarray(x, dtype=float)
    if arr.ndim not in (1, 2):
        raise ValueError(f"expected one record (n,) or a batch (n_records, n), got an array of shape {arr.shape}")
    axis = _normalise_axis(axis, arr.ndim)
    n = arr.shape[axis]
    _check_level(n, level)
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"samples must be finite; found NaN or inf at index {tuple(int(i) for i in bad)}")
    coeffs = _wavedecn_quiet(arr, _as_wavelet(wavelet), mode, level, axis)
    out, _ = pywt.coeffs_to_array(coeffs, axes=(axis,))
    return out


def wavelet_reconstruct(
    c: np.ndarray,
    wavelet: str | pywt.Wavelet,
    mode: str = "periodization",
    level: int = WAVELET_LEVEL,
    axis: int = -1,
) -> np.ndarray:
    """Inverse of :func:`wavelet_coefficients` for ``mode="periodization"``.

    Parameters
    ----------
    c : array_like, shape (n,) or (n_records, n)
        Coefficients in the layout ``[cA_level, cD_level, ..., cD1]``.
    wavelet, mode, level, axis
        As used for the forward transform.

    Returns
    -------
    ndarray
        Time-domain samples, same shape as ``c``.
    """
    arr = np.asarray(c, dtype=float)
    if mode != "periodization":
        raise ValueError("wavelet_reconstruct supports only mode='periodization' (the only length-preserving layout)")
    if arr.ndim not in (1, 2):
        raise ValueError(f"expected shape (n,) or (n_records, n), got {arr.shape}")
    axis = _normalise_axis(axis, arr.ndim)
    n = arr.shape[axis]
    _check_level(n, level)
    template = _wavedecn_quiet(np.zeros(arr.shape), _as_wavelet(wavelet), mode, level, axis)
    _, slices = pywt.coeffs_to_array(template, axes=(axis,))
    coeffs = pywt.array_to_coeffs(arr, slices, output_format="wavedecn")
    return pywt.waverecn(coeffs, _as_wavelet(wavelet), mode=mode, axes=(axis,))


def channel_features(x: np.ndarray, channel: str, level: int = WAVELET_LEVEL) -> np.ndarray:
    """Coefficients of a channel with the paper's wavelet for that channel.

    Parameters
    ----------
    x : array_like, shape (2048,) or (n_records, 2048)
        Samples of ``channel`` in its unit (see ``engine.constants.CHANNEL_UNITS``).
    channel : str
        One of ``engine.constants.CHANNELS``.
    level : int, default 10
        Decomposition level (the paper's is 10).

    Returns
    -------
    ndarray
        Periodized DWT coefficients, layout of :func:`wavelet_coefficients`.
    """
    if channel not in CHANNEL_WAVELETS:
        raise ValueError(f"unknown channel {channel!r}; known channels: {', '.join(CHANNEL_WAVELETS)}")
    return wavelet_coefficients(x, CHANNEL_WAVELETS[channel], mode="periodization", level=level, axis=-1)


def level_slices(
    n: int = N_SAMPLES, level: int = WAVELET_LEVEL, sample_interval: float = SAMPLE_INTERVAL
) -> tuple[Band, ...]:
    """Blocks of the coefficient layout with their frequency bands.

    Parameters
    ----------
    n : int, default 2048
        Record length [samples]; a multiple of ``2**level``.
    level : int, default 10
        Decomposition level.
    sample_interval : float, default 1e-4
        Ts [s]; the sampling frequency is ``fs = 1 / Ts`` [Hz].

    Returns
    -------
    tuple of Band
        In layout order ``cA_level, cD_level, ..., cD1``. Detail level j covers
        ``[fs / 2**(j+1), fs / 2**j]`` Hz, the approximation
        ``[0, fs / 2**(level+1)]`` Hz (nominal, ideal-filter bands; real
        wavelet filters overlap their neighbours).
    """
    _check_level(int(n), level)
    if not (np.isfinite(sample_interval) and sample_interval > 0):
        raise ValueError(f"sample_interval must be a positive number of seconds, got {sample_interval}")
    fs = 1.0 / sample_interval
    size = n // 2**level
    bands = [Band(f"cA{level}", "approximation", level, slice(0, size), 0.0, fs / 2 ** (level + 1))]
    start = size
    for j in range(level, 0, -1):
        size = n // 2**j
        bands.append(Band(f"cD{j}", "detail", j, slice(start, start + size), fs / 2 ** (j + 1), fs / 2**j))
        start += size
    return tuple(bands)


def level_for_interval(sample_interval: float, n: int) -> int:
    """Decomposition level whose bands in Hz are nearest MODEL.md's level 10 at 0.1 ms, for another grid.

    The level grows by one for every halving of the interval (its coarsest band stays near
    0-2.4 Hz and the detail bands keep their frequencies), and is capped at ``log2(n)``.

    Parameters
    ----------
    sample_interval : float
        Ts [s].
    n : int
        Samples of the signal.

    Returns
    -------
    int
        At least 1.
    """
    level = WAVELET_LEVEL + round(math.log2(SAMPLE_INTERVAL / sample_interval))
    return max(1, min(level, int(math.log2(max(n, 2)))))
