"""The paper's wavelet-neural width identifier applied to the BRFD friction damper.

The seed's method (:class:`~engine.identification.paper.PaperIdentifier`: one network per backlash
width, its output weights ``W3[0, :]`` the width's pattern, a test record's own network compared
with every pattern by ``D(i) = sum_j |Wt(j) - Ww(i, j)|``, the width ``argmin D``) was designed for
the simulated backlash drive. On the BRFD it runs as follows.

Event and window
    The paper's records start just before an event (the motor switch-off) and hold 2048 samples.
    The BRFD's event is a **reversal of the imposed displacement** (:meth:`BrfdPlant.events`):
    right after it the linkage crosses its play and transmits no force, a flat stretch whose
    length grows with the play. The window is the 2048 samples (2 s at the data set's 1024 Hz) of
    the force starting :data:`LEAD_TIME` before the first reversal after the plant's settle time
    (:data:`~engine.plants.brfd.model.SETTLE`). A record without such a reversal, or too short to
    hold the window after it, is refused (:class:`ValueError`).

Training records
    The paper simulates its plant at each of six widths with seven values of the motor inertia
    J1. Here the plant is simulated on the **same record's displacement**
    (``plant.simulate(record, values)["force"]``, same window) at each width of
    :data:`WIDTH_GRID` (effect ``"backlash"``, [m]) with :data:`N_VARIATIONS` variations of the
    calibrated parameters around ``calibration``: the friction level ``Fc`` and the pre-sliding
    stiffness ``sigma0`` are scaled by factors evenly spread over ``1 +- VARIATION_SPREAD`` (0.85 .. 1.15),
    paired as a Latin hypercube (``Fc`` takes the levels in order, ``sigma0`` a permutation of them
    drawn from ``seed``), so each parameter sweeps its whole range as J1 does in the paper. 6 x 7 =
    42 windows train ``PaperIdentifier(channel="force", wavelet=WAVELET, widths=WIDTH_GRID)``
    (every other setting the paper's); the measured window is then identified.

Units: the force per unit of the calibrated Fc
    The paper's channels are in relative units (the motor torque m_el in pu, of order 1), and its
    method is not scale-free: the first layer's weights start at the mean ``m1`` of the raw
    wavelet coefficients and the target range ``[h2, k2]`` of eq. (2) follows from them (case 2:
    ``h4 = m1``). In newtons (forces of 10-30 kN) ``m1`` is about 200, every first-layer sigmoid
    is exactly 1.0, all six patterns are bit-identical and every D is 0, a tie (measured on the
    shipped 1 Hz record). Every window, simulated and measured, is therefore divided by the
    calibrated ``Fc`` (the force in pu of the Coulomb level, of order 1 like m_el); this also makes
    the result independent of the force level (band tension), since the training forces scale
    with ``Fc`` too.

Widths
    :data:`WIDTH_GRID` starts at 0 (no play): the identifier's normalisation (eqs. 2-5) selects
    rows by width *index* and never divides by a width, so a zero width is allowed.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from engine.constants import N_SAMPLES
from engine.identification.paper import PaperIdentifier
from engine.plants.brfd.model import SETTLE, BrfdPlant
from engine.plants.brfd.record import BrfdRecord

__all__ = [
    "CHANNEL",
    "EFFECT",
    "LEAD_TIME",
    "N_VARIATIONS",
    "VARIATION_SPREAD",
    "WAVELET",
    "WIDTH_GRID",
    "PaperWidth",
    "event_window",
    "paper_width",
    "variation_factors",
]

#: The six backlash widths of the patterns [m]: 0 to 5 mm in 1 mm steps (the continuous fit of the
#: shipped sinusoidal records gives about 3.4 mm; the catalogue's range is 0-12 mm).
WIDTH_GRID: tuple[float, ...] = (0.0, 0.001, 0.002, 0.003, 0.004, 0.005)
#: Variations of the calibrated parameters per width (the paper's seven J1 cases).
N_VARIATIONS: int = 7
#: Half-spread of the scale factors of Fc and sigma0 [share]: factors from 0.85 to 1.15.
VARIATION_SPREAD: float = 0.15
#: Time the window starts before the reversal [s] (the paper's records start 4.8 ms before the
#: event; here 50 ms, so the force's approach to the reversal is in the window too).
LEAD_TIME: float = 0.05
#: Wavelet of the force channel (the paper's db6, its wavelet for the force-like channels m_el, a2).
WAVELET: str = "db6"
#: The plant's channel the identifier works on.
CHANNEL: str = "force"
#: The catalogue effect whose value is the width [m].
EFFECT: str = "backlash"


@dataclass(frozen=True)
class PaperWidth:
    """The width the paper's method identifies on a BRFD record.

    Attributes
    ----------
    width : float
        Identified width: the grid width at the smallest D [m].
    index : int
        0-based index of ``width`` in ``widths`` (``argmin D``; the paper's ``nr5 - 1``).
    D : list of float
        ``D(i) = sum_j |Wt(j) - Ww(i, j)|`` for each grid width, ``widths`` order [-] (network
        weights of the force in pu of the calibrated Fc).
    widths : tuple of float
        The width grid of the patterns [m].
    window : tuple of float
        Instants of the first and the last sample of the record's window [s].
    n_training : int
        Training records simulated (widths x variations).
    """

    width: float
    index: int
    D: list[float]
    widths: tuple[float, ...]
    window: tuple[float, float]
    n_training: int


def event_window(plant: BrfdPlant, record: BrfdRecord) -> slice:
    """The record's window: 2048 samples from :data:`LEAD_TIME` before the first reversal after SETTLE.

    Parameters
    ----------
    plant : BrfdPlant
        The plant (gives the reversals, :meth:`BrfdPlant.events`, in s).
    record : BrfdRecord
        The record.

    Returns
    -------
    slice
        Sample indices of the window (2048 samples).

    Raises
    ------
    ValueError
        No reversal after SETTLE, or fewer than 2048 samples from the window's start to the end
        of the record.
    """
    events = np.asarray(plant.events(record), dtype=float)
    after = events[events > SETTLE]
    if after.size == 0:
        raise ValueError(
            f"record {record.name!r} has no reversal of the displacement after the settle time {SETTLE} s; "
            "the paper's method needs one as its event"
        )
    t_rev = float(after[0])
    start = max(0, int(np.searchsorted(record.t, t_rev - LEAD_TIME - 0.5 * record.ts)))
    stop = start + N_SAMPLES
    if stop > record.n:
        have = record.n - start
        raise ValueError(
            f"record {record.name!r} is too short for the paper's method: its window starts at "
            f"{record.t[start]:.3f} s ({LEAD_TIME} s before the first reversal after {SETTLE} s, at {t_rev:.3f} s) "
            f"and needs {N_SAMPLES} samples ({N_SAMPLES * record.ts:.3f} s), but the record ends after {have} "
            f"({record.t[-1]:.3f} s)"
        )
    return slice(start, stop)


def variation_factors(variations: int = N_VARIATIONS, seed: int = 0) -> np.ndarray:
    """Scale factors of (Fc, sigma0) of each variation, a Latin hypercube over ``1 +- VARIATION_SPREAD``.

    Parameters
    ----------
    variations : int
        Number of variations (at least 1; 1 gives the calibration itself).
    seed : int
        Seed of the pairing of the sigma0 levels with the Fc levels.

    Returns
    -------
    ndarray, shape (variations, 2)
        Column 0 multiplies Fc, column 1 sigma0 [-].
    """
    if not (isinstance(variations, (int, np.integer)) and variations >= 1):
        raise ValueError(f"variations must be a positive integer, got {variations!r}")
    levels = np.linspace(1.0 - VARIATION_SPREAD, 1.0 + VARIATION_SPREAD, variations) if variations > 1 else np.ones(1)
    return np.column_stack([levels, np.random.default_rng(seed).permutation(levels)])


def paper_width(
    plant: BrfdPlant,
    record: BrfdRecord,
    calibration: Mapping[str, float],
    widths: tuple[float, ...] = WIDTH_GRID,
    variations: int = N_VARIATIONS,
    seed: int = 0,
) -> PaperWidth:
    """Identify the BRFD's backlash width on a record with the paper's wavelet-neural method.

    Parameters
    ----------
    plant : BrfdPlant
        The plant.
    record : BrfdRecord
        The record (displacement [m] imposed, force [N] measured).
    calibration : mapping of str to float
        Calibrated parameters, at least ``Fc`` [N] and ``sigma0`` [N/m]; other plant parameters
        or effects given here are held in every training simulation (``"backlash"`` is overridden).
    widths : tuple of float, default WIDTH_GRID
        Six strictly increasing widths of the patterns [m].
    variations : int, default N_VARIATIONS
        Variations of Fc and sigma0 per width (:func:`variation_factors`).
    seed : int, default 0
        Seed of the variations' pairing.

    Returns
    -------
    PaperWidth

    Raises
    ------
    ValueError
        The record has no usable window (:func:`event_window`), the calibration lacks Fc or
        sigma0 or its Fc is not positive, or the widths are not six strictly increasing values.
    """
    missing = [name for name in ("Fc", "sigma0") if name not in calibration]
    if missing:
        raise ValueError(f"calibration lacks {missing}; it needs Fc [N] and sigma0 [N/m]")
    base = float(calibration["Fc"])  # force base [N]: windows in pu of Fc (module docstring, Units)
    if not (np.isfinite(base) and base > 0.0):
        raise ValueError(f"calibration Fc must be a positive force [N], got {calibration['Fc']!r}")
    window = event_window(plant, record)
    factors = variation_factors(variations, seed)
    X, y = [], []
    for b in widths:
        for f_fc, f_s0 in factors:
            values = {
                **calibration,
                "Fc": float(calibration["Fc"]) * float(f_fc),
                "sigma0": float(calibration["sigma0"]) * float(f_s0),
                EFFECT: float(b),
            }
            X.append(plant.simulate(record, values)[CHANNEL][window] / base)
            y.append(float(b))
    ident = PaperIdentifier(channel=CHANNEL, wavelet=WAVELET, widths=tuple(float(b) for b in widths))
    ident.fit(np.asarray(X), np.asarray(y))
    result = ident.identify(plant.measured(record)[CHANNEL][window] / base)
    index = result.index - 1
    return PaperWidth(
        width=float(ident.widths_[index]),
        index=index,
        D=[float(d) for d in result.D],
        widths=tuple(float(b) for b in ident.widths_),
        window=(float(record.t[window.start]), float(record.t[window.stop - 1])),
        n_training=len(X),
    )
