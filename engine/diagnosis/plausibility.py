"""Is the record what this plant can produce? Warnings that name the suspicion and what to check.

A record in a wrong unit or with a wrong sample interval is not refused by anything else: the
calibration fits it as well as it can and a width comes out, confidently (issue 50: omega1 in rpm
and a1 in g gave 7.5 mm for 5 mm; a sample interval 10x too long gave a width). These checks look
for what the plant cannot produce and say so in a :class:`PlausibilityWarning`, one or two
sentences with the suspicion and what to check. They warn, they never refuse (the record
boundary refuses what no computation survives, :mod:`engine.records.limits`).

* :func:`check_record` needs no fit (cheap, cached simulations of the plausible box only):

  - ``constant_channel``: a channel without a single change over the test window (a stuck or
    disconnected sensor, a placeholder column).
  - ``channel_scale``: a channel whose peak lies more than :data:`RANGE_MARGIN` times outside
    the range of peaks the plant produces over its plausible box (:func:`peak_envelope`); when a
    unit mistake (:func:`unit_suspects`) brings it into that range, the message names the unit.
  - ``sample_interval``: the load's motion (v2, and a2 integrated: :data:`TIME_CHANNELS`) has a rise
    time (:func:`rise_time`: the shortest time it takes to cover 15-25 % of its range) more than
    :data:`TIME_MARGIN` times outside the range the plant produces over its plausible box
    (:func:`rise_envelope`, from the same cached simulations, in seconds so that any grid compares),
    and the record read with its interval multiplied by a factor of :data:`TIME_FACTORS` brings it back
    within that margin (the issue's CSV with 1 ms declared for 0.1 ms samples, which a record without a
    fit used to pass). Measured (``check_record`` on noiseless records and with white or coloured noise
    at 30 and 40 dB; each count per noise level): no warning on 446 records with one catalogued effect
    at each of its bounds at the box's 16 corners (worst: 1.6x outside the box's range), on 846 with two
    effects at their bounds at 6 corners (worst 2.1x), on the box's 80 cases rendered at 1 ms and at
    10 us (1.08x), and on the 30 blind records of ``out/dev-width-seed233`` (27 with v2: 1.16x). Read at
    10x or 0.1x its interval, a record of 32 box points warns in 32 of 32 cases (v2 alone, a2 alone or
    all five channels; 30 and 40 dB), and the reading named includes the true one; at 5x too long in 32 of
    32, at 5x too short in 12-14 of 32, at 2x in none. a1, m_el and omega1 are not read (see
    :data:`TIME_CHANNELS`): on their own they never warn. v2 alone at 20 dB (outside the blind runs'
    30-50 dB) warns on 10 of 446 effect records (noise read as fast motion; 0 at 25 dB); a2 integrated
    and a record with both do not (the two must agree).

* :func:`check_calibration` reads a calibration of the record (its residuals and simulation):

  - ``channel_scale``: a channel the fit does not reproduce (chi2 per sample above
    :data:`MISFIT_CHI2`) whose peak is out of the plant's range as above, or whose least-squares
    scale against the calibrated simulation (record = s x simulation) is far from 1 (outside
    1/:data:`SCALE_FAR` to :data:`SCALE_FAR`), explains the misfit (the scaled simulation fits
    :data:`EVIDENCE` times better) and matches a unit mistake within :data:`UNIT_MATCH`.
  - ``sample_interval``: the fit is poor and the record, read with its sample interval multiplied
    by one of :data:`TIME_FACTORS`, fits the plant :data:`EVIDENCE` times better
    (:func:`time_scale_evidence`, a few dozen short simulations, run only on a poor fit): the
    witness of the motor-side channels, which :func:`check_record` cannot read.
  - ``misfit``: chi2 per sample of a channel above :data:`MISFIT_CHI2`: the model does not
    reproduce the record there and numbers fitted to it carry model error.

Both return lists; :func:`merge_warnings` joins them without repeating a (code, channel).
Where they fail: a plant with a large unmodelled effect can move a channel's peak out of the
box's range (a contact 10x stiffer raises a1's by 3.7x, the most of any catalogued effect,
measured at the catalogue's bounds) and, on one channel, can look like a time scale (a load
inertia 2x fits omega1 read at half the interval 49x better); the messages therefore say what
else the finding may mean. The load's rise time tells a wrong interval only by a factor of about 5 or
more, and not which of two neighbouring factors (the box's range is 2.8x wide): the warning names every
reading that brings it inside.
"""

from __future__ import annotations

import functools
import itertools
import logging
import math
from collections.abc import Collection, Iterable
from dataclasses import dataclass
from typing import Any, Final

import numpy as np

from engine.constants import CHANNELS, MAX_SAMPLE_INTERVAL, MIN_SAMPLE_INTERVAL, SAMPLE_INTERVAL
from engine.diagnosis.calibration import CalibrationResult, CalibrationSettings, sobol
from engine.diagnosis.space import default_space, drive_bounds
from engine.records import GridError, Record, SampleGrid
from engine.records.units import UNITS, UnitError, factor
from engine.simulation import Case, run_cases
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription

