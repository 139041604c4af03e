"""Simulation for the service: request values -> engine cases -> records.

Everything physical happens in :mod:`engine.simulation`; this module only builds
``Case`` objects from the request's flat values and calls ``simulate_batch``
(which is safe to call from request threads and training threads at once).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from engine.simulation import Case, SimulationResult, apply_effects, simulate_batch


def make_case(K: float, J1: float | None = None, c: float | None = None, c1: float | None = None) -> Case:
    """A case of the reference plant with the given values and MODEL.md's defaults for the rest."""
    given = {"K": K, "J1": J1, "c": c, "c1": c1}
    return Case.from_overrides({k: v for k, v in given.items() if v is not None})


def prepare(cases: Sequence[Case], effects: Sequence[Mapping[str, float] | None]) -> list[Case]:
    """Apply each case's effects and validate it, without simulating.

    Raises ``ParameterError`` / ``UnknownEffectError`` (with the engine's message) on
    out-of-range values or unknown effect names.
    """
    if len(cases) != len(effects):
        raise ValueError(f"got {len(effects)} effect mappings for {len(cases)} cases")
    return [apply_effects(case, eff or {}).validate() for case, eff in zip(cases, effects, strict=True)]


def run(cases: Sequence[Case]) -> SimulationResult:
    """Simulate prepared cases (see :func:`prepare`); raises ``SimulationError`` for cases without an event."""
    return simulate_batch(list(cases))
