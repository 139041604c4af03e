"""Model 1.3: what the sealed family SEALED alone has (docs/model-changes.md, version 1.3).

Simulation only. SEALED is kept for scoring: nothing here diagnoses, calibrates, locates or
validates a record of these effects.

The checks model 1.3 shares with 1.1 and 1.2 run for the sealed effects from the table of
``tests/test_simulation_model_versions.py``: every new term exactly neutral at zero (also inside
the kernel's extended path, ``P_EXTENDED``, which the terms of 1.1 and 1.2 switch on), the kernel
against the independent scipy reference for every sealed effect at its upper bound and in the
combinations where two terms meet (with the measured errors in that module's docstring), each
effect visible at 40 dB at half its upper bound, the family disjoint from the catalogue, HELD_BACK
and HELD_OUT, one effect per locus, registered as the family ``sealed`` (``backlash validate
--held-back sealed``), and drawn by the case generator of protocol 2. Here, the terms with a
physics of their own:

* the leakages are the plant's reactances (no slot of their own in the parameter vector);
* the progressive contact is stiffer by one plus the value at X_REF;
* the accelerometer's cross-talk adds v times a1 to a2;
* bench/family_visibility.py prints the rule's table of docs/model-changes.md.
"""

from __future__ import annotations

import numpy as np
import pytest
from bench_scripts import load_bench

from engine.constants import CHANNELS, X_REF
from engine.simulation import SEALED, SEALED2, Case, EffectLibrary, PlantParameters, simulate_batch
from engine.simulation import _kernel as kern
from engine.simulation.simulator import parameter_vector

NOMINAL = PlantParameters(K=0.005, J1=0.87, c=1.0)


@pytest.mark.parametrize(
    ("family", "library", "row"),
    [
        ("sealed", SEALED, "| accelerometer_crosstalk 0.05 | 0 | 0 | 0 | "),  # a2 alone
        ("sealed2", SEALED2, "| speed_sample_hold 0.001 | 0 | 0 | "),  # omega1 alone (model 1.4)
    ],
)
def test_the_visibility_script_prints_the_rule_s_table(family: str, library: EffectLibrary, row: str) -> None:
    """bench/family_visibility.py (the tables of docs/model-changes.md, 1.3 and 1.4): one row per effect,
    simulation only; the measurement chain's effect changes its one channel alone."""
    script = load_bench("family_visibility")
    rows = script.visibility(family, 0.5)
    assert [r.name for r in rows] == list(library)
    text = script.table(rows, 0.5)
    assert text.count("\n") == len(library) + 1 and row in text


def test_the_crosstalk_adds_a1() -> None:
    """a2 + v a1, to rounding (the channel being a2 only is checked with the encoder's in the versions' module)."""
    v = 0.1
    res = simulate_batch([Case(NOMINAL), SEALED["accelerometer_crosstalk"].apply(Case(NOMINAL), v)])
    a1, a2 = CHANNELS.index("a1"), CHANNELS.index("a2")
    np.testing.assert_allclose(res.channels[1, a2], res.channels[0, a2] + v * res.channels[0, a1], rtol=0, atol=1e-12)


def test_the_leakages_are_the_reactances_of_the_plant() -> None:
    """leakage_reactance v is the plant with x_s + v and x_r + v: the same record bit for bit, x_m kept."""
    v = 0.01
    res = simulate_batch(
        [
            SEALED["leakage_reactance"].apply(Case(NOMINAL), v),
            Case(NOMINAL.replace(x_s=NOMINAL.x_s + v, x_r=NOMINAL.x_r + v)),
        ]
    )
    assert res.channels[0].tobytes() == res.channels[1].tobytes()


def test_the_leakages_switch_the_extended_path_on_without_a_slot() -> None:
    """Both leakage reactances higher, x_m kept, and no value in the slots (the others' slots: the versions' module)."""
    e = SEALED["leakage_reactance"]
    value = 0.5 * e.bounds[1]
    P = parameter_vector(e.apply(Case(NOMINAL), value))
    assert P[kern.P_EXTENDED] == 1.0
    assert P[kern.P_X_S] == NOMINAL.x_s + value and P[kern.P_X_R] == NOMINAL.x_r + value
    assert P[kern.P_X_M] == NOMINAL.x_m
    assert np.count_nonzero(P[kern.P_U_NEG : kern.P_XTALK2 + 1]) == 0


def test_the_progressive_contact_is_stiffer_by_one_plus_the_value_at_x_ref() -> None:
    """X_REF (0.01 rad) is the nominal plant's largest penetration (0.0107 rad), rounded."""
    assert X_REF == 0.01
    P = parameter_vector(SEALED["clutch_progressive_contact"].apply(Case(NOMINAL), 0.5))
    b, k12 = NOMINAL.b, NOMINAL.k12
    for d, sign in ((b + X_REF, 1.0), (-b - X_REF, -1.0)):
        assert kern.contact_push(d, 0.0, b, P, True) == pytest.approx(sign * k12 * X_REF * 1.5, rel=1e-12)
        assert kern.contact_push(d, 0.0, b, P, False) == pytest.approx(sign * k12 * X_REF, rel=1e-12)  # guard off
    base, strong = simulate_batch(
        [Case(NOMINAL), SEALED["clutch_progressive_contact"].apply(Case(NOMINAL), 1.0)]
    ).event_times
    assert strong < base  # the stiffer contact pushes the motor back sooner
