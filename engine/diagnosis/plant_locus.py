"""Where a gap no catalogue effect explains lies, on any plant of the interface, and what the missing term looks like.

A plant states, per locus (a part of the machine), the signals a missing term there would follow
(:meth:`engine.plants.base.Plant.locus_signals`): a force on a positioning axis's carriage that
follows the velocity is a friction law at the guides, one that follows the position an external
load, one that follows the screw's angle a transmission ripple; a reading error that follows the
time is a sensor's drift. This module asks which of those spaces the record's residual lies in.

Method (an unknown-input estimate, linearised around the calibrated model, in the manner of the
backlash drive's own locus estimate, :mod:`engine.diagnosis.locus`, but read through the interface):

1. **Bases.** Each signal s of a locus spans a space of inputs ``d(t) = factor(t) f(s(t))`` at its
   entry, ``f`` expanded in :data:`N_HATS` hat functions over the signal's range on the scored
   samples (piecewise linear: any smooth law), or in :data:`N_HARMONICS` harmonics when the signal
   is periodic (an angle).
2. **Responses.** Every basis function is added at its entry, scaled so that its response is about
   one noise RMS (:func:`probe_scale`), and simulated: the whitened change of the channels over the
   scored samples is its column. The calibrated parameters' columns (finite differences of the
   plant's ``diff_step``) are projected out of every locus's: what they can absorb is not evidence
   for any part.
3. **Fit per locus.** The whitened residual on the locus's columns, the calibrated columns
   projected out of both, with a small ridge and a roughness penalty on the coefficients of neighbouring hats (a small ridge on harmonics) whose
   weight minimises the penalised fit's ``BIC = RSS / tau + dof ln(n / tau)`` (``dof`` the trace of
   the hat matrix; ``tau`` the noise's correlation time: n samples correlated over tau carry n / tau
   independent ones). At that weight the term and the calibrated parameters' step are then fitted
   together, the step bounded to the calibrated parameters' box: a level of the term the projection
   leaves to the calibration (a constant force beside a force offset) goes where the calibration
   can take it.
4. **Check by simulation.** Each locus's fitted input is simulated with the calibrated parameters
   refitted beside it (bounded least squares from the calibration: their linearisation is poor
   where the plant is stiff in them), the input scaled down by :data:`STEP_FRACTIONS` until it
   improves on the calibrated model: the locus is scored on that simulated residual, not on the
   linear prediction. The best :data:`REFINE_LOCI` loci are then refined: up to
   :data:`REFINE_ITERATIONS` Gauss-Newton steps re-linearised around the fitted term and the refitted
   calibration, each kept only if the simulated fit improves (a strong term is rarely linear).
5. **Evidence.** Weights ``exp(-dBIC / 2)`` over the loci, with the BIC differences divided by the
   best fit's dispersion (its RSS / tau per degree of freedom, at least 1: on a real record the
   residual is model error far above the sensors' noise, and the same differences mean less); loci
   within :data:`TIE_BIC` of the best are ties. When even the best term leaves a dispersion above
   :data:`FIRST_GUESS_DISPERSION` and removes less than :data:`EXPLAINED_SHARE` of the gap, one term at one part does not reproduce the record: the
   confidence is capped at :data:`FIRST_GUESS_CONFIDENCE` and a note says the locus is a first
   guess. A best locus that does not beat the calibrated
   model without any term by :data:`TIE_BIC` is no locus.

Assumptions: one missing term, at one locus, small enough to linearise around the calibrated
trajectory (step 4 checks it) and a function of one signal the plant declares (a term following
two signals at once is fitted by the one that carries more of it). Loci whose signals coincide on a
record (the same force following the position and the screw's angle on a short stroke) cannot be
told apart: the answer says so with a tie rather than a guess.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.parallel import MapLike
from engine.plants.base import LocusSignal, Plant, difference_step, free_parameters
from engine.plants.noise import NoiseLevel

__all__ = [
    "EXPLAINED_SHARE",
    "FIRST_GUESS_DISPERSION",
    "N_HARMONICS",
    "N_HATS",
    "TIE_BIC",
    "LocusScore",
    "PlantLocusReport",
    "estimate_plant_locus",
    "signal_basis",
]

logger = logging.getLogger(__name__)

#: Dispersion of the best locus's fit (its RSS / tau per degree of freedom) above which one term at
#: one part does not reproduce the record: the locus is then a first guess, and no evidence against a
#: catalogue set (:func:`engine.diagnosis.plant_gap.open_world`).
FIRST_GUESS_DISPERSION: float = 10.0
#: Share of the gap a term (or a named set, :mod:`engine.diagnosis.plant_gap`) must remove to explain it.
EXPLAINED_SHARE: float = 0.9
#: The most a first-guess locus's confidence may say (the backlash drive's locus estimate caps it alike).
FIRST_GUESS_CONFIDENCE: float = 0.5
#: Hat functions per signal (knots at evenly spaced quantiles of the signal on the scored samples).
N_HATS: int = 8
#: Harmonics per periodic signal (a cosine and a sine each).
N_HARMONICS: int = 3
#: Quantiles of a signal that bound its hats (its extremes are often a few samples).
SIGNAL_RANGE: tuple[float, float] = (0.005, 0.995)
#: BIC difference (after the dispersion scaling) within which two loci are a tie, and by which the
#: best must beat the calibrated model alone to be a locus at all.
TIE_BIC: float = 10.0
#: Roughness weights tried, relative to the mean diagonal of the columns' normal matrix.
PENALTIES: tuple[float, ...] = tuple(float(x) for x in np.logspace(-6.0, 1.0, 8))
#: Fractions of the linear step simulated, in turn, until the simulated fit stops improving.
STEP_FRACTIONS: tuple[float, ...] = (1.0, 0.5, 0.25, 0.125)
#: Simulations of the calibrated parameters' refit beside a locus's input.
REFIT_NFEV: int = 30
#: Ridge on a term's coefficients, as a share of its columns' mean scale (:func:`_penalised_fit`).
RIDGE: float = 1e-4
#: Loci (the best by their first fit) whose term is refined by re-linearised steps.
REFINE_LOCI: int = 2
#: Re-linearised steps of a refinement at most.
REFINE_ITERATIONS: int = 2
#: Whitened RMS of a probe's response the probe scale aims at [noise RMS].
PROBE_TARGET: float = 1.0
#: Rescalings of a probe before its scale is accepted.
PROBE_TRIES: int = 6


@dataclass(frozen=True)
class LocusScore:
    """One locus's fit.

    Attributes
    ----------
    locus : str
    bic : float
        ``RSS / tau + dof ln(n / tau)`` of the simulated fit.
    chi2 : float
        Simulated whitened RSS (sum of squared residuals over noise RMS) with the locus's term.
    dof : float
        Effective number of the term's coefficients (trace of the penalised hat matrix).
    explained : float
        Share of the calibrated model's whitened RSS the term removes (simulated).
    weight : float
        Posterior weight among the loci.
    """

    locus: str
    bic: float
    chi2: float
    dof: float
    explained: float
    weight: float = 0.0


@dataclass
class PlantLocusReport:
    """The locus of a gap and its missing term (module docstring).

    Attributes
    ----------
    locus : str or None
        The part of the plant the missing term acts at; None when no part's term beats the
        calibrated model alone.
    confidence : float
        The locus's posterior weight (0 without a locus).
    ties : list of str
        Loci the record cannot tell from it.
    scores : dict of str to LocusScore
    term : dict
        The best locus's input: ``entry``, ``unit``, ``rms``, ``peak``, ``signal`` (the one that carries
        most of it), ``factor``, ``curve`` (the law ``f`` at the hats' knots, or the harmonics'
        amplitudes), ``shares`` (per signal), ``description``.
    chi2_before : float
        Whitened RSS of the calibrated model.
    n_simulations : int
        Simulations the estimate ran (in a diagnosis, with those of the stand-in test's estimate
        from the calibration, :func:`engine.diagnosis.plant_gap.open_world`).
    note : str
    tau, n_eff, dispersion : float
        The noise's correlation time [samples], the record's independent samples and the best fit's
        dispersion the evidence was weighed with (:meth:`advantage`).
    """

    locus: str | None
    confidence: float
    ties: list[str]
    scores: dict[str, LocusScore]
    term: dict[str, Any]
    chi2_before: float
    n_simulations: int
    note: str = ""
    tau: float = 1.0
    n_eff: float = 1.0
    dispersion: float = 1.0

    @property
    def reproduces(self) -> bool:
        """Whether the best locus's term reproduces the record: it leaves a dispersion of at most
        :data:`FIRST_GUESS_DISPERSION`, or removes :data:`EXPLAINED_SHARE` of the gap. Else the locus is
        a first guess."""
        if self.locus is None:
            return False
        return self.dispersion <= FIRST_GUESS_DISPERSION or self.scores[self.locus].explained >= EXPLAINED_SHARE

    def advantage(self, chi2: float, k: int) -> float:
        """How much better the best locus's term fits than another model: its scaled BIC difference.

        ``chi2`` is the other model's whitened RSS on the same samples (e.g. the named catalogue set's)
        and ``k`` its extra parameters beside the calibrated ones. Positive: the term fits better; above
        :data:`TIE_BIC`, the record holds evidence for it against that model.
        """
        if self.locus is None:
            return -math.inf
        other = chi2 / self.tau + k * math.log(self.n_eff)
        return (other - self.scores[self.locus].bic) / self.dispersion

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (without the input's series)."""
        return {
            "locus": self.locus,
            "confidence": self.confidence,
            "ties": list(self.ties),
            "scores": {
                k: {"bic": s.bic, "chi2": s.chi2, "dof": s.dof, "explained": s.explained, "weight": s.weight}
                for k, s in self.scores.items()
            },
            "term": self.term,
            "chi2_before": self.chi2_before,
            "n_simulations": self.n_simulations,
            "note": self.note,
        }


