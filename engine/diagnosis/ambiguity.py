"""Near twins: effects that a record cannot tell from a named one, by the decision's own evidence rule.

Exact twins give the very same record whatever it is (a measurement delay and a trigger offset:
:func:`engine.diagnosis.space.indistinguishable`) and are known before any fit. Other effects are
twins only in a given record: seen through the drive's own channels (m_el and omega1) a change of
the supply voltage and a rotor-resistance drift beside a stator drift can move the record alike to
within its noise, and the search then fits both sets to the noise with almost the same BIC. Naming
one of them as *the* answer would be a coin toss presented as a finding.

Rule
----
Let M be the model the decision chose (:func:`engine.diagnosis.diagnose.choose_model`: a single
effect or a set). An effect ``e`` of M has a **near twin** ``f`` when the search fitted a model M'
of the same size that holds ``f`` in place of ``e`` and nothing else changed, and M'

* explains the record as M does: refined at the final integrator step, fits to the noise, every
  effect strong (the caller's ``explains``), and
* is worse than M by less than ``max_delta_bic`` in BIC; the diagnosis passes its
  ``min_delta_bic``, the margin a larger model must gain to replace a smaller one, so a near
  twin is exactly what the decision would not call evidence against.

The verdict lists each near twin beside the named effect with its fitted value and the BIC
difference (``verdict.effects[i].near_twins``), apart from the exact twins
(``alternatives``): an exact twin is the same record, a near twin only the same record to within
this record's noise, and another record of the same machine (more channels, another operating
point) may tell them apart.

Where it fails: only models that the search fitted are compared, so a near twin that the search
never tried is not reported. Since 2026-11-25 the set search's swap step
(:attr:`engine.diagnosis.sets.SetSettings.n_swap`) fits, beside the others of an explaining set,
the two effects the profiled screen ranks best in each member's place, so a twin is missed only when
the screen ranks it lower than that (or when the named model is a single effect); and a
model that fits no better than M but that the search did not refine at the final step is left
out (like for like: search-step fits carry the coarser step's integration error).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from engine.diagnosis.candidate import Candidate
from engine.diagnosis.candidate_set import CandidateSet
from engine.diagnosis.space import indistinguishable
from engine.simulation import EffectLibrary

__all__ = ["Model", "NearTwin", "near_twins"]

Model = Candidate | CandidateSet
"""A fitted alternative to the nominal model: one effect, or a set of effects."""


@dataclass(frozen=True)
class NearTwin:
    """An effect that stands in for a named one as well as the record can tell.

    Attributes
    ----------
    effect : str
        The other effect.
    value : float or None
        Its fitted value in the model that holds it, in ``unit``.
    unit : str
        Unit of the value.
    delta_bic : float
        BIC of the model that holds it minus that of the chosen model (below the decision's
        margin; not negative, as the chosen model is the best of its size).
    """

    effect: str
    value: float | None
    unit: str
    delta_bic: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {"effect": self.effect, "value": self.value, "unit": self.unit, "delta_bic": self.delta_bic}


def _effects(m: Model) -> tuple[str, ...]:
    return (m.effect,) if isinstance(m, Candidate) else m.effects


def _value_and_unit(m: Model, name: str) -> tuple[float | None, str]:
    if isinstance(m, Candidate):
        return m.value, m.unit
    return m.values.get(name), m.units[name]


def _exact_twins(m: Model, name: str, library: EffectLibrary) -> tuple[str, ...]:
    value, _ = _value_and_unit(m, name)
    return indistinguishable(name, float(value), library) if value is not None else ()


def near_twins(
    chosen: Model,
    models: Sequence[Model],
    explains: Callable[[Model], bool],
    max_delta_bic: float,
    library: EffectLibrary,
) -> dict[str, tuple[NearTwin, ...]]:
    """Near twins of each effect of the chosen model (see the module notes).

    Parameters
    ----------
    chosen : Candidate or CandidateSet
        The model the verdict names.
    models : sequence of Candidate or CandidateSet
        Every model the search fitted (``chosen`` among them or not).
    explains : callable
        Whether a model explains the record as the chosen one does (refined, fits to the noise,
        every effect strong).
    max_delta_bic : float
        A model whose BIC exceeds the chosen one's by this much or more is worse by the decision's
        rule: not a near twin.
    library : EffectLibrary
        The candidate effects: a named effect's exact twins in it
        (:func:`~engine.diagnosis.space.indistinguishable` at the named value) are its
        ``alternatives``, never its near twins.

    Returns
    -------
    dict of str to tuple of NearTwin
        Per effect of ``chosen`` that has near twins, best BIC first; effects without any are absent.
    """
    mine = _effects(chosen)
    out: dict[str, list[NearTwin]] = {}
    for m in sorted(models, key=lambda x: x.bic):
        if m is chosen or m.calibration is None:
            continue
        theirs = _effects(m)
        gone, new = set(mine) - set(theirs), set(theirs) - set(mine)
        if len(theirs) != len(mine) or len(gone) != 1 or len(new) != 1:
            continue
        delta = m.bic - chosen.bic
        if not delta < max_delta_bic or not explains(m):
            continue
        (named,), (other,) = gone, new
        if any(t.effect == other for t in out.get(named, [])) or other in _exact_twins(chosen, named, library):
            continue
        value, unit = _value_and_unit(m, other)
        out.setdefault(named, []).append(NearTwin(other, value, unit, delta))
    return {k: tuple(v) for k, v in out.items()}
