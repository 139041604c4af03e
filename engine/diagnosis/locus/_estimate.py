"""The locus estimate: :func:`estimate_locus`.

Runs the steps of the method in order (see :mod:`engine.diagnosis.locus`), ranks the refined loci
and the sensor library by their evidence (step 6) and writes the report.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from engine.constants import CHANNELS, DERIVATIVE_CHANNELS
from engine.diagnosis.calibration import CalibrationError, CalibrationResult
from engine.diagnosis.locus._interference import Interference, periodic_extension
from engine.diagnosis.locus._linear import orth, penalised_fit, project, sparse_extension
from engine.diagnosis.locus._refine import Estimate, refine
from engine.diagnosis.locus._report import LocusError, LocusReport, LocusScore, LocusSettings
from engine.diagnosis.locus._responses import N_EXTRAS, Observed, Responses, responses
from engine.diagnosis.locus._starts import extras_scan, joint_fits, refinement_start
from engine.diagnosis.locus._term import locus_term, sensor_term
from engine.diagnosis.locus._uncertainty import part_term_sigma
from engine.diagnosis.space import ModelSpace, default_space
from engine.parallel import single_threaded_blas
from engine.records import Record
from engine.simulation import DISTURBANCE_LOCI
from engine.simulation.parameters import input_part, locus_group

logger = logging.getLogger(__name__)


#: Largest confidence of a locus whose fit leaves the record far from the noise (``first_guess_chi2``).
FIRST_GUESS_CONFIDENCE: float = 0.5
#: The measurement chain's locus (a parametric library, not an unknown input).
SENSORS: str = "sensors"


def estimate_locus(
    record: Record,
    calibration: CalibrationResult,
    settings: LocusSettings = LocusSettings(),  # noqa: B008 (frozen, so immutable; imported, so ruff cannot tell)
    space: ModelSpace | None = None,
    known_drifts: Mapping[str, Mapping[str, float]] | None = None,
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
    known_drifts : mapping, optional
        Global joint fits of part-parameter drifts already made (the diagnosis's escalated
        catalogue candidates of the same fields), by field: the fitted calibrated parameters and
        the drift's factor under ``"factor"``; those are not fitted again (:func:`~engine.diagnosis.locus._starts.joint_fits`).

    Returns
    -------
    LocusReport

    Raises
    ------
    LocusError
        The calibration holds no simulation, or its case cannot be simulated.
    """
    with single_threaded_blas():  # small matrices: BLAS threads only compete with the simulations
        return _estimate(record, calibration, settings, space, known_drifts)


@dataclass(frozen=True)
class SensorFit:
    """The measurement chain's fit to the whitened residual (step 5 of the method).

    Attributes
    ----------
    rss, bic, dof : float
        The fit's residual, its BIC and its degrees of freedom [chi2 units; -], the interference's
        included when one is taken.
    coef : ndarray
        Coefficients of the base library's columns (``Responses.sensor_names``).
    cross : list of int
        The cross-talk columns taken (``Responses.crosstalk_names``), with ``cross_coef``.
    cross_coef : ndarray
    base_rss : float
        The residual before the interference (the base library and the cross-talk) [chi2 units].
    interference : Interference or None
        The periodic interference taken, if any (:mod:`engine.diagnosis.locus._interference`).
    """

    rss: float
    bic: float
    dof: float
    coef: np.ndarray
    cross: list[int]
    cross_coef: np.ndarray
    base_rss: float
    interference: Interference | None

    def values(self, resp: Responses, names: list[str], sigma: np.ndarray) -> dict[str, float]:
        """The fitted values by name, as :func:`~engine.diagnosis.locus._term.sensor_term` reads them."""
        values = dict(zip(resp.sensor_names, (float(v) for v in self.coef), strict=True))
        values |= {resp.crosstalk_names[j]: float(v) for j, v in zip(self.cross, self.cross_coef, strict=True)}
        hum = self.interference
        if hum is not None:
            values["interference_hz"] = hum.frequency_hz
            for j, (a, b) in zip(hum.channels, hum.coef, strict=True):
                values[f"interference_{names[j]}"] = float(math.hypot(a, b) * sigma[j])
        return values


