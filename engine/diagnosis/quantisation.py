"""The speed quantum, the one candidate effect least squares cannot fit.

``speed_quantization`` (omega1 rounded to multiples of q) has a jagged cost in
q (every q moves the rounding thresholds of thousands of samples), so least
squares cannot fit q. Rounding is applied after the simulation, so q is found
by a dense scan of the rounded calibrated omega1 (:func:`quantum_scan`); the
calibration is refitted on the unrounded omega1 with the rounding treated as
extra white noise (variance q^2/12), and q is scanned again (two rounds). Its
uncertainty is the half-width of the interval where chi2 rises by 1.

The recorded cells (:class:`CellResidual`)
------------------------------------------
Rounding as extra white noise blurs what the record says: a rounded sample tells which cell
``[(k - 1/2) q, (k + 1/2) q)`` the speed was in, and the instants where the record steps from
one level to the next pin the trajectory far more tightly than white noise of variance
``q^2 / 12`` does; q also trades against the plant (a larger q and a larger omega1 round
alike), so scanning q on a fixed fit and refitting at a fixed q can stall off the truth (a
seed-151 development record, low-pass + quantum on m_el and omega1 only: c 1.17 for a true
1.05, chi2/n 5.1 where the true parameters give 0.69). After the two rounds, q and the plant
are therefore fitted together by least squares on the probability of each sample's recorded
cell (:class:`CellResidual`, q a free parameter within ``LATTICE_BAND`` of the scan's,
edges of width ``CELL_WIDTHS`` times q narrowed in turn), when the record shows a lattice
(:func:`lattice_quantum`; without one its "cells" mean nothing) and the rounded model does not
already fit to the noise (``CELL_SKIP_BELOW``). That cost is only a surrogate: with
wide edges its optimum is biased, with narrow ones it is rough. So a cell fit is kept only
where it lowers the chi-square of the *rounded* model, the one every fit is judged by; the
answer is never worse than without it. On 38 quantised development records (seed-151 and
seed-97 cases, the true set fitted from the nominal plant; ``docs/diagnosis.md`` 8b) it
brought 3 true sets under chi2/n 1.05 that were not and one from 5.1 to 1.6. Cost, one
diagnosis at a time on 2 idle cores (``lab/scripts/case_times.py``, the 75 seed-151 singles, 5 of them
quantised): median 5.9 s and p90 14.0 s with it, 5.9 s and 13.6 s before (median ratio per record
1.01); two quantised singles it made right took 4.2 and 6.1 s (9.9 and 11.9 s before). Pairs and
triples not measured.

The scans weigh omega1's residual by its noise standard deviation in time; the fit's
reported chi-square, which its BIC and the decision compare with every other fit's, is
computed like theirs (whitened per wavelet level when the noise is coloured,
:meth:`engine.diagnosis.noise.NoiseModel.chi2`). It used to be computed in time on
coloured records too, so that on clean records with low-passed noise
the quantum's BIC differed from the nominal fit's by the difference of two estimates of
the same noise energy (hundreds), which read as evidence (11 of 36 clean records of a
protocol-2 progress run answered ``weak_gap``, docs/diagnosis.md 8c).

The lattice of the record itself (:func:`lattice_quantum`)
-----------------------------------------------------------
The model's omega1 is only as good as the calibration: beside a strong effect the
scan of the rounded *model* omega1 finds a wrong q (a seed-107 progress record with a
Coulomb friction of 0.059 pu and q = 0.294 rad/s: the single candidate fitted q =
0.398). The record shows its quantum without any model: rounded values lie on a
lattice ``q Z`` (shifted by a sensor offset, blurred by the noise added after the
rounding). For each trial q the samples are binned to their nearest lattice level
``k = round(w / q)``; each level with at least ``LATTICE_MIN_SAMPLES`` samples gives the
mean of ``exp(2 pi i w / q)`` over its samples, and the statistic is the modulus of the
mean of those level means,

    R(q) = | (1/L) sum_l mean_{i in l} exp(2 pi i w_i / q) |,

near 1 when every level sits at the same phase of q (a lattice), small otherwise.
Weighting levels equally, not samples, keeps a plateau of the speed (the drive at
rest before switch-on, a steady state) from counting: a plateau is one level,
concentrated at any q. The scan runs over q with steps small enough to resolve the
peak (relative step ``LATTICE_STEP * q / ptp(w)``); the estimate is the q of the
largest R if ``R >= LATTICE_MIN_R`` over at least ``LATTICE_MIN_LEVELS`` levels.
On the 400 records of four protocol-2 progress runs (seeds 101-107; development
data, the thresholds were set on them) the 20 quantised ones gave R 0.86-0.997 at q
within 1 % of the truth (8 to 22 levels), the others at most 0.79 on 6 or more levels. Where it fails:
noise comparable to q (R falls as ``exp(-2 pi^2 sigma^2 / q^2)``: 0.83 at sigma =
q / 10), a record spanning fewer than ``LATTICE_MIN_LEVELS`` quanta, and a gain or
low-pass applied *after* the rounding (the catalogue's chain rounds last). The
estimate only narrows the dense scan of the fit and brings the quantum into the set
search (:mod:`engine.diagnosis.sets`); the BIC still decides.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from numba import njit
from scipy.special import log_ndtr, ndtr

from engine.constants import CHANNELS
from engine.diagnosis.calibration import CalibrationError, CalibrationResult, CalibrationSettings, calibrate
from engine.diagnosis.cell_edges import edge_spread, tolerant_levels
from engine.diagnosis.noise import NoiseModel
from engine.diagnosis.space import ModelSpace
from engine.records import Record
from engine.simulation import Case, Effect

__all__ = [
    "CellResidual",
    "Lattice",
    "fit_quantisation",
    "is_speed_quantum",
    "lattice_quantum",
    "quanta",
    "quantum_scan",
    "record_lattice",
]

logger = logging.getLogger(__name__)

#: Fewest samples of a lattice level that counts in R(q).
LATTICE_MIN_SAMPLES: int = 3
#: Fewest levels (quanta spanned, each with LATTICE_MIN_SAMPLES samples) for a lattice.
LATTICE_MIN_LEVELS: int = 6
#: Most levels a scanned q may give (the finest q scanned is ptp(w) / this).
LATTICE_MAX_LEVELS: int = 100
#: Smallest R(q) of a lattice [-] (quantised development records: >= 0.86; others: <= 0.79, see the notes).
LATTICE_MIN_R: float = 0.8
#: Relative step of the q scan in units of q / ptp(w) (a phase step of 2 pi * this at the top level).
LATTICE_STEP: float = 0.02
#: Half-width of the dense q scan around a lattice estimate, relative to q [-].
LATTICE_BAND: float = 0.02
#: Edge widths of the refits on the recorded cells after the first two rounds, relative to q [-]
#: (:class:`CellResidual`; empty: the rounding stays extra white noise, as before).
CELL_WIDTHS: tuple[float, ...] = (0.1, 0.03, 0.01)
#: No cell fits when the rounded model's chi2/n is already at most this [-] (it fits to the noise).
CELL_SKIP_BELOW: float = 1.0


@dataclass(frozen=True)
class Lattice:
    """The quantum read from a record's lattice of values.

    Attributes
    ----------
    q : float
        Lattice spacing [rad/s].
    r : float
        R(q) [-], 1 for a perfect lattice.
    levels : int
        Levels that count at q.
    """

    q: float
    r: float
    levels: int


@njit(cache=True)
def _lattice_scan(w: np.ndarray, q: np.ndarray, min_samples: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
    r = np.zeros(q.size)
    n_levels = np.zeros(q.size, dtype=np.int64)
    w0 = w.min()
    for j in range(q.size):
        qj = q[j]
        k0 = int(np.round(w0 / qj))
        size = int(np.round(w.max() / qj)) - k0 + 1
        cnt = np.zeros(size, dtype=np.int64)
        re = np.zeros(size)
        im = np.zeros(size)
        for i in range(w.size):
            k = int(np.round(w[i] / qj)) - k0
            ph = 2.0 * np.pi * w[i] / qj
            cnt[k] += 1
            re[k] += np.cos(ph)
            im[k] += np.sin(ph)
        sr = 0.0
        si = 0.0
        n = 0
        for k in range(size):
            if cnt[k] >= min_samples:
                sr += re[k] / cnt[k]
                si += im[k] / cnt[k]
                n += 1
        if n > 0:
            r[j] = np.hypot(sr, si) / n
        n_levels[j] = n
    return r, n_levels


def lattice_quantum(omega: np.ndarray, bounds: tuple[float, float]) -> Lattice | None:
    """The quantum of a record's omega1 read from its lattice of values, or None (see the module notes).

    Parameters
    ----------
    omega : ndarray
        Recorded omega1 [rad/s].
    bounds : (float, float)
        Range of quanta searched [rad/s].

    Returns
    -------
    Lattice or None
        The spacing with the largest R(q), if it is a lattice by the module's thresholds.
    """
    w = np.asarray(omega, dtype=float)
    w = w[np.isfinite(w)]
    span = float(np.ptp(w)) if w.size else 0.0
    lo = max(float(bounds[0]), span / LATTICE_MAX_LEVELS)
    hi = min(float(bounds[1]), span / LATTICE_MIN_LEVELS)
    if w.size < LATTICE_MIN_SAMPLES * LATTICE_MIN_LEVELS or not span > 0.0 or not lo < hi:
        return None
    # steps of LATTICE_STEP * q^2 / span: sum of dq / (c q^2) = (1/lo - 1/hi) / c steps
    c = LATTICE_STEP / span
    n = math.ceil((1.0 / lo - 1.0 / hi) / c) + 1
    q = 1.0 / np.linspace(1.0 / lo, 1.0 / hi, n)
    r, levels = _lattice_scan(w, q, LATTICE_MIN_SAMPLES)
    r[levels < LATTICE_MIN_LEVELS] = 0.0
    j = int(np.argmax(r))
    if r[j] < LATTICE_MIN_R:
        return None
    return Lattice(q=float(q[j]), r=float(r[j]), levels=int(levels[j]))


def is_speed_quantum(effect: Effect) -> bool:
    """True for the effect that rounds the speed sensor's output (``speed_quantum``)."""
    return effect.target == "sensors" and effect.field == "speed_quantum"


