"""The speed quantum, the one candidate effect least squares cannot fit.

``speed_quantization`` (omega1 rounded to multiples of q) has a jagged cost in
q (every q moves the rounding thresholds of thousands of samples), so least
squares cannot fit q. Rounding is applied after the simulation, so q is found
by a dense scan of the rounded calibrated omega1 (:func:`quantum_scan`); the
calibration is refitted on the unrounded omega1 with the rounding treated as
extra white noise (variance q^2/12), and q is scanned again (two rounds). Its
uncertainty is the half-width of the interval where chi2 rises by 1.

The scans weigh omega1's residual by its noise standard deviation in time; the fit's
reported chi-square, which its BIC and the decision compare with every other fit's, is
computed like theirs (whitened per wavelet level when the noise is coloured,
:meth:`engine.diagnosis.noise.NoiseModel.chi2`). It used to be computed in time on
coloured records too, so that on clean records with low-passed noise
the quantum's BIC differed from the nominal fit's by the difference of two estimates of
the same noise energy (hundreds), which read as evidence (11 of 36 clean records of a
protocol-2 progress run answered ``weak_gap``, docs/diagnosis.md 8c).
"""

from __future__ import annotations

import math

import numpy as np

from engine.constants import CHANNELS
from engine.diagnosis.calibration import CalibrationError, CalibrationResult, CalibrationSettings, calibrate
from engine.diagnosis.noise import NoiseModel
from engine.diagnosis.space import ModelSpace
from engine.records import Record
from engine.simulation import Case, Effect

__all__ = ["fit_quantisation", "is_speed_quantum", "quantum_scan"]


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


def _simulation(cal: CalibrationResult) -> np.ndarray:
    if cal.simulation is None:
        raise CalibrationError("this calibration result holds no simulation")
    return cal.simulation


def fit_quantisation(
    record: Record,
    nominal: CalibrationResult,
    space: ModelSpace,
    effect: Effect,
    n_quantum: int,
    first: CalibrationSettings,
    refit: CalibrationSettings,
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

    Returns
    -------
    CalibrationResult
        The last refit, reported with the record's own noise and the rounded
        omega1: ``values[effect.name]`` is the quantum [rad/s], its uncertainty
        the half-width of the interval where chi2 rises by 1.
    """
    lo, hi = effect.bounds
    q = np.linspace(lo, hi, n_quantum)
    data = np.asarray(record["omega1"])
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
    c2 = quantum_scan(omega, data, sig, q)
    q_best = float(q[int(np.argmin(c2))])
    # report the fit with the record's own noise and the rounded omega1
    cal.noise, cal.sigma = dict(nominal.noise), dict(nominal.sigma)
    rounded = q_best * np.round(omega / q_best) if q_best > 0 else omega
    simulation = _simulation(cal).copy()
    simulation[j] = rounded
    cal.simulation = simulation
    # the chi-square of every other fit: whitened per wavelet level when the noise is coloured
    weights = NoiseModel.of(nominal.sigma)
    others = {n: float(weights.chi2(n, np.asarray(record[n]) - simulation[CHANNELS.index(n)])) for n in record.channels}
    cal.chi2_per_channel = others
    cal.chi2 = float(sum(others.values()))
    if cal.case is not None:
        cal.case = Case(cal.case.plant, cal.case.sensors.replace(speed_quantum=q_best))
    inside = q[c2 <= c2.min() + 1.0]
    unc = max(float(inside.max() - inside.min()) / 2.0, float(q[1] - q[0]))
    cal.values = {**cal.values, effect.name: q_best}
    cal.uncertainties = {**cal.uncertainties, effect.name: unc}
    cal.effect = effect.name
    cal.n_simulations = n_sim
    return cal
