"""Sim-to-real gap diagnosis (issue 4): calibrate, localise, rank candidate effects, decide.

Entry point: :func:`diagnose`. Blind validation: :func:`engine.diagnosis.validation.run_validation`.

Modules, one idea each:

* :mod:`~engine.diagnosis.noise`: the channels' noise level and the whiteness of a residual;
* :mod:`~engine.diagnosis.space`: the fitted parameters, the operating range and the search box;
* :mod:`~engine.diagnosis.objective`: the noise-normalised cost and its Jacobian;
* :mod:`~engine.diagnosis.calibration`: the calibration (global search, continuation, polish);
* :mod:`~engine.diagnosis.localisation`: where the residual lies (channel x band x window);
* :mod:`~engine.diagnosis.gap`: how large the gap is, and how much a fit shrinks it;
* :mod:`~engine.diagnosis.candidate`: one candidate effect's joint fit and evidence;
* :mod:`~engine.diagnosis.quantisation`: the speed quantum's dense-scan fit;
* :mod:`~engine.diagnosis.candidates`: fitting and ranking every candidate;
* :mod:`~engine.diagnosis.sets`: sets of up to three effects fitted together (the set type in
  :mod:`~engine.diagnosis.candidate_set`; each member's share of the gap and strength in
  :mod:`~engine.diagnosis.budget`);
* :mod:`~engine.diagnosis.diagnose`: the diagnosis in order (its settings in
  :mod:`~engine.diagnosis.settings`, the staged search of sets in :mod:`~engine.diagnosis.staged`,
  the decision rule in :mod:`~engine.diagnosis.decision`, verdict and result in
  :mod:`~engine.diagnosis.result`);
* :mod:`~engine.diagnosis.identification`: identification before and after the fix;
* :mod:`~engine.diagnosis.plots`, :mod:`~engine.diagnosis.validation`: figures, blind validation.

The continuous width estimate built on the calibration is an identifier:
:mod:`engine.identification.width`.
"""

from engine.diagnosis.calibration import CalibrationError, CalibrationResult, CalibrationSettings, calibrate
from engine.diagnosis.candidate import Candidate, CandidateSettings
from engine.diagnosis.candidates import fit_candidates
from engine.diagnosis.diagnose import DiagnosisResult, DiagnosisSettings, IdentificationHook, Verdict, diagnose
from engine.diagnosis.gap import Gap, gap_of
from engine.diagnosis.localisation import Cell, level_band, localise
from engine.diagnosis.noise import estimate_noise
from engine.diagnosis.space import ModelSpace, default_space

__all__ = [
    "CalibrationError",
    "CalibrationResult",
    "CalibrationSettings",
    "Candidate",
    "CandidateSettings",
    "Cell",
    "DiagnosisResult",
    "DiagnosisSettings",
    "Gap",
    "IdentificationHook",
    "ModelSpace",
    "Verdict",
    "calibrate",
    "default_space",
    "diagnose",
    "estimate_noise",
    "fit_candidates",
    "gap_of",
    "level_band",
    "localise",
]
