"""How likely an ``explained`` verdict is a catalogue stand-in for physics outside the catalogue.

Three families kept for scoring (HELD_OUT, SEALED, SEALED2; 105 records of physics outside the
catalogue, each blind run once and now spent) were answered ``explained`` 25 times, every time
wrongly: a catalogue effect fitted to the noise stood in for the physics the catalogue lacks (a DC
component of the supply as a rotor-resistance drift of -2 to -7 %, a squeeze film in the clutch as
contact damping). 19 of the 25 were *weak* gaps, the nominal model's chi2/n below 10, where a small
drift of any of several parameters reproduces the record; of the 1260 in-catalogue records of the
development runs (protocols 2 and 1) 139 were explained at such a gap. Once a stand-in reaches the noise the record
holds no evidence against it (its chi2/n after is 0.96-1.05, as a right answer's), so no test on the
record can tell the two apart: what can be stated honestly is how often an answer of that kind is
a stand-in.

:class:`OpenWorldMap` holds, per band of the nominal model's chi2/n (:data:`OPEN_WORLD_EDGES`), how
often a record with one or more catalogue effects is answered ``explained`` in that band (``in``:
the development runs' single, pair and triple records), how often a record of physics outside the
catalogue is (``out``: the spent families' records), and the share of records with a gap whose cause
lies outside the catalogue (:data:`OPEN_WORLD_SHARE`, an assumption). Bayes' rule then gives the
probability that an ``explained`` answer in that band is a stand-in (:meth:`OpenWorldMap.stand_in`);
the verdict's confidence is multiplied by one minus it
(:func:`engine.diagnosis.confidence.calibrated_confidence`), and when it reaches
:data:`STAND_IN_WARN` (:func:`stand_in_doubt`, the one rule) the answer carries a ``stand_in``
warning (:func:`stand_in_warnings`) that says so and what to check, and its width interval is
widened (term 5 of :mod:`engine.diagnosis.width`). The status is not changed: on the development runs such answers are right 133
times in 139, and abstaining there would refuse those 133 right answers (11 % of the in-catalogue
records).

The map is fitted by ``bench/confidence_reliability.py --fit ... --open-world-runs ...`` and
committed inside the confidence map with its provenance. Its ``out`` rates come from families whose
figures are spent (development data); the share is the protocol-2 mix's (20 % of records outside
the catalogue against 50 % with catalogue effects), not a property of any fleet: a user whose
machines rarely show new physics is told too little confidence, one whose machines often do too much.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from engine.diagnosis.plausibility import PlausibilityWarning
from engine.diagnosis.result import Verdict

__all__ = [
    "OPEN_WORLD_EDGES",
    "OPEN_WORLD_FEATURE",
    "OPEN_WORLD_SHARE",
    "STAND_IN_WARN",
    "OpenWorldMap",
    "fit_open_world",
    "stand_in_doubt",
    "stand_in_warnings",
]

#: Band edges of the nominal model's chi2/n. One edge: the weak gaps below 10 (19 of the 25
#: stand-ins of the spent families; 139 of the 1197 explained in-catalogue records of the development
#: runs) and the rest. Chosen on those data (the third spent family, SEALED2, was looked at too).
OPEN_WORLD_EDGES: tuple[float, ...] = (10.0,)
#: What the bands are of.
OPEN_WORLD_FEATURE: str = "chi2/n of the nominal calibration"
#: Prior share of records with a gap whose cause lies outside the catalogue: protocol 2's mix (held
#: back 0.20 against single 0.25 + pair 0.15 + triple 0.10), an assumption (module docstring).
OPEN_WORLD_SHARE: float = 0.20 / 0.70
#: Stand-in probability from which an explained answer carries the ``stand_in`` warning.
STAND_IN_WARN: float = 0.2
#: Beta(1/2, 1/2) prior on each band's rates (no band states 0 or 1).
_PRIOR: float = 0.5


@dataclass(frozen=True)
class OpenWorldMap:
    """Per band of the nominal chi2/n: how often in- and out-of-catalogue records are answered ``explained``.

    Attributes
    ----------
    edges : tuple of float
        Band edges of :data:`OPEN_WORLD_FEATURE` (band i holds ``edges[i-1] <= x < edges[i]``).
    explained_in : tuple of (int, int)
        Per band, ``(k, n)``: in-catalogue records answered explained whose nominal chi2/n lies in the
        band, of all ``n`` in-catalogue records (every band holds the same ``n``).
    explained_out : tuple of (int, int)
        The same for records of physics outside the catalogue.
    share : float
        Prior share of gaps caused outside the catalogue.
    """

    edges: tuple[float, ...]
    explained_in: tuple[tuple[int, int], ...]
    explained_out: tuple[tuple[int, int], ...]
    share: float = OPEN_WORLD_SHARE

    def __post_init__(self) -> None:
        bands = len(self.edges) + 1
        if len(self.explained_in) != bands or len(self.explained_out) != bands:
            raise ValueError(
                f"{bands} bands need {bands} counts each, got {self.explained_in} and {self.explained_out}"
            )
        if any(b <= a for a, b in zip(self.edges, self.edges[1:], strict=False)):
            raise ValueError(f"the band edges must increase, got {self.edges}")
        for k, n in (*self.explained_in, *self.explained_out):
            if not 0 <= k <= n or n <= 0:
                raise ValueError(f"a band's count must be 0 <= k <= n with n > 0, got ({k}, {n})")
        if not 0.0 < self.share < 1.0:
            raise ValueError(f"the share must lie in (0, 1), got {self.share}")

    def band(self, x: float) -> int:
        """The band of a nominal chi2/n."""
        return sum(x >= e for e in self.edges)

    def stand_in(self, x: float) -> float:
        """Probability that an ``explained`` answer at nominal chi2/n ``x`` is a stand-in (Bayes' rule).

        Raises
        ------
        ValueError
            ``x`` is not finite.
        """
        if not math.isfinite(x):
            raise ValueError(f"the nominal chi2/n must be finite, got {x}")
        i = self.band(x)
        (k_in, n_in), (k_out, n_out) = self.explained_in[i], self.explained_out[i]
        r_in = (k_in + _PRIOR) / (n_in + 2 * _PRIOR)
        r_out = (k_out + _PRIOR) / (n_out + 2 * _PRIOR)
        out = self.share * r_out
        return out / (out + (1.0 - self.share) * r_in)

    def to_dict(self) -> dict[str, Any]:
        return {
            "feature": OPEN_WORLD_FEATURE,
            "edges": list(self.edges),
            "explained_in": [list(c) for c in self.explained_in],
            "explained_out": [list(c) for c in self.explained_out],
            "share": self.share,
            "stand_in": [self.stand_in(x) for x in (0.0, *self.edges)],
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> OpenWorldMap:
        return cls(
            tuple(float(e) for e in d["edges"]),
            tuple((int(k), int(n)) for k, n in d["explained_in"]),
            tuple((int(k), int(n)) for k, n in d["explained_out"]),
            float(d["share"]),
        )


def fit_open_world(
    inside: Sequence[tuple[float, bool]],
    outside: Sequence[tuple[float, bool]],
    edges: Sequence[float] = OPEN_WORLD_EDGES,
    share: float = OPEN_WORLD_SHARE,
) -> OpenWorldMap:
    """Count, per band, how often in- and out-of-catalogue records were answered ``explained``.

    Parameters
    ----------
    inside, outside : sequence of (float, bool)
        Per record, the nominal calibration's chi2/n and whether the answer was ``explained``: records
        with catalogue effects, and records of physics outside the catalogue.
    edges : sequence of float
        Band edges.
    share : float
        Prior share of gaps caused outside the catalogue.

    Raises
    ------
    ValueError
        No record of one of the two kinds, or a chi2/n is not finite.
    """
    bands = len(edges) + 1

    def counts(rows: Sequence[tuple[float, bool]]) -> tuple[tuple[int, int], ...]:
        k = [0] * bands
        for x, explained in rows:
            if not math.isfinite(x):
                raise ValueError(f"every chi2/n must be finite, got {x}")
            k[sum(x >= e for e in edges)] += bool(explained)
        return tuple((ki, len(rows)) for ki in k)

    return OpenWorldMap(tuple(float(e) for e in edges), counts(inside), counts(outside), share)


def stand_in_doubt(status: str, nominal_chi2: float | None, world: OpenWorldMap | None) -> float | None:
    """The stand-in probability of an answer that is in doubt: ``explained``, and at or above :data:`STAND_IN_WARN`.

    The one rule that decides both the ``stand_in`` warning (:func:`stand_in_warnings`) and the
    width's term 5 (:func:`engine.diagnosis.width.answer_width`), in a diagnosis and when stored
    answers are re-scored (:func:`engine.validation.width_coverage.stand_in_reach`).

    Parameters
    ----------
    status : str
        The verdict's status.
    nominal_chi2 : float or None
        The nominal calibration's chi2/n.
    world : OpenWorldMap or None
        The committed map's open-world part.

    Returns
    -------
    float or None
        :meth:`OpenWorldMap.stand_in`, or None: another status, no map, no finite chi2/n, or below
        :data:`STAND_IN_WARN`.
    """
    if status != "explained" or world is None or nominal_chi2 is None or not math.isfinite(nominal_chi2):
        return None
    p = world.stand_in(nominal_chi2)
    return p if p >= STAND_IN_WARN else None


def stand_in_warnings(verdict: Verdict, nominal_chi2: float, doubt: float | None) -> list[PlausibilityWarning]:
    """The ``stand_in`` warning of an answer in doubt (:func:`stand_in_doubt`), or none.

    Parameters
    ----------
    verdict : Verdict
        The diagnosis's verdict (its named effects go into the message).
    nominal_chi2 : float
        The nominal calibration's chi2/n.
    doubt : float or None
        :func:`stand_in_doubt` of the answer.

    Returns
    -------
    list of PlausibilityWarning
        One warning when ``doubt`` is not None, else none.
    """
    if doubt is None:
        return []
    named = " and ".join(f"{r['effect']} = {r['value']:.4g} {r['unit']}" for r in verdict.effects)
    return [
        PlausibilityWarning(
            "stand_in",
            f"The gap is weak (the nominal model leaves chi2/n = {nominal_chi2:.3g}): {named or verdict.effect} "
            "reproduces it, but at such gaps physics outside the catalogue is often reproduced by a small change "
            f"of a catalogue parameter (a {100 * doubt:.0f} % chance here that the named effect stands in for "
            "something else, included in the confidence). Before acting on it, check that the named change is "
            "plausible for this machine (a measured resistance, a known friction), or repeat the test with a "
            "stronger excitation, where the two part company.",
        )
    ]