logger = logging.getLogger(__name__)

__all__ = [
    "ENVELOPE_POINTS",
    "EVIDENCE",
    "MISFIT_CHI2",
    "OTHER_UNITS",
    "RANGE_MARGIN",
    "RISE_FRACTIONS",
    "RISE_RESOLUTION",
    "SCALE_FAR",
    "TIME_CHANNELS",
    "TIME_FACTORS",
    "TIME_MARGIN",
    "TIME_POINTS",
    "UNIT_MATCH",
    "PlausibilityWarning",
    "check_calibration",
    "check_record",
    "interval_message",
    "merge_warnings",
    "peak_envelope",
    "rise_envelope",
    "rise_time",
    "time_scale_evidence",
    "unit_suspects",
]

#: chi2 per sample of a channel above which the calibrated model is said not to reproduce it: the
#: residual's RMS is then 5 times the noise. A fit to the noise gives 1 (0.9-1.1 measured on clean
#: records at 30-50 dB, coloured noise included); the issue's misfits that gave a width without a
#: warning sat at 172-1105, unit and interval mistakes at 1e3-1e5 (measured here).
MISFIT_CHI2: Final[float] = 25.0
#: How far outside the range of peaks the plant produces (:func:`peak_envelope`) a channel's peak
#: must lie to be suspect [-]. The unit mistakes (:data:`OTHER_UNITS` and the accepted units) are
#: factors of 9.5 or more: with 2, omega1 in rpm or deg/s, v2 in mm/s and m_el in % are caught
#: anywhere in the box (omega1 in rpm at the box's slowest: 22.7 against 2 x 8.5 rad/s), a1 in g
#: wherever its true peak is below 136 m/s^2 (a2: 60), i.e. all but the box's most violent corner.
#: The catalogued effects at their bounds change a channel's peak by at most 3.7x (a contact 10x
#: stiffer, on a1), which reaches 2x beyond the box only at its edge.
RANGE_MARGIN: Final[float] = 2.0
#: A least-squares scale between record and calibrated simulation outside [1/SCALE_FAR, SCALE_FAR]
#: is far from 1 [-]: no plant parameter in the box scales a channel by 2 while fitting it.
SCALE_FAR: Final[float] = 2.0
#: Tolerance of a match between an observed factor and a unit mistake's factor [-]: 25 %, wider
#: than the spread of a misfit's least-squares scale around the true factor (9.16 for rpm's 9.55
#: when the other channels pin the fit) and narrower than the gap between any two candidates.
UNIT_MATCH: Final[float] = 1.25
#: Factors tried on the sample interval [-]: the record read at ``Ts * a`` (a < 1: the declared
#: interval was too long, the record looks slower than the plant). Decimal slips (10x), the usual
#: decimations (2x, 5x) and both directions.
TIME_FACTORS: Final[tuple[float, ...]] = (0.1, 0.2, 0.5, 2.0, 5.0, 10.0)
#: How many times better (in chi2) another reading of a record must fit the plant than the record as
#: read for a warning to name it [-]: the record's channel scaled to a unit's factor (``channel_scale``
#: from the least-squares scale; omega1 in rpm, the other channels pinning the fit: 2350x) or read
#: with a scaled sample interval (``sample_interval``). Measured on the interval (16 box points,
#: first 20 ms after the event): records with the interval declared 2-10x wrong score 10 to 1e4 on
#: most channels and on the full record (m_el alone, mostly a step, stays below 7); correct records
#: with catalogued effects at their bounds score below 2.5 on the full record, up to 10 on a single
#: a1 or m_el channel and 49 on omega1 alone with a load inertia 2x (hence the message's "if it is").
EVIDENCE: Final[float] = 10.0
#: Points of the plausible box (scrambled Sobol) simulated per time factor, besides the calibrated
#: case and the nominal one [-]: enough to come near the best fit of the smooth first 20 ms after
#: the event (the calibration's first horizon), cheap (18 cases x 7 grids, about 0.1-0.3 s).
TIME_POINTS: Final[int] = 16
#: Points of the plausible box (scrambled Sobol, besides its 16 corners) whose peaks make
#: :func:`peak_envelope` [-]: the corners alone miss the lowest peaks (a1 24.9 inside, 27.8 at the
#: corners); 64 points come within a few % of 256.
ENVELOPE_POINTS: Final[int] = 64
#: Channels whose time scale :func:`check_record` compares with the plant's without a fit: the load's speed v2
#: and its acceleration a2 (integrated over the test window, it is v2 but for a constant). The load's motion over
#: the test window is set by the resilient element, the load's inertia and the absorber; no instant in it is
#: sharp (no impact, no switch-off step), so its time scale is the plant's and not the sampling's. The motor side
#: moves by impacts whose duration a contact 10x stiffer or softer changes by 3.2x, and the switch-off makes a1
#: and m_el jump within one sample at any interval: their time scales say nothing a catalogued effect cannot
#: also say. Measured with :func:`rise_time` (30 dB, the box's range from its noiseless cases): a1's and m_el's
#: rise times are the switch-off's jump (box 0.03-0.95 and 0.01-0.70 ms) and a record read at 10x or 0.1x its
#: interval stays inside; omega1 read at 10x or 0.1x lies at most 2.0x outside in the median, while a speed
#: quantisation at its bound puts it 9.4x outside.
TIME_CHANNELS: Final[tuple[str, ...]] = ("a2", "v2")
#: Fractions of a channel's range whose fastest rise times make its time scale (:func:`rise_time`, their
#: geometric mean) [-]: small enough to be local (the time of the steepest stretch, not of the window: a fraction
#: near the height of a first small hump makes the time jump to a later, larger one, as 0.3-0.35 does with a
#: softer resilient element), large enough that noise at 20-30 dB does not reach it by itself.
RISE_FRACTIONS: Final[tuple[float, ...]] = (0.15, 0.2, 0.25)
#: Finest time step at which :func:`rise_time` reads a channel [s] (MODEL.md's interval, the envelope's grid):
#: a record on a finer grid is averaged over blocks of this length first, so that a 10 us record is as noisy,
#: per step, as one at 0.1 ms and its rise times are comparable with the envelope's.
RISE_RESOLUTION: Final[float] = SAMPLE_INTERVAL
#: How far outside the range of rise times the plant produces over its plausible box (:func:`rise_envelope`) a
#: channel's rise time must lie, as a factor, before :func:`check_record` tries the readings of
#: :data:`TIME_FACTORS` [-]; a reading brings it back when it lies within the same factor of the range. Measured
#: (module docstring): one catalogued effect at its bound moves the load's rise time at most 1.6x outside the
#: box's range, two at their bounds at most 2.1x; a record read at 10x or 0.1x its interval lies 3.8x or more
#: outside, at 5x 2.9x or more (at 0.2x 1.8x or more).
TIME_MARGIN: Final[float] = 2.5
#: Units a channel is often given in by mistake beside the accepted ones
#: (:data:`engine.records.units.UNITS`): channel -> unit -> factor to the model unit.
OTHER_UNITS: Final[dict[str, dict[str, float]]] = {
    "a1": {"mm/s^2": 1e-3},
    "a2": {"mm/s^2": 1e-3},
    "omega1": {"deg/s": math.pi / 180.0},
    "m_el": {"%": 1e-2},
    "v2": {"cm/s": 1e-2},
}
#: Relative slack of a time-scaled interval against the accepted range (as :mod:`engine.records.grid`).
_SLACK = 1e-9
#: Ratio between successive lags of :func:`rise_time` [-] (its times are interpolated between them).
_LAG_RATIO = 1.06
#: Share of a channel's samples left out at each end of its range in :func:`rise_time` [-]: a noise spike does not
#: set the range.
_RANGE_QUANTILE = 0.005
#: What to ask when a record's dynamics point at another sample interval (both checks of ``sample_interval``).
_INTERVAL_QUESTION = (
    "is the sample interval (or the time column) right? If it is, the plant's dynamics are far from the model's."
)


