"""The settings and the results of the locus estimate.

:class:`LocusSettings` (the method's settings), :class:`LocusScore` (how well one locus explains
the residual), :class:`Term` (what the missing term looks like), :class:`LocusReport` (the
outcome) and :class:`LocusError`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from engine.simulation.parameters import LOCUS_GROUP_REASONS, locus_group_name


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
    interference_min_periods : float
        Fewest periods over the test window of a periodic interference of the measurement chain
        (:mod:`engine.diagnosis.locus._interference`) [-]: a slower sinusoid is a drift, which the
        loci's inputs hold as well.
    friction_fits : bool
        Fit the Coulomb friction of every part (:data:`COULOMB_FIELDS`) jointly with the
        calibrated parameters by a global search (a candidate's escalated fit,
        :func:`engine.diagnosis.candidate.fit_candidate` with ``global_search=True``), as one
        more start of that locus (False: the friction is only scanned).
    part_drifts : bool
        Fit a drift of each of every part's own MODEL.md parameters
        (:data:`~engine.simulation.parameters.PART_FIELDS`) jointly with the calibrated parameters
        (a catalogue candidate's seeded fit), as one more start of its locus.
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
    interference_min_periods: float = 4.0
    first_guess_chi2: float = 10.0
    friction_fits: bool = True
    part_drifts: bool = True
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
    group : list of str
        The loci the recorded channels cannot tell from the best one, the best first
        (:data:`engine.simulation.parameters.LOCUS_GROUPS`; the best alone when it is in no group): the
        answer is this part of the plant, and ``confidence`` is the group's posterior weight.
    input : str or None
        The best of ``scores``: the unknown input (one of :data:`engine.simulation.DISTURBANCE_LOCI`), or
        ``sensors``, whose part is ``locus`` (the clutch's torque, ``clutch_torque``, is the clutch's);
        None when no locus is named (reports written before it: ``locus``).
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
    group: list[str] = field(default_factory=list)
    input: str | None = None

    @property
    def group_name(self) -> str | None:
        """What a sentence calls ``group`` (None when the best locus is in no group)."""
        return locus_group_name(self.locus) if self.locus is not None and len(self.group) > 1 else None

    @property
    def description(self) -> str:
        """One sentence for the user."""
        if self.locus is None or self.term is None:
            return "no locus explains the residual better than the calibration alone"
        text = self.term.description
        name = self.group_name
        if name is not None:
            text += (
                f"; the part is {name}: the recorded channels cannot tell {' from '.join(self.group)} apart "
                f"({LOCUS_GROUP_REASONS[name]})"
            )
        if self.ties:
            text += f" (the record cannot tell this locus from {', '.join(self.ties)})"
        return text

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (series as lists)."""
        return {
            "locus": self.locus,
            "confidence": self.confidence,
            "ties": list(self.ties),
            "group": list(self.group) if self.group else ([self.locus] if self.locus else []),
            "group_name": self.group_name,
            "input": self.input if self.input is not None else self.locus,
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
