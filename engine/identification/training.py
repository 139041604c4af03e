"""Training identifiers into pattern sets, and rebuilding them from the store.

One place for the orchestration shared by the main job, the service's
training jobs and the gap diagnosis (patterns retrained with an effect):
simulate the six widths x the J1 values of one c group, fit the identifier on
one channel, and package the result as a :class:`~engine.storage.PatternSet`.
"""

from __future__ import annotations

import inspect
import logging
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from engine.constants import CHANNELS, J1_GRID, K_GRID, MODEL_VERSION
from engine.identification.base import Identifier
from engine.identification.paper import PaperIdentifier
from engine.identification.template import TemplateIdentifier
from engine.simulation import Case, SimulationResult, paper_grid, simulate_batch
from engine.simulation.drive import DriveDescription
from engine.storage import PatternSet

logger = logging.getLogger(__name__)

#: Identifier kinds by name. ``template`` is the default: it beats the paper's
#: method on every held-out evaluation (see docs/identification.md, "Evaluation").
IDENTIFIERS: dict[str, type[TemplateIdentifier] | type[PaperIdentifier]] = {
    "template": TemplateIdentifier,
    "paper": PaperIdentifier,
}
DEFAULT_KIND = "template"

Progress = Callable[[float, str], None]


def make_identifier(kind: str, channel: str, **params: Any) -> Identifier:
    """A fresh (unfitted) identifier of ``kind`` for ``channel``.

    Parameters
    ----------
    kind : str
        A key of :data:`IDENTIFIERS`.
    channel : str
        One of ``engine.constants.CHANNELS``.
    **params
        Constructor parameters of that kind.

    Raises
    ------
    ValueError
        Unknown kind, channel or parameter; the message lists the accepted ones.
    """
    try:
        cls = IDENTIFIERS[kind]
    except KeyError:
        raise ValueError(f"unknown identifier kind {kind!r}; known kinds: {', '.join(IDENTIFIERS)}") from None
    if channel not in CHANNELS:
        raise ValueError(f"unknown channel {channel!r}; known channels: {', '.join(CHANNELS)}")
    accepted = set(inspect.signature(cls).parameters) - {"channel"}
    unknown = set(params) - accepted
    if unknown:
        raise ValueError(f"identifier {kind!r} has no parameter(s) {sorted(unknown)}; accepted: {sorted(accepted)}")
    return cls(channel=channel, **params)


def identifier_params(kind: str, drive: DriveDescription | None = None) -> dict[str, Any]:
    """Constructor parameters an identifier of ``kind`` needs to be trained for ``drive``: the paper's method is
    given the drive's width grid (:meth:`DriveDescription.k_grid`) when it is not K_GRID; the template method reads
    its widths from the training records. Empty for the reference plant."""
    if kind == "paper" and drive is not None and drive.k_grid() != K_GRID:
        return {"widths": list(drive.k_grid())}
    return {}


def training_cases(c: float, J1_values: Sequence[float], drive: DriveDescription | None = None) -> list[Case]:
    """The six widths x ``J1_values`` [kg m^2] at apparent viscosity ``c`` [pu], width-major.

    On MODEL.md's reference plant (:func:`engine.simulation.paper_grid`), or on ``drive``'s nominal plant
    with K, J1 and c set (:meth:`DriveDescription.plant`).
    """
    if drive is None:
        return paper_grid(c, tuple(J1_values))
    return [Case(drive.plant(K=K, J1=float(J1), c=float(c))) for K in drive.k_grid() for J1 in J1_values]


def simulate_training_grid(
    c: float,
    J1_values: Sequence[float] = J1_GRID,
    effects: Mapping[str, float] | None = None,
    drive: DriveDescription | None = None,
) -> SimulationResult:
    """The six widths x ``J1_values`` at apparent viscosity ``c`` [pu], with optional effects.

    With ``drive``, on its nominal plant, within its ``t_event_max``; the records are on MODEL.md's grid
    whatever the drive's protocol (pattern sets compare records resampled onto it).
    """
    if drive is None:
        return simulate_batch(paper_grid(c, tuple(J1_values)), effects=effects)
    return simulate_batch(training_cases(c, J1_values, drive), effects=effects, solver=drive.solver())


def train_pattern_set(
    channel: str,
    c: float,
    kind: str = DEFAULT_KIND,
    J1_values: Sequence[float] = J1_GRID,
    params: Mapping[str, Any] | None = None,
    effects: Mapping[str, float] | None = None,
    grid: SimulationResult | None = None,
    progress: Progress | None = None,
    drive: DriveDescription | None = None,
) -> PatternSet:
    """Train one identifier on one channel of one c group and package it (unsaved).

    Parameters
    ----------
    channel : str
        Channel to train on.
    c : float
        Apparent viscosity of the group [pu].
    kind : str
        Identifier kind (``IDENTIFIERS``).
    J1_values : sequence of float
        Motor inertias of the training cases [kg m^2].
    params : mapping, optional
        Identifier hyper-parameters (e.g. ``learning_rate``, ``delta1``, ``max_epochs``).
    effects : mapping, optional
        Unmodelled effects the training plant includes (name -> value).
    grid : SimulationResult, optional
        Already simulated training grid (skips the simulation).
    progress : callable, optional
        ``progress(fraction, message)``.
    drive : DriveDescription, optional
        The drive the set is trained for (default MODEL.md's reference plant); stored in the set's
        ``params["drive"]`` (:meth:`DriveDescription.provenance`), so that it never identifies records of
        another drive (:func:`engine.identification.selection.drive_fingerprint`). ``grid``, when given,
        must have been simulated on it.
    """
    params = {**identifier_params(kind, drive), **dict(params or {})}
    est = make_identifier(kind, channel, **params)
    if len(J1_values) < 1:
        raise ValueError("J1_values needs at least one inertia")
    if progress:
        progress(0.05, f"simulating {len(K_GRID) * len(J1_values)} training cases")
    grid = grid if grid is not None else simulate_training_grid(c, J1_values, effects, drive)
    if progress:
        progress(0.4, f"fitting the {kind} identifier on {channel}")
    y = np.array([case.plant.K for case in grid.cases])
    groups = np.array([case.plant.J1 for case in grid.cases])
    est.fit(grid.channel(channel), y, groups=groups)
    if progress:
        progress(0.95, "packaging the pattern set")
    stored_params = {**est.get_params(), "effects": dict(effects or {})}
    if drive is not None:
        stored_params["drive"] = drive.provenance()
    return PatternSet(
        kind=kind,
        channel=channel,
        c=float(c),
        j1_values=[float(v) for v in J1_values],
        wavelet=str(getattr(est, "wavelet_", est.get_params().get("wavelet"))),
        params=stored_params,
        model_version=MODEL_VERSION,
        arrays=est.to_arrays(),
    )


def identifier_from_pattern_set(ps: PatternSet) -> Identifier:
    """Rebuild the fitted identifier stored in a pattern set."""
    try:
        cls = IDENTIFIERS[ps.kind]
    except KeyError:
        raise ValueError(f"pattern set {ps.id} has unknown identifier kind {ps.kind!r}") from None
    # stored params also carry metadata (effects, source, ...): pass only constructor parameters
    accepted = set(inspect.signature(cls).parameters)
    params = {k: v for k, v in ps.params.items() if k in accepted}
    return cls.from_arrays(params, ps.arrays)
