"""Blind validation of the gap diagnosis, protocol v2: the open world (docs/validation-v2.md).

Every case gets the same library (the whole catalogue); cases hold one, two or
three catalogue effects, one held-back effect never in the library, or none, at
operating points across the plausible box, with white or coloured noise and
sometimes only a drive's own sensors. Protocol v1 stays in
:mod:`engine.diagnosis.validation`.

Modules, one idea each: :mod:`~engine.validation.protocol` (the protocol's numbers and
targets), :mod:`~engine.validation.noise` (white and coloured noise),
:mod:`~engine.validation.cases` (the case generator and its strength rule),
:mod:`~engine.validation.key` (the answer key), :mod:`~engine.validation.layout` (the
run's directory and files), :mod:`~engine.validation.blind` (the blind, resumable
diagnosis), :mod:`~engine.validation.stats` (Wilson and median intervals),
:mod:`~engine.validation.score` (the scorer), :mod:`~engine.validation.report` (JSON and
Markdown), :mod:`~engine.validation.provenance` (code version),
:mod:`~engine.validation.run` (orchestration).
"""

from engine.validation.cases import BlindCase, generate_cases
from engine.validation.key import KeyEntry, TrueEffect
from engine.validation.layout import RunLayout
from engine.validation.protocol import DEFAULT_MIX, PROTOCOL_VERSION, TARGETS
from engine.validation.run import prepare_cases, run_validation, score_run
from engine.validation.score import score_cases
from engine.validation.stats import median_interval, wilson_interval

__all__ = [
    "DEFAULT_MIX",
    "PROTOCOL_VERSION",
    "TARGETS",
    "BlindCase",
    "KeyEntry",
    "RunLayout",
    "TrueEffect",
    "generate_cases",
    "median_interval",
    "prepare_cases",
    "run_validation",
    "score_cases",
    "score_run",
    "wilson_interval",
]
