"""Shared by the development scripts of ``lab/scripts/``: a case of a protocol-2 run fitted as the diagnosis starts.

:func:`seeded_singles` reads one case's test window, calibrates the nominal model and fits every
single candidate of the catalogue from seeds (no escalation, the front runners refined), with the
diagnosis's own settings: the state in which the diagnosis decides whether to escalate and which
sets to try (``lab/scripts/set_search.py``, ``lab/scripts/seeded_ranks.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from engine.diagnosis.calibration import CalibrationResult, calibrate
from engine.diagnosis.candidate import Candidate
from engine.diagnosis.candidates import fit_candidates
from engine.diagnosis.diagnose import DiagnosisSettings
from engine.diagnosis.space import ModelSpace, default_space
from engine.records import Record
from engine.simulation import CATALOGUE
from engine.validation.layout import RunLayout
from engine.validation.run import prepare_cases


@dataclass(frozen=True)
class Seeded:
    """A case's test window, its nominal space and calibration, and its seeded single candidates (best BIC first)."""

    record: Record
    space: ModelSpace
    nominal: CalibrationResult
    singles: list[Candidate]


def open_run(run: Path, n_cases: int, seed: int) -> RunLayout:
    """The run's directory, its cases drawn from ``seed`` first when it holds none (no diagnosis)."""
    layout = RunLayout(run)
    prepare_cases(layout, n_cases, seed)
    return layout


def seeded_singles(layout: RunLayout, case_id: str, settings: DiagnosisSettings) -> Seeded:
    """Fit case ``case_id`` as the diagnosis does before any escalation or set (see the module notes)."""
    record, _ = layout.read_case(case_id).test_window()
    space = default_space(record)
    nominal = calibrate(record, space, settings.calibration)
    singles = fit_candidates(record, nominal, space, CATALOGUE, settings.candidates, escalate=False)
    return Seeded(record, space, nominal, singles)