def quantum_scan(omega: np.ndarray, data: np.ndarray, sigma: float, q: np.ndarray) -> np.ndarray:
    """chi2 of omega1 rounded to each quantum, as the simulator rounds it.

    Parameters
    ----------
    omega : ndarray
        Simulated, unrounded omega1 [rad/s].
    data : ndarray
        Recorded omega1 [rad/s].
    sigma : float
        Its residual normalisation [rad/s].
    q : ndarray
        Quanta [rad/s] (0 means no rounding).

    Returns
    -------
    ndarray
        chi2 per quantum [noise variances].
    """
    out = np.empty(q.size)
    for i, qi in enumerate(q):
        sim = qi * np.round(omega / qi) if qi > 0 else omega
        out[i] = np.sum(((sim - data) / sigma) ** 2)
    return out


@dataclass(frozen=True)
class CellResidual:
    """Residual of a model's unrounded omega1 against a rounded record: is it in the recorded cell?

    A rounded sample ``y = q k`` (plus noise added after the rounding, small beside q) says
    only that the unrounded speed lay in the cell ``[(k - 1/2) q, (k + 1/2) q)``; where in the
    cell it cannot say. With the model's value ``x`` uncertain by ``N(0, width^2)`` (the model's
    error, or noise before the rounding), the probability of the recorded cell is
    ``P = Phi(b) - Phi(a)``, ``a = ((k - 1/2) q - x) / width``, ``b = ((k + 1/2) q - x) / width``,
    and the residual is ``sign(x - q k) sqrt(2 (log P0 - log P))`` with ``P0`` its value at the
    cell's centre: zero inside the cell (up to its edges' width), the distance to the cell over
    ``width`` outside it. Least squares on it moves a model across the record's rounding
    thresholds, which the hard rounding (piecewise constant) cannot and the rounding as extra
    white noise only blurs.

    With ``takes`` the name of the space's speed-quantum effect, q is a parameter of the fit
    (:class:`engine.diagnosis.objective.ChannelResidual`): the cells move with it, so q and the
    plant (whose scale of omega1 a q can mimic) are fitted together.

    Parameters
    ----------
    q : float
        Quantum [rad/s], > 0, when ``takes`` is None.
    width : float
        Width of the cells' edges relative to q [-], > 0.
    takes : str or None
        The speed-quantum effect whose fitted value is q, or None for the fixed ``q``.
    """

    q: float
    width: float
    takes: str | None = None

    def __post_init__(self) -> None:
        if not (self.q > 0.0 and self.width > 0.0):
            raise ValueError(f"a cell residual needs q > 0 and width > 0, got q = {self.q}, width = {self.width}")

    def __call__(self, sim: np.ndarray, data: np.ndarray, value: np.ndarray | None = None) -> np.ndarray:
        """Residuals [-] of unrounded simulated omega1 ``sim`` (m, n) against recorded ``data`` (n,) [rad/s];
        ``value`` (m,): q per row [rad/s] when the residual takes the quantum."""
        q = np.full((np.shape(sim)[0], 1), self.q) if value is None else np.asarray(value, dtype=float)[:, None]
        w = self.width * q
        k = np.round(data[None, :] / q)
        a = ((k - 0.5) * q - sim) / w
        b = ((k + 0.5) * q - sim) / w
        below = a + b >= 0.0  # x below the cell's centre: P = Phi(-a) - Phi(-b), else both terms near 1
        hi = np.where(below, log_ndtr(-a), log_ndtr(b))
        lo = np.where(below, log_ndtr(-b), log_ndtr(a))
        log_p = hi + np.log1p(-np.exp(np.minimum(lo - hi, 0.0)))
        log_p0 = math.log(2.0 * float(ndtr(0.5 / self.width)) - 1.0)
        out: np.ndarray = np.sign(sim - q * k) * np.sqrt(np.maximum(2.0 * (log_p0 - log_p), 0.0))
        return out


