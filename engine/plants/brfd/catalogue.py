"""Candidate unmodelled effects of the BRFD: each one scalar, each at one locus.

Loci of this plant (:data:`LOCI`): ``linkage`` (the linkage from the actuator to the drum: its
play and its own stiffness), ``brake`` (the friction contact of band and drum), ``band`` (the
band brake's self-energizing geometry), ``sensors`` (load cell and displacement transducer).

Each effect sets one field of :class:`~engine.plants.brfd.model.BrfdParameters`; its neutral value
is the nominal model (a Dahl-type friction element, no play). Fixed parts of an effect are
documented choices in :mod:`engine.plants.brfd.model` (``STRIBECK_VELOCITY``,
``REVERSAL_TOLERANCE``).
"""

from __future__ import annotations

from engine.plants.base import CandidateEffect

__all__ = ["CATALOGUE", "EFFECT_FIELDS", "LOCI"]

#: The parts of the BRFD where an effect may act (module docstring).
LOCI: tuple[str, ...] = ("linkage", "brake", "band", "sensors")

#: name -> field of BrfdParameters the effect's scalar sets.
EFFECT_FIELDS: dict[str, str] = {
    "backlash": "play",
    "self_energizing": "kappa",
    "stribeck": "stribeck",
    "asymmetric_friction": "asym",
    "viscous_friction": "sigma2",
    "linkage_compliance": "c_link",
    "sensor_offset": "offset",
    "sensor_gain": "gain",
    "delay": "delay",
}

#: The catalogue, in a fixed order.
CATALOGUE: dict[str, CandidateEffect] = {
    e.name: e
    for e in (
        CandidateEffect(
            "backlash",
            "A play of width b in the displacement path between actuator and drum: inside it no force "
            "is transmitted; scalar b [m] (the backlash width).",
            (0.0, 0.012),
            0.0,
            "m",
            "linkage",
        ),
        CandidateEffect(
            "self_energizing",
            "Self-energizing amplification of the band brake: the force grows as (1 + kappa w) with the "
            "wind-up w = |x - x_rev| since the last reversal; scalar kappa [1/m].",
            (0.0, 100.0),
            0.0,
            "1/m",
            "band",
        ),
        CandidateEffect(
            "stribeck",
            "Stribeck friction: the friction level Fc (1 + r exp(-(v / v_s)^2)), higher (r > 0) or lower "
            "(r < 0) at low speed (v_s fixed, see the model); scalar r [share of Fc].",
            (-0.5, 1.0),
            0.0,
            "x Fc",
            "brake",
        ),
        CandidateEffect(
            "asymmetric_friction",
            "Friction level that differs with the direction: Fc (1 + a) moving out, Fc (1 - a) moving in; "
            "scalar a [share of Fc].",
            (-0.5, 0.5),
            0.0,
            "x Fc",
            "brake",
        ),
        CandidateEffect(
            "viscous_friction",
            "Viscous friction sigma2 v added to the transmitted force in contact; scalar sigma2 [N s/m].",
            (0.0, 50_000.0),
            0.0,
            "N s/m",
            "brake",
        ),
        CandidateEffect(
            "linkage_compliance",
            "The linkage's own stiffness k_L in series with the friction element, as its compliance "
            "1 / k_L [m/N] (neutral 0: a rigid linkage).",
            (0.0, 1e-6),
            0.0,
            "m/N",
            "linkage",
        ),
        CandidateEffect(
            "sensor_offset",
            "An offset of the load cell; scalar [N] (searched over +-5 kN, a quarter of the device's 20 kN "
            "rating: first set at +-2 kN, where the 36 lb sine tests' offsets sat on the bound).",
            (-5000.0, 5000.0),
            0.0,
            "N",
            "sensors",
        ),
        CandidateEffect(
            "sensor_gain",
            "A gain error of the load cell; scalar [x] (neutral 1).",
            (0.8, 1.2),
            1.0,
            "x",
            "sensors",
        ),
        CandidateEffect(
            "delay",
            "A time shift between the displacement and the force channels (positive: the force lags); scalar [s].",
            (-0.02, 0.02),
            0.0,
            "s",
            "sensors",
        ),
    )
}
