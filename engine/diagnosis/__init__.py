"""Sim-to-real gap diagnosis (issue 4): calibrate, localise, rank candidate effects, decide.

Entry point: :func:`diagnose`. Blind validation: :func:`engine.diagnosis.validation.run_validation`.
"""

from engine.diagnosis.calibration import (
    CalibrationError,
    CalibrationResult,
    CalibrationSettings,
    ModelSpace,
    WidthEstimate,
    calibrate,
    default_space,
    estimate_noise,
    estimate_width,
)
from engine.diagnosis.candidates import Candidate, CandidateSettings, Gap, fit_candidates, gap_of
from engine.diagnosis.diagnose import DiagnosisResult, DiagnosisSettings, IdentificationHook, Verdict, diagnose
from engine.diagnosis.localisation import Cell, level_band, localise

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
    "WidthEstimate",
    "calibrate",
    "default_space",
    "diagnose",
    "estimate_noise",
    "estimate_width",
    "fit_candidates",
    "gap_of",
    "level_band",
    "localise",
]