@functools.lru_cache(maxsize=16)
def _lattice_of(data: bytes, lo: float, hi: float) -> Lattice | None:
    return lattice_quantum(np.frombuffer(data, dtype=float), (lo, hi))


def record_lattice(omega: np.ndarray, bounds: tuple[float, float]) -> Lattice | None:
    """:func:`lattice_quantum`, remembered for the last few records (a diagnosis asks it many times)."""
    return _lattice_of(np.ascontiguousarray(omega, dtype=float).tobytes(), float(bounds[0]), float(bounds[1]))


def quanta(omega: np.ndarray, bounds: tuple[float, float], n: int) -> np.ndarray:
    """The quanta a dense scan tries [rad/s]: ``n`` evenly over ``bounds``, and ``n // 4`` more within
    ``LATTICE_BAND`` of the record's lattice spacing when it has one (:func:`lattice_quantum`)."""
    lo, hi = bounds
    q = np.linspace(lo, hi, n)
    lat = record_lattice(omega, bounds)
    if lat is None:
        return q
    band = np.linspace(lat.q * (1.0 - LATTICE_BAND), lat.q * (1.0 + LATTICE_BAND), max(n // 4, 2))
    return np.unique(np.concatenate([q, band.clip(lo, hi)]))


def _simulation(cal: CalibrationResult) -> np.ndarray:
    if cal.simulation is None:
        raise CalibrationError("this calibration result holds no simulation")
    return cal.simulation


def _rounded_chi2(
    record: Record, sim: np.ndarray, q: float, sigma: Mapping[str, float], levels: np.ndarray | None = None
) -> dict[str, float]:
    """Per channel, the chi2 [-] of simulated channels ``sim`` (unrounded) with omega1 rounded to ``q``
    (none for q = 0), as every fit's is reported: whitened per wavelet level when the noise is coloured.
    ``levels``: omega1's rounding levels when given (:func:`engine.diagnosis.cell_edges.tolerant_levels`)."""
    weights = NoiseModel.of(sigma)
    out = {}
    for n in record.channels:
        x = sim[CHANNELS.index(n)]
        if n == "omega1" and q > 0.0:
            x = q * (np.round(x / q) if levels is None else levels)
        out[n] = float(weights.chi2(n, np.asarray(record[n]) - x))
    return out


def _edge_levels(
    record: Record,
    cal: CalibrationResult,
    space: ModelSpace,
    noise: Mapping[str, float],
    q: float,
    sigma_q: float,
    settings: CalibrationSettings,
) -> np.ndarray | None:
    """omega1's rounding levels of a quantum fit with the flip tolerance (:mod:`engine.diagnosis.cell_edges`),
    or None (plain rounding) when the fit's gradient cannot be simulated. ``settings``: the fit's,
    whose difference step of the uncertainties the spread uses."""
    try:
        x, spread = edge_spread(record, space, cal.values, noise, q, sigma_q, cal.step, settings.fd_step_uncertainty)
    except CalibrationError as exc:
        logger.info("no flip tolerance for this quantum fit: %s", exc)
        return None
    return tolerant_levels(x, np.asarray(record["omega1"]), q, spread)


def fit_quantisation(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    effect: Effect,
    n_quantum: int,
    first: CalibrationSettings,
    refit: CalibrationSettings,
    flip_tolerance: bool = True,
) -> CalibrationResult:
    """Fit a speed quantum by dense scans around refits of the calibration (see the module notes).

    Rounding makes the cost jagged in the plant parameters too, so the
    calibration is refitted on the *unrounded* simulated omega1 with the
    quantisation treated as extra white noise (variance q^2 / 12 added to the
    channel's); q is then scanned on the refitted omega1. Two rounds.

    Parameters
    ----------
    record : Record
        The measured record (with an omega1 channel).
    nominal : CalibrationResult
        Calibration of the nominal model (first omega1; noise levels).
    space : ModelSpace
        The nominal model space.
    effect : Effect
        The speed-quantum effect (its bounds are the scanned range, in rad/s).
    n_quantum : int
        Values of each dense scan.
    first, refit : CalibrationSettings
        Settings of the first round's refit and of the second's.
    flip_tolerance : bool
        Where the record shows a lattice, report the chi-square with the samples across an edge
        that the fit cannot place at the record's level (:mod:`engine.diagnosis.cell_edges`);
        False: the plain rounding.

    Returns
    -------
    CalibrationResult
        The last refit, reported with the record's own noise and the rounded
        omega1: ``values[effect.name]`` is the quantum [rad/s], its uncertainty
        the half-width of the interval where chi2 rises by 1.
    """
    data = np.asarray(record["omega1"])
    q = quanta(data, effect.bounds, n_quantum)
    sig = nominal.sigma["omega1"]
    j = CHANNELS.index("omega1")
    omega = _simulation(nominal)[j]
    values = nominal.values
    n_sim = 0
    cal = nominal
    for rnd in range(2):
        q_best = float(q[int(np.argmin(quantum_scan(omega, data, sig, q)))])
        noise = {**nominal.noise, "omega1": math.hypot(nominal.noise["omega1"], q_best / math.sqrt(12.0))}
        cal = calibrate(record, space, first if rnd == 0 else refit, noise=noise, seeds=[values], polish=True)
        n_sim += cal.n_simulations
        values, omega = cal.values, _simulation(cal)[j]
    q_best = float(q[int(np.argmin(quantum_scan(omega, data, sig, q)))])
    c2_old = sum(_rounded_chi2(record, _simulation(cal), q_best, nominal.sigma).values()) if q_best > 0.0 else math.inf
    lattice = record_lattice(data, effect.bounds)  # cells only where the record shows them
    if CELL_WIDTHS and lattice is not None and q_best > 0.0 and c2_old > CELL_SKIP_BELOW * cal.n_data:
        # q and the plant together on the recorded cells, q within LATTICE_BAND of the scan's;
        # a cell fit is kept only where it lowers the chi-square of the rounded model
        best = (c2_old, cal, q_best)
        band = (q_best * (1.0 - LATTICE_BAND), q_best * (1.0 + LATTICE_BAND))
        qspace = space.with_effect(replace(effect, bounds=band))
        seed = {**values, effect.name: q_best}
        for width in CELL_WIDTHS:
            cells = {"omega1": CellResidual(q_best, width, takes=effect.name)}
            fit = calibrate(record, qspace, refit, noise=nominal.noise, seeds=[seed], polish=True, residual_of=cells)
            n_sim += fit.n_simulations
            seed = fit.values
            # the fitted q, and the scan's best q for the fitted omega1 (no simulation)
            q_scan = float(q[int(np.argmin(quantum_scan(_simulation(fit)[j], data, sig, q)))])
            for q_fit in (fit.values[effect.name], q_scan):
                c2_fit = (
                    sum(_rounded_chi2(record, _simulation(fit), q_fit, nominal.sigma).values())
                    if q_fit > 0.0
                    else math.inf
                )
                logger.debug("cell fit (width %.3g q): q = %.6g, chi2 %.6g (best %.6g)", width, q_fit, c2_fit, best[0])
                if c2_fit < best[0]:
                    best = (c2_fit, fit, q_fit)
        _, cal, q_best = best
        cal.values = {k: v for k, v in cal.values.items() if k != effect.name}
        cal.uncertainties = {k: v for k, v in cal.uncertainties.items() if k != effect.name}
        omega = _simulation(cal)[j]
    q = np.unique(np.concatenate([q, [q_best]]))  # the scan about the kept q, for its uncertainty
    c2 = quantum_scan(omega, data, sig, q)
    inside = q[c2 <= c2.min() + 1.0]
    i = int(np.argmin(c2))
    step = float(np.max(np.diff(q[max(i - 1, 0) : i + 2])))  # the scan's resolution at its best point
    unc = max(float(inside.max() - inside.min()) / 2.0, step)
    # where the record shows a lattice, a sample across an edge the fit cannot place counts at the
    # record's level (the flip tolerance, engine.diagnosis.cell_edges)
    levels = None
    if flip_tolerance and lattice is not None and q_best > 0.0:
        levels = _edge_levels(record, cal, space, nominal.noise, q_best, unc, refit)
    # report the fit with the record's own noise and the rounded omega1
    cal.noise, cal.sigma = dict(nominal.noise), dict(nominal.sigma)
    simulation = _simulation(cal).copy()
    # the chi-square of every other fit: whitened per wavelet level when the noise is coloured
    cal.chi2_per_channel = _rounded_chi2(record, simulation, q_best, nominal.sigma, levels)
    cal.chi2 = float(sum(cal.chi2_per_channel.values()))
    if q_best > 0:
        simulation[j] = q_best * (np.round(omega / q_best) if levels is None else levels)
    cal.simulation = simulation
    if cal.case is not None:
        cal.case = Case(cal.case.plant, cal.case.sensors.replace(speed_quantum=q_best))
    cal.values = {**cal.values, effect.name: q_best}
    cal.uncertainties = {**cal.uncertainties, effect.name: unc}
    cal.effect = effect.name
    cal.n_simulations = n_sim
    return cal
