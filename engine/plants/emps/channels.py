"""The measured channels of an EMPS record, obtained as the benchmark's authors obtain them.

``Simulation_EMPS.m`` of the benchmark: the position ``qm`` is low-passed by a 4th-order
Butterworth filter with cut-off 100 Hz (``butter(4, 100/500)``) applied forward and backward
(``filtfilt``: zero phase), then differenced twice by central differences (``diffcent.m``:
``[y2 - y1, (y3 - y1)/2, ..., yn - yn-1] / Ts``) to give velocity and acceleration; the force is
``gtau * vir``. We do exactly that with scipy's ``butter`` and ``filtfilt``, with MATLAB's padding:
both extend the signal by its odd reflection and start the filter at its steady state
(``lfilter_zi``), but MATLAB pads ``3 * (max(len(a), len(b)) - 1)`` = 12 samples where scipy's
default is 15, so the pad length is given explicitly.
"""

from __future__ import annotations

import numpy as np

from engine.plants.emps.record import EmpsRecord

__all__ = ["BUTTER_CUTOFF", "BUTTER_ORDER", "N_BORDER", "diffcent", "measured_channels", "process"]

#: Cut-off of the zero-phase position filter [Hz] (``freq_fil = 5*20.0`` in the authors' script).
BUTTER_CUTOFF: float = 100.0
#: Order of the Butterworth filter.
BUTTER_ORDER: int = 4
#: Samples dropped at the start of every comparison (the authors' ``n_border = 50``, keeping
#: samples 50..N in MATLAB's 1-based indexing, i.e. from index 49).
N_BORDER: int = 50


def diffcent(y: np.ndarray, ts: float) -> np.ndarray:
    """Central-difference derivative with one-sided ends (the authors' ``diffcent.m``).

    Parameters
    ----------
    y : ndarray
        Samples, at least 3.
    ts : float
        Sample interval [s].
    """
    y = np.asarray(y, dtype=float)
    if y.size < 3:
        raise ValueError(f"diffcent needs at least 3 samples, got {y.size}")
    return np.concatenate(([y[1] - y[0]], (y[2:] - y[:-2]) / 2.0, [y[-1] - y[-2]])) / ts


def process(position: np.ndarray, force: np.ndarray, ts: float) -> dict[str, np.ndarray]:
    """The measurement chain: position [m] and force [N] to the four channels (module docstring).

    Parameters
    ----------
    position : ndarray
        Position samples [m] (measured qm, or a simulated position).
    force : ndarray
        Force samples [N].
    ts : float
        Sample interval [s].
    """
    from scipy.signal import butter, filtfilt  # here: scipy.signal adds about 1 s to every service start

    b, a = butter(BUTTER_ORDER, BUTTER_CUTOFF / (0.5 / ts))
    q = filtfilt(b, a, position, padtype="odd", padlen=3 * (max(len(a), len(b)) - 1))
    dq = diffcent(q, ts)
    ddq = diffcent(dq, ts)
    return {"position": q, "velocity": dq, "acceleration": ddq, "force": np.asarray(force, dtype=float)}


def measured_channels(record: EmpsRecord) -> dict[str, np.ndarray]:
    """Position [m], velocity [m/s], acceleration [m/s^2] and force [N] of a record (module docstring)."""
    return process(record.qm, record.gtau * record.vir, record.ts)
