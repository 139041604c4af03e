"""The numbers of the blind validation's protocol v2: what is drawn, how, and the targets.

Every parameter of the protocol lives here (one home): the operating box the
cases are drawn from, the noise, the channel subsets, the mix of case kinds,
the combinations of effects that are the same physics, and the targets the
scorer marks as met or not met. The strength rule (an effect counts when it
moves some recorded channel by more than 3 noise RMS) and the SNR range are
those of protocol v1 (:mod:`engine.diagnosis.validation`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final, Literal

from engine.constants import C1_NOMINAL, OPERATING_RANGE, PLAUSIBLE_RANGE
from engine.diagnosis.space import drive_bounds, nominal_ratios
from engine.diagnosis.validation import SAME_PHYSICS, SNR_RANGE_DB, STRENGTH_THRESHOLD
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.simulation.noise import LOWPASS_ORDERS

__all__ = [
    "C1_CONDITION",
    "CASE_KINDS",
    "CHANNEL_SUBSETS",
    "COLOURED_CUTOFF_FS",
    "COLOURED_ORDERS",
    "COLOURED_SHARE",
    "COMPOUND_KINDS",
    "DEFAULT_MIX",
    "GENERATOR_RULES",
    "MAX_CHANNEL_SNR_SPREAD_DB",
    "MAX_DRAWS_PER_CASE",
    "MAX_DRAWS_PER_EFFECT_SET",
    "OPERATING_BOX",
    "PROTOCOL_VERSION",
    "REFIT_FD_STEP",
    "REFIT_NFEV",
    "SAME_PHYSICS",
    "SNR_RANGE_DB",
    "STRENGTH_THRESHOLD",
    "SUBSET_SHARE",
    "TARGETS",
    "Target",
    "c1_condition",
    "operating_box",
    "operating_range",
]

#: Version of the protocol defined here (protocol 1 is :mod:`engine.diagnosis.validation`).
PROTOCOL_VERSION: Final[int] = 2

#: Case kinds: one catalogue effect; two or three distinct catalogue effects; one effect of the
#: held-back family (never in the library handed to the diagnosis); no effect.
CASE_KINDS: Final[tuple[str, ...]] = ("single", "pair", "triple", "held_back", "clean")
#: Kinds with more than one effect.
COMPOUND_KINDS: Final[tuple[str, ...]] = ("pair", "triple")
#: Default share of each kind (25 / 15 / 10 / 20 / 30 %).
DEFAULT_MIX: Final[dict[str, float]] = {"single": 0.25, "pair": 0.15, "triple": 0.10, "held_back": 0.20, "clean": 0.30}

#: Operating box the cases are drawn from, uniformly: ``name -> (low, high, unit)``; K [m], J1
#: [kg m^2], c [pu]: the plausible box (:data:`engine.constants.PLAUSIBLE_RANGE`, K 1-15 mm, J1
#: 0.6-1.2 kg m^2, c 0.5-2.0 pu), wider than the catalogue's operating range
#: (:data:`engine.constants.OPERATING_RANGE`, K 2.5-10 mm, J1 0.75-0.93, c 0.8-1.5): a case is
#: "on" that range or "off" it, and the scorer breaks false alarms down by it.
OPERATING_BOX: Final[dict[str, tuple[float, float, str]]] = PLAUSIBLE_RANGE
#: The absorber discontinuity c1 [pu], the only condition a record gives (K, J1, c are unknown).
C1_CONDITION: Final[float] = C1_NOMINAL


def operating_box(drive: DriveDescription = REFERENCE_DRIVE) -> dict[str, tuple[float, float, str]]:
    """The box a drive's cases are drawn from: its plausible box for K, J1 and c.

    Parameters
    ----------
    drive : DriveDescription
        The drive the cases are simulated on (default MODEL.md's reference plant).

    Returns
    -------
    dict of str to (float, float, str)
        ``name -> (low, high, unit)`` for K [m], J1 [kg m^2] and c [pu], in that order:
        :data:`OPERATING_BOX` itself for the reference drive, else the K, J1 and c intervals of
        :func:`engine.diagnosis.space.drive_bounds` (MODEL.md's box scaled by the drive's nominal
        value over MODEL.md's), i.e. the box the diagnosis searches on that drive.
    """
    if drive.is_reference:
        return dict(OPERATING_BOX)
    box = drive_bounds(drive)
    return {name: box[name] for name in OPERATING_BOX}


def operating_range(drive: DriveDescription = REFERENCE_DRIVE) -> dict[str, tuple[float, float, str]]:
    """A drive's operating range: :data:`engine.constants.OPERATING_RANGE` scaled as its box is.

    A case is "on" this range or "off" it (the scorer breaks false alarms down by it).

    Parameters
    ----------
    drive : DriveDescription
        The drive (default MODEL.md's reference plant).

    Returns
    -------
    dict of str to (float, float, str)
        ``name -> (low, high, unit)`` for K [m], J1 [kg m^2] and c [pu]: each interval of
        :data:`~engine.constants.OPERATING_RANGE` multiplied by the drive's nominal value over
        MODEL.md's (:func:`engine.diagnosis.space.nominal_ratios`, as
        :func:`~engine.diagnosis.space.drive_bounds` scales the plausible box); the range itself
        for the reference drive.
    """
    if drive.is_reference:
        return dict(OPERATING_RANGE)
    ratio = nominal_ratios(drive)
    return {name: (lo * ratio[name], hi * ratio[name], unit) for name, (lo, hi, unit) in OPERATING_RANGE.items()}


def c1_condition(drive: DriveDescription = REFERENCE_DRIVE) -> float:
    """The c1 [pu] a drive's records give as their only condition: :data:`C1_CONDITION` for the
    reference drive, else the drive's nominal absorber discontinuity ``drive.c1``."""
    return C1_CONDITION if drive.is_reference else float(drive.c1)


#: Largest difference between the SNRs of two channels of one record [dB] (each channel's SNR is
#: drawn within ``SNR_RANGE_DB``).
MAX_CHANNEL_SNR_SPREAD_DB: Final[float] = 10.0
#: Share of the cases whose noise is coloured (low-passed white noise) rather than white.
COLOURED_SHARE: Final[float] = 0.5
#: Orders of the Butterworth low-pass that colours the noise (drawn with equal probability).
COLOURED_ORDERS: Final[tuple[int, ...]] = LOWPASS_ORDERS
#: Cut-off of the colouring low-pass, as fractions of the sampling rate fs (log-uniform between).
COLOURED_CUTOFF_FS: Final[tuple[float, float]] = (1.0 / 20.0, 1.0 / 3.0)

#: Share of the cases recorded on a subset of the channels.
SUBSET_SHARE: Final[float] = 0.15
#: The subsets (drawn with equal probability): a drive's own sensors; the same plus the motor-side
#: accelerometer.
CHANNEL_SUBSETS: Final[tuple[tuple[str, ...], ...]] = (("m_el", "omega1"), ("a1", "m_el", "omega1"))

# SAME_PHYSICS (imported above, one home with protocol 1): groups of catalogue effects that are the
# same physics on a record (pure time shifts); a compound case never holds two of one group. Two
# effects on the same field are excluded too.

#: Draws of values, operating point and noise for one set of effects before the set itself is
#: drawn again (a set that cannot be made strong at any draw, e.g. an effect no recorded channel sees).
MAX_DRAWS_PER_EFFECT_SET: Final[int] = 25
#: Draws for one case before the generator gives up (raises).
MAX_DRAWS_PER_CASE: Final[int] = 500

#: The rules a draw must pass (written into every run's manifest and fingerprint):
#: ``strength``, each effect moves some recorded channel by more than ``STRENGTH_THRESHOLD``
#: noise RMS on its own and within its set; ``absorption`` (added after the seed-105 progress run,
#: see docs/validation-v2.md), each effect still leaves more than that once the plant's calibrated
#: parameters (K, J1, c) and the case's other effects are refitted without it, i.e. the rest of the
#: model cannot mimic it (a draw no diagnosis could name is not a case).
GENERATOR_RULES: Final[tuple[str, ...]] = ("strength", "absorption")
#: Cap on the residual evaluations of the absorption rule's local refit (a bounded least-squares
#: fit started at the truth; :func:`engine.validation.cases.absorbed_strength`).
REFIT_NFEV: Final[int] = 30
#: Finite-difference step (unit box) of that refit: the optimiser's step when the rule was written,
#: kept when the diagnosis's default became smaller (2026-11-24) so that a seed draws the same
#: cases as before; the rule is a local test either way (docs/validation-v2.md).
REFIT_FD_STEP: Final[float] = 2e-3


@dataclass(frozen=True)
class Target:
    """A target of the protocol: a metric's value must be ``>=`` or ``<=`` a threshold.

    Parameters
    ----------
    threshold : float
        The threshold, in the metric's unit (a rate in 0..1, a ratio, seconds).
    direction : {">=", "<="}
        Which side is met.
    gating : bool
        False for targets reported only (the diagnosis times).
    """

    threshold: float
    direction: Literal[">=", "<="]
    gating: bool = True

    def met(self, value: float) -> bool:
        """Whether ``value`` meets the target."""
        return value >= self.threshold if self.direction == ">=" else value <= self.threshold

    def text(self, percent: bool) -> str:
        """The target as text, e.g. ``>= 95 %``."""
        v = f"{100 * self.threshold:g} %" if percent else f"{self.threshold:g}"
        return f"{self.direction} {v}" + ("" if self.gating else " (report only)")


#: Targets by metric name (see :mod:`engine.validation.score`): rates in 0..1, the median gap
#: left after an explaining fit in noise RMS, the 90th percentile of the diagnosis times in seconds.
TARGETS: Final[dict[str, Target]] = {
    "single_named": Target(0.95, ">="),
    "compound_exact": Target(0.80, ">="),
    "pair_exact": Target(0.80, ">="),
    "triple_exact": Target(0.80, ">="),
    "compound_contains": Target(0.90, ">="),
    "pair_contains": Target(0.90, ">="),
    "triple_contains": Target(0.90, ">="),
    "held_back_unexplained": Target(0.80, ">="),
    "held_back_locus": Target(0.80, ">="),
    "clean_false_alarm": Target(0.03, "<="),
    "median_gap_after": Target(1.2, "<="),
    "seconds_single_p90": Target(10.0, "<=", gating=False),
    "seconds_compound_p90": Target(60.0, "<=", gating=False),
}
#: Issue 50, item 5's targets on a family kept for scoring (its one blind run), stricter than
#: :data:`TARGETS`' for the held-back family developed on: abstention 90 %, the right part 80 %.
#: The scorer's report states :data:`TARGETS`; the pages that quote a sealed family's run state these.
SEALED_TARGETS: Final[dict[str, Target]] = {
    "held_back_unexplained": Target(0.90, ">="),
    "held_back_locus": Target(0.80, ">="),
}
