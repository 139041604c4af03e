"""The response columns (step 1 of the method) and the record as the fits see it.

In one batch, the whitened change of the record's channels per unit of every locus's input (its
free hats, the constant and the step, in the locus's unit), per unit of every calibrated parameter
and for the sensor library (:func:`responses`); and the record's channels whitened alike by the
calibration's per-channel sigma (:class:`Observed`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from engine.constants import CHANNELS, DISTURBANCE_MAX_KNOTS
from engine.diagnosis.calibration import CalibrationResult
from engine.diagnosis.locus._cases import parameter_cases, with_input
from engine.diagnosis.locus._report import LocusError, LocusSettings
from engine.records import Record
from engine.simulation import DISTURBANCE_LOCI, Case, Disturbance, run_cases

logger = logging.getLogger(__name__)


#: Size of the hat of d used for the response columns, per locus, in the locus's unit: small
#: enough to keep the sequence of clutch impacts, large enough to stand far above the
#: integrator's rounding (a torque hat of 5e-3 pu moves a1 by about 0.09 m/s^2 at its peak).
PROBE: dict[str, float] = {
    "supply": 5e-3,
    "motor_electrical": 5e-3,
    "motor_shaft": 5e-3,
    "clutch": 1e-4,
    "drive_train": 5e-3,
    "load": 5e-3,
    "clutch_torque": 5e-3,
}
#: Unpenalised extras of every locus's input: a constant from switch-on and a step at the switch-off.
N_EXTRAS: int = 2


@dataclass
class Responses:
    """Whitened response columns of every locus, the calibrated parameters and the sensor library.

    The input's knots run from switch-on to the end of the test window (one of them on the
    event); the hats of the knots from ``first_free`` on (the test window and ``history`` before
    it) are free, and two more columns per locus are unpenalised *extras*: a constant input from
    switch-on (a constant term acts on the whole run: e.g. an offset of the backlash zone moves
    the first contact already) and a step at the switch-off (where the motor's torque jumps,
    e.g. a torque left at the switch-off).
    """

    knots: np.ndarray  # (n_knots,) knot times [s since switch-on]
    first_free: int  # first knot with a free hat
    columns: dict[str, np.ndarray]  # locus -> (n_res, n_free + N_EXTRAS): free hats, constant, step; per unit of d
    params: np.ndarray  # (n_res, k) calibrated parameters' columns, per unit of each
    param_names: list[str]
    sensors: np.ndarray  # (n_res, 2 n_ch + 2)
    sensor_names: list[str]
    crosstalk: np.ndarray  # (n_res, n_ch (n_ch - 1)) channel i reading a share of channel j (i != j)
    crosstalk_names: list[str]
    base: np.ndarray  # (5, n_samples) the calibrated case at the settings' step, all channels
    n_simulations: int

    @property
    def n_free(self) -> int:
        return self.knots.size - self.first_free

    def values(self, x: np.ndarray, e: np.ndarray) -> np.ndarray:
        """Knot values of the input with free hats ``x`` on top of the constant ``e[0]``."""
        v = np.full(self.knots.size, float(e[0]))
        v[self.first_free :] += x
        return v

    def schedule(self, locus: str, x: np.ndarray, e: np.ndarray) -> Disturbance:
        """The input: free hats ``x``, the constant ``e[0]`` from switch-on and the step ``e[1]`` at the switch-off."""
        v = self.values(x, e)
        if locus == "supply":  # a simulation needs a positive voltage
            v = np.clip(v, -0.9, None)
        return _schedule(locus, self.knots, v, float(e[1]))

    def probes(self, locus: str, x: np.ndarray, e: np.ndarray) -> list[Disturbance]:
        """The input (x, e) with a probe added to each free hat, then to the constant, then to the step."""
        out = []
        for j in range(self.n_free):
            dx = np.zeros(self.n_free)
            dx[j] = PROBE[locus]
            out.append(self.schedule(locus, x + dx, e))
        for i in range(N_EXTRAS):
            de = np.zeros(N_EXTRAS)
            de[i] = PROBE[locus]
            out.append(self.schedule(locus, x, e + de))
        return out


def _schedule(locus: str, knots: np.ndarray, values: np.ndarray, step: float = 0.0) -> Disturbance:
    return Disturbance(locus, float(knots[0]), float(knots[1] - knots[0]), tuple(float(v) for v in values), step)


def responses(
    record: Record, cal: CalibrationResult, sigma: np.ndarray, rows: list[int], settings: LocusSettings
) -> Responses:
    """One batch: the calibrated case, every locus's probes, the parameters' and the sensor probes."""
    assert cal.case is not None and cal.event_time is not None
    grid = record.grid
    ts = record.sample_interval
    t_end = cal.event_time + (record.n_samples - record.event_index) * ts
    t_start = max(0.0, cal.event_time - record.event_index * ts - settings.history)
    dt = settings.knot_spacing
    if math.ceil(t_end / dt) + 2 > DISTURBANCE_MAX_KNOTS:
        dt = t_end / (DISTURBANCE_MAX_KNOTS - 2)
        logger.warning("locus: knot spacing widened to %.3g ms to cover %.3g s", dt * 1e3, t_end)
    # a knot sits on the event, where the motor is switched off (an input may start there)
    first = cal.event_time - dt * math.floor(cal.event_time / dt)
    knots = first + dt * np.arange(math.ceil((t_end - first) / dt) + 1)
    first_free = int(np.searchsorted(knots, t_start - 1e-12))
    none = np.zeros((0, 0))
    shell = Responses(knots, first_free, {}, none, [], none, [], none, [], none, 0)
    zero_x, zero_e = np.zeros(shell.n_free), np.zeros(N_EXTRAS)
    # every simulation carries a schedule, so the integrator cuts its steps at the same knots
    base_case = with_input(cal.case, shell.schedule("load", zero_x, zero_e))
    cases = [base_case]
    for locus in DISTURBANCE_LOCI:
        cases += [with_input(cal.case, d) for d in shell.probes(locus, zero_x, zero_e)]
    pcases, psteps, pnames = parameter_cases(base_case, list(cal.values))
    cases += pcases
    s = base_case.sensors
    delay = (
        s.delay + settings.delay_probe if s.delay + settings.delay_probe <= 0.005 else s.delay - settings.delay_probe
    )
    fc = settings.lowpass_probe_hz if s.lowpass_hz == 0 else 0.9 * s.lowpass_hz
    cases.append(Case(base_case.plant, s.replace(delay=delay)))
    cases.append(Case(base_case.plant, s.replace(lowpass_hz=fc)))
    ch, _, status = run_cases(cases, cal.solver(settings.step), grid)
    if status[0] != 0:
        raise LocusError(f"the calibrated case cannot be simulated (kernel status {int(status[0])})")
    base = ch[0]
    diff = ch[:, rows] - base[None, rows]
    diff[status != 0] = 0.0  # a probe that fails tells nothing (counted as no response)
    white = (diff / sigma[None, :, None]).reshape(len(cases), -1).T  # (n_res, n_cases)
    m = shell.n_free + N_EXTRAS
    columns = {locus: white[:, 1 + i * m : 1 + (i + 1) * m] / PROBE[locus] for i, locus in enumerate(DISTURBANCE_LOCI)}
    k0 = 1 + len(DISTURBANCE_LOCI) * m
    params = white[:, k0 : k0 + len(pcases)] / np.array(psteps)[None, :] if pcases else np.zeros((white.shape[0], 0))
    # sensors: per channel offset and gain, one delay, one low-pass
    n_ch, n_s = len(rows), record.n_samples
    offs = np.zeros((n_ch * n_s, n_ch))
    gains = np.zeros((n_ch * n_s, n_ch))
    for j, row in enumerate(rows):
        offs[j * n_s : (j + 1) * n_s, j] = 1.0 / sigma[j]
        gains[j * n_s : (j + 1) * n_s, j] = base[row] / sigma[j]
    probes = white[:, k0 + len(pcases) :]
    names = [f"offset_{CHANNELS[r]}" for r in rows] + [f"gain_{CHANNELS[r]}" for r in rows] + ["delay", "lowpass"]
    sensors = np.hstack([offs, gains, probes])
    cross, cross_names = crosstalk_columns(base, rows, sigma)
    return Responses(knots, first_free, columns, params, pnames, sensors, names, cross, cross_names, base, len(cases))


def crosstalk_columns(base: np.ndarray, rows: list[int], sigma: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Whitened columns of every channel reading a share of another: ``y_i + g_ij y_j`` (i != j).

    The measurement chain's cross-talk in its generic, linear form: a channel picks up part of
    another channel's signal (an accelerometer's cross-axis sensitivity, a shared ground, a
    multiplexer's settling). Per unit of ``g_ij``, the change of channel i is the calibrated
    simulation's channel j [channel j's unit per channel i's unit]; the columns are the
    library's candidates, selected sparsely (:func:`engine.diagnosis.locus._linear.sparse_extension`).

    Parameters
    ----------
    base : ndarray, shape (5, n_samples)
        The calibrated simulation, every channel.
    rows : list of int
        The record's channels (indices into :data:`~engine.constants.CHANNELS`).
    sigma : ndarray, shape (n_ch,)
        Each record channel's noise standard deviation (the whitening).

    Returns
    -------
    columns : ndarray, shape (n_ch n_samples, n_ch (n_ch - 1))
    names : list of str
        ``crosstalk_<i>_from_<j>`` per column.
    """
    n_ch, n_s = len(rows), base.shape[1]
    cols, names = [], []
    for i, ri in enumerate(rows):
        for rj in rows:
            if rj == ri:
                continue
            col = np.zeros(n_ch * n_s)
            col[i * n_s : (i + 1) * n_s] = base[rj] / sigma[i]
            cols.append(col)
            names.append(f"crosstalk_{CHANNELS[ri]}_from_{CHANNELS[rj]}")
    return (np.stack(cols, axis=1) if cols else np.zeros((n_ch * n_s, 0))), names


@dataclass(frozen=True)
class Observed:
    """The record's channels as the fits see them."""

    record: Record
    rows: list[int]
    data: np.ndarray  # (n_ch, n_samples), model units
    sigma: np.ndarray  # (n_ch,)

    def residual(self, sim: np.ndarray) -> np.ndarray:
        """Whitened record minus simulation (all five channels given), flattened."""
        return ((self.data - sim[self.rows]) / self.sigma[:, None]).ravel()
