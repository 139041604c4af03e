"""Identification of the backlash zone width from backlash-test records.

Shared types in :mod:`engine.identification.base`; the paper's method in
:mod:`~engine.identification.paper` (its normalisation, eqs. 2-5, in
:mod:`~engine.identification.normalisation`); our nearest-template identifier in
:mod:`~engine.identification.template`; training into pattern sets in
:mod:`~engine.identification.training`; the choice of a stored set for a record (nearest c) in
:mod:`~engine.identification.selection`; the calibrated continuous width in
:mod:`~engine.identification.width` (imported from there: it builds on the diagnosis's calibration).
"""

from engine.identification.base import IdentificationResult, Identifier, NotFittedError
from engine.identification.normalisation import normalisation_terms, normalise
from engine.identification.paper import PaperIdentifier
from engine.identification.template import TemplateIdentifier

__all__ = [
    "IdentificationResult",
    "Identifier",
    "NotFittedError",
    "PaperIdentifier",
    "TemplateIdentifier",
    "normalisation_terms",
    "normalise",
]