@dataclass(frozen=True)
class PlausibilityWarning:
    """A suspicion that a record is not what the plant can produce, and what to check.

    Attributes
    ----------
    code : str
        Short stable id: ``constant_channel``, ``channel_scale``, ``sample_interval``, ``misfit`` (and
        ``stand_in``, :mod:`engine.diagnosis.open_world`).
    message : str
        One or two sentences: the suspicion, with the numbers behind it, and what to check.
    channel : str or None
        The channel it concerns (None when it concerns the record as a whole).
    """

    code: str
    message: str
    channel: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready ``{"code", "message", "channel"}``."""
        return {"code": self.code, "message": self.message, "channel": self.channel}


def merge_warnings(*groups: Iterable[PlausibilityWarning]) -> list[PlausibilityWarning]:
    """The warnings of several checks in order, the first of each (code, channel) only."""
    seen: set[tuple[str, str | None]] = set()
    out = []
    for w in itertools.chain(*groups):
        if (w.code, w.channel) not in seen:
            seen.add((w.code, w.channel))
            out.append(w)
    return out


# -- the plant's range ----------------------------------------------------------------------------
@functools.lru_cache(maxsize=4)
def _box_records(drive: DriveDescription = REFERENCE_DRIVE) -> np.ndarray:
    """The channels of the drive's plausible box's cases on its protocol grid, shape (cases, 5, n_samples) (failed
    cases left out).

    The box is the calibration's (:func:`engine.diagnosis.space.drive_bounds`: K, J1, c, c1; for the reference
    :data:`engine.diagnosis.space.DEFAULT_BOUNDS` on MODEL.md's grid), its 16 corners and :data:`ENVELOPE_POINTS`
    scrambled Sobol points, simulated once per process and drive with the nominal sensors.
    """
    box = drive_bounds(drive)
    names = list(box)
    lo = np.array([box[n][0] for n in names])
    hi = np.array([box[n][1] for n in names])
    corners = np.array(list(itertools.product((0.0, 1.0), repeat=len(names))))
    inside = sobol(len(names), scramble=True, seed=0).random(ENVELOPE_POINTS)
    cases = [
        Case(drive.plant(**{n: float(v) for n, v in zip(names, lo + u * (hi - lo), strict=True)}))
        for u in np.vstack([corners, inside])
    ]
    solver = drive.solver(CalibrationSettings().search_step)
    channels, _, status = run_cases(cases, solver, drive.grid())
    logger.debug("plausible box: %d of %d cases simulated", int(np.sum(status == 0)), len(cases))
    out = channels[status == 0]
    out.setflags(write=False)
    return out


@functools.lru_cache(maxsize=4)
def peak_envelope(drive: DriveDescription = REFERENCE_DRIVE) -> dict[str, tuple[float, float]]:
    """Smallest and largest peak ``max |x|`` of each channel over the drive's plausible box, in model units.

    The box's cases (:func:`_box_records`: its 16 corners and :data:`ENVELOPE_POINTS` scrambled Sobol
    points of K, J1, c, c1) are simulated once per process on the drive's protocol grid (MODEL.md's for the
    reference; the test window; the peaks barely depend on the interval: within 2 % from 10 us to 1 ms,
    measured) with the nominal sensors.

    Parameters
    ----------
    drive : DriveDescription
        The drive (default MODEL.md's reference plant).

    Returns
    -------
    dict of str to (float, float)
        Channel -> (lowest peak, highest peak) [model unit].
    """
    peaks = np.max(np.abs(_box_records(drive)), axis=2)
    return {c: (float(peaks[:, j].min()), float(peaks[:, j].max())) for j, c in enumerate(CHANNELS)}


def _load_motion(channel: str, x: np.ndarray, sample_interval: float) -> np.ndarray:
    """The samples whose rise time is read: v2 as it is, a2 integrated over the samples given (v2 but for a constant)."""
    x = np.asarray(x, dtype=float)
    return np.cumsum(x) * sample_interval if channel == "a2" else x


def rise_time(x: np.ndarray, sample_interval: float) -> float:
    """The time a signal takes, at its fastest, to cover a fifth of its range [s] (NaN when it never does).

    For each fraction ``q`` of :data:`RISE_FRACTIONS`, the shortest span ``h`` over which the straight line fitted
    (least squares) to the samples of some stretch of length ``h`` rises or falls by ``q`` of the signal's range
    (its :data:`_RANGE_QUANTILE` to ``1 - _RANGE_QUANTILE`` quantiles), interpolated between lags
    :data:`_LAG_RATIO` apart; the result is their geometric mean. A record on a grid finer than
    :data:`RISE_RESOLUTION` is first averaged over blocks of that length. A time of the signal's own shape: in
    seconds, whatever the grid, the unit, a gain or an offset; noise at 20 dB barely moves it (the line's fit
    averages it, and the fractions are far above it).

    Parameters
    ----------
    x : ndarray
        The samples (e.g. a channel over the test window; :func:`check_record` reads v2 and a2 integrated).
    sample_interval : float
        Their interval [s].

    Returns
    -------
    float
        The geometric mean over :data:`RISE_FRACTIONS` of the shortest rise times [s]; NaN for a constant
        signal, fewer than 3 samples, or a fraction never reached.
    """
    x = np.asarray(x, dtype=float)
    ts = float(sample_interval)
    block = int(RISE_RESOLUTION / ts * (1.0 + _SLACK))
    if block > 1:
        n_blocks = x.size // block
        x = x[: n_blocks * block].reshape(n_blocks, block).mean(axis=1)
        ts *= block
    n = x.size
    if n < 3:
        return math.nan
    low, high = np.quantile(x, [_RANGE_QUANTILE, 1.0 - _RANGE_QUANTILE])
    span = float(high - low)
    if not (math.isfinite(span) and span > 0.0):
        return math.nan
    x = (x - float(np.mean(x))) / span
    k = np.arange(n, dtype=float)
    s0 = np.concatenate(([0.0], np.cumsum(x)))
    s1 = np.concatenate(([0.0], np.cumsum(k * x)))
    n_lags = math.ceil(math.log(n - 1) / math.log(_LAG_RATIO)) + 1
    lags = np.unique(np.round(np.geomspace(1, n - 1, n_lags)).astype(int))
    fractions = sorted(RISE_FRACTIONS)
    times: list[float] = []
    prev_h, prev_m = 0, 0.0
    for h in lags:
        t = np.arange(n - h)
        total = s0[t + h + 1] - s0[t]
        moment = s1[t + h + 1] - s1[t]
        # least-squares slope over samples t .. t+h, times h: the line's rise over the stretch
        rise = (moment - (t + h / 2.0) * total) * (12.0 / ((h + 1) * (h + 2)))
        m = float(np.max(np.abs(rise)))
        while len(times) < len(fractions) and m >= fractions[len(times)]:
            q = fractions[len(times)]
            times.append((prev_h + (q - prev_m) / (m - prev_m) * (h - prev_h)) * ts)
        if len(times) == len(fractions):
            return float(np.exp(np.mean(np.log(times))))
        prev_h, prev_m = int(h), m
    return math.nan


@functools.lru_cache(maxsize=4)
def rise_envelope(drive: DriveDescription = REFERENCE_DRIVE) -> dict[str, tuple[float, float]]:
    """Shortest and longest :func:`rise_time` of each of :data:`TIME_CHANNELS` over the drive's plausible box [s].

    Read over the test window of the box's cases (:func:`_box_records`, the same simulations as
    :func:`peak_envelope`; in seconds, so that a record on any accepted grid compares with them: the box's
    cases rendered at 1 ms and at 10 us lie within this range noiseless, within 8 % of it at 30 dB, measured).

    Returns
    -------
    dict of str to (float, float)
        Channel -> (shortest, longest) rise time [s].
    """
    ts = drive.sample_interval
    out = {}
    for c in TIME_CHANNELS:
        j = CHANNELS.index(c)
        times = np.array([rise_time(_load_motion(c, x[j], ts), ts) for x in _box_records(drive)])
        times = times[np.isfinite(times)]
        out[c] = (float(times.min()), float(times.max()))
    return out


def unit_suspects(record: Record, channel: str) -> dict[str, float]:
    """Units the channel may really be in, and by what its values (as read) would then be multiplied.

    Parameters
    ----------
    record : Record
        The record (its declared unit of ``channel`` and its conditions, e.g. ``base_torque``).
    channel : str
        One of its channels.

    Returns
    -------
    dict of str to float
        Unit -> factor from the values as read (model units) to what they would be in the model
        unit had the samples been in that unit: the accepted units and :data:`OTHER_UNITS`, less
        the declared one (and N*m without ``conditions.base_torque``).
    """
    declared = record.unit(channel)
    f_declared = factor(channel, declared, record.conditions)
    out: dict[str, float] = {}
    for unit in (*UNITS[channel], *OTHER_UNITS.get(channel, {})):
        if unit == declared:
            continue
        try:
            f = (
                OTHER_UNITS[channel][unit]
                if unit in OTHER_UNITS.get(channel, {})
                else factor(channel, unit, record.conditions)
            )
        except UnitError:
            continue
        out[unit] = f / f_declared
    return out


def _fix(record: Record, channel: str, unit: str, ratio: float) -> str:
    """What to do if ``channel`` is in ``unit``."""
    if unit in UNITS[channel]:
        return f'declare it ("units": {{"{channel}": "{unit}"}})'
    return f"convert it to {record.unit(channel)} (multiply its values by {ratio:.4g})"


def _as_given(record: Record, channel: str, value: float) -> float:
    """A model-unit value of ``channel`` in the unit the record declares for it."""
    return value / factor(channel, record.unit(channel), record.conditions)


def _range_message(record: Record, channel: str, peak: float, drive: DriveDescription) -> str | None:
    """The sentence about a peak out of the drive's range (None when it is within the range's margin)."""
    lo, hi = peak_envelope(drive)[channel]
    unit = record.unit(channel)
    if peak > hi * RANGE_MARGIN:
        where = f"while the plant's never exceeds {_as_given(record, channel, hi):.3g} {unit}"
    elif peak < lo / RANGE_MARGIN:
        where = f"while the plant's peak never falls below {_as_given(record, channel, lo):.3g} {unit}"
    else:
        return None
    head = (
        f"{channel} peaks at {_as_given(record, channel, peak):.4g} {unit} {where} "
        "(over its plausible box of K, J1, c, c1)"
    )
    fits = {u: r for u, r in unit_suspects(record, channel).items() if lo / UNIT_MATCH <= peak * r <= hi * UNIT_MATCH}
    if fits:
        centre = math.sqrt(lo * hi)
        unit_best = min(fits, key=lambda u: abs(math.log(peak * fits[u] / centre)))
        return f"{head}: is it in {unit_best}? If so, {_fix(record, channel, unit_best, fits[unit_best])}."
    return f"{head}: check its unit, the sensor's gain and the record's scaling."


# -- the sample interval --------------------------------------------------------------------------
def _factors(sample_interval: float) -> list[float]:
    """The factors of :data:`TIME_FACTORS` that give an accepted interval (10 us to 1 ms) from ``sample_interval``."""
    return [
        a
        for a in TIME_FACTORS
        if MIN_SAMPLE_INTERVAL * (1 - _SLACK) <= a * sample_interval <= MAX_SAMPLE_INTERVAL * (1 + _SLACK)
    ]


def _times(a: float) -> str:
    """``10x`` for 10 or 0.1, ``2x`` for 2 or 0.5."""
    return f"{max(a, 1.0 / a):g}x"


def _pace(*factors: float) -> str:
    """How the record's dynamics compare with the plant's when it fits read at ``factors`` times its interval."""
    ordered = sorted(factors, key=lambda a: abs(math.log(a)))
    return f"{' or '.join(_times(a) for a in ordered)} {'slower' if ordered[0] < 1 else 'faster'}"


def _read_at(sample_interval: float, *factors: float) -> str:
    """The reading with the interval multiplied by one of ``factors``, as the messages say it."""
    ordered = sorted(factors, key=lambda a: abs(math.log(a)))
    intervals = " or ".join(f"{a * sample_interval:.3g}" for a in ordered)
    return f"read with a sample interval of {intervals} s instead of the declared {sample_interval:.3g} s"


def interval_message(sample_interval: float, factor: float, evidence: float, what: str) -> str:
    """The ``sample_interval`` warning of a fit: ``what`` (the part of the record compared), read with its
    interval multiplied by ``factor``, fits the plant ``evidence`` times better (chi2) than as declared."""
    return (
        f"the record's dynamics fit {_pace(factor)} than the model's: {_read_at(sample_interval, factor)}, "
        f"{what} fit the plant {min(evidence, 1e6):.3g} times better; {_INTERVAL_QUESTION}"
    )


def _rise_times(record: Record, sample_interval: float, channels: Collection[str]) -> dict[str, float]:
    """:func:`rise_time` of the record's ``channels`` over the test window, read at ``sample_interval``.

    Empty when the record read at that interval does not cover the test window (or the interval is not accepted).
    """
    try:
        window = SampleGrid(sample_interval, record.n_samples, record.event_index).window()
    except GridError:
        return {}
    return {c: rise_time(_load_motion(c, record[c][window], sample_interval), sample_interval) for c in channels}


def _outside(channel: str, time: float, drive: DriveDescription) -> float:
    """How many times outside the drive's range of rise times (:func:`rise_envelope`) ``time`` lies (1 within it)."""
    lo, hi = rise_envelope(drive)[channel]
    return max(lo / time, time / hi, 1.0) if math.isfinite(time) and time > 0 else math.nan


