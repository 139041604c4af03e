"""Which stored pattern set identifies a record: the policy of the nearest apparent-viscosity group.

Pattern sets are trained at a few values of the apparent-viscosity group ``c`` [pu]; a record
of another ``c`` is identified with the set whose ``c`` is nearest (as the paper does for its
off-grid cases, section 3). The store only lists and reads sets
(:meth:`engine.storage.PatternStore.list`, :meth:`~engine.storage.PatternStore.get`); this
module decides which one.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

from engine.constants import C_GROUPS, MODEL_VERSION
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.storage import PatternSet, PatternSetNotFound, PatternSetSummary, PatternStore
from engine.storage.validation import require_c, require_channel, require_text

logger = logging.getLogger(__name__)

__all__ = [
    "MAX_C_DISTANCE",
    "TIE_ABS_TOL",
    "TIE_REL_TOL",
    "drive_fingerprint",
    "is_plain",
    "nearest_c_group",
    "nearest_pattern_set",
]

#: Two sets are equally near ``c`` for ``prefer_kind`` when their distances to it agree to
#: these tolerances (``math.isclose``) [-] and [pu].
TIE_REL_TOL = 1e-9
TIE_ABS_TOL = 1e-12

#: Farthest a chosen set's c may lie from the record's [pu]: a quarter of a pu, the widest gap
#: between two of the paper's groups (1.0 -> 1.25), so that a store holding the four groups
#: serves every c from 0.55 to 1.65 pu; beyond it the patterns were trained on a visibly
#: different deceleration and the service refuses rather than answers (train a set at that c).
MAX_C_DISTANCE = 0.25


def drive_fingerprint(summary: PatternSetSummary | PatternSet) -> str:
    """The fingerprint of the drive a set was trained for (``params["drive"]``); MODEL.md's reference plant's when
    the set names none (every set trained before drive descriptions existed)."""
    return DriveDescription.fingerprint_of((summary.params or {}).get("drive"))


def _drive_of(summary: PatternSetSummary | PatternSet) -> DriveDescription:
    stored = (summary.params or {}).get("drive")
    return REFERENCE_DRIVE if stored is None else DriveDescription.from_mapping(stored["description"])


def is_plain(summary: PatternSetSummary | PatternSet) -> bool:
    """Whether a set was trained as the paper trains: no effects, on the paper's J1 grid (any order).

    Only such sets are chosen automatically; a set trained with effects or on another J1 grid
    identifies a record only when it is asked for by id. For a set trained for a described drive, the
    paper's grid is the drive's (:meth:`DriveDescription.j1_grid`: scaled to its nominal J1).
    """
    effects = (summary.params or {}).get("effects") or {}
    grid = sorted(float(v) for v in summary.j1_values)
    paper = sorted(_drive_of(summary).j1_grid())
    same_grid = len(grid) == len(paper) and all(
        math.isclose(a, b, rel_tol=1e-9) for a, b in zip(grid, paper, strict=True)
    )
    return not effects and same_grid


def nearest_c_group(c: float, groups: Sequence[float] = C_GROUPS) -> float:
    """The apparent-viscosity group nearest to ``c`` (ties to the smaller group).

    Parameters
    ----------
    c : float
        Apparent viscosity of a record [pu].
    groups : sequence of float
        The groups, ascending [pu]: the paper's ``engine.constants.C_GROUPS`` (default), or a described
        drive's (:meth:`engine.simulation.drive.DriveDescription.c_groups`).

    Returns
    -------
    float
        An element of ``groups`` [pu]: the group whose patterns identify the record.
    """
    return float(min(groups, key=lambda g: abs(g - c)))


def _nearest(candidates: list[PatternSetSummary], c: float, prefer_kind: str | None) -> PatternSetSummary:
    """The candidate nearest ``c``; near-ties go to ``prefer_kind``, exact ties to the first (newest) one."""
    best = min(candidates, key=lambda s: abs(s.c - c))  # min keeps the first of equals: the newest
    if prefer_kind is None or best.kind == prefer_kind:
        return best
    preferred = [s for s in candidates if s.kind == prefer_kind]
    if not preferred:
        return best
    alt = min(preferred, key=lambda s: abs(s.c - c))
    same_distance = math.isclose(abs(alt.c - c), abs(best.c - c), rel_tol=TIE_REL_TOL, abs_tol=TIE_ABS_TOL)
    return alt if same_distance else best


def nearest_pattern_set(
    store: PatternStore,
    channel: str,
    c: float,
    kind: str | None = None,
    model_version: str = MODEL_VERSION,
    *,
    prefer_kind: str | None = None,
    plain_only: bool = False,
    drive: str | None = None,
) -> PatternSet | None:
    """Return the stored set of ``channel`` whose ``c`` is nearest to the requested one.

    Parameters
    ----------
    store : PatternStore
        Where the sets are.
    channel : str
        Channel, one of ``engine.constants.CHANNELS``.
    c : float
        Apparent-viscosity group wanted [pu].
    kind : str or None
        Only sets of this identifier kind (any kind if ``None``).
    model_version : str
        Only sets of this reference-model version (sets of other versions are never returned).
    plain_only : bool
        Only sets trained as the paper trains (:func:`is_plain`: no effects, the paper's J1 grid); the
        service's automatic choice asks for this (``any_set`` widens it).
    prefer_kind : str or None
        Among equally near sets (distances equal to :data:`TIE_REL_TOL` / :data:`TIE_ABS_TOL`),
        the nearest set of this kind wins over sets of other kinds (``None``: no preference).
    drive : str or None
        Only sets trained for the drive of this fingerprint (:func:`drive_fingerprint`); ``None``: MODEL.md's
        reference plant. A set of another drive is never returned.

    Returns
    -------
    PatternSet or None
        The nearest set with its arrays: the ``prefer_kind`` one among equally near sets, else
        the most recently saved one among those exactly as near. ``None`` if there is no
        candidate.

    Raises
    ------
    engine.storage.InvalidPatternSet
        For an unknown channel, a non-finite ``c`` or an empty ``model_version``.
    engine.storage.CorruptPatternSet
        If the chosen set fails its checksum.

    Notes
    -----
    The choice is made on the sets' metadata, then the chosen set is read; if another process
    deletes it in between, the choice is made again among the sets that remain.
    """
    cv = require_c(c)
    version = require_text(model_version, "model_version")
    channel = require_channel(channel)
    while True:
        wanted = REFERENCE_DRIVE.fingerprint if drive is None else drive
        candidates = [
            s for s in store.list(channel, kind=kind, model_version=version) if drive_fingerprint(s) == wanted
        ]
        if plain_only:
            candidates = [s for s in candidates if is_plain(s)]
        if not candidates:
            return None
        chosen = _nearest(candidates, cv, prefer_kind)
        try:
            return store.get(chosen.id)
        except PatternSetNotFound:
            logger.debug("pattern set %s was deleted while being chosen; choosing again", chosen.id)
