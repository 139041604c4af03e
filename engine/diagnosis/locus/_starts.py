"""Where a gap outside the catalogue lies, and what the missing term looks like.

When no catalogue effect explains a record (verdict "unexplained"), the
residual of the calibration is explained instead by an *unknown input* d(t) at
one locus of the plant (model 1.1's :class:`~engine.simulation.Disturbance`):
a relative supply-voltage deviation, an additive electromagnetic torque, a
torque on the motor shaft, an angle offset of the backlash zone, a torque on
the drive wheel, or a torque on the load. The method is unknown-input
estimation around the calibrated trajectory, one locus at a time:

1. **Responses** (one batch). d(t) is piecewise linear, with knots every
   ``knot_spacing`` (one of them on the calibrated event); the hats of the
   knots over the test window and ``history`` before it are free, plus two
   unpenalised *extras*: a constant from switch-on and a step at the switch-off.
   For every locus, hat and extra, the calibrated case is simulated with a small
   probe of it; the difference from the calibrated simulation, whitened by the
   calibration's per-channel ``sigma``, is one column of the locus's response
   matrix A (record channels only). The calibrated parameters' own columns (K,
   J1, c, c1, ...) are projected out, so a term that a small change of the
   operating point explains is not credited to any locus.
2. **Linearised fit per locus.** The whitened residual r is fitted by ``A x``
   with a roughness penalty ``lambda (|D x|^2 + eps |x|^2)`` (D first differences:
   a stretch the record does not determine, e.g. a zone offset while the clutch is
   open, is interpolated rather than set to zero); lambda minimises
   ``BIC = RSS + (dof + k) ln(n)``, dof the effective degrees of freedom.
3. **Scan of simple inputs.** A constant or a step of several sizes at every
   locus, with the calibrated parameters re-fitted (linearised, then two damped
   Gauss-Newton steps): a global start where a term is too strong to linearise
   (a zone offset of a few tenths of a millimetre moves every impact). The same from each
   of the calibration's global starts, and a dense scan of a zone offset from each start
   along the widths that keep one side of the zone in place (``_zone_trials``). The parts
   with a rotating mass (motor shaft, drive wheel, load) also get a term that follows the
   state, a Coulomb friction against the part's own speed (:data:`COULOMB_FIELDS`): scanned,
   and fitted with the calibrated parameters by a global search (``_friction_fits``); a
   friction that stops a part is out of reach of any schedule d(t) linearised around a
   trajectory where it moves.
4. **Refinement.** From the better of the two starts, damped Gauss-Newton
   iterations re-linearise each locus around its current estimate (one
   iteration for every locus, more for the best ``refine_loci``); every step is
   kept only if its *simulated* chi2 falls. The loci are ranked by the
   simulated chi2 plus ``(dof + extras + k) ln(n)``.
5. **Sensors.** An arbitrary additive sensor error would explain any residual,
   so the measurement chain gets a parametric library instead: per-channel
   offset and gain, one delay and one first-order low-pass (their response
   columns, unpenalised, linearised).
6. **Evidence.** Posterior weights ``exp(-BIC / 2)``, with the BIC differences
   divided by the best fit's dispersion (chi2 per degree of freedom, at least
   1: a best fit far above the noise means the model is still wrong somewhere),
   give the confidence; loci within ``tie_delta`` of the best are *ties*.
7. **Term.** The best locus's d(t) on the record's grid: amplitude (RMS, peak),
   dominant frequency, and what it follows: ``constant``, ``time`` (a sinusoid
   of fixed frequency, or a transient from the event), ``angle`` (periodic in the
   motor angle, the integral of omega1, so its frequency is proportional to the
   speed) or ``speed`` (a sign and a proportional part of the motor or the load
   speed), each fitted by weighted least squares, the weight of every instant
   the resolution of d there, with and without damping isolated spikes.

Assumptions, limits and measured accuracy: ``docs/diagnosis.md`` ("Locus of a
gap outside the catalogue").
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, cast

import numpy as np

from engine.constants import CHANNELS, DISTURBANCE_MAX_KNOTS, OMEGA_B, W_SMOOTH
from engine.diagnosis.calibration import CalibrationError, CalibrationResult
from engine.diagnosis.candidate import fit_candidate
from engine.diagnosis.space import ModelSpace, default_space
from engine.parallel import single_threaded_blas
from engine.records import Record
from engine.simulation import DISTURBANCE_LOCI, Case, Disturbance, Effect, Locus, SolverSettings, run_cases
from engine.simulation.parameters import COULOMB_FIELDS, DISTURBANCE_MEANING

logger = logging.getLogger(__name__)

__all__ = ["LocusError", "LocusReport", "LocusScore", "LocusSettings", "Term", "estimate_locus"]

#: Largest confidence of a locus whose fit leaves the record far from the noise (``first_guess_chi2``).
FIRST_GUESS_CONFIDENCE: float = 0.5
#: The measurement chain's locus (a parametric library, not an unknown input).
SENSORS: str = "sensors"
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
}
#: Unpenalised extras of every locus's input: a constant from switch-on and a step at the switch-off.
N_EXTRAS: int = 2
#: Steps of the calibrated parameters' response columns, in their units (relative for K, J1, c).
_PARAM_STEP_REL: dict[str, float] = {"K": 1e-3, "J1": 1e-3, "c": 1e-3}
_PARAM_STEP_ABS: dict[str, float] = {"c1": 1e-3, "trigger_offset": 1e-6}
#: How the unknown input is called in a sentence, per locus.
#: (The place is said once, by ``_WHERE``: "a periodic torque of about 0.03 pu at 37 Hz on the load".)
_WHAT: dict[str, str] = {
    "supply": "supply-voltage deviation",
    "motor_electrical": "additive electromagnetic torque",
    "motor_shaft": "torque",
    "clutch": "angle offset of the backlash zone",
    "drive_train": "torque",
    "load": "torque",
}
_WHERE: dict[str, str] = {
    "supply": "at the motor's terminals",
    "motor_electrical": "in the motor",
    "motor_shaft": "on the motor shaft",
    "clutch": "in the clutch",
    "drive_train": "on the drive wheel",
    "load": "on the load",
}


class LocusError(RuntimeError):
    """Raised when the locus cannot be estimated (e.g. the calibrated case cannot be simulated)."""


@dataclass(frozen=True)
class LocusSettings:
    """Settings of :func:`estimate_locus`.

    Parameters
    ----------
    knot_spacing : float
        Spacing of the knots of d(t) [s]; 2.5 ms resolves terms up to about 100 Hz.
    history : float
        How long before the test window d is estimated too [s]: an input before it acts on the
        window only through the state at its start, which the calibrated parameters absorb.
    step : float
        Integrator step of the response simulations [s].
    refine_loci : int
        Loci (the best after one Gauss-Newton iteration of every locus) given the remaining
        ``refine_iterations - 1`` iterations.
    refine_iterations : int
        Gauss-Newton iterations of the best loci (each one batch of a probe per knot and extra,
        and one of three step lengths).
    extras_iterations : int
        Gauss-Newton iterations of the best constant input or step of every locus's scan jointly
        with the calibrated parameters (each two small batches).
    scan_from_starts : bool
        Scan the simple inputs from the calibration's global starts as well as from the
        calibration.
    n_zone_scan : int
        Offsets of the backlash zone scanned densely from every global start along the widths
        that keep one side of the zone in place (0: none; see ``_zone_trials``).
    ridge : float
        Weight of the amplitude penalty relative to the roughness penalty [-].
    n_lambda : int
        Penalty weights tried per locus (log-spaced over the response's singular values).
    tie_delta : float
        Loci whose BIC, divided by the best fit's dispersion (its chi2 per degree of freedom,
        at least 1), is within this of the best are reported as ties [chi2 units] (10: "very
        strong" evidence on Kass and Raftery's scale).
    lowpass_probe_hz : float
        Cut-off of the low-pass whose response column stands for a sensor low-pass [Hz].
    delay_probe : float
        Delay whose response column stands for a sensor delay [s].
    max_frequency_hz : float
        Highest frequency searched in the term [Hz] (at most 0.4 / knot_spacing is used).
    friction_fits : bool
        Fit the Coulomb friction of every part (:data:`COULOMB_FIELDS`) jointly with the
        calibrated parameters by a global search (a candidate's escalated fit,
        :func:`engine.diagnosis.candidate.fit_candidate` with ``global_search=True``), as one
        more start of that locus (False: the friction is only scanned).
    first_guess_chi2 : float
        When the best locus's fit leaves more than this chi2 per residual, the locus is a first
        guess: its confidence is capped at :data:`FIRST_GUESS_CONFIDENCE` and a note says so
        (measured: 6 of the 8 wrong loci of the accuracy run left more than 14, 7 of the 23
        right ones more than 10; ``docs/diagnosis.md``).
    const_share : float
        A term whose mean carries at least this share of its (weighted) energy is ``constant``.
    min_shape_r2 : float
        Below this (weighted) R^2 of the best shape, the term's shape is ``unclear``.
    shape_margin : float
        The best shape's R^2 must exceed the second best's by this factor, else ``unclear``.
    """

    knot_spacing: float = 2.5e-3
    history: float = 10e-3
    step: float = 5e-5
    refine_loci: int = 2
    refine_iterations: int = 2
    extras_iterations: int = 2
    scan_from_starts: bool = True
    n_zone_scan: int = 121
    ridge: float = 1e-2
    n_lambda: int = 60
    tie_delta: float = 10.0
    lowpass_probe_hz: float = 2000.0
    delay_probe: float = 2e-5
    max_frequency_hz: float = 150.0
    first_guess_chi2: float = 10.0
    friction_fits: bool = True
    const_share: float = 0.8
    min_shape_r2: float = 0.3
    shape_margin: float = 1.5


@dataclass(frozen=True)
class LocusScore:
    """How well one locus explains the residual.

    Attributes
    ----------
    bic : float
        Penalised fit ``RSS + (dof + k) ln(n)`` [chi2 units] (linearised).
    delta_bic : float
        BIC minus the best locus's.
    rss : float
        Whitened residual sum of squares after the fit [chi2 units] (linearised).
    dof : float
        Effective degrees of freedom of the locus's fit.
    explained : float
        Fraction of the residual's energy (chi2 of the calibration) the fit removes [-].
    weight : float
        Posterior probability ``exp(-BIC / 2)``, normalised over the candidates (the refined loci,
        the sensors and "none"); 0 for a locus that was not refined.
    simulated : bool
        Whether ``rss`` is the simulated chi2 of the refined estimate (the locus was a candidate)
        rather than the linearised fit's (the locus fell behind in the linearised comparison).
    """

    bic: float
    delta_bic: float
    rss: float
    dof: float
    explained: float
    weight: float
    simulated: bool = False

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Term:
    """What the missing term looks like at the best locus.

    Attributes
    ----------
    kind : str
        What it is (e.g. "torque on the load", "angle offset of the backlash zone", "sensor error").
    unit : str
        Unit of ``series``, ``rms``, ``peak`` (pu torque, rad, x u; empty for a sensor error).
    t : ndarray
        Sample times of the record's grid relative to the event [s].
    series : ndarray
        The estimated d(t) at ``t`` (empty for a sensor error). A Coulomb friction found at the
        locus (``details["coulomb_friction"]``) is not in it: it depends on the part's speed,
        which the record need not carry.
    rms, peak : float
        RMS and largest magnitude of ``series`` over the test window, in ``unit``.
    amplitude : float
        Amplitude of the fitted shape (sinusoid amplitude, mean for a constant, ...), in ``unit``.
    dominant_frequency_hz : float
        Frequency of the best-fitting sinusoid in time, or of the angle-periodic fit at the
        test's mean speed [Hz]; NaN for a constant or unclear term.
    follows : str
        ``constant``, ``time``, ``angle``, ``speed`` or ``unclear``.
    shape_r2 : dict of str to float
        Weighted R^2 of every shape tried (constant, time, transient, angle, speed).
    details : dict
        Shape parameters (order per revolution, time constant, speed channel, sensor values, ...);
        ``coulomb_friction`` [pu] and ``coulomb_field`` (the plant's field) when a Coulomb friction
        against the part's motion was found beside (or instead of) the schedule.
    description : str
        One sentence.
    """

    kind: str
    unit: str
    t: np.ndarray
    series: np.ndarray
    rms: float
    peak: float
    amplitude: float
    dominant_frequency_hz: float
    follows: str
    shape_r2: dict[str, float]
    details: dict[str, Any]
    description: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "unit": self.unit,
            "t": [float(v) for v in self.t],
            "series": [float(v) for v in self.series],
            "rms": _num(self.rms),
            "peak": _num(self.peak),
            "amplitude": _num(self.amplitude),
            "dominant_frequency_hz": _num(self.dominant_frequency_hz),
            "follows": self.follows,
            "shape_r2": {k: _num(v) for k, v in self.shape_r2.items()},
            "details": {k: (_num(v) if isinstance(v, float) else v) for k, v in self.details.items()},
            "description": self.description,
        }


@dataclass
class LocusReport:
    """Outcome of :func:`estimate_locus`.

    Attributes
    ----------
    locus : str or None
        The best locus (one of :data:`engine.simulation.LOCI`), or None when no locus
        explains the residual better than the calibration alone.
    scores : dict of str to LocusScore
        Per locus.
    term : Term or None
        The missing term at the best locus.
    confidence : float
        Posterior weight of the best locus [0, 1]; at most ``FIRST_GUESS_CONFIDENCE`` when its fit
        leaves chi2/n above ``LocusSettings.first_guess_chi2``.
    ties : list of str
        Other loci within ``tie_delta`` of the best: the record cannot tell them apart.
    chi2 : float
        chi2 of the calibration [chi2 units] (record channels, test window).
    chi2_injected : float
        chi2 after injecting the best locus's estimated input into the calibrated case
        (simulated, not linearised); NaN for the sensors locus or when none.
    n_data : int
        Whitened residuals (channels x samples).
    n_simulations : int
        Simulations run.
    seconds : float
        Wall time [s].
    notes : list of str
        Caveats (e.g. the linearisation failed).
    dispersion : float
        chi2 per degree of freedom of the best fit (at least 1); the BIC differences behind
        ``confidence`` and ``ties`` are divided by it.
    """

    locus: str | None
    scores: dict[str, LocusScore]
    term: Term | None
    confidence: float
    ties: list[str]
    chi2: float
    chi2_injected: float
    n_data: int
    n_simulations: int
    seconds: float
    notes: list[str] = field(default_factory=list)
    dispersion: float = 1.0

    @property
    def description(self) -> str:
        """One sentence for the user."""
        if self.locus is None or self.term is None:
            return "no locus explains the residual better than the calibration alone"
        text = self.term.description
        if self.ties:
            text += f" (the record cannot tell this locus from {', '.join(self.ties)})"
        return text

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (series as lists)."""
        return {
            "locus": self.locus,
            "confidence": self.confidence,
            "ties": list(self.ties),
            "description": self.description,
            "scores": {k: v.to_dict() for k, v in self.scores.items()},
            "term": None if self.term is None else self.term.to_dict(),
            "chi2": self.chi2,
            "chi2_injected": _num(self.chi2_injected),
            "n_data": self.n_data,
            "n_simulations": self.n_simulations,
            "seconds": self.seconds,
            "dispersion": self.dispersion,
            "notes": list(self.notes),
        }


def _num(v: float) -> float | None:
    """A float for JSON (None for NaN or infinity)."""
    return float(v) if math.isfinite(v) else None


# --------------------------------------------------------------------------------------------
# the response columns
# --------------------------------------------------------------------------------------------
@dataclass
class _Responses:
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


def _with_input(case: Case, dist: Disturbance) -> Case:
    return Case(case.plant.replace(disturbance=dist), case.sensors)


def _with_friction(case: Case, locus: str, f: float) -> Case:
    """``case`` with ``f`` [pu] more Coulomb friction against the motion of the part at ``locus``."""
    if f == 0.0:
        return case
    name = COULOMB_FIELDS[locus]
    return Case(case.plant.replace(**{name: getattr(case.plant, name) + f}), case.sensors)


def _friction_loci(names: list[str]) -> list[str]:
    """Loci whose Coulomb friction the locus estimate tries: those whose field is not calibrated."""
    return [locus for locus, name in COULOMB_FIELDS.items() if name not in names]


def _parameter_cases(case: Case, names: list[str]) -> tuple[list[Case], list[float], list[str]]:
    """The calibrated parameters, each moved by a small step (for their response columns)."""
    out, steps, used = [], [], []
    for name in names:
        if name in _PARAM_STEP_REL:
            h = _PARAM_STEP_REL[name] * float(getattr(case.plant, name))
            out.append(Case(case.plant.replace(**{name: getattr(case.plant, name) + h}), case.sensors))
        elif name == "c1":
            h = _PARAM_STEP_ABS[name]
            out.append(Case(case.plant.replace(c1=case.plant.c1 + h), case.sensors))
        elif name == "trigger_offset":
            h = _PARAM_STEP_ABS[name]
            lo = -0.005 + h
            t0 = min(max(case.sensors.trigger_offset, lo), 0.005 - h)
            out.append(Case(case.plant, case.sensors.replace(trigger_offset=t0 + h)))
        else:
            continue  # an effect's value fitted with the calibration: not projected
        steps.append(h)
        used.append(name)
    return out, steps, used


def _responses(
    record: Record, cal: CalibrationResult, sigma: np.ndarray, rows: list[int], settings: LocusSettings
) -> _Responses:
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
    shell = _Responses(knots, first_free, {}, np.zeros((0, 0)), [], np.zeros((0, 0)), [], np.zeros((0, 0)), 0)
    zero_x, zero_e = np.zeros(shell.n_free), np.zeros(N_EXTRAS)
    # every simulation carries a schedule, so the integrator cuts its steps at the same knots
    base_case = _with_input(cal.case, shell.schedule("load", zero_x, zero_e))
    cases = [base_case]
    for locus in DISTURBANCE_LOCI:
        cases += [_with_input(cal.case, d) for d in shell.probes(locus, zero_x, zero_e)]
    pcases, psteps, pnames = _parameter_cases(base_case, list(cal.values))
    cases += pcases
    s = base_case.sensors
    delay = (
        s.delay + settings.delay_probe if s.delay + settings.delay_probe <= 0.005 else s.delay - settings.delay_probe
    )
    fc = settings.lowpass_probe_hz if s.lowpass_hz == 0 else 0.9 * s.lowpass_hz
    cases.append(Case(base_case.plant, s.replace(delay=delay)))
    cases.append(Case(base_case.plant, s.replace(lowpass_hz=fc)))
    ch, _, status = run_cases(cases, SolverSettings(max_step=settings.step), grid)
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
    return _Responses(knots, first_free, columns, params, pnames, sensors, names, base, len(cases))


# --------------------------------------------------------------------------------------------
# the fits
# --------------------------------------------------------------------------------------------
@dataclass
class _Fit:
    rss: float
    dof: float
    bic: float
    x: np.ndarray  # knot values (NaN where the locus has no response)
    resolution: np.ndarray  # per knot, in [0, 1]


def _orth(M: np.ndarray, n: int) -> np.ndarray:
    """Orthonormal basis (n, rank) of the column space of M (n, m); columns without a response are dropped.

    A plain QR would turn a zero column (e.g. a supply step after the switch-off, when the motor
    is off) into an arbitrary direction, and projecting that out would remove part of the data.
    """
    if M.shape[1] == 0:
        return np.zeros((n, 0))
    U, sv, _ = np.linalg.svd(M, full_matrices=False)
    rank = int(np.sum(sv > 1e-9 * max(float(sv.max(initial=0.0)), 1e-300)))
    return U[:, :rank]


def _project(Q: np.ndarray, M: np.ndarray) -> np.ndarray:
    """M less its part in the span of Q's orthonormal columns."""
    return M - Q @ (Q.T @ M) if Q.shape[1] else M


def _penalised_fit(A: np.ndarray, r: np.ndarray, k: int, settings: LocusSettings) -> _Fit:
    """Roughness-penalised least squares of r on A, lambda by the penalised fit (BIC with effective dof).

    Worked in the Gram matrix: with the penalty ``pen = L L^T`` and ``B = A L^-T``, the
    eigen-decomposition ``B^T B = V diag(s^2) V^T`` gives, for every lambda, the shrink factors
    ``f = s^2 / (s^2 + lambda)``, the effective dof ``sum(f)`` and the residual
    ``|r|^2 - sum((2 f - f^2) c^2)`` with ``c = V^T B^T r / s``.
    """
    n, m_all = A.shape
    ln_n = math.log(max(n, 2))
    norms = np.linalg.norm(A, axis=0)
    keep = np.flatnonzero(norms > 1e-9 * max(float(norms.max(initial=0.0)), 1e-300))
    x_all = np.full(m_all, np.nan)
    res_all = np.zeros(m_all)
    rr = float(r @ r)
    if keep.size == 0:
        return _Fit(rr, 0.0, rr + k * ln_n, x_all, res_all)
    Ak = A[:, keep]
    m = keep.size
    D = np.diff(np.eye(m), axis=0)
    pen = D.T @ D + settings.ridge * np.eye(m)
    L = np.linalg.cholesky(pen)  # pen = L L^T
    Linv_T = np.linalg.inv(L).T  # x = L^-T w
    G = Linv_T.T @ (Ak.T @ Ak) @ Linv_T
    s2, V = np.linalg.eigh(0.5 * (G + G.T))
    s2 = np.clip(s2, 0.0, None)
    g = V.T @ (Linv_T.T @ (Ak.T @ r))  # = s * c
    ok = s2 > 1e-12 * max(float(s2.max(initial=0.0)), 1e-300)
    c2 = np.where(ok, g**2 / np.where(ok, s2, 1.0), 0.0)
    top = float(s2.max(initial=1.0))
    best: tuple[float, float, float, float] | None = None
    for lam in top * np.logspace(-10, 2, settings.n_lambda):
        f = np.where(ok, s2 / (s2 + lam), 0.0)
        rss = rr - float(np.sum((2.0 * f - f**2) * c2))
        dof = float(np.sum(f))
        bic = rss + (dof + k) * ln_n
        if best is None or bic < best[0]:
            best = (bic, rss, dof, lam)
    assert best is not None
    bic, rss, dof, lam = best
    f = np.where(ok, s2 / (s2 + lam), 0.0)
    w = V @ np.where(ok, g / (s2 + lam), 0.0)
    x = Linv_T @ w
    # resolution: diagonal of (A^T A + lam pen)^-1 A^T A = L^-T V diag(f) V^T L^T
    R = Linv_T @ (V * f) @ (V.T @ L.T)
    x_all[keep] = x
    res_all[keep] = np.clip(np.diag(R), 0.0, 1.0)
    return _Fit(max(rss, 0.0), dof, bic, x_all, res_all)


def _linear_fit(A: np.ndarray, r: np.ndarray, k: int) -> tuple[float, float, np.ndarray]:
    """Unpenalised least squares: (rss, bic, coefficients)."""
    n = A.shape[0]
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    res = r - A @ coef
    rank = int(np.linalg.matrix_rank(A)) if A.size else 0
    rss = float(res @ res)
    return rss, rss + (rank + k) * math.log(max(n, 2)), coef


# --------------------------------------------------------------------------------------------
# the term's shape
# --------------------------------------------------------------------------------------------
def _centred_r2(X: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Weighted R^2 about the weighted mean of y on [1, X], and the coefficients (weighted normal equations)."""
    Xc = np.column_stack([np.ones_like(y), X])
    G = (Xc * w[:, None]).T @ Xc
    try:
        coef = np.linalg.solve(G, (Xc * w[:, None]).T @ y)
    except np.linalg.LinAlgError:
        coef = np.linalg.lstsq(G, (Xc * w[:, None]).T @ y, rcond=None)[0]
    res = y - Xc @ coef
    mean = float(np.sum(w * y) / np.sum(w))
    tss = float(np.sum(w * (y - mean) ** 2))
    return (1.0 - float(np.sum(w * res**2)) / tss if tss > 0 else 0.0), coef


def _spike_weights(series: np.ndarray) -> np.ndarray:
    """Weights that damp isolated spikes of an estimated input (Huber-like beyond 3 robust sigmas).

    Spikes appear where a clutch impact of the record and of the calibrated model fall at
    slightly different instants: the input explains the shift, which says little about its shape.
    """
    med = float(np.median(series))
    scale = 1.4826 * float(np.median(np.abs(series - med)))
    if scale <= 0:
        return np.ones_like(series)
    z = np.abs(series - med) / (3.0 * scale)
    return np.minimum(1.0, 1.0 / np.maximum(z, 1e-12) ** 2)


def _best_of(
    designs: list[tuple[Any, np.ndarray]], series: np.ndarray, weights: list[np.ndarray]
) -> tuple[float, Any, np.ndarray]:
    """The best (R^2, label, coefficients) of several designs, each under several weightings."""
    best: tuple[float, Any, np.ndarray] = (-np.inf, None, np.zeros(0))
    for w in weights:
        for label, X in designs:
            q, coef = _centred_r2(X, series, w)
            if q > best[0]:
                best = (q, label, coef)
    return best


def _shape(
    series: np.ndarray,
    weight: np.ndarray,
    t: np.ndarray,
    base: np.ndarray,
    radius: float,
    settings: LocusSettings,
    f_max: float,
) -> tuple[str, float, float, dict[str, float], dict[str, Any]]:
    """(follows, amplitude, dominant frequency [Hz], R^2 per shape, details) of a term on the grid.

    ``base`` is the calibrated simulation (all five channels) on the grid ``t`` [s from the
    event], ``radius`` the wheel radius [m] (v2 = r Omega_b w_3), ``weight`` the resolution of
    the term at each instant. Every shape is fitted under that weighting and under it times
    :func:`_spike_weights`; each shape keeps its better R^2.
    """
    w = weight / max(float(weight.max(initial=0.0)), 1e-300)
    if float(np.sum(w)) <= 0 or not np.any(series):
        return "unclear", 0.0, math.nan, {}, {}
    weights = [w, w * _spike_weights(series)]
    mean = float(np.sum(w * series) / np.sum(w))
    energy = float(np.sum(w * series**2) / np.sum(w))
    const_share = mean**2 / energy if energy > 0 else 0.0
    r2: dict[str, float] = {"constant": const_share}
    details: dict[str, Any] = {"mean": mean}
    span = float(t[-1] - t[0])
    # time: a sinusoid of fixed frequency
    freqs = np.arange(max(1.5 / span, 2.0), f_max, 0.25)
    q_t, f_t, c_t = _best_of(
        [(float(f), np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])) for f in freqs],
        series,
        weights,
    )
    r2["time"] = q_t
    # time: a transient from the event, exp(-t / tau) for t >= 0
    after = (t >= 0).astype(float)
    q_x, tau_x, c_x = _best_of(
        [(float(tau), (after * np.exp(-np.clip(t, 0.0, None) / tau))[:, None]) for tau in np.geomspace(2e-4, 0.1, 40)],
        series,
        weights,
    )
    r2["transient"] = q_x
    # angle: periodic in the motor angle theta_1 = integral of omega1
    omega1 = base[CHANNELS.index("omega1")]
    dt_s = float(t[1] - t[0])
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (omega1[1:] + omega1[:-1]) * dt_s)])
    w_max = max(float(np.max(np.abs(omega1))), 1e-9)
    swept = float(np.ptp(theta))
    q_a, order_a, c_a = -np.inf, math.nan, np.zeros(3)
    if swept > 0:
        orders = np.arange(max(0.5, 2 * np.pi / swept), 2 * np.pi * f_max / w_max, max(0.05, 0.25 * np.pi / swept))
        q_a, order_a, c_a = _best_of(
            [(float(o), np.column_stack([np.sin(o * theta), np.cos(o * theta)])) for o in orders[:4000]],
            series,
            weights,
        )
    r2["angle"] = q_a
    # speed: a + b tanh(w / W_SMOOTH) + c w of the motor or the load speed (pu)
    speeds = {"w_1": omega1 / OMEGA_B, "w_3": base[CHANNELS.index("v2")] / (OMEGA_B * radius)}
    q_s, speed_s, c_s = _best_of(
        [(name, np.column_stack([np.tanh(sp / W_SMOOTH), sp])) for name, sp in speeds.items()], series, weights
    )
    r2["speed"] = q_s
    if const_share >= settings.const_share:
        details["constant_share"] = const_share
        return "constant", mean, math.nan, r2, details
    shapes = {k: v for k, v in r2.items() if k != "constant"}
    ranked = sorted(shapes, key=lambda k: shapes[k], reverse=True)
    kind = ranked[0]
    second = max(shapes[ranked[1]], 0.0)
    if shapes[kind] < settings.min_shape_r2 or shapes[kind] < settings.shape_margin * second:
        return "unclear", math.sqrt(energy), math.nan, r2, details
    if kind == "time":
        details["frequency_hz"] = f_t
        return "time", float(np.hypot(c_t[1], c_t[2])), f_t, r2, details
    if kind == "transient":
        details["time_constant_s"] = tau_x
        details["transient"] = True
        return "time", float(c_x[1]), math.nan, r2, details
    if kind == "angle":
        mean_speed = float(np.sum(w * np.abs(omega1)) / np.sum(w))
        details["order_per_revolution"] = order_a
        details["mean_speed_rad_s"] = mean_speed
        return "angle", float(np.hypot(c_a[1], c_a[2])), order_a * mean_speed / (2 * np.pi), r2, details
    details["speed"] = speed_s
    details["sign_part"] = float(c_s[1])
    details["proportional_part"] = float(c_s[2])
    return "speed", abs(float(c_s[1])), math.nan, r2, details


#: The part whose motion a Coulomb friction at a locus opposes, and the speed it follows.
_FRICTION_PART: dict[str, tuple[str, str]] = {
    "motor_shaft": ("motor shaft", "w_1"),
    "drive_train": ("drive wheel", "w_2"),
    "load": ("load", "w_3"),
}
#: A schedule smaller than the Coulomb friction beside it is described too when its weighted RMS exceeds
#: this share of the friction (a larger one is the term's shape, the friction described beside it).
_FRICTION_ALONE: float = 0.25


def _describe(locus: str, unit: str, follows: str, amplitude: float, freq: float, details: Mapping[str, Any]) -> str:
    what, where = _WHAT[locus], _WHERE[locus]
    a = "an" if what[0] in "aeiou" else "a"
    amp = f"{abs(amplitude):.2g} {unit}"
    if follows == "constant":
        if locus == "clutch":
            return (
                f"a constant angle offset of about {amplitude:+.2g} rad in the clutch (the backlash zone is off-centre)"
            )
        return f"a constant {what} of about {amplitude:+.2g} {unit} {where}"
    if follows == "time" and details.get("transient"):
        tau = details["time_constant_s"]
        return (
            f"{a} {what} of about {amp} at the event {where}, decaying with a time constant of about {tau * 1e3:.2g} ms"
        )
    if follows == "time":
        return f"a periodic {what} of about {amp} at {freq:.3g} Hz (fixed frequency) {where}"
    if follows == "angle":
        order = details["order_per_revolution"]
        return (
            f"{a} {what} of about {amp} periodic in the motor angle ({order:.3g} periods per revolution, "
            f"about {freq:.3g} Hz at the test's mean speed) {where}"
        )
    if follows == "speed":
        sp = "the motor speed" if details["speed"] == "w_1" else "the load speed"
        return f"{a} {what} of about {amp} that follows {sp} (like a friction) {where}"
    return f"{a} {what} of RMS about {amp} {where}, of no clear shape"


# --------------------------------------------------------------------------------------------
# the entry point
# --------------------------------------------------------------------------------------------
def estimate_locus(
    record: Record,
    calibration: CalibrationResult,
    settings: LocusSettings = LocusSettings(),
    space: ModelSpace | None = None,
) -> LocusReport:
    """Where in the plant the residual of a calibration comes from, and what the missing term looks like.

    Parameters
    ----------
    record : Record
        The record the calibration was fitted on (its test window is used); any subset of channels.
    calibration : CalibrationResult
        The nominal (or the best candidate's) calibration; its ``case``, ``simulation``,
        ``event_time`` and ``sigma`` are used.
    settings : LocusSettings
        Method settings.
    space : ModelSpace, optional
        The calibration's model space (its free parameters and search box), for the joint fits
        of a Coulomb friction with the calibration; default :func:`default_space` of the record.

    Returns
    -------
    LocusReport

    Raises
    ------
    LocusError
        The calibration holds no simulation, or its case cannot be simulated.
    """
    with single_threaded_blas():  # small matrices: BLAS threads only compete with the simulations
        return _estimate(record, calibration, settings, space)


def _estimate(
    record: Record, calibration: CalibrationResult, settings: LocusSettings, space: ModelSpace | None
) -> LocusReport:
    t0 = time.perf_counter()
    record, _ = record.test_window()
    cal = calibration
    if cal.case is None or cal.event_time is None:
        raise LocusError("the calibration holds no simulated case")
    try:
        sim = cal.simulated_record(record)
    except CalibrationError as exc:
        raise LocusError(str(exc)) from None
    names = list(record.channels)
    rows = [CHANNELS.index(n) for n in names]
    sigma = np.array([cal.sigma[n] for n in names])
    data = np.stack([record[n] for n in names])
    model = np.stack([sim[n] for n in names])
    r = ((data - model) / sigma[:, None]).ravel()
    n = r.size
    chi2 = float(r @ r)
    ln_n = math.log(max(n, 2))
    obs = _Observed(record, rows, data, sigma)

    # 1. linearised around the calibrated trajectory, every locus at once
    resp = _responses(record, cal, sigma, rows, settings)
    n_sim = resp.n_simulations
    Q = _orth(resp.params, n)
    k = Q.shape[1]
    rp = _project(Q, r[:, None])[:, 0]
    rr = float(rp @ rp)
    estimates: dict[str, _Estimate] = {}
    for locus in DISTURBANCE_LOCI:
        hats, extras = resp.columns[locus][:, :-N_EXTRAS], resp.columns[locus][:, -N_EXTRAS:]
        # the parameters and the locus's extras are unpenalised: projected out
        free = np.hstack([resp.params, extras])
        Qc = _orth(free, n)
        fit = _penalised_fit(_project(Qc, hats), _project(Qc, r[:, None])[:, 0], Qc.shape[1], settings)
        x = np.nan_to_num(fit.x)
        coef = np.linalg.lstsq(free, r - hats @ x, rcond=None)[0]
        estimates[locus] = _Estimate(x, coef[-N_EXTRAS:], coef[:-N_EXTRAS], fit, fit.rss, fit.bic, refined=False)
    s_rss, s_bic, s_coef = _linear_fit(_project(Q, resp.sensors), rp, k)
    bic_none = rr + k * ln_n

    # 2. a scan of a constant input per locus: a global start where a term is too strong to
    # linearise (a constant offset of the backlash zone shifts the impacts)
    scan, chi2_base, used = _extras_scan(cal, resp, obs, settings)
    n_sim += used
    if settings.friction_fits:
        # on the test window, as the calibration and every locus fit (a longer record is cut, not misread)
        scan, used = _friction_fits(record, cal, space or default_space(record), resp, obs, scan, settings)
        n_sim += used

    # 3. Gauss-Newton refinement: one iteration of every locus (the linearised ranking misleads
    # when the term is strong), then more for the best ones
    for locus in DISTURBANCE_LOCI:
        start, used = _start(cal, locus, resp, estimates[locus], obs, chi2_base, scan[locus], settings)
        estimates[locus], more = _refine(cal, locus, resp, start, obs, 1, settings)
        n_sim += used + more
    for locus in sorted(DISTURBANCE_LOCI, key=lambda key: estimates[key].bic)[: settings.refine_loci]:
        estimates[locus], used = _refine(
            cal, locus, resp, estimates[locus], obs, settings.refine_iterations - 1, settings
        )
        n_sim += used

    # 4. ranking: the refined loci (simulated chi2) and the sensor library. The evidence is
    # scaled by the best fit's dispersion (quasi-likelihood): a best fit far above the noise says
    # the model is still wrong somewhere, and BIC differences in chi2 units then overstate it.
    bics = {locus: e.bic for locus, e in estimates.items() if e.refined}
    bics[SENSORS] = s_bic
    leader = min(bics, key=lambda key: bics[key])
    lead_rss = estimates[leader].rss if leader in estimates else s_rss
    lead_dof = (
        estimates[leader].fit.dof + estimates[leader].n_extras if leader in estimates else float(resp.sensors.shape[1])
    )
    dispersion = max(1.0, lead_rss / max(n - lead_dof - k, 1.0))
    best_bic = min(min(bics.values()), bic_none)
    all_w = {key: math.exp(-0.5 * (b - best_bic) / dispersion) for key, b in {**bics, "none": bic_none}.items()}
    total = sum(all_w.values())
    scores: dict[str, LocusScore] = {}
    for locus in (*DISTURBANCE_LOCI, SENSORS):
        b = bics[locus] if locus in bics else estimates[locus].bic
        rss = estimates[locus].rss if locus in estimates else s_rss
        dof = estimates[locus].fit.dof if locus in estimates else float(resp.sensors.shape[1])
        scores[locus] = LocusScore(
            bic=b,
            delta_bic=b - min(bics.values()),
            rss=rss,
            dof=dof,
            explained=1.0 - rss / chi2 if chi2 > 0 else 0.0,
            weight=all_w[locus] / total if locus in all_w else 0.0,
            simulated=locus in estimates and estimates[locus].refined,
        )
    ranked = sorted(bics, key=lambda key: bics[key])
    best = ranked[0]
    notes: list[str] = []
    if bic_none <= bics[best]:
        logger.info("locus: no locus beats the calibration alone (chi2 %.4g, n %d)", chi2, n)
        return LocusReport(
            locus=None,
            scores=scores,
            term=None,
            confidence=all_w["none"] / total,
            ties=[],
            chi2=chi2,
            chi2_injected=math.nan,
            n_data=n,
            n_simulations=n_sim,
            seconds=time.perf_counter() - t0,
            notes=notes,
        )
    ties = [key for key in ranked[1:] if (bics[key] - bics[best]) / dispersion < settings.tie_delta]
    t_rel = record.grid.time
    chi2_injected = math.nan
    if best == SENSORS:
        values = dict(zip(resp.sensor_names, (float(v) for v in s_coef), strict=True))
        term = _sensor_term(values, names, settings)
    else:
        est = estimates[best]
        chi2_injected = est.rss if est.refined else math.nan
        term = _term(best, est, resp, cal, t_rel, settings)
        if not est.refined or est.rss > chi2:
            notes.append(
                "injecting the estimated input into the calibrated case does not lower chi2: the gap is too "
                "large for the linearisation around the calibrated trajectory; the locus is a first guess"
            )
    confidence = scores[best].weight
    left = scores[best].rss / n
    if left > settings.first_guess_chi2:
        confidence = min(confidence, FIRST_GUESS_CONFIDENCE)
        notes.append(
            f"the best input leaves chi2/n = {left:.3g}, far above the noise: one additive input at one locus "
            f"does not reproduce the record, and the locus is a first guess"
        )
    report = LocusReport(
        locus=best,
        scores=scores,
        term=term,
        confidence=confidence,
        ties=ties,
        chi2=chi2,
        chi2_injected=chi2_injected,
        n_data=n,
        n_simulations=n_sim,
        seconds=time.perf_counter() - t0,
        notes=notes,
        dispersion=dispersion,
    )
    logger.info(
        "locus: %s (confidence %.2f%s), %s; %d simulations, %.1f s",
        best,
        report.confidence,
        f", ties {ties}" if ties else "",
        term.description,
        n_sim,
        report.seconds,
    )
    return report


@dataclass(frozen=True)
class _Observed:
    """The record's channels as the fits see them."""

    record: Record
    rows: list[int]
    data: np.ndarray  # (n_ch, n_samples), model units
    sigma: np.ndarray  # (n_ch,)

    def residual(self, sim: np.ndarray) -> np.ndarray:
        """Whitened record minus simulation (all five channels given), flattened."""
        return ((self.data - sim[self.rows]) / self.sigma[:, None]).ravel()


@dataclass
class _Estimate:
    """One locus's estimate: free hats, extras (constant, step), calibrated-parameter moves, fit, evidence."""

    x: np.ndarray
    e: np.ndarray
    p: np.ndarray
    fit: _Fit
    rss: float  # chi2 of the estimate: linearised, or simulated once refined
    bic: float
    refined: bool
    f: float = 0.0  # Coulomb friction added against the part's motion (COULOMB_FIELDS) [pu]

    @property
    def n_extras(self) -> int:
        """Unpenalised parameters of the input: the constant, the step, and the friction if used."""
        return N_EXTRAS + (self.f > 0.0)


def _moved(case: Case, names: list[str], p: np.ndarray) -> Case:
    """``case`` with its calibrated parameters moved by ``p`` (kept when that is not a valid case)."""
    moved = {k: _current(case, k) + float(v) for k, v in zip(names, p, strict=True)}
    plant = {k: v for k, v in moved.items() if hasattr(case.plant, k)}
    sensors = {k: v for k, v in moved.items() if k not in plant}
    try:
        return Case(case.plant.replace(**plant), case.sensors.replace(**sensors)).validate()
    except ValueError:
        return case


def _start(
    cal: CalibrationResult,
    locus: str,
    resp: _Responses,
    est: _Estimate,
    obs: _Observed,
    chi2_cal: float,
    scan: _Start,
    settings: LocusSettings,
) -> tuple[_Estimate, int]:
    """The start of a locus's refinement, simulated: the better of the linearised estimate and the scan.

    The linearised estimate (input and parameter moves) is tried at full, half and quarter length
    from the calibration (one batch of three); the scan's best simple input (``scan``) is already
    simulated. When neither lowers the calibration's chi2 the start is no input at all. Returns
    the start (``refined``, its chi2 simulated) and the simulations used.
    """
    assert cal.case is not None
    names = resp.param_names
    solver = SolverSettings(max_step=settings.step)
    ln_n = math.log(max(obs.data.size, 2))
    extra = len(names) + N_EXTRAS  # the parameters and the extras
    trials = [
        _with_input(_moved(cal.case, names, a * est.p), resp.schedule(locus, a * est.x, a * est.e))
        for a in _STEP_LENGTHS
    ]
    ch, _, status = run_cases(trials, solver, obs.record.grid)
    chi2s = [float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf for c, st in zip(ch, status, strict=True)]
    i = int(np.argmin(chi2s))
    if min(chi2s[i], scan.chi2) >= chi2_cal:  # neither start helps: the linearisation fails here
        zero = _Estimate(0.0 * est.x, 0.0 * est.e, 0.0 * est.p, est.fit, chi2_cal, chi2_cal + extra * ln_n, True)
        return zero, len(trials)
    if chi2s[i] <= scan.chi2:
        a0 = _STEP_LENGTHS[i]
        out = _Estimate(a0 * est.x, a0 * est.e, a0 * est.p, est.fit, chi2s[i], math.nan, True)
    else:
        out = _Estimate(0.0 * est.x, scan.e, scan.p, est.fit, scan.chi2, math.nan, True, f=scan.f)
    out.bic = out.rss + (out.fit.dof + len(names) + out.n_extras) * ln_n
    return out, len(trials)


def _refine(
    cal: CalibrationResult,
    locus: str,
    resp: _Responses,
    est: _Estimate,
    obs: _Observed,
    iterations: int,
    settings: LocusSettings,
) -> tuple[_Estimate, int]:
    """Damped Gauss-Newton iterations of one locus's input, re-linearised around the current estimate.

    The calibrated parameters stay where the start (:func:`_start`) put them: freeing them again
    at every iteration lets the input and the backlash width trade large, opposite moves whose
    effects on the impact times are far from linear (measured: the chi2 rose 65-fold). Every
    iteration simulates the current estimate with a probe on every free hat and extra (one
    batch), refits the penalised input on its residual, and tries the step at full, half and
    quarter length (one batch of three); the best is kept if its *simulated* chi2 is lower, else
    the iterations stop. Returns the refined estimate, with its BIC from the simulated chi2, and
    the simulations used.
    """
    assert cal.case is not None
    names = resp.param_names
    solver = SolverSettings(max_step=settings.step)
    ln_n = math.log(max(obs.data.size, 2))

    def case_of(base: Case, x: np.ndarray, e: np.ndarray) -> Case:
        return _with_input(base, resp.schedule(locus, x, e))

    x, e, p, fit, chi2_cur = est.x, est.e, est.p, est.fit, est.rss
    used = 0
    base = _with_friction(_moved(cal.case, names, p), locus, est.f)
    for _ in range(iterations):
        cases = [case_of(base, x, e)]
        cases += [_with_input(base, d) for d in resp.probes(locus, x, e)]
        ch, _, status = run_cases(cases, solver, obs.record.grid)
        used += len(cases)
        if status[0] != 0:
            break
        r_cur = obs.residual(ch[0])
        diff = ch[:, obs.rows] - ch[0][None, obs.rows]
        diff[status != 0] = 0.0
        cols = (diff[1:] / obs.sigma[None, :, None]).reshape(len(cases) - 1, -1).T / PROBE[locus]
        A, U = cols[:, :-N_EXTRAS], cols[:, -N_EXTRAS:]
        Qc = _orth(U, U.shape[0])
        # the fit is for the new input as a whole (its roughness is penalised, not the step's)
        r_eff = r_cur + A @ x
        new_fit = _penalised_fit(_project(Qc, A), _project(Qc, r_eff[:, None])[:, 0], Qc.shape[1], settings)
        dx = np.nan_to_num(new_fit.x) - x
        de = np.linalg.lstsq(U, r_cur - A @ dx, rcond=None)[0]
        trials = [case_of(base, x + a * dx, e + a * de) for a in _STEP_LENGTHS]
        ch, _, status = run_cases(trials, solver, obs.record.grid)
        used += len(trials)
        chi2s = [float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf for c, st in zip(ch, status, strict=True)]
        i = int(np.argmin(chi2s))
        if not chi2s[i] < chi2_cur:
            break
        a = _STEP_LENGTHS[i]
        x, e, fit, chi2_cur = x + a * dx, e + a * de, new_fit, chi2s[i]
    out = _Estimate(x, e, p, fit, chi2_cur, math.nan, refined=True, f=est.f)
    out.bic = chi2_cur + (fit.dof + len(names) + out.n_extras) * ln_n
    return out, used


#: Constant inputs of the scan, as fractions of the locus's scale :data:`SCAN_SCALE`.
_SCAN_FRACTIONS: tuple[float, ...] = (-1.0, -0.5, -0.25, -0.1, 0.1, 0.25, 0.5, 1.0)
#: Coulomb frictions of the scan (loci of :data:`COULOMB_FIELDS`), as fractions of :data:`SCAN_SCALE`;
#: friction only opposes motion, so none is negative.
_FRICTION_FRACTIONS: tuple[float, ...] = (0.1, 0.25, 0.5, 1.0)
#: Largest constant input of the scan per locus, in the locus's unit: a fifth of the rated
#: torque, a tenth of the voltage, the angle of the smallest backlash's quarter width.
SCAN_SCALE: dict[str, float] = {
    "supply": 0.1,
    "motor_electrical": 0.2,
    "motor_shaft": 0.2,
    "clutch": 0.006,
    "drive_train": 0.2,
    "load": 0.2,
}


def _extras_scan(
    cal: CalibrationResult, resp: _Responses, obs: _Observed, settings: LocusSettings
) -> tuple[dict[str, _Start], float, int]:
    """chi2 of simple inputs at every locus: a constant, or a step at the switch-off, of several sizes.

    The sizes are :data:`_SCAN_FRACTIONS` of :data:`SCAN_SCALE`. A first batch simulates each
    with the calibrated parameters; a second the same inputs with the calibrated parameters moved
    by the linearised fit of what each first run leaves (the parameters' response columns of the
    calibrated case), so that a term the calibration partly absorbed (e.g. a zone offset taken up
    by the width) is matched with the parameters it needs; then ``extras_iterations`` damped
    Gauss-Newton steps of every locus's best (extras, parameters). Returns the best start per
    locus, the chi2 of the calibrated case, all at the settings' integrator step (the scale of
    every chi2 the refinement compares), and the simulations used.
    """
    assert cal.case is not None
    solver = SolverSettings(max_step=settings.step)
    names = resp.param_names
    zeros = np.zeros(resp.n_free)
    no_move = np.zeros(len(names))
    cases = [_with_input(cal.case, resp.schedule("load", zeros, np.zeros(N_EXTRAS)))]
    bases = _base_points(cal, names) if settings.scan_from_starts else [no_move]
    trials: list[_Trial] = []
    for locus in DISTURBANCE_LOCI:
        for i in range(N_EXTRAS):
            for f in _SCAN_FRACTIONS:
                e = np.zeros(N_EXTRAS)
                e[i] = f * SCAN_SCALE[locus]
                trials += [_Trial(locus, e, base) for base in bases]
    for locus in _friction_loci(names):
        for f in _FRICTION_FRACTIONS:
            trials += [_Trial(locus, np.zeros(N_EXTRAS), base, f * SCAN_SCALE[locus]) for base in bases]
    trials += _zone_trials(cal.case, bases[1:], names, settings.n_zone_scan)
    cases += [t.case(cal.case, names, resp, t.p) for t in trials]
    ch, _, status = run_cases(cases, solver, obs.record.grid)
    chi2_base = float(np.sum(obs.residual(ch[0]) ** 2)) if status[0] == 0 else math.inf
    best = {locus: _Start(np.zeros(N_EXTRAS), no_move, math.inf) for locus in DISTURBANCE_LOCI}
    moves = []
    for t, c, st in zip(trials, ch[1:], status[1:], strict=True):
        if st != 0:
            moves.append(t.p)
            continue
        res = obs.residual(c)
        c2 = float(res @ res)
        if c2 < best[t.locus].chi2:
            best[t.locus] = _Start(t.e, t.p, c2, t.f)
        moves.append(t.p + np.linalg.lstsq(resp.params, res, rcond=None)[0] if names else no_move)
    used = len(cases)
    if names:
        cases = [t.case(cal.case, names, resp, p) for t, p in zip(trials, moves, strict=True)]
        ch, _, status = run_cases(cases, solver, obs.record.grid)
        used += len(cases)
        for t, p, c, st in zip(trials, moves, ch, status, strict=True):
            c2 = float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf
            if c2 < best[t.locus].chi2:
                best[t.locus] = _Start(t.e, p, c2, t.f)
    for _ in range(settings.extras_iterations):
        best, n = _polish_extras(cal, resp, obs, best, solver)
        used += n
    return best, chi2_base, used


def _friction_effect(case: Case, locus: str) -> Effect:
    """A Coulomb friction against the motion of the part at ``locus``, as an effect on top of ``case``:
    its value is the field's total (neutral: the case's), at most :data:`SCAN_SCALE` more."""
    name = COULOMB_FIELDS[locus]
    now = float(getattr(case.plant, name))
    return Effect(
        f"{locus}_coulomb_friction",
        f"Coulomb friction against the motion of the part at {locus} ({name} * tanh(w / W_SMOOTH))",
        "plant",
        name,
        "set",
        (now, now + SCAN_SCALE[locus]),
        now,
        "pu",
        cast(Locus, locus),
    )


def _friction_fits(
    record: Record,
    cal: CalibrationResult,
    space: ModelSpace,
    resp: _Responses,
    obs: _Observed,
    best: dict[str, _Start],
    settings: LocusSettings,
) -> tuple[dict[str, _Start], int]:
    """Every part's Coulomb friction fitted jointly with the calibrated parameters, globally.

    The scan's coarse friction sizes and two Gauss-Newton steps find a friction only near the
    calibrated point; one strong enough to stop a part moves the impacts, and its valley in
    (friction, K, J1) is narrower than the scan's steps, and the calibration's global starts,
    searched without the friction, are off too. On the record of
    ``tests/test_locus.py::test_a_wheel_friction_that_stops_the_wheel_is_a_coulomb_friction_on_the_drive_wheel``
    (a wheel friction of 0.09 pu at the nominal plant, 40 dB; the test asserts the last is above 100):
    the true friction, J1 and c give chi2/n 1.02 with the true K, 159 with K 1 % off and 547 with
    K 3 % off. The joint fit is a catalogue candidate's fit with the global search
    (:func:`~engine.diagnosis.candidate.fit_candidate`, ``global_search=True``; 2-3 s and about
    1000 simulations each on 2 cores). Its point, simulated at the locus's step, replaces the
    scan's start of that locus where its chi2 is lower. Returns the starts and the simulations
    used.
    """
    assert cal.case is not None
    names = resp.param_names
    used = 0
    fitted: list[_Trial] = []
    for locus in _friction_loci(names):
        effect = _friction_effect(cal.case, locus)
        try:
            cand = fit_candidate(record, cal, space, effect, global_search=True)
        except (CalibrationError, ValueError) as exc:
            logger.info("locus: the %s friction could not be fitted (%s)", locus, exc)
            continue
        fit = cand.calibration
        if fit is None:
            continue
        used += fit.n_simulations
        p = np.array([fit.values[n] - _current(cal.case, n) if n in fit.values else 0.0 for n in names])
        f = fit.values[effect.name] - effect.neutral
        if f > 0.0:
            fitted.append(_Trial(locus, np.zeros(N_EXTRAS), p, f))
    if not fitted:
        return best, used
    ch, _, status = run_cases(
        [t.case(cal.case, names, resp, t.p) for t in fitted], SolverSettings(max_step=settings.step), obs.record.grid
    )
    used += len(fitted)
    out = dict(best)
    for t, c, st in zip(fitted, ch, status, strict=True):
        c2 = float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf
        logger.debug("locus: %s friction fitted %.4g pu, chi2 %.4g (scan %.4g)", t.locus, t.f, c2, out[t.locus].chi2)
        if c2 < out[t.locus].chi2:
            out[t.locus] = _Start(t.e, t.p, c2, t.f)
    return out, used


def _base_points(cal: CalibrationResult, names: list[str]) -> list[np.ndarray]:
    """Points the scan of simple inputs starts from, as moves of the calibrated parameters: the
    calibration itself, and each of its global starts (the early window's best points).

    A missing term that acts late (after the first impacts) pulls the continuation of the nominal
    calibration away from the early window's points, which were near the truth; an input scanned
    only at the calibrated parameters then has to undo that pull too. Pass 1b of the single
    candidates starts from the same points for the same reason (``refit_from_starts``).
    """
    assert cal.case is not None
    out = [np.zeros(len(names))]
    for start in cal.starts:
        p = np.array([start[n] - _current(cal.case, n) if n in start else 0.0 for n in names])
        if np.any(p != 0.0):
            out.append(p)
    return out


def _current(case: Case, name: str) -> float:
    """A calibrated parameter's value in a case (plant or sensors)."""
    return float(getattr(case.plant, name) if hasattr(case.plant, name) else getattr(case.sensors, name))


def _zone_trials(case: Case, starts: list[np.ndarray], names: list[str], n: int) -> list[_Trial]:
    """A dense scan of a constant offset of the backlash zone from each global start, along the
    widths that keep one side of the zone in place.

    The zone is ``-b + o <= theta_1 - theta_2 <= b + o`` (half-width ``b = K / r``). Where the
    early window closes the clutch on one side only, an offset ``o`` looks like a width ``K + o r``
    (contact on the positive side) or ``K - o r``, and the early window's starts carry that width.
    From such a start the true point lies on the line ``(o, K_start - o r)`` (or ``+ o r``), and
    along it chi2 has a narrow valley in ``o`` (on a synthetic record at K 7.6 mm, o = -3.8 mrad,
    36 dB: chi2/n 1.2 at the true offset, 341 and 265 at -3.0 and -4.5 mrad), which the coarse
    scan of every locus steps over and no Gauss-Newton step from it reaches. So ``n`` offsets
    evenly spread over ``+-SCAN_SCALE["clutch"]`` on both lines from every start (none when the
    width is not calibrated).
    """
    if n <= 0 or "K" not in names or not starts:
        return []
    out = []
    k = names.index("K")
    for o in np.linspace(-1.0, 1.0, n) * SCAN_SCALE["clutch"]:
        e = np.zeros(N_EXTRAS)
        e[0] = o
        for start in starts:
            for side in (1.0, -1.0):
                p = start.copy()
                p[k] -= side * o * case.plant.r
                out.append(_Trial("clutch", e, p))
    return out


@dataclass(frozen=True)
class _Start:
    """A starting point of the refinement: extras (constant, step), parameter moves, its chi2, and
    the Coulomb friction added at the locus (:data:`COULOMB_FIELDS`) [pu]."""

    e: np.ndarray
    p: np.ndarray
    chi2: float
    f: float = 0.0


@dataclass(frozen=True)
class _Trial:
    """A simple input of the scan: the locus, its extras, the parameter moves it starts from, and
    a Coulomb friction added at the locus [pu]."""

    locus: str
    e: np.ndarray
    p: np.ndarray
    f: float = 0.0

    def case(self, cal_case: Case, names: list[str], resp: _Responses, p: np.ndarray) -> Case:
        """The calibrated case with this input, its parameters moved by ``p``."""
        zeros = np.zeros(resp.n_free)
        moved = _with_friction(_moved(cal_case, names, p), self.locus, self.f)
        return _with_input(moved, resp.schedule(self.locus, zeros, self.e))


def _polish_extras(
    cal: CalibrationResult, resp: _Responses, obs: _Observed, best: dict[str, _Start], solver: SolverSettings
) -> tuple[dict[str, _Start], int]:
    """One damped Gauss-Newton step of every locus's (extras, friction, parameter moves), jointly.

    One batch of finite differences (each extra, the Coulomb friction where the start has one, and
    each calibrated parameter, around each locus's current point) and one batch of three step
    lengths; a locus keeps the step if its simulated chi2 falls. The friction stays >= 0.
    """
    assert cal.case is not None
    names = resp.param_names
    zeros = np.zeros(resp.n_free)
    loci = [locus for locus in DISTURBANCE_LOCI if math.isfinite(best[locus].chi2)]
    cases: list[Case] = []
    steps: dict[str, list[float]] = {}
    for locus in loci:
        start = best[locus]
        h = 5.0 * PROBE[locus]
        trial = _Trial(locus, start.e, start.p, start.f)
        centre = trial.case(cal.case, names, resp, start.p)
        cases.append(centre)
        if start.f > 0.0:  # a friction is polished with the parameters alone (the extras would trade with it)
            cases.append(_with_friction(centre, locus, h))
        else:
            for i in range(N_EXTRAS):
                de = np.zeros(N_EXTRAS)
                de[i] = h
                cases.append(_with_input(centre, resp.schedule(locus, zeros, start.e + de)))
        pcases, psteps, _ = _parameter_cases(centre, names)
        cases += pcases
        steps[locus] = [h] * (1 if start.f > 0.0 else N_EXTRAS) + psteps
    ch, _, status = run_cases(cases, solver, obs.record.grid)
    used = len(cases)
    trials: list[_Trial] = []
    i = 0
    for locus in loci:
        m = len(steps[locus])
        block, st = ch[i : i + 1 + m], status[i : i + 1 + m]
        i += 1 + m
        start = best[locus]
        n_in = 1 if start.f > 0.0 else N_EXTRAS  # the input's own unknowns, before the parameters
        if np.any(st != 0) or m != n_in + len(names):
            continue
        r0 = obs.residual(block[0])
        J = np.stack([(obs.residual(b) - r0) / h for b, h in zip(block[1:], steps[locus], strict=True)], axis=1)
        delta = -np.linalg.lstsq(J, r0, rcond=None)[0]
        de, df = (0.0 * start.e, float(delta[0])) if start.f > 0.0 else (delta[:N_EXTRAS], 0.0)
        trials += [
            _Trial(locus, start.e + a * de, start.p + a * delta[n_in:], max(start.f + a * df, 0.0))
            for a in _STEP_LENGTHS
        ]
    if not trials:
        return best, used
    tcases = [t.case(cal.case, names, resp, t.p) for t in trials]
    ch, _, status = run_cases(tcases, solver, obs.record.grid)
    used += len(tcases)
    out = dict(best)
    for t, c, st in zip(trials, ch, status, strict=True):
        c2 = float(np.sum(obs.residual(c) ** 2)) if st == 0 else math.inf
        if c2 < out[t.locus].chi2:
            out[t.locus] = _Start(t.e, t.p, c2, t.f)
    return out, used


#: Step lengths tried by every Gauss-Newton iteration of :func:`_refine`.
_STEP_LENGTHS: tuple[float, ...] = (1.0, 0.5, 0.25)


def _term(
    locus: str, est: _Estimate, resp: _Responses, cal: CalibrationResult, t_rel: np.ndarray, settings: LocusSettings
) -> Term:
    """The estimated input of ``locus`` on the record's grid, and its shape."""
    assert cal.case is not None and cal.event_time is not None
    t_abs = cal.event_time + t_rel
    series = np.interp(t_abs, resp.knots, resp.values(est.x, est.e)) + np.where(t_rel >= 0, est.e[1], 0.0)
    # how well the record determines the input at each instant (the constant is determined throughout)
    resolution = np.ones(resp.knots.size)
    resolution[resp.first_free :] = est.fit.resolution
    weight = np.interp(t_abs, resp.knots, resolution)
    unit = DISTURBANCE_MEANING[locus][1]
    f_max = min(settings.max_frequency_hz, 0.4 / float(resp.knots[1] - resp.knots[0]))
    follows, amp, freq, r2, details = _shape(series, weight, t_rel, resp.base, cal.case.plant.r, settings, f_max)
    description = _describe(locus, unit, follows, amp, freq, details)
    if est.f > 0.0:  # a Coulomb friction at the locus: it follows the part's speed, beside the schedule
        part, speed = _FRICTION_PART[locus]
        rms = float(np.sqrt(np.average(series**2, weights=weight))) if np.any(weight > 0) else 0.0
        friction = f"a Coulomb friction of about {est.f:.2g} pu against the motion of the {part} (it follows the sign of {speed})"
        details = {**details, "coulomb_friction": est.f, "coulomb_field": COULOMB_FIELDS[locus]}
        if rms <= est.f:  # the friction is the larger part: it is the term's shape
            if rms > _FRICTION_ALONE * est.f:
                friction += "; besides it, " + description
            description = friction
            details["speed"] = speed
            follows, amp, freq = "speed", est.f, math.nan
        else:
            description += "; besides it, " + friction
    return Term(
        kind=_WHAT[locus],
        unit=unit,
        t=t_rel,
        series=series,
        rms=float(np.sqrt(np.mean(series**2))),
        peak=float(np.max(np.abs(series))),
        amplitude=float(amp),
        dominant_frequency_hz=float(freq),
        follows=follows,
        shape_r2=r2,
        details=details,
        description=description,
    )


def _sensor_term(values: Mapping[str, float], names: list[str], settings: LocusSettings) -> Term:
    """The sensor library's fit as a term (no time series).

    The delay and low-pass columns are responses to the probe delay and the probe cut-off, so their
    coefficients scale those: a delay of about ``coef * delay_probe`` [s], and a first-order lag of
    about ``coef / (2 pi lowpass_probe_hz)`` [s] (valid while the terms are small).
    """
    parts = []
    details: dict[str, Any] = {}
    for name in names:
        off, gain = values[f"offset_{name}"], values[f"gain_{name}"]
        details[f"offset_{name}"] = off
        details[f"gain_error_{name}"] = gain
        parts.append(f"{name}: gain {1 + gain:.3g}, offset {off:+.3g}")
    delay = values["delay"] * settings.delay_probe
    lag = values["lowpass"] / (2 * math.pi * settings.lowpass_probe_hz)
    details["delay_s"] = delay
    details["lag_s"] = lag
    parts.append(f"delay {delay * 1e6:+.3g} us, first-order lag {lag * 1e6:+.3g} us")
    return Term(
        kind="sensor error",
        unit="",
        t=np.zeros(0),
        series=np.zeros(0),
        rms=math.nan,
        peak=math.nan,
        amplitude=math.nan,
        dominant_frequency_hz=math.nan,
        follows="constant",
        shape_r2={},
        details=details,
        description="an error of the measurement chain (" + "; ".join(parts) + ")",
    )