def _interval_warning(
    record: Record, drive: DriveDescription, skip: Collection[str] = ()
) -> PlausibilityWarning | None:
    """``sample_interval`` when the load's rise times lie far outside the plant's and another reading brings them back.

    The record's :data:`TIME_CHANNELS` (v2, a2 integrated: two witnesses of one motion, which must agree) must
    each have a rise time more than :data:`TIME_MARGIN` times outside the range the plant produces
    (:func:`rise_envelope`); each is then read again with its interval multiplied by each factor of
    :data:`TIME_FACTORS` (its test window at that interval; a reading that does not cover it is skipped), and
    some reading must bring it within :data:`TIME_MARGIN` of the range. The warning names the readings that
    bring it inside the range (two neighbouring factors often do: the range is 2.8x wide), or the nearest one:
    those both channels agree on, else those of the farther one. Channels in ``skip`` (e.g. constant ones) are
    not read.
    """
    ts = record.sample_interval
    channels = [c for c in TIME_CHANNELS if c in record.channels and c not in skip]
    declared = {c: t for c, t in _rise_times(record, ts, channels).items() if math.isfinite(_outside(c, t, drive))}
    if not declared or any(_outside(c, t, drive) <= TIME_MARGIN for c, t in declared.items()):
        return None
    if len({t > rise_envelope(drive)[c][1] for c, t in declared.items()}) > 1:
        return None  # one witness too slow, the other too fast: not a sample interval
    readings = {a: _rise_times(record, a * ts, list(declared)) for a in _factors(ts)}
    suspects: dict[str, list[float]] = {}
    for c in declared:
        outside = {a: _outside(c, times[c], drive) for a, times in readings.items() if c in times}
        outside = {a: v for a, v in outside.items() if math.isfinite(v)}
        if not outside or min(outside.values()) > TIME_MARGIN:
            return None
        suspects[c] = [a for a, v in outside.items() if v <= 1.0] or [min(outside, key=outside.__getitem__)]
    farthest = max(suspects, key=lambda c: _outside(c, declared[c], drive))
    factors = [a for a in suspects[farthest] if all(a in fs for fs in suspects.values())] or suspects[farthest]
    lo, hi = rise_envelope(drive)[farthest]
    longer = "longer than the plant's longest" if declared[farthest] > hi else "shorter than the plant's shortest"
    on = " and ".join(
        f"{declared[c] * 1e3:.3g} ms on {'a2 integrated' if c == 'a2' else c}" for c in TIME_CHANNELS if c in suspects
    )
    fixed = " or ".join(f"{readings[a][farthest] * 1e3:.2g}" for a in sorted(factors, key=lambda a: abs(math.log(a))))
    fractions = f"{min(RISE_FRACTIONS) * 100:g}-{max(RISE_FRACTIONS) * 100:g} %"
    return PlausibilityWarning(
        "sample_interval",
        f"the load's motion looks {_pace(*factors)} than the plant's: its rise time (the shortest time to cover "
        f"{fractions} of its range) is {on}, {_outside(farthest, declared[farthest], drive):.2g}x {longer} over its "
        f"plausible box of K, J1, c, c1 ({lo * 1e3:.2g}-{hi * 1e3:.2g} ms); {_read_at(ts, *factors)}, it is "
        f"{fixed} ms, within that range; {_INTERVAL_QUESTION}",
    )


