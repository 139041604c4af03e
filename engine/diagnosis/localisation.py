"""Where the gap lies: the residual split by channel, wavelet band and time window.

The residual of every channel (record minus calibrated simulation, divided by
the channel's noise level so that channels are comparable) is split into its
wavelet multiresolution components (``pywt.mra``: periodization DWT of level
10 with the channel's wavelet of MODEL.md section 3; the components sum to the
residual and, the transform being orthogonal, the energies of the levels add
up to the residual's energy). Each component is then cut into time windows
relative to the event. A cell is one (channel, level, window).

For white noise of the estimated level sigma, the expected energy of a cell
(in units of sigma^2) is ``n_level / N * L_window``: the level holds
``n_level = N / 2**j`` of the ``N`` orthonormal coefficients, spread evenly
in time. The cell's *excess* is its energy minus that expectation (floored at
zero), and its *share* is its excess over the sum of all excesses.

Frequency band of detail level j for sample interval Ts:
``[1 / (2**(j+1) Ts), 1 / (2**j Ts)]`` Hz (level 1: 2500-5000 Hz at Ts = 0.1 ms;
level 10: 4.9-9.8 Hz); the approximation of level 10 covers ``[0, 1 / (2**11 Ts)]``.
The bands follow the record's own interval: on another grid the level is chosen
so that the bands in Hz stay near those of 0.1 ms
(:func:`engine.features.wavelet.level_for_interval`: level 12 at 25 us, 8 at
0.5 ms), and a cell's expected noise energy uses the actual number of
coefficients of its level.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np
import pywt

from engine.constants import CHANNEL_WAVELETS, WAVELET_LEVEL
from engine.features.wavelet import level_for_interval
from engine.records import Record

__all__ = ["DEFAULT_WINDOWS_MS", "Cell", "level_band", "localise", "residual_components"]

#: Time windows relative to the event [ms]: (name, start, end); the first one is
#: the pre-event part of the record (its start is clipped to the record).
DEFAULT_WINDOWS_MS: tuple[tuple[str, float, float], ...] = (
    ("pre-event", -1e9, 0.0),
    ("0-20 ms", 0.0, 20.0),
    ("20-50 ms", 20.0, 50.0),
    ("50-100 ms", 50.0, 100.0),
    ("100-200 ms", 100.0, 1e9),
)


@dataclass(frozen=True)
class Cell:
    """One cell of the residual map.

    Attributes
    ----------
    channel : str
        Channel name.
    level : str
        ``"D<j>"`` for detail level j or ``"A10"`` for the approximation.
    band_hz : tuple of float
        Frequency band of the level [Hz].
    window : str
        Name of the time window.
    window_ms : tuple of float
        Window start and end relative to the event [ms] (clipped to the record).
    energy : float
        Residual energy in the cell [noise variances, i.e. sum of (r / sigma)^2].
    noise_energy : float
        Energy that white noise of the estimated level would put there [noise variances].
    excess : float
        ``max(energy - noise_energy, 0)`` [noise variances].
    share : float
        Fraction of the total excess over all cells (0 when there is none).
    """

    channel: str
    level: str
    band_hz: tuple[float, float]
    window: str
    window_ms: tuple[float, float]
    energy: float
    noise_energy: float
    excess: float
    share: float

    def to_dict(self) -> dict:
        d = asdict(self)
        d["band_hz"] = list(self.band_hz)
        d["window_ms"] = list(self.window_ms)
        return d


def level_band(level: int, sample_interval: float, approximation: bool = False) -> tuple[float, float]:
    """Frequency band [Hz] of a wavelet level for sample interval Ts [s].

    Detail level j covers ``[fs / 2**(j+1), fs / 2**j]`` and the approximation of
    level j covers ``[0, fs / 2**(j+1)]``, with ``fs = 1 / Ts``.
    """
    fs = 1.0 / sample_interval
    if approximation:
        return (0.0, fs / 2 ** (level + 1))
    return (fs / 2 ** (level + 1), fs / 2**level)


def residual_components(x: np.ndarray, wavelet: str, level: int = WAVELET_LEVEL) -> list[np.ndarray]:
    """Multiresolution components ``[A_level, D_level, ..., D1]`` of a signal (they sum to it).

    Periodization DWT; PyWavelets' warning that level 10 exceeds its
    recommended maximum for 2048 samples is silenced on purpose (the paper's
    level; the periodized transform stays orthogonal).
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"Level value of \d+ is too high", category=UserWarning)
        return pywt.mra(np.array(x, dtype=float), wavelet, level=level, transform="dwt", mode="periodization")


def localise(
    record: Record,
    simulation: Record | Mapping[str, np.ndarray],
    sigma: Mapping[str, float],
    windows_ms: Sequence[tuple[str, float, float]] = DEFAULT_WINDOWS_MS,
    level: int | None = None,
) -> list[Cell]:
    """Split the residual record - simulation into cells, sorted by excess energy.

    Parameters
    ----------
    record : Record
        The measured record.
    simulation : Record or mapping of str to ndarray
        The calibrated simulation (at least the record's channels).
    sigma : mapping of str to float
        Noise standard deviation per channel (channel unit).
    windows_ms : sequence of (name, start, end)
        Time windows relative to the event [ms].
    level : int, optional
        Wavelet decomposition level; default from the record's interval and length
        (:func:`~engine.features.wavelet.level_for_interval`: 10 at 0.1 ms).

    Returns
    -------
    list of Cell
        Every (channel, level, window) cell, largest excess first.
    """
    sim = simulation.channels if isinstance(simulation, Record) else simulation
    t_ms = record.time * 1e3
    n = t_ms.size
    if level is None:
        level = level_for_interval(record.sample_interval, n)
    win_masks = []
    for name, lo, hi in windows_ms:
        mask = (t_ms >= lo) & (t_ms < hi)
        if mask.any():
            win_masks.append(
                (name, mask, (float(max(lo, t_ms[0])), float(min(hi, t_ms[-1] + record.sample_interval * 1e3))))
            )
    cells: list[Cell] = []
    for ch, x in record.channels.items():
        r = (np.asarray(x) - np.asarray(sim[ch])) / float(sigma[ch])
        comps = residual_components(r, CHANNEL_WAVELETS[ch], level)
        for idx, comp in enumerate(comps):
            if idx == 0:
                lname, band, n_level = f"A{level}", level_band(level, record.sample_interval, True), n / 2**level
            else:
                j = level - idx + 1
                lname, band, n_level = f"D{j}", level_band(j, record.sample_interval), n / 2**j
            for wname, mask, wms in win_masks:
                e = float(np.sum(comp[mask] ** 2))
                e0 = n_level / n * float(mask.sum())
                cells.append(Cell(ch, lname, band, wname, wms, e, e0, max(e - e0, 0.0), 0.0))
    total = sum(c.excess for c in cells)
    if total > 0:
        cells = [Cell(**{**asdict(c), "share": c.excess / total}) for c in cells]
    cells.sort(key=lambda c: (-c.excess, -c.energy))
    return cells
