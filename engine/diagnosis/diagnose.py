"""The sim-to-real gap diagnosis of one record: calibrate, localise, rank candidate effects, decide.

Decision rule (thresholds in :class:`DiagnosisSettings`)
--------------------------------------------------------
Every candidate effect is fitted (with the calibration) and ranked by BIC.
The fit statistic of a calibration is its noise-normalised residual energy
per sample, ``chi2 / n`` (1 when the model reproduces the record to the
noise), in total and per channel. The noise level comes from the record
itself (:func:`~engine.diagnosis.noise.estimate_noise`, relative
standard error about 2.2 % per channel), so the statistic scatters by a few
per cent around 1 even without a gap; the thresholds allow for that. A fit is
"to the noise" when total ``chi2/n <= max_reduced_chi2`` and every channel's
``chi2_j/n_j <= max_channel_chi2``.

* Evidence for an effect: the best candidate lowers the BIC of the nominal
  model by at least ``min_delta_bic`` (a likelihood-ratio test; unlike the
  absolute fit statistic it does not depend on the noise estimate's error).
* With evidence: ``explained`` when the best candidate fits to the noise and
  the fitted effect moves the record clearly beyond the noise (some channel's
  RMS change, fit with the effect minus the same calibration without it, above
  ``min_strength`` = 3 noise standard deviations: the validation's rule);
  ``no_gap`` when it fits but is weaker than that; ``unexplained`` when no
  candidate fits to the noise.
  When no candidate fits to the noise, the verdict is still ``no_gap`` if the
  gap is not clearly beyond the noise by both measures at hand: the nominal
  misfit (RMS beyond the noise, ``sqrt(chi2_j/n_j - 1)``, at most
  ``min_strength`` in every channel) and the best candidate's strength (at
  most ``min_strength``): a statistically significant but weak residue, such
  as a fine speed quantum that no candidate models (added after the seed-31
  blind run, see docs/diagnosis.md section 4).
* Without evidence: ``no_gap`` when the nominal model fits to the noise;
  ``weak_gap`` when its misfit is statistically beyond the noise but weaker
  than the rule above (the nominal misfit at most ``min_strength`` in every
  channel), else ``unexplained``.

Several effects at once (issue 10)
----------------------------------
When no single candidate fits to the noise, sets of two and three effects are
fitted (:mod:`engine.diagnosis.sets`). The model compared with the rules above
is then the most parsimonious of the best single candidate, the best pair and
the best triple: a larger set replaces a smaller model only when it lowers the
BIC by at least ``min_delta_bic`` and every one of its effects is strong
(moves the record by more than ``min_strength`` noise RMS on its own). The
verdict lists the set's effects with their share of the gap (the gap budget,
:func:`engine.diagnosis.sets.gap_budget`), largest first; ``effect`` and
``value`` are the largest share's.

Weak gaps
---------
``weak_gap`` replaces the former ``no_gap`` answers for gaps that are
statistically real but too weak to attribute: the nominal misfit beyond the
noise but at most ``min_strength`` noise RMS in every channel, or an effect
with evidence whose fit moves the record by at most ``min_strength`` while the
nominal model does not fit to the noise itself. ``no_gap`` is kept for records
the nominal model fits to the noise, with or without such a weak effect. The
strengths are in units of the noise the fit used, floored at 60 dB below each
channel's RMS (:data:`engine.diagnosis.noise.NOISE_FLOOR_REL`): a noiseless
(simulated) record is judged against that floor, not against a zero noise.

Locus
-----
Every verdict with a gap names the part of the plant where the missing physics
acts (``verdict.locus``, one of :data:`engine.simulation.LOCI`): the locus of
the named effect with the largest share; for ``unexplained`` and ``weak_gap``
the locus the data point to (:func:`engine.diagnosis.locus.estimate_locus`,
which also estimates the missing term: ``verdict.missing_term``).

Confidence
----------
``verdict.confidence`` is a probability that the verdict is right (issue 50): the decision's raw
score (``verdict.score``: for ``no_gap`` and ``unexplained`` a logistic function of how far the
deciding statistic lies from its threshold, in units of its scatter on clean records; for
``explained`` the same for the named model's fit times its posterior weight among every model
fitted, BIC weights) mapped through an isotonic calibration per status
(:mod:`engine.diagnosis.confidence`), fitted on the development blind runs and scored on held-out
ones (``docs/validation/confidence/``). For ``unexplained`` it is how sure the answer is that no
catalogue effect or set explains the record; ``verdict.locus_confidence`` says, apart, how sure it
is of the locus (calibrated the same way on the locus estimate's fit).

Plausibility
------------
``result.warnings`` lists what the plant cannot produce (:mod:`engine.diagnosis.plausibility`):
a channel out of the plant's range or in a likely wrong unit, a sample interval the dynamics
contradict, a misfit of the answer's model far above the noise. Each names the suspicion and
what to check; the verdict and the width stand beside them, to be read with them. An ``explained``
answer at a weak gap also carries a ``stand_in`` warning when the chance that its named effect stands
in for physics outside the catalogue reaches :data:`engine.diagnosis.open_world.STAND_IN_WARN`
(that chance is already in its confidence, :mod:`engine.diagnosis.open_world`).

Twins
-----
Each named effect lists its exact twins (``alternatives``: effects that give the very same
record, :func:`engine.diagnosis.space.indistinguishable`) and its near twins in this record
(``near_twins``: an effect that, in place of the named one, gives a model that explains the
record as well and whose BIC is higher by less than ``min_delta_bic``,
:mod:`engine.diagnosis.ambiguity`).

Modules
-------
This module runs the steps in order (:func:`diagnose`); the settings are in
:mod:`engine.diagnosis.settings`, the verdict and the result in :mod:`engine.diagnosis.result`,
the decision on the fitted models (the rules above, the twins) in :mod:`engine.diagnosis.decision`,
and the staged search of sets of effects in :mod:`engine.diagnosis.staged`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

from engine.diagnosis.ambiguity import Model
from engine.diagnosis.calibration import CalibrationResult, calibrate
from engine.diagnosis.candidate import Candidate
from engine.diagnosis.candidate_set import CandidateSet
from engine.diagnosis.candidates import fit_candidates
from engine.diagnosis.confidence import load_map, locus_confidence
from engine.diagnosis.decision import (
    choose_model,
    decide,
    explains_single,
    fit_statistic,
    fits_noise,
    model_near_twins,
    reweight,
    with_alternatives,
)
from engine.diagnosis.gap import gap_of
from engine.diagnosis.localisation import DEFAULT_WINDOWS_MS, Cell, localise
from engine.diagnosis.open_world import stand_in_doubt, stand_in_warnings
from engine.diagnosis.plausibility import PlausibilityWarning, check_calibration, check_record, merge_warnings
from engine.diagnosis.result import DiagnosisResult, Verdict
from engine.diagnosis.sets import search_sets
from engine.diagnosis.settings import NOMINAL_CALIBRATION as NOMINAL_CALIBRATION
from engine.diagnosis.settings import DiagnosisSettings
from engine.diagnosis.space import Bounds, ModelSpace, default_space
from engine.diagnosis.staged import singles_of_sets, staged_search
from engine.diagnosis.width import MISSING_PHYSICS, answer_calibration, answer_width
from engine.parallel import single_threaded_blas
from engine.records import Record
from engine.simulation import CATALOGUE, EffectLibrary
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.simulation.parameters import PART_FIELDS

logger = logging.getLogger(__name__)

__all__ = [
    "DiagnosisResult",
    "DiagnosisSettings",
    "IdentificationHook",
    "Verdict",
    "decide",
    "diagnose",
    "fit_statistic",
]

#: Hook for identification before/after (wired by the service, e.g.
#: :func:`engine.diagnosis.identification.identification_hook`): called as
#: ``hook(record, result)`` once the result is complete (verdict, calibration,
#: ``before``/``after`` simulations); returns a JSON-ready dict stored under
#: ``"identification"``.
IdentificationHook = Callable[[Record, "DiagnosisResult"], dict]


def _known_drifts(cands: Sequence[Candidate], library: EffectLibrary) -> dict[str, dict[str, float]]:
    """The escalated (globally searched) catalogue candidates that drift a part's own parameter by a
    factor, by field: their fitted values, the factor under ``"factor"`` (the locus estimate's
    ``known_drifts``: it need not fit them again)."""
    part = {field for fields in PART_FIELDS.values() for field in fields}
    out: dict[str, dict[str, float]] = {}
    for c in cands:
        if not c.escalated or c.calibration is None or c.effect not in library:
            continue
        effect = library[c.effect]
        if effect.target == "plant" and effect.mode == "multiply" and effect.field in part:
            values = dict(c.calibration.values)
            out[effect.field] = {**values, "factor": values.pop(c.effect)}
    return out


def _locate(
    record: Record,
    nominal: CalibrationResult,
    verdict: Verdict,
    space: ModelSpace,
    known: Mapping[str, Mapping[str, float]] | None = None,
) -> tuple[Verdict, dict[str, Any] | None]:
    """The verdict with the locus and missing term the data point to (see :mod:`engine.diagnosis.locus`)."""
    from engine.diagnosis.locus import estimate_locus

    try:
        report = estimate_locus(record, nominal, space=space, known_drifts=known)
    except (ValueError, RuntimeError) as exc:  # the diagnosis stands without it; say why
        logger.warning("locus estimate failed: %s", exc)
        return replace(verdict, reason=f"{verdict.reason}; the locus could not be estimated ({exc})"), None
    out = report.to_dict()
    term = {k: v for k, v in out.get("term", {}).items() if k not in ("series", "t")} if out.get("term") else None
    return (
        replace(
            verdict,
            locus=report.locus,
            missing_term=term,
            locus_confidence=locus_confidence(out),
            locus_group=tuple(report.group),
        ),
        out,
    )


def diagnose(
    record: Record,
    library: EffectLibrary = CATALOGUE,
    settings: DiagnosisSettings = DiagnosisSettings(),  # noqa: B008 (frozen, so immutable; imported, so ruff cannot tell)
    identify: IdentificationHook | None = None,
    noise: Mapping[str, float] | None = None,
    bounds: Bounds | None = None,
    progress: Callable[[float, str], None] | None = None,
    drive: DriveDescription = REFERENCE_DRIVE,
) -> DiagnosisResult:
    """Diagnose the sim-to-real gap of one record.

    Parameters
    ----------
    record : Record
        The measured record (any subset of channels; conditions may fix K [m],
        J1 [kg m^2], c [pu], c1 [pu]).
    library : EffectLibrary
        Candidate effects (default: the full catalogue of issue 4).
    settings : DiagnosisSettings
        Search settings and decision thresholds.
    identify : IdentificationHook, optional
        Identification before/after the fix (stored under ``identification``).
    noise : mapping of str to float, optional
        Known noise standard deviation per channel (channel unit); estimated when omitted.
    bounds : mapping, optional
        Search box of the calibrated parameters, ``name -> (low, high)`` in the parameter's
        unit (K [m], J1 [kg m^2], c [pu], c1 [pu]); parameters not given keep
        :data:`~engine.diagnosis.space.DEFAULT_BOUNDS`, the plausible box (see
        :func:`~engine.diagnosis.space.check_bounds`).
    progress : callable, optional
        ``progress(fraction, stage)`` at each stage (calibration, candidates, sets, verdict,
        identification), fraction 0..1 of the stages (not of the time, which the candidates dominate).
    drive : DriveDescription
        The drive the record was measured on (default MODEL.md's reference plant, issue 52): its nominal plant is
        the model calibrated, its box (:func:`~engine.diagnosis.space.drive_bounds`) the default search box, its
        envelopes the plausibility checks' range, its ``t_event_max`` the simulations' limit.

    Returns
    -------
    DiagnosisResult

    Raises
    ------
    CalibrationError
        When the record cannot be fitted at all (no simulable parameter set).
    BoundsError
        When ``bounds`` is invalid (unknown name, low >= high, outside the physical limits).

    Notes
    -----
    The record's test window (4.8 ms before to 200 ms after the event) is analysed on the
    record's own grid; ``records.before``/``records.after`` cover that window (a longer record's other
    samples are not simulated: memory and the answer stay bounded by the window). When the
    record's event was located from the data, its instant within the located interval is
    calibrated too, and pure time shifts (trigger offset, measurement delay) cannot be
    diagnosed (their candidates say so).
    """
    with single_threaded_blas():
        return _diagnose(record, library, settings, identify, noise, bounds, progress or _no_progress, drive)


def _no_progress(fraction: float, stage: str) -> None:
    """Default progress callback: ignore."""


def _diagnose(
    record: Record,
    library: EffectLibrary,
    settings: DiagnosisSettings,
    identify: IdentificationHook | None,
    noise: Mapping[str, float] | None,
    bounds: Bounds | None = None,
    progress: Callable[[float, str], None] = _no_progress,
    drive: DriveDescription = REFERENCE_DRIVE,
) -> DiagnosisResult:
    t0 = time.perf_counter()
    stages: list[dict[str, Any]] = []
    mark = t0

    def stage(name: str) -> None:
        """Close a stage of the work: its name and wall time [s] go to ``DiagnosisResult.stages``."""
        nonlocal mark
        now = time.perf_counter()
        stages.append({"stage": name, "seconds": now - mark})
        mark = now

    whole = record
    record, window = whole.test_window()
    space = default_space(record, bounds, drive)
    progress(0.0, "calibrating the nominal model")
    nominal = calibrate(record, space, settings.calibration, noise=noise)
    cells = localise(record, nominal.simulated_record(record), nominal.sigma, DEFAULT_WINDOWS_MS)
    gap_before = gap_of(nominal)
    n_sim = nominal.n_simulations
    stage("nominal calibration")

    cs = settings.candidates
    set_settings = settings.set_search()
    use_sets = set_settings.max_size >= 2 and not fits_noise(nominal, settings)
    staged = use_sets and set_settings.before_escalation
    progress(0.15, f"fitting {len(library)} candidate effects")
    cands = fit_candidates(
        record,
        nominal,
        space,
        library,
        cs,
        escalate=not staged,
        progress=lambda f, what: progress(0.15 + 0.35 * f, what),
        reseed=not (staged and set_settings.escalate_before_reseed),
    )
    stage("single candidates" if staged else "single candidates, escalation included")
    if use_sets and not explains_single(cands, settings):
        progress(0.55, "no single effect explains the record: searching sets of effects")
    sets: list[CandidateSet] = []
    if staged:
        cands, sets = staged_search(record, nominal, space, library, cands, settings, stage)
    elif use_sets and not explains_single(cands, settings):
        sets = search_sets(record, nominal, space, library, cands, cs, set_settings)
        stage("sets of up to three")
    if sets:
        cands = singles_of_sets(record, nominal, space, library, cands, sets, settings)
        stage("singles from the sets")
    n_sim += sum(c.calibration.n_simulations for c in cands if c.calibration)
    n_sim += sum(s.calibration.n_simulations for s in sets if s.calibration)
    if sets:
        reweight(nominal, cands, sets)
    progress(0.85, "deciding the verdict")
    verdict = decide(nominal, cands, settings, sets)
    model = choose_model(cands, sets, settings)  # the model the verdict names, when explained
    verdict = with_alternatives(verdict, library, model_near_twins(verdict, model, [*cands, *sets], settings, library))
    models: list[Model] = [*cands, *sets]
    final, source = answer_calibration(verdict.status, nominal, model, models)
    fitted = [nominal, *(m.calibration for m in models if m.calibration is not None)]
    doubt = stand_in_doubt(verdict.status, nominal.reduced_chi2, load_map().open_world)
    width = answer_width(
        record,
        final,
        source,
        space,
        fitted,
        settings.min_delta_bic,
        verdict.status in MISSING_PHYSICS,
        stand_in_from=nominal if doubt is not None else None,
    )
    stage("decision")
    # what the plant cannot produce, judged on the model the answer ends with (a named effect's misfit is no warning)
    try:
        warnings = merge_warnings(check_record(record, drive), check_calibration(record, final))
    except (ValueError, RuntimeError) as exc:  # the answer stands without the checks; say they did not run
        logger.warning("plausibility checks failed: %s", exc)
        warnings = [PlausibilityWarning("checks_failed", f"the plausibility checks could not run ({exc})")]
    warnings += stand_in_warnings(verdict, nominal.reduced_chi2, doubt)
    for w in warnings:
        logger.warning("%s", w.message)
    stage("plausibility")

    after = None
    gap_after = None
    shrinkage = None
    cells_after: list[Cell] = []
    locus: dict[str, Any] | None = None
    if verdict.status == "explained":
        if model is None:  # an explained verdict names a fitted model (answer_calibration checked its fit)
            raise RuntimeError(f"the named effect {verdict.effect} has no fit")
        after = final.simulated_record(record)
        gap_after = gap_of(final)
        shrinkage = model.shrinkage
        cells_after = localise(record, final.simulated_record(record), nominal.sigma, DEFAULT_WINDOWS_MS)
        stage("gap after the fix")
    elif verdict.status in ("unexplained", "weak_gap") and settings.locate:
        verdict, locus = _locate(record, nominal, verdict, space, _known_drifts(cands, library))
        stage("locus and missing term")
    result = DiagnosisResult(
        calibration=nominal,
        cells=cells,
        candidates=cands,
        verdict=verdict,
        gap_before=gap_before,
        gap_after=gap_after,
        before=nominal.simulated_record(record),
        after=after,
        cells_after=cells_after,
        n_simulations=n_sim,
        n_cells=settings.n_cells,
        window=window,
        record=whole,
        sets=sets,
        locus=locus,
        shrinkage=shrinkage,
        stages=stages,
        answer_calibration=final,
        width=width,
        warnings=[w.to_dict() for w in warnings],
    )
    if identify is not None:
        progress(0.9, "identifying the width before and after")
        result.identification = identify(whole, result)
        stage("identification")
    result.seconds = time.perf_counter() - t0
    logger.info(
        "diagnosis: %s %s (confidence %.2f), %d simulations, %.1f s",
        verdict.status,
        verdict.effect or "",
        verdict.confidence,
        n_sim,
        result.seconds,
    )
    return result