# -- checks without a fit -------------------------------------------------------------------------
def check_record(record: Record, drive: DriveDescription = REFERENCE_DRIVE) -> list[PlausibilityWarning]:
    """Warnings about a record that need no calibration: constant channels, channels out of the plant's range,
    a sample interval the load's motion contradicts.

    Parameters
    ----------
    record : Record
        The drive's record (its test window is read, as every analysis does).
    drive : DriveDescription
        The drive it was measured on (default MODEL.md's reference plant): its envelopes are the plant's range.

    Returns
    -------
    list of PlausibilityWarning
        ``constant_channel`` and ``channel_scale`` warnings, in channel order, then at most one
        ``sample_interval`` (:data:`TIME_CHANNELS`' rise times, :func:`rise_time`); empty when none.
    """
    window, _ = record.test_window()
    out = []
    for c, x in window.channels.items():
        if np.ptp(x) == 0.0:
            out.append(
                PlausibilityWarning(
                    "constant_channel",
                    f"{c} does not change over the test window (every sample "
                    f"{_as_given(record, c, float(x[0])):.4g} {record.unit(c)}): a stuck or disconnected sensor, "
                    "or a placeholder column; check the sensor, or leave the channel out of the record.",
                    c,
                )
            )
            continue
        message = _range_message(record, c, float(np.max(np.abs(x))), drive)
        if message is not None:
            out.append(PlausibilityWarning("channel_scale", message, c))
    timing = _interval_warning(
        record, drive, skip={w.channel for w in out if w.code == "constant_channel" and w.channel}
    )
    if timing is not None:
        out.append(timing)
    for w in out:
        logger.info("plausibility: %s", w.message)
    return out


