"""Identification of the backlash zone width from backlash-test records."""

from engine.identification.paper import (
    IdentificationResult,
    NotFittedError,
    PaperIdentifier,
    normalisation_terms,
    normalise,
)

__all__ = ["IdentificationResult", "NotFittedError", "PaperIdentifier", "normalisation_terms", "normalise"]