def sensor_fit(
    resp: Responses,
    Q: np.ndarray,
    rp: np.ndarray,
    t: np.ndarray,
    names: list[str],
    sigma: np.ndarray,
    cal: CalibrationResult,
    settings: LocusSettings,
) -> SensorFit:
    """The measurement chain's fit: its base library, the cross-talk and the periodic interference the data ask for.

    Parameters
    ----------
    resp : Responses
        The response batch (its sensor and cross-talk columns).
    Q : ndarray, shape (n, k)
        Orthonormal basis of the calibrated parameters' columns, projected out of every column.
    rp : ndarray, shape (n,)
        The whitened residual, the calibrated parameters projected out.
    t : ndarray, shape (n_samples,)
        The window's sample instants [s].
    names : list of str
        The record's channels, in the residual's order.
    sigma : ndarray, shape (n_ch,)
        Each channel's noise standard deviation (the whitening).
    cal : CalibrationResult
        The calibration (the plant's wheel radius scales a1 against omega1).
    settings : LocusSettings
    """
    k = Q.shape[1]
    sensors, crosstalk = project(Q, resp.sensors), project(Q, resp.crosstalk)
    rss, bic, coef, cross, cross_coef = sparse_extension(sensors, crosstalk, rp, k)
    dof = float(resp.sensors.shape[1] + len(cross))
    assert cal.case is not None
    motions = []  # the pairs of a channel and its time derivative, their scale between whitened values
    for deriv, chan, scale in DERIVATIVE_CHANNELS:
        if deriv in names and chan in names:
            i, j = names.index(deriv), names.index(chan)
            factor = 1.0 if scale is None else float(getattr(cal.case.plant, scale))
            motions.append((i, j, factor * float(sigma[j] / sigma[i])))
    hum = periodic_extension(
        np.hstack([sensors, crosstalk[:, cross]]),
        rp,
        t,
        len(names),
        k,
        Q,
        settings.interference_min_periods,
        motions=motions,
    )
    if hum is None:
        return SensorFit(rss, bic, dof, coef, cross, cross_coef, rss, None)
    m = coef.size
    return SensorFit(
        hum.rss,
        bic + hum.rss - rss + hum.penalty,
        dof + 1 + 2 * len(hum.channels),
        hum.design_coef[:m],
        cross,
        hum.design_coef[m:],
        rss,
        hum,
    )


