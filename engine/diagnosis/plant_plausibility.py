"""Is the record what the plant can produce? The plant interface's warnings, for any plant.

The backlash drive's checks (:mod:`engine.diagnosis.plausibility`) read its own channels, units and
plausible box. A plant of :mod:`engine.plants.base` (EMPS, the BRFD, a user's FMU) declares its
channels with a unit and a noise model, nothing more, so these checks read only that, after the
diagnosis, on the model the answer ends with (the named set's fit, or the calibrated model):

- ``channel_scale``: a channel the answer's model does not reproduce (chi2 per sample above
  :data:`~engine.diagnosis.plausibility.MISFIT_CHI2`) whose least-squares scale against the plant's
  nominal simulation (record = a x simulation; the nominal one, since a fit to a mis-scaled channel
  distorts every fitted value) lies outside 1/:data:`~engine.diagnosis.plausibility.SCALE_FAR` to
  :data:`~engine.diagnosis.plausibility.SCALE_FAR`, and scaled it fits
  :data:`~engine.diagnosis.plausibility.EVIDENCE` times better: the record is probably in another
  unit than the one declared (a factor of :data:`UNIT_FACTORS` is named when ``a`` matches it within
  :data:`~engine.diagnosis.plausibility.UNIT_MATCH`), or a sensor's gain is far from the model's.
- ``misfit``: chi2 per sample above ``MISFIT_CHI2`` on a channel no scale explains: the model does
  not reproduce the record there, and every number fitted to it carries model error.

:func:`check_channels` runs before any fit: a channel without a change over the scored window
(beyond its reading's rounding, :data:`CONSTANT_CHANNEL_REL`; ``constant_channel``: a stuck sensor,
a placeholder column) is refused, since no noise level and no fit can be read from it.

:func:`check_interval` runs after them when the answer's model leaves a misfit:

- ``sample_interval``: the record read with its sample interval multiplied by a factor of
  :data:`~engine.diagnosis.plausibility.TIME_FACTORS` (the plant's own reading,
  :meth:`~engine.plants.base.Plant.retimed`) fits the plant ``EVIDENCE`` times better than as declared
  (the best of the answer's model and the nominal one at each reading): a time column in ms declared
  in s, a decimation or a sample rate misread. A plant whose records have one fixed grid, which its
  reader enforces (EMPS), has nothing to check.

What these checks do not do for a generic plant: a peak outside the plant's plausible range (a
generic plant declares no box of its own beyond its calibrated parameters).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Collection, Mapping, Sequence
from typing import Any, Final

import numpy as np

from engine.diagnosis.plausibility import (
    EVIDENCE,
    MISFIT_CHI2,
    SCALE_FAR,
    TIME_FACTORS,
    UNIT_MATCH,
    PlausibilityWarning,
    interval_message,
)
from engine.plants.base import Plant
from engine.plants.noise import NoiseLevel
from engine.records import RecordError

__all__ = [
    "CONSTANT_CHANNEL_REL",
    "UNIT_FACTORS",
    "ConstantChannelError",
    "check_channels",
    "check_fit",
    "check_interval",
    "interval_evidence",
]

logger = logging.getLogger(__name__)

#: A channel whose values span at most this share of their magnitude over the scored window never
#: changes [-]: far below any sensor's resolution (a 24-bit converter resolves 6e-8 of its range),
#: far above the rounding of a plant's reading (a zero-phase filter of a constant varies by about
#: 1e-15 of it, by the platform's arithmetic).
CONSTANT_CHANNEL_REL: Final[float] = 1e-9

#: Factors between a record's values and the model's that a unit mistake makes [-], with what to ask:
#: the record in milli-units (mm for m), in kilo-units (kN for N), in centi-units (cm for m), an
#: acceleration in g for m/s^2 (or the reverse), a speed in rpm for rad/s, an angle in degrees for radians.
UNIT_FACTORS: Final[dict[float, str]] = {
    1e3: "is it in milli-units (mm for m, mm/s for m/s, mN for N)?",
    1e-3: "is it in kilo-units (kN for N, km for m) or in base units where milli-units are declared?",
    1e2: "is it in centi-units (cm for m)?",
    1.0 / 9.80665: "is it in g where m/s^2 is declared?",
    9.80665: "is it in m/s^2 where g is declared?",
    60.0 / (2.0 * math.pi): "is it in rpm where rad/s is declared?",
    180.0 / math.pi: "is it in degrees where radians are declared?",
}


class ConstantChannelError(RecordError):
    """A channel of the record does not change over the scored window: nothing can be read from it."""


def check_channels(plant: Plant, record: Any) -> None:
    """Refuse a record with a channel that never changes over the scored window.

    Raises
    ------
    ConstantChannelError
        Naming the channel and its value: a stuck or disconnected sensor, or a placeholder column;
        the message says to check the sensor or leave the channel out.
    """
    window = plant.scored(record)
    measured = plant.measured(record)
    for c in plant.channels:
        y = np.asarray(measured[c.name], dtype=float)[window]
        if y.size and float(np.ptp(y)) <= CONSTANT_CHANNEL_REL * float(np.max(np.abs(y))):
            raise ConstantChannelError(
                f"channel {c.name} is {y[0]:.6g} {c.unit} at every one of its {y.size} scored samples: a stuck or "
                "disconnected sensor, or a placeholder column? Check the sensor, or leave the channel out of the "
                "record"
            )


def _unit_question(a: float) -> str | None:
    """What to ask when a channel is ``a`` times the model's, if a unit mistake makes that factor."""
    for f, question in UNIT_FACTORS.items():
        if 1.0 / UNIT_MATCH <= a / f <= UNIT_MATCH:
            return question
    return None