# -- checks on a calibration ----------------------------------------------------------------------
def _window(record: Record, calibration: CalibrationResult) -> Record:
    """The samples the calibration fitted: the record's test window (the record itself when it is that window)."""
    if calibration.grid is not None and record.grid == calibration.grid:
        return record
    window, _ = record.test_window()
    if calibration.grid is not None and window.grid != calibration.grid:
        raise ValueError(
            f"the calibration was fitted on {calibration.grid}, not on this record's test window ({window.grid}); "
            "pass the record that was calibrated"
        )
    return window


def time_scale_evidence(
    record: Record, calibration: CalibrationResult, channels: Collection[str] | None = None
) -> tuple[float, float]:
    """How much better the record fits the plant when read with its sample interval scaled.

    For each factor ``a`` of :data:`TIME_FACTORS` whose interval ``a * Ts`` lies in the accepted
    range (10 us to 1 ms), the calibrated case, the nominal one (the record's conditions applied)
    and :data:`TIME_POINTS` points of the plausible box are simulated on the record's grid with
    the interval ``a * Ts``, over the first 20 ms of model time after the event (the calibration's
    first horizon, where the cost is smooth in the parameters), and the best noise-normalised chi2
    on those samples is compared with the best of the same cases read at ``Ts``.

    Parameters
    ----------
    record : Record
        The record that was calibrated (its test window is used).
    calibration : CalibrationResult
        Its calibration (its ``case`` and noise normalisation ``sigma``).
    channels : collection of str, optional
        The channels compared (default: every channel calibrated); a channel in a wrong unit
        would make any reading fit it badly, so :func:`check_calibration` leaves those out.

    Returns
    -------
    (evidence, factor) : (float, float)
        The largest ratio chi2 at ``Ts`` / chi2 at ``a * Ts`` and its factor ``a``; (0, 1) when no
        factor gives an accepted interval or no channel is compared.
    """
    window = _window(record, calibration)
    names = [c for c in window.channels if c in calibration.sigma and (channels is None or c in channels)]
    if not names:
        return 0.0, 1.0
    rows = [CHANNELS.index(c) for c in names]
    data = np.array([window[c] for c in names])
    sigma = np.array([float(calibration.sigma[c]) for c in names])[:, None]
    space = default_space(window, drive=calibration.drive)
    cases = [space.base] if calibration.case is None else [calibration.case, space.base]
    if space.dim:
        cases += [space.case(u) for u in sobol(space.dim, scramble=True, seed=0).random(TIME_POINTS)]
    settings = CalibrationSettings()
    solver = space.solver(settings.search_step)
    horizon = settings.horizons_ms[0] * 1e-3
    ts, n, e = window.sample_interval, window.n_samples, window.event_index
    factors = _factors(ts)
    if not factors:
        return 0.0, 1.0
    first = {a: min(n, e + max(1, round(horizon / (a * ts)))) for a in factors}

    def chi2(sims: np.ndarray, status: np.ndarray, h: int) -> float:
        c2 = np.sum(((data[None, :, :h] - sims[:, rows, :h]) / sigma[None]) ** 2, axis=(1, 2))
        c2 = c2[(status == 0) & np.isfinite(c2)]
        return float(c2.min()) if c2.size else math.inf

    ref, _, ref_status = run_cases(cases, solver, window.grid, first=max(first.values()))
    best = (0.0, 1.0)
    for a in factors:
        try:
            grid = SampleGrid(a * ts, n, e)
        except GridError:  # no grid at that interval: that reading is moot
            continue
        try:
            sims, _, status = run_cases(cases, solver, grid, first=first[a])
        except GridError:  # a calibrated sensor effect reads the test window, which this reading no longer covers
            if calibration.case is None or len(cases) < 2:
                continue
            sims, _, status = run_cases(cases[1:], solver, grid, first=first[a])  # the plant's own cases only
        scaled, declared = chi2(sims, status, first[a]), chi2(ref, ref_status, first[a])
        if not math.isfinite(declared):
            continue
        evidence = math.inf if scaled == 0.0 else declared / scaled
        logger.debug("time scale %g: chi2 %.4g against %.4g as declared (%d samples)", a, scaled, declared, first[a])
        if evidence > best[0]:
            best = (evidence, a)
    return best