def _estimate(
    record: Record,
    calibration: CalibrationResult,
    settings: LocusSettings,
    space: ModelSpace | None,
    known_drifts: Mapping[str, Mapping[str, float]] | None,
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
    obs = Observed(record, rows, data, sigma)
    space = space or default_space(record, drive=cal.drive)  # the joint fits' space (friction, drifts)

    # 1. linearised around the calibrated trajectory, every locus at once
    resp = responses(record, cal, sigma, rows, settings)
    n_sim = resp.n_simulations
    Q = orth(resp.params, n)
    k = Q.shape[1]
    rp = project(Q, r[:, None])[:, 0]
    rr = float(rp @ rp)
    estimates: dict[str, Estimate] = {}
    for locus in DISTURBANCE_LOCI:
        hats, extras = resp.columns[locus][:, :-N_EXTRAS], resp.columns[locus][:, -N_EXTRAS:]
        # the parameters and the locus's extras are unpenalised: projected out
        free = np.hstack([resp.params, extras])
        Qc = orth(free, n)
        fit = penalised_fit(project(Qc, hats), project(Qc, r[:, None])[:, 0], Qc.shape[1], settings)
        x = np.nan_to_num(fit.x)
        coef = np.linalg.lstsq(free, r - hats @ x, rcond=None)[0]
        estimates[locus] = Estimate(x, coef[-N_EXTRAS:], coef[:-N_EXTRAS], fit, fit.rss, fit.bic, refined=False)
    # the measurement chain: its base library, and the cross-talk and interference the data ask for
    sf = sensor_fit(resp, Q, rp, record.grid.time, names, sigma, cal, settings)
    bic_none = rr + k * ln_n

    # 2. a scan of a constant input per locus: a global start where a term is too strong to
    # linearise (a constant offset of the backlash zone shifts the impacts)
    scan, chi2_base, used = extras_scan(cal, resp, obs, settings)
    n_sim += used
    # each part's Coulomb friction and parameter drifts, fitted jointly with the calibrated
    # parameters on the test window, as the calibration and every locus fit (a longer record is
    # cut, not misread)
    scan, used = joint_fits(record, cal, space, resp, obs, scan, settings, known_drifts)
    n_sim += used

    # 3. Gauss-Newton refinement: one iteration of every locus (the linearised ranking misleads
    # when the term is strong), then more for the best ones
    for locus in DISTURBANCE_LOCI:
        start, used = refinement_start(cal, locus, resp, estimates[locus], obs, chi2_base, scan[locus], settings)
        estimates[locus], more = refine(cal, locus, resp, start, obs, 1, settings)
        n_sim += used + more
    for locus in sorted(DISTURBANCE_LOCI, key=lambda key: estimates[key].bic)[: settings.refine_loci]:
        estimates[locus], used = refine(
            cal, locus, resp, estimates[locus], obs, settings.refine_iterations - 1, settings
        )
        n_sim += used

    # 4. ranking: the refined loci (simulated chi2) and the sensor library. The evidence is
    # scaled by the best fit's dispersion (quasi-likelihood): a best fit far above the noise says
    # the model is still wrong somewhere, and BIC differences in chi2 units then overstate it.
    bics = {locus: e.bic for locus, e in estimates.items() if e.refined}
    bics[SENSORS] = sf.bic
    leader = min(bics, key=lambda key: bics[key])
    lead_rss = estimates[leader].rss if leader in estimates else sf.rss
    lead_dof = estimates[leader].fit.dof + estimates[leader].n_extras if leader in estimates else sf.dof
    dispersion = max(1.0, lead_rss / max(n - lead_dof - k, 1.0))
    best_bic = min(min(bics.values()), bic_none)
    all_w = {key: math.exp(-0.5 * (b - best_bic) / dispersion) for key, b in {**bics, "none": bic_none}.items()}
    total = sum(all_w.values())
    scores: dict[str, LocusScore] = {}
    for locus in (*DISTURBANCE_LOCI, SENSORS):
        b = bics[locus] if locus in bics else estimates[locus].bic
        rss = estimates[locus].rss if locus in estimates else sf.rss
        dof = estimates[locus].fit.dof if locus in estimates else sf.dof
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
    # the part the record can name (an input's part: the clutch's torque is the clutch's), with the parts
    # its channels cannot tell from it
    part = input_part(best)
    group = list(locus_group(part))
    ties = list(
        dict.fromkeys(
            input_part(key)
            for key in ranked[1:]
            if input_part(key) not in group and (bics[key] - bics[best]) / dispersion < settings.tie_delta
        )
    )
    t_rel = record.grid.time
    chi2_injected = math.nan
    if best == SENSORS:
        values = sf.values(resp, names, sigma)
        term = sensor_term(values, names, settings)
    else:
        est = estimates[best]
        chi2_injected = est.rss if est.refined else math.nan
        # how well the record determines the value of a part term, if the locus ends with one
        part_sigma, used = part_term_sigma(cal, best, resp, est, obs, dispersion, settings)
        n_sim += used
        term = locus_term(best, est, resp, cal, t_rel, settings, part_sigma)
        if not est.refined or est.rss > chi2:
            notes.append(
                "injecting the estimated input into the calibrated case does not lower chi2: the gap is too "
                "large for the linearisation around the calibrated trajectory; the locus is a first guess"
            )
    confidence = sum(s.weight for key, s in scores.items() if input_part(key) in group)
    left = scores[best].rss / n
    if left > settings.first_guess_chi2:
        confidence = min(confidence, FIRST_GUESS_CONFIDENCE)
        notes.append(
            f"the best input leaves chi2/n = {left:.3g}, far above the noise: one additive input at one locus "
            f"does not reproduce the record, and the locus is a first guess"
        )
    report = LocusReport(
        locus=part,
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
        group=group,
        input=best,
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