def check_fit(
    plant: Plant,
    residuals: Mapping[str, np.ndarray],
    nominal: Mapping[str, np.ndarray],
    measured: Mapping[str, np.ndarray],
    levels: Mapping[str, NoiseLevel],
    model: str,
) -> list[PlausibilityWarning]:
    """The warnings of the answer's model (module docstring): ``channel_scale`` and ``misfit``.

    Parameters
    ----------
    plant : Plant
        The plant (its channels' names and units).
    residuals, nominal : mapping
        Channel -> simulated minus measured over the scored samples, at the answer's model and at the
        plant's nominal values.
    measured : mapping
        Channel -> the measured samples over the same window.
    levels : mapping
        Channel -> its noise (:meth:`~engine.plants.base.Plant.noise`).
    model : str
        The answer's model as the message names it ("the calibrated model", "the model with X").

    Returns
    -------
    list of PlausibilityWarning
        In the plant's channel order; empty when the model reproduces every channel to within
        ``MISFIT_CHI2``.
    """
    out: list[PlausibilityWarning] = []
    for c in plant.channels:
        y = np.asarray(measured[c.name], dtype=float)
        var = levels[c.name].sigma ** 2
        chi2 = float(np.mean(np.asarray(residuals[c.name], dtype=float) ** 2)) / var
        if not math.isfinite(chi2) or chi2 <= MISFIT_CHI2:
            continue
        sim = y + np.asarray(nominal[c.name], dtype=float)
        ss = float(sim @ sim)
        a = float(sim @ y) / ss if ss > 0.0 else math.nan
        as_is = float(np.mean((sim - y) ** 2)) / var
        scaled = float(np.mean((a * sim - y) ** 2)) / var if math.isfinite(a) else math.inf
        if math.isfinite(a) and not (1.0 / SCALE_FAR <= abs(a) <= SCALE_FAR) and scaled * EVIDENCE < as_is:
            question = _unit_question(abs(a)) or "is its unit, or the sensor's gain, the one declared?"
            out.append(
                PlausibilityWarning(
                    "channel_scale",
                    f"channel {c.name} is {a:.3g} times the plant's nominal simulation (scaled by that it fits "
                    f"{as_is / scaled:.3g} times better), and {model} leaves a residual of {math.sqrt(chi2):.3g} "
                    f"times the noise there: {question} It is declared in {c.unit or 'the model unit'}; the "
                    "numbers fitted to the record are not to be trusted until it is.",
                    c.name,
                )
            )
        else:
            out.append(
                PlausibilityWarning(
                    "misfit",
                    f"{model} leaves a residual on {c.name} of {math.sqrt(chi2):.3g} times its noise: it does not "
                    "reproduce the record there, and every value fitted to the record carries that model error "
                    "(its uncertainty does not).",
                    c.name,
                )
            )
    return out


def _scored_mask(plant: Plant, record: Any, n: int) -> np.ndarray:
    mask = np.zeros(n, dtype=bool)
    mask[plant.scored(record)] = True
    return mask


def _simulations(plant: Plant, record: Any, cases: Sequence[Mapping[str, float]]) -> list[dict[str, np.ndarray]]:
    """The channels of each of ``cases`` simulated on ``record``; a case the plant cannot simulate there is left out."""
    out = []
    for values in cases:
        try:
            out.append(plant.simulate(record, values))
        except (ValueError, RuntimeError, ArithmeticError) as exc:  # a reading the plant cannot simulate is moot
            logger.debug("sample-interval check: %s does not simulate (%s)", dict(values), exc)
    return out