def _hats(s: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Piecewise-linear hat functions at ``knots`` evaluated at ``s`` (clipped to the knots' range)."""
    s = np.clip(s, knots[0], knots[-1])
    out = np.zeros((s.size, knots.size))
    for j in range(knots.size):
        e = np.zeros(knots.size)
        e[j] = 1.0
        out[:, j] = np.interp(s, knots, e)
    return out


def signal_basis(sig: LocusSignal, scored: slice) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The basis of a signal's inputs on the record's grid (module docstring, step 1).

    Returns
    -------
    basis : ndarray, shape (n, m)
        Columns ``factor(t) phi_j(s(t))``.
    knots : ndarray or None
        The hats' knots, in the signal's unit (None for harmonics).
    penalty : ndarray, shape (m, m)
        The roughness penalty ``D^T D`` (first differences of neighbouring hats; identity for harmonics).
    """
    s = np.asarray(sig.values, dtype=float)
    factor = np.ones(s.size) if sig.factor is None else np.asarray(sig.factor, dtype=float)
    if sig.period is not None:
        phase = 2.0 * math.pi * s / sig.period
        cols = [f(k * phase) for k in range(1, N_HARMONICS + 1) for f in (np.cos, np.sin)]
        basis = np.column_stack(cols) * factor[:, None]
        return basis, None, np.eye(basis.shape[1])
    lo, hi = np.quantile(s[scored], SIGNAL_RANGE)
    if not hi > lo:
        lo, hi = float(s[scored].min()), float(s[scored].max()) + 1e-300
    knots = np.linspace(lo, hi, N_HATS)
    basis = _hats(s, knots) * factor[:, None]
    d = np.diff(np.eye(N_HATS), axis=0)
    return basis, knots, d.T @ d


class _Responses:
    """Whitened channel responses of the plant on one record (module docstring, step 2)."""

    def __init__(
        self,
        plant: Plant,
        record: Any,
        values: Mapping[str, float],
        levels: Mapping[str, NoiseLevel],
        base: Mapping[str, np.ndarray] | None = None,
        workers: MapLike | None = None,
    ):
        self.plant, self.record, self.values = plant, record, dict(values)
        self.base = dict(base or {})
        self.workers = workers
        self._lock = threading.Lock()  # the workers' threads share the count
        self.window = plant.scored(record)
        self.channels = [c.name for c in plant.channels]
        self.sigma = {c: levels[c].sigma for c in self.channels}
        meas = plant.measured(record)
        self.y = np.concatenate([meas[c][self.window] / self.sigma[c] for c in self.channels])
        self.n_sim = 0
        self.y0 = self.sim(self.values, None)

    def sim(self, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None) -> np.ndarray:
        """Whitened channels at ``values`` with ``inputs`` added to the base input."""
        with self._lock:
            self.n_sim += 1
        return self._sim(values, inputs)

    def sims(self, points: Sequence[tuple[Mapping[str, float], Mapping[str, np.ndarray] | None]]) -> list[np.ndarray]:
        """:meth:`sim` at each ``(values, inputs)`` of ``points``, in their order (on the workers' threads when given)."""
        with self._lock:
            self.n_sim += len(points)
        return list(self.map(lambda point: self._sim(*point), points))

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
        """``fn`` on each of ``items``, in their order, on the workers' threads when given."""
        return list((self.workers or map)(fn, items))

    def _sim(self, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None) -> np.ndarray:
        total = dict(self.base)
        for e, d in (inputs or {}).items():
            total[e] = total[e] + d if e in total else d
        out = self.plant.simulate(self.record, values, total or None)
        return np.concatenate([out[c][self.window] / self.sigma[c] for c in self.channels])

    def residual(self) -> np.ndarray:
        return self.y - self.y0

    def calibrated_columns(self) -> tuple[np.ndarray, list[tuple[str, float, float]]]:
        """Columns of the calibrated parameters (per unit-box step) and their (name, u0, step)."""
        points, info = [], []
        h = self.plant.diff_step
        for p in free_parameters(self.plant, self.record):
            u, step = difference_step(p, self.values.get(p.name, p.nominal), h)
            points.append(({**self.values, p.name: float(p.value(u + step))}, None))
            info.append((p.name, u, step))
        cols = [(yp - self.y0) / step for yp, (_, _, step) in zip(self.sims(points), info, strict=True)]
        n = self.y0.size
        return (np.column_stack(cols) if cols else np.zeros((n, 0))), info

    def refit(
        self, inputs: Mapping[str, np.ndarray], start: Mapping[str, float] | None = None
    ) -> tuple[float, dict[str, float]]:
        """Whitened RSS with ``inputs`` added, the calibrated parameters refitted beside them (bounded
        least squares from ``start``, default the calibration, :data:`REFIT_NFEV` simulations at most),
        and their values."""
        from engine.diagnosis.plant_gap import solve_unit_box

        free = free_parameters(self.plant, self.record)
        if not free:
            r = self.y - self.sim(self.values, inputs)
            return float(r @ r), dict(self.values)

        def values(z: np.ndarray) -> dict[str, float]:
            return {**self.values, **{p.name: float(p.value(zi - 1.0)) for p, zi in zip(free, z, strict=True)}}

        def residual(z: np.ndarray) -> np.ndarray:
            return self.y - self.sim(values(z), inputs)

        begin = {**self.values, **(start or {})}
        u0 = np.array([p.unit_coord(begin.get(p.name, p.nominal)) for p in free])
        res = solve_unit_box(
            residual, u0, self.plant.diff_step, [p.name for p in free], max_nfev=REFIT_NFEV, workers=self.workers
        )
        return float(res.fun @ res.fun), values(res.x)

    def probe_scale(self, entry: str, shape: np.ndarray) -> float:
        """A scale a such that the response to ``a * shape`` at ``entry`` is about one noise RMS."""
        a = 1.0
        for _ in range(PROBE_TRIES):
            try:
                r = self.sim(self.values, {entry: a * shape}) - self.y0
                rho = float(np.sqrt(np.mean(r**2)))
            except (RuntimeError, FloatingPointError, ValueError):
                rho = math.inf
            if not math.isfinite(rho):
                a *= 1e-3
                continue
            if rho == 0.0:
                a *= 1e3
                continue
            if 0.3 < rho / PROBE_TARGET < 3.0:
                return a
            a *= PROBE_TARGET / rho
        return a

    def columns(self, entry: str, basis: np.ndarray) -> np.ndarray:
        """Whitened responses to each basis column at ``entry``, per unit coefficient (probed at :meth:`probe_scale`)."""
        a = self.probe_scale(entry, basis.sum(axis=1))
        moved = self.sims([(self.values, {entry: a * basis[:, j]}) for j in range(basis.shape[1])])
        return np.column_stack([(y - self.y0) / a for y in moved])


def _penalised_fit(
    A: np.ndarray, r: np.ndarray, penalty: np.ndarray, tau: float, n_eff: float
) -> tuple[np.ndarray, float, np.ndarray]:
    """Coefficients and dof of the BIC-best penalised fit of ``r`` on ``A`` (module docstring, step 3).

    ``A`` and ``r`` come with the calibrated parameters' columns projected out. Beside the roughness
    ``penalty``, a fixed ridge of :data:`RIDGE` of the columns' mean scale keeps the coefficients off
    the directions the calibration absorbs (a term whose response it could cancel is no evidence).
    """
    G = A.T @ A
    b = A.T @ r
    m = A.shape[1]
    scale = float(np.mean(np.diag(G))) or 1.0
    best: tuple[float, np.ndarray, float, np.ndarray] | None = None
    for lam in PENALTIES:
        P = lam * scale * penalty + RIDGE * scale * np.eye(m)
        S = G + P
        try:
            theta = np.linalg.solve(S, b)
            dof = float(np.trace(np.linalg.solve(S, G)))
        except np.linalg.LinAlgError:
            continue
        res = r - A @ theta
        bic = float(res @ res) / tau + dof * math.log(n_eff)
        if best is None or bic < best[0]:
            best = (bic, theta, dof, P)
    if best is None:
        raise RuntimeError("the locus fit failed at every penalty weight")
    return best[1], best[2], best[3]


def _bounded_joint(
    Jc: np.ndarray, u0: np.ndarray, A: np.ndarray, r: np.ndarray, P: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The calibrated parameters' unit-box step and the term's coefficients fitted together, the step
    bounded to the box: ``min |r - Jc dz - A theta|^2 + theta' P theta``, ``u0 + dz`` in [0, 1].

    What the projected fit leaves undetermined (a constant force beside a calibrated offset) is then
    put where the calibration can take it: a term whose level the calibration cannot absorb within
    its interval is fitted with that level.
    """
    from scipy.optimize import lsq_linear  # here: scipy.optimize adds about 0.7 s to a service start

    w, V = np.linalg.eigh(P)
    L = np.sqrt(np.clip(w, 0.0, None))[:, None] * V.T
    nf, m = Jc.shape[1], A.shape[1]
    M = np.block([[Jc, A], [np.zeros((m, nf)), L]])
    b = np.concatenate([r, np.zeros(m)])
    lo = np.concatenate([-u0, np.full(m, -np.inf)])
    hi = np.concatenate([1.0 - u0, np.full(m, np.inf)])
    res = lsq_linear(M, b, bounds=(lo, hi), method="trf", lsmr_tol="auto")
    return res.x[:nf], res.x[nf:]


def _describe(sig: LocusSignal, knots: np.ndarray | None, coef: np.ndarray, unit: str) -> dict[str, Any]:
    """The law f of one signal's part of the term: values at the knots, or harmonic amplitudes."""
    if knots is None:
        amps = [float(math.hypot(coef[2 * k], coef[2 * k + 1])) for k in range(coef.size // 2)]
        return {"harmonic_amplitudes": amps, "period": sig.period, "unit": unit}
    return {"knots": [float(v) for v in knots], "values": [float(v) for v in coef], "unit": unit}


def estimate_plant_locus(
    plant: Plant,
    record: Any,
    values: Mapping[str, float],
    levels: Mapping[str, NoiseLevel] | None = None,
    workers: MapLike | None = None,
) -> PlantLocusReport:
    """The locus and missing term of the gap left by the model at ``values`` on ``record`` (module docstring).

    Parameters
    ----------
    plant, record
        The plant and one of its records.
    values : mapping
        The model the answer ends with (calibrated parameters, and any named effects): the residual
        read is the one it leaves.
    levels : mapping of str to NoiseLevel, optional
        The plant's noise per channel (default :meth:`~engine.plants.base.Plant.noise`).
    workers : map-like, optional
        Runs the independent simulations (the responses' columns, the refits' Jacobians) on threads
        (:func:`engine.diagnosis.plant_gap.simulation_pool`); the same result as without.

    Raises
    ------
    ValueError
        When the plant declares no locus signals (its locus estimate is its own).
    """
    signals: Sequence[LocusSignal] = plant.locus_signals(record, values)
    if not signals:
        raise ValueError(f"plant {plant.name!r} declares no locus signals")
    levels = dict(levels or plant.noise(record))
    resp = _Responses(plant, record, values, levels, workers=workers)
    r = resp.residual()
    taus = [levels[c].tau for c in resp.channels]
    tau = float(np.mean(taus))
    n_eff = max(r.size / tau, 2.0)
    chi2_0 = float(r @ r)
    cal = resp.calibrated_columns()
    n_free = cal[0].shape[1]
    window = resp.window

    per_signal: list[_Basis] = []
    for sig in signals:
        if sig.entry not in plant.entries:
            raise ValueError(f"locus signal {sig.signal!r} enters by unknown entry {sig.entry!r}")
        per_signal.append(_Basis(sig, *signal_basis(sig, window)))
    # every signal's columns, every locus's fit and the refinements are independent: each stage's
    # items run on the workers (their own simulations then one after another on each thread)
    columns = dict(enumerate(resp.map(lambda b: resp.columns(b.sig.entry, b.basis), per_signal)))

    loci = list(dict.fromkeys(sig.locus for sig in signals))
    groups: list[list[int]] = []
    for locus in loci:
        members = [i for i, b in enumerate(per_signal) if b.sig.locus == locus]
        # the locus's signals together, and each alone (one signal's input may leave the linear range
        # where another's holds): the locus scores its best simulated fit
        groups += [members] + ([[i] for i in members] if len(members) > 1 else [])
    fits: dict[str, _GroupFit] = {}
    for fitted in resp.map(lambda g: _fit_group(resp, per_signal, columns, g, cal, tau, n_eff, chi2_0), groups):
        locus = fitted.score.locus
        if locus not in fits or fitted.score.bic < fits[locus].score.bic:
            fits[locus] = fitted
    n_sim = resp.n_sim
    best_loci = sorted(fits, key=lambda k: fits[k].score.bic)[:REFINE_LOCI]
    refined = resp.map(
        lambda k: _refine(plant, record, levels, per_signal, fits[k], tau, n_eff, chi2_0, workers), best_loci
    )
    for locus, (fitted, n) in zip(best_loci, refined, strict=True):
        fits[locus] = fitted
        n_sim += n
    scores = {k: f.score for k, f in fits.items()}

    best = min(scores.values(), key=lambda s: s.bic)
    dof_best = best.dof + n_free
    dispersion = max(1.0, best.chi2 / tau / max(n_eff - dof_best, 1.0))
    bic_none = chi2_0 / tau
    rel = {k: (s.bic - best.bic) / dispersion for k, s in scores.items()}
    w = {k: math.exp(-0.5 * min(v, 1400.0)) for k, v in rel.items()}
    total = sum(w.values())
    scores = {k: LocusScore(s.locus, s.bic, s.chi2, s.dof, s.explained, w[k] / total) for k, s in scores.items()}
    if (bic_none - best.bic) / dispersion < TIE_BIC:
        return PlantLocusReport(
            None,
            0.0,
            [],
            scores,
            {},
            chi2_0,
            n_sim,
            f"no part's term beats the calibrated model alone by {TIE_BIC:g} (scaled BIC)",
            tau,
            n_eff,
            dispersion,
        )
    ties = sorted((k for k, v in rel.items() if k != best.locus and v < TIE_BIC), key=lambda k: rel[k])
    inputs, parts = fits[best.locus].inputs, fits[best.locus].parts
    term = _term(plant, per_signal, parts, inputs, window)
    note = ""
    if dispersion > FIRST_GUESS_DISPERSION and scores[best.locus].explained < EXPLAINED_SHARE:
        note = (
            f"the best term leaves {dispersion:.3g} times the noise's dispersion: one term at one part does not "
            "reproduce the record, and the locus is a first guess"
        )
    confidence = scores[best.locus].weight
    if note:
        confidence = min(confidence, FIRST_GUESS_CONFIDENCE)
    return PlantLocusReport(
        best.locus,
        confidence,
        ties,
        scores,
        term,
        chi2_0,
        n_sim,
        note,
        tau,
        n_eff,
        dispersion,
    )


@dataclass(frozen=True, eq=False)
class _Basis:
    """One locus signal's basis (:func:`signal_basis`): columns on the record's grid, hat knots, penalty."""

    sig: LocusSignal
    basis: np.ndarray
    knots: np.ndarray | None
    penalty: np.ndarray


@dataclass
class _GroupFit:
    """One locus's fitted term: its signals, input per entry (total), coefficients, calibrated values."""

    score: LocusScore
    group: list[int]
    inputs: dict[str, np.ndarray]
    parts: list[tuple[int, np.ndarray]]
    values: dict[str, float]


def _fit_group(
    resp: _Responses,
    per_signal: Sequence[_Basis],
    cols: Mapping[int, np.ndarray],
    group: Sequence[int],
    cal: tuple[np.ndarray, list[tuple[str, float, float]]],
    tau: float,
    n_eff: float,
    chi2_0: float,
    dof: float | None = None,
    previous: _GroupFit | None = None,
) -> _GroupFit:
    """Steps 3 and 4 of the module docstring for the signals ``group`` of one locus, around ``resp``'s
    point (its base input: ``previous``'s, whose coefficients the step adds to); ``cal``: the
    calibrated parameters' columns and (name, unit coordinate, step) at that point. ``dof``: the
    term's effective dof when already known (a refinement keeps the first fit's)."""
    locus = per_signal[group[0]].sig.locus
    Jc, info = cal
    Q = np.linalg.qr(Jc)[0] if Jc.shape[1] else np.zeros((Jc.shape[0], 0))
    r = resp.residual()
    r_p = r - Q @ (Q.T @ r)
    A = np.column_stack([cols[i] for i in group])
    pen = _block_diag([per_signal[i].penalty for i in group])
    _, dof_fit, P = _penalised_fit(A - Q @ (Q.T @ A), r_p, pen, tau, n_eff)
    dof = dof_fit if dof is None else dof
    u0 = np.array([u for _, u, _ in info])
    dz, theta = _bounded_joint(Jc, u0, A, r, P)
    params = {p.name: p for p in free_parameters(resp.plant, resp.record)}
    step: dict[str, np.ndarray] = {}
    steps: list[tuple[int, np.ndarray]] = []
    k = 0
    for i in group:
        basis = per_signal[i].basis
        coef = theta[k : k + basis.shape[1]]
        k += basis.shape[1]
        entry = per_signal[i].sig.entry
        step[entry] = step.get(entry, 0.0) + basis @ coef
        steps.append((i, coef))
    chi2, frac, values = math.inf, 0.0, dict(resp.values)
    limit = previous.score.chi2 if previous is not None else chi2_0
    for alpha in STEP_FRACTIONS:  # damped: the linear step scaled until the simulation agrees
        start = dict(resp.values)
        for (name, u, _), d in zip(info, dz, strict=True):
            start[name] = float(params[name].value(u + alpha * d))
        try:
            c, v = resp.refit({e: alpha * d for e, d in step.items()}, start)
        except (RuntimeError, FloatingPointError, ValueError) as exc:
            logger.info("locus %s: the fitted input does not simulate at %g of its step (%s)", locus, alpha, exc)
            continue
        if c < chi2:
            chi2, frac, values = c, alpha, v
        if chi2 < limit:
            break
    inputs = dict(resp.base)
    for e, d in step.items():
        inputs[e] = inputs[e] + frac * d if e in inputs else frac * d
    before = dict(previous.parts) if previous is not None else {}
    parts = [(i, before.get(i, 0.0) + frac * coef) for i, coef in steps]
    bic = chi2 / tau + dof * math.log(n_eff)
    score = LocusScore(locus, bic, chi2, dof, 1.0 - chi2 / chi2_0 if chi2_0 > 0 else 0.0)
    return _GroupFit(score, list(group), inputs, parts, values)


def _refine(
    plant: Plant,
    record: Any,
    levels: Mapping[str, NoiseLevel],
    per_signal: Sequence[_Basis],
    fit: _GroupFit,
    tau: float,
    n_eff: float,
    chi2_0: float,
    workers: MapLike | None = None,
) -> tuple[_GroupFit, int]:
    """Gauss-Newton steps re-linearised around a locus's fitted term (module docstring, step 4), each
    kept only if its simulated fit improves; returns the fit and the simulations run."""
    n_sim = 0
    for _ in range(REFINE_ITERATIONS):
        resp = _Responses(plant, record, fit.values, levels, base=fit.inputs, workers=workers)
        cal = resp.calibrated_columns()
        cols = {i: resp.columns(per_signal[i].sig.entry, per_signal[i].basis) for i in fit.group}
        new = _fit_group(resp, per_signal, cols, fit.group, cal, tau, n_eff, chi2_0, fit.score.dof, fit)
        n_sim += resp.n_sim
        if not new.score.chi2 < fit.score.chi2 * (1.0 - 1e-3):
            break
        fit = new
    return fit, n_sim


def _block_diag(blocks: Sequence[np.ndarray]) -> np.ndarray:
    m = sum(b.shape[0] for b in blocks)
    out = np.zeros((m, m))
    k = 0
    for b in blocks:
        out[k : k + b.shape[0], k : k + b.shape[0]] = b
        k += b.shape[0]
    return out


def _term(
    plant: Plant,
    per_signal: Sequence[_Basis],
    parts: Sequence[tuple[int, np.ndarray]],
    inputs: Mapping[str, np.ndarray],
    window: slice,
) -> dict[str, Any]:
    """The best locus's input described (see :class:`PlantLocusReport`, ``term``)."""
    contrib = {}
    for i, coef in parts:
        part = (per_signal[i].basis @ coef)[window]
        contrib[i] = float(np.sqrt(np.mean(part**2)))
    total = sum(contrib.values()) or 1.0
    main = max(contrib, key=lambda i: contrib[i])
    sig = per_signal[main].sig
    coef = next(c for i, c in parts if i == main)
    unit = plant.entries[sig.entry]
    d = inputs[sig.entry][window]
    law = _describe(sig, per_signal[main].knots, coef, unit)
    by = f" times the {sig.factor_name}" if sig.factor is not None and sig.factor_name else ""
    rms = float(np.sqrt(np.mean(d**2)))
    description = (
        f"a {sig.entry} input of about {rms:.3g} {unit} RMS at the {sig.locus}, following the {sig.signal}{by}"
    )
    return {
        "entry": sig.entry,
        "unit": unit,
        "rms": rms,
        "peak": float(np.max(np.abs(d))),
        "signal": sig.signal,
        "signal_unit": sig.unit,
        "factor": sig.factor_name or None,
        "curve": law,
        "shares": {per_signal[i].sig.signal: contrib[i] / total for i in contrib},
        "description": description,
    }
