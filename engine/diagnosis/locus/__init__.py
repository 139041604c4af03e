"""Where a gap outside the catalogue lies, and what the missing term looks like.

The method and its whole code are in :mod:`engine.diagnosis.locus._starts` for now (moved there
from ``engine/diagnosis/locus.py`` so that its history follows); the next commit splits it into
one module per idea.
"""

from __future__ import annotations

from engine.diagnosis.locus._starts import FIRST_GUESS_CONFIDENCE as FIRST_GUESS_CONFIDENCE
from engine.diagnosis.locus._starts import N_EXTRAS as N_EXTRAS
from engine.diagnosis.locus._starts import PROBE as PROBE
from engine.diagnosis.locus._starts import SCAN_SCALE as SCAN_SCALE
from engine.diagnosis.locus._starts import SENSORS as SENSORS
from engine.diagnosis.locus._starts import LocusError, LocusReport, LocusScore, LocusSettings, Term, estimate_locus

__all__ = ["LocusError", "LocusReport", "LocusScore", "LocusSettings", "Term", "estimate_locus"]