def _best_chi2(
    sims: Sequence[Mapping[str, np.ndarray]],
    y: Mapping[str, np.ndarray],
    sigma: Mapping[str, float],
    mask: np.ndarray,
) -> float:
    """The lowest chi2 per compared sample over ``sims`` against ``y`` [noise variances]; inf if none is finite."""
    best = math.inf
    for sim in sims:
        with np.errstate(over="ignore", invalid="ignore"):
            chi2 = sum(float(np.mean((np.asarray(sim[c]) - y[c])[mask] ** 2)) / s**2 for c, s in sigma.items())
        if math.isfinite(chi2):
            best = min(best, chi2)
    return best


def interval_evidence(
    plant: Plant,
    record: Any,
    cases: Sequence[Mapping[str, float]],
    levels: Mapping[str, NoiseLevel],
    channels: Collection[str] | None = None,
) -> tuple[float, float]:
    """How much better the record fits the plant read at another sample interval: ``(evidence, factor)``.

    For each factor ``a`` of :data:`~engine.diagnosis.plausibility.TIME_FACTORS` at which the plant can
    read the record (:meth:`~engine.plants.base.Plant.retimed`), every one of ``cases`` is simulated on
    the record read at ``a`` times its interval; the best chi2 per sample (over the compared channels,
    each against its noise level, on the samples scored at both readings) as declared, divided by the
    best at ``a``, is that reading's evidence.

    Parameters
    ----------
    plant, record
        The plant and the record diagnosed.
    cases : sequence of mapping
        Parameter and effect values to simulate (the answer's model, the nominal one ``{}``).
    levels : mapping
        Channel -> its noise (:meth:`~engine.plants.base.Plant.noise` of the record as declared).
    channels : collection of str, optional
        The channels compared (default every channel; a channel in a wrong unit fits no reading).

    Returns
    -------
    (evidence, factor) : (float, float)
        The largest evidence and its factor; (0, 1) when the plant reads the record at no other
        interval, no channel is compared, or the record as declared does not simulate.
    """
    sigma = {c.name: levels[c.name].sigma for c in plant.channels if channels is None or c.name in channels}
    sigma = {c: s for c, s in sigma.items() if s > 0.0 and math.isfinite(s)}
    if not sigma:
        return 0.0, 1.0
    n = len(plant.time(record))
    declared_mask = _scored_mask(plant, record, n)
    y = plant.measured(record)  # the samples, the same at every reading
    as_declared: list[dict[str, np.ndarray]] | None = None  # simulated once a reading exists (none on EMPS)
    best = (0.0, 1.0)
    for a in TIME_FACTORS:
        try:
            reading = plant.retimed(record, a)
        except ValueError as exc:
            logger.debug("sample-interval check: no reading at %gx (%s)", a, exc)
            continue
        mask = declared_mask & _scored_mask(plant, reading, n)
        if not mask.any():
            continue
        if as_declared is None:
            as_declared = _simulations(plant, record, cases)
        declared = _best_chi2(as_declared, y, sigma, mask)
        if not math.isfinite(declared):
            return 0.0, 1.0
        scaled = _best_chi2(_simulations(plant, reading, cases), y, sigma, mask)
        evidence = declared / scaled if scaled > 0.0 else math.inf
        logger.debug("sample-interval check: %gx fits %.4g, as declared %.4g", a, scaled, declared)
        if evidence > best[0]:
            best = (evidence, a)
    return best


def check_interval(
    plant: Plant,
    record: Any,
    cases: Sequence[Mapping[str, float]],
    levels: Mapping[str, NoiseLevel],
    channels: Collection[str] | None = None,
) -> list[PlausibilityWarning]:
    """``sample_interval`` when the record read at another interval fits the plant ``EVIDENCE`` times better.

    Parameters as :func:`interval_evidence`, which it runs (a dozen simulations or so: run it on a poor
    fit only). Returns one warning or none.
    """
    evidence, a = interval_evidence(plant, record, cases, levels, channels)
    if evidence < EVIDENCE:
        return []
    t = np.asarray(plant.time(record), dtype=float)
    ts = float(np.median(np.diff(t)))
    return [PlausibilityWarning("sample_interval", interval_message(ts, a, evidence, "its scored samples"))]
