"""Settings of the diagnosis of one record (:class:`DiagnosisSettings`) and the search settings of its
nominal calibration (:data:`NOMINAL_CALIBRATION`); the decision rule they set is described in
:mod:`engine.diagnosis.diagnose`."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from engine.diagnosis.calibration import CalibrationSettings
from engine.diagnosis.candidate import CandidateSettings
from engine.diagnosis.sets import SetSettings

__all__ = ["NOMINAL_CALIBRATION", "DiagnosisSettings"]

#: Search settings of the nominal calibration of a diagnosis: 256 Sobol points, 16 of them screened
#: on the first horizon, 2 continued over six horizons with a scan of every parameter at each
#: extension (a wide backlash seen only in the drive's own channels leaves the early window flat
#: in c; docs/diagnosis.md section 8c).
NOMINAL_CALIBRATION = CalibrationSettings(
    n_global=256, n_starts=2, n_screen=16, horizons_ms=(10.0, 20.0, 40.0, 80.0, 130.0, 200.0), n_extend_scan=17
)


@dataclass(frozen=True)
class DiagnosisSettings:
    """Settings of :func:`~engine.diagnosis.diagnose.diagnose`.

    Parameters
    ----------
    calibration : CalibrationSettings
        Search settings of the nominal calibration.
    candidates : CandidateSettings
        Search settings of the candidate fits.
    max_reduced_chi2 : float
        Largest total chi2/n of a fit "to the noise".
    max_channel_chi2 : float
        Largest chi2_j/n_j of any one channel of a fit "to the noise".
    chi2_scatter : float
        Scatter (standard deviation) of the total chi2/n on clean records; sets
        the width of the confidence's logistic function.
    min_delta_bic : float
        Smallest BIC improvement of the best candidate over the nominal model
        that counts as evidence for an effect.
    min_strength : float
        An explaining effect counts as a gap only when it moves some channel by
        more than this many noise standard deviations (RMS); the blind
        validation's rule for "clearly beyond the noise".
    strength_scatter : float
        Width of the logistic confidence around ``min_strength``.
    n_cells : int or None
        Localisation cells kept in :meth:`DiagnosisResult.to_dict`, largest
        excess first (None: all 5 x 11 x 5 of a five-channel record; the object keeps all).
    sets : SetSettings
        Search settings of the sets of effects (``max_size = 1`` turns the set search off).
    locate : bool
        Estimate the locus and the missing term of an unexplained or weak gap.
    """

    calibration: CalibrationSettings = NOMINAL_CALIBRATION
    candidates: CandidateSettings = field(default_factory=CandidateSettings)
    max_reduced_chi2: float = 1.05
    max_channel_chi2: float = 1.2
    chi2_scatter: float = 0.02
    min_delta_bic: float = 10.0
    min_strength: float = 3.0
    strength_scatter: float = 0.3
    n_cells: int | None = None
    sets: SetSettings = field(default_factory=SetSettings)
    locate: bool = True

    def set_search(self) -> SetSettings:
        """The set search's settings with this diagnosis's decision thresholds (``min_strength``,
        ``max_reduced_chi2``), which the search uses to stop and to drop weak members."""
        return replace(self.sets, min_strength=self.min_strength, max_reduced_chi2=self.max_reduced_chi2)