def check_calibration(record: Record, calibration: CalibrationResult) -> list[PlausibilityWarning]:
    """Warnings about a record that its calibration reveals: channel scale, sample interval, misfit.

    Parameters
    ----------
    record : Record
        The record that was calibrated (the whole record or its test window; the test window is read).
    calibration : CalibrationResult
        Its calibration (:func:`engine.diagnosis.calibration.calibrate`): per-channel chi2, the
        calibrated simulation on the record's grid, the noise normalisation.

    Returns
    -------
    list of PlausibilityWarning
        ``channel_scale`` (per channel), ``sample_interval`` (the record), ``misfit`` (per
        channel), in that order; empty when the fit reproduces every channel to within
        :data:`MISFIT_CHI2`. Checks that need no fit are :func:`check_record`'s.

    Raises
    ------
    ValueError
        The calibration was fitted on another grid than the record's test window.
    """
    window = _window(record, calibration)
    n_channels = max(len(calibration.chi2_per_channel), 1)
    per_sample = calibration.n_data / n_channels
    chi2n = {
        c: calibration.chi2_per_channel[c] / per_sample for c in window.channels if c in calibration.chi2_per_channel
    }
    poor = {c: v for c, v in chi2n.items() if v > MISFIT_CHI2}
    if not poor:
        return []
    scale: list[PlausibilityWarning] = []
    for c, v in poor.items():
        x = window[c]
        message = _range_message(record, c, float(np.max(np.abs(x))), calibration.drive)
        if message is None and calibration.simulation is not None:
            sim = calibration.simulation[CHANNELS.index(c)]
            s = float(np.dot(x, sim) / np.dot(sim, sim)) if np.dot(sim, sim) > 0 else math.nan
            if math.isfinite(s) and s > 0 and abs(math.log(s)) > math.log(SCALE_FAR):
                fits = {
                    u: r for u, r in unit_suspects(record, c).items() if abs(math.log(s * r)) < math.log(UNIT_MATCH)
                }
                noise = float(calibration.sigma[c]) if c in calibration.sigma else 1.0
                as_read = float(np.sum(((x - sim) / noise) ** 2))
                scaled = float(np.sum(((x - s * sim) / noise) ** 2))
                if fits and scaled * EVIDENCE <= as_read:
                    u = min(fits, key=lambda k: abs(math.log(s * fits[k])))
                    message = (
                        f"the model reproduces {c} only scaled: the record is {s:.3g} x the calibrated simulation "
                        f"(chi2 per sample {v:.3g} as it is): is it in {u} rather than {record.unit(c)}? "
                        f"If so, {_fix(record, c, u, fits[u])}."
                    )
        if message is not None:
            scale.append(PlausibilityWarning("channel_scale", message, c))
    timing: list[PlausibilityWarning] = []
    evidence, a = time_scale_evidence(record, calibration, [c for c in chi2n if c not in {w.channel for w in scale}])
    if evidence >= EVIDENCE:
        timing.append(
            PlausibilityWarning(
                "sample_interval",
                interval_message(
                    window.sample_interval,
                    a,
                    evidence,
                    f"the record's first {CalibrationSettings().horizons_ms[0]:g} ms after the event",
                ),
            )
        )
    misfit = [
        PlausibilityWarning(
            "misfit",
            f"the calibrated model leaves {v:.3g} noise variances per sample on {c} (noise alone gives about 1): it "
            f"does not reproduce the record there, and every number fitted to it (the width, its interval) carries "
            f"model error; check {c}'s unit, the sample interval, the event index and the record's conditions.",
            c,
        )
        for c, v in poor.items()
    ]
    out = [*scale, *timing, *misfit]
    for w in out:
        logger.info("plausibility: %s", w.message)
    return out
