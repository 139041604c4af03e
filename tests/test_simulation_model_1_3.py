"""Model 1.3: the sealed family SEALED (docs/model-changes.md, version 1.3).

Simulation only. SEALED is kept for scoring: nothing here diagnoses, calibrates, locates or
validates a record of these effects (the case generator is run without its absorption rule, which
refits).

* every new term is exactly neutral at zero: the records are bit for bit those without it, also
  inside the kernel's extended path (``P_EXTENDED``), which the terms of 1.1 and 1.2 switch on;
* the kernel agrees with the independent scipy reference (engine.simulation.reference) for every
  sealed effect at its upper bound and in the combinations where two terms meet (the flicker with
  the unbalance and a supply input, the leakages with saturation, the progressive contact with the
  zone's offset and the preload spring, the Stribeck and the Coulomb friction of the motor, the dry
  friction with the hardening of the resilient element, the drag with the load's spring, the
  cross-talk behind the sensor low-pass and gain);
* at half its upper bound every effect is visible at 40 dB on the nominal plant;
* the family is disjoint from the catalogue, HELD_BACK and HELD_OUT, one effect per locus, is
  registered as the family ``sealed`` (``backlash validate --held-back sealed``), and the case
  generator of protocol 2 draws held-back cases from it.

Measured with the default SolverSettings against the reference (DOP853, rtol 1e-9), worst over
the cases, in % of peak-to-peak: effects at their upper bound 0.0160 % (a1, leakage_reactance
0.02), |dt_e| 1.9e-8 s (leakage_reactance 0.02); combinations 0.0339 % (a1, the leakages with
saturation 0.5: the kernel's step, 0.0060 % at 10 us), |dt_e| 2.0e-8 s (every sealed effect at
once). Guards as for model 1.1 and 1.2: 0.04 % and 5e-8 s.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest
from bench_scripts import load_bench

from engine.constants import CHANNELS, MODEL_VERSION, X_REF
from engine.simulation import (
    CATALOGUE,
    HELD_BACK,
    HELD_OUT,
    LOCI,
    SEALED,
    Case,
    Disturbance,
    ParameterError,
    PlantParameters,
    SensorParameters,
    UnknownEffectError,
    noise_std,
    simulate,
    simulate_batch,
)
from engine.simulation import _kernel as kern
from engine.simulation.families import FAMILIES, locus_of
from engine.simulation.reference import SEALED_NEUTRAL, reference_inputs, reference_simulate
from engine.simulation.sealed import RULE
from engine.simulation.simulator import parameter_vector

SPEC_REL = 0.005
SPEC_EVENT_TIME = 1e-6
GUARD_REL = 4e-4
GUARD_EVENT_TIME = 5e-8
PLANT = {"K": 0.005, "J1": 0.87, "c": 1.0}
NOMINAL = PlantParameters(**PLANT)
LIBRARY = CATALOGUE + HELD_BACK + HELD_OUT + SEALED
DOCS = Path(__file__).resolve().parents[1] / "docs"

#: Where two terms meet: each case by effect name and value (the reference takes the same names).
COMBINATIONS: dict[str, dict[str, float]] = {
    "leakages-and-saturation": {"leakage_reactance": 0.02, "magnetic_saturation": 0.5},
    "progressive-contact-zone-offset-and-preload": {
        "clutch_progressive_contact": 1.0,
        "clutch_offset": -0.004,
        "clutch_preload_spring": 0.02,
    },
    "stribeck-and-coulomb": {"motor_stribeck": 0.1, "motor_coulomb_friction": 0.1},
    "dry-friction-and-hardening": {"resilient_dry_friction": 0.05, "resilient_hardening": 1.0},
    "drag-and-load-spring": {"load_quadratic_drag": 20.0, "load_position_spring": 0.5},
    "crosstalk-lowpass-and-gain": {"accelerometer_crosstalk": 0.1, "sensor_lowpass": 1000.0, "sensor_gain": 1.2},
    "every-sealed-effect": {n: e.bounds[1] for n, e in SEALED.items()},
}
_SUPPLY_INPUT = {"locus": "supply", "t0": 0.01, "dt": 0.01, "values": [0.04, -0.03, 0.05, 0.02, -0.05] * 4}
#: The kernel's slot of each sealed value (the leakages have none: they enter x_s and x_r).
SLOTS = {
    "u_flicker": kern.P_FLICKER,
    "tau_S1": kern.P_TAU_S1,
    "prog12": kern.P_PROG12,
    "tau_dry2": kern.P_TAU_DRY2,
    "b_3": kern.P_B_3,
    "xtalk2": kern.P_XTALK2,
}


@cache
def _compare(kind: str, name: str) -> tuple[np.ndarray, float, np.ndarray, float]:
    """(kernel record, kernel t_e, reference record, reference t_e) of one case."""
    plant, disturbance = NOMINAL, None
    if kind == "effect":
        effects = {name: SEALED[name].bounds[1]}
    elif kind == "combination":
        effects = COMBINATIONS[name]
    else:  # the flicker and the unbalance on top of a supply input: u includes every factor
        effects = {"supply_flicker": SEALED["supply_flicker"].bounds[1], "supply_unbalance": 0.1}
        disturbance = _SUPPLY_INPUT
        spec = _SUPPLY_INPUT
        plant = NOMINAL.replace(disturbance=Disturbance("supply", spec["t0"], spec["dt"], tuple(spec["values"])))
    sim = simulate_batch([Case(plant)], effects, library=LIBRARY)
    ref = reference_simulate(PLANT, effects, disturbance=disturbance)
    return sim.channels[0], float(sim.event_times[0]), ref.channels, ref.event_time


CASES = (
    [("effect", n) for n in SEALED]
    + [("combination", n) for n in COMBINATIONS]
    + [("input", "flicker-unbalance-and-supply-input")]
)


@pytest.mark.parametrize(("kind", "name"), CASES, ids=[f"{k}-{n}" for k, n in CASES])
def test_kernel_meets_the_spec_and_the_guard_against_the_reference(kind: str, name: str) -> None:
    kernel, te_k, ref, te_r = _compare(kind, name)
    rel = np.max(np.abs(kernel - ref), axis=1) / np.ptp(ref, axis=1)
    assert abs(te_k - te_r) < min(SPEC_EVENT_TIME, GUARD_EVENT_TIME)
    assert np.all(rel < min(SPEC_REL, GUARD_REL)), dict(zip(CHANNELS, rel.round(6), strict=True))


def test_every_sealed_effect_is_neutral_at_its_neutral_value_and_acts_otherwise() -> None:
    """Alone, on top of a held-back effect and on top of every held-out effect (the extended path on)."""
    held_out = {n: 0.5 * e.bounds[1] for n, e in HELD_OUT.items()}
    bases = (
        Case(NOMINAL),
        HELD_BACK["motor_cogging"].apply(Case(NOMINAL), 0.03),
        HELD_OUT.apply(Case(NOMINAL), held_out),
    )
    for base in bases:
        cases = [base]
        for e in SEALED.values():
            cases += [e.apply(base, e.neutral), e.apply(base, e.bounds[1])]
        res = simulate_batch(cases)
        plain = res.channels[0]
        for i, name in enumerate(SEALED):
            neutral, strong = res.channels[1 + 2 * i], res.channels[2 + 2 * i]
            assert neutral.tobytes() == plain.tobytes(), f"{name} at its neutral value changed the record"
            assert res.event_times[1 + 2 * i] == res.event_times[0]
            assert np.max(np.abs(strong - plain)) > 1e-3, f"{name} at its bound left the record unchanged"


def test_the_extended_path_with_every_term_zero_is_model_1_0_bit_for_bit() -> None:
    """Forcing P_EXTENDED on with every 1.1, 1.2 and 1.3 term zero changes no bit: each term is guarded.

    The cases and grids of test_simulation_model_1_2.py's test, and a 25 us grid with a finer step.
    """
    from engine.records import SampleGrid
    from engine.simulation import SolverSettings

    cases = [Case(NOMINAL), Case(PlantParameters(K=0.0025, J1=0.7612, c=0.8), SensorParameters(1e-3, 1000.0))]
    settings = [(SolverSettings(), 2048, None), (SolverSettings(max_step=1e-5), 8400, SampleGrid(2.5e-5, 8400, 200))]
    for solver, n, grid in settings:
        P = np.stack(
            [parameter_vector(c, solver) if grid is None else parameter_vector(c, solver, grid) for c in cases]
        )
        assert np.all(P[:, kern.P_EXTENDED] == 0.0)
        assert np.all(P[:, kern.P_FLICKER :] == 0.0)
        forced = P.copy()
        forced[:, kern.P_EXTENDED] = 1.0
        runs = []
        for vectors in (P, forced):
            out = np.zeros((len(cases), kern.N_CHANNELS, n))
            t_e = np.zeros(len(cases))
            status = np.zeros(len(cases), dtype=np.int64)
            kern.simulate_serial(vectors, out, t_e, status)
            assert np.all(status == kern.OK)
            runs.append((out, t_e))
        assert runs[0][0].tobytes() == runs[1][0].tobytes()
        assert runs[0][1].tobytes() == runs[1][1].tobytes()


def test_each_sealed_value_switches_the_extended_path_on_in_its_own_slot() -> None:
    assert sorted(SLOTS.values()) == list(range(kern.P_ECC1 + 1, kern.N_PARAMS))  # appended after 1.2's
    plain = parameter_vector(Case(NOMINAL))
    for e in SEALED.values():
        value = 0.5 * e.bounds[1]
        P = parameter_vector(e.apply(Case(NOMINAL), value))
        assert P[kern.P_EXTENDED] == 1.0
        if e.field == "x_leak":  # no slot: both leakage reactances higher, x_m kept
            assert P[kern.P_X_S] == NOMINAL.x_s + value and P[kern.P_X_R] == NOMINAL.x_r + value
            assert P[kern.P_X_M] == NOMINAL.x_m
            assert np.count_nonzero(P[kern.P_U_NEG :]) == 0
        else:
            assert P[SLOTS[e.field]] == value
            assert np.count_nonzero(P[kern.P_U_NEG :]) == 1
            assert P[kern.P_X_S] == plain[kern.P_X_S] and P[kern.P_X_R] == plain[kern.P_X_R]


def test_half_the_upper_bound_is_visible_at_40_db_on_the_nominal_plant() -> None:
    """The bounds' rule (docs/model-changes.md, 1.3): > 3 noise RMS on two channels at half the bound.

    The accelerometer's cross-talk is in a2 only, by definition: one channel for it.
    """
    base = Case(NOMINAL)
    res = simulate_batch([base] + [e.apply(base, 0.5 * e.bounds[1]) for e in SEALED.values()])
    plain = res.channels[0]
    sd = noise_std(plain, 40.0)[:, 0]
    for i, (name, e) in enumerate(SEALED.items(), 1):
        rms = np.sqrt(np.mean((res.channels[i] - plain) ** 2, axis=1)) / sd
        need = 1 if e.locus == "sensors" else 2
        assert np.sum(rms > 3.0) >= need, (name, dict(zip(CHANNELS, rms.round(1), strict=True)))


def test_the_visibility_script_prints_the_rule_s_table() -> None:
    """bench/family_visibility.py (the table of docs/model-changes.md, 1.3): one row per effect, simulation only."""
    script = load_bench("family_visibility")
    rows = script.visibility("sealed", 0.5)
    assert [r.name for r in rows] == list(SEALED)
    text = script.table(rows, 0.5)
    assert text.count("\n") == len(SEALED) + 1 and "| accelerometer_crosstalk 0.05 | 0 | 0 | 0 | " in text


def test_every_sealed_effect_at_its_upper_bound_keeps_the_event_across_the_plausible_box() -> None:
    corners = [PlantParameters(K=K, J1=J1, c=c) for K in (0.001, 0.015) for J1 in (0.6, 1.2) for c in (0.5, 2.0)]
    res = simulate_batch([e.apply(Case(p), e.bounds[1]) for p in [NOMINAL, *corners] for e in SEALED.values()])
    assert np.all(np.isfinite(res.event_times))  # simulate_batch raises on a missing event


def test_simulate_takes_sealed_effects_by_name_from_their_library() -> None:
    rec = simulate(NOMINAL, {"clutch_progressive_contact": 0.5}, library=SEALED)
    direct = simulate(NOMINAL.replace(prog12=0.5))
    for ch in CHANNELS:
        assert rec.channels[ch].tobytes() == direct.channels[ch].tobytes()
    acc = simulate(NOMINAL, {"accelerometer_crosstalk": 0.05}, library=SEALED)
    assert (
        acc.channels["a2"].tobytes() == simulate(Case(NOMINAL, SensorParameters(xtalk2=0.05))).channels["a2"].tobytes()
    )
    with pytest.raises(UnknownEffectError):
        simulate(NOMINAL, {"clutch_progressive_contact": 0.5})  # not in the catalogue


def test_the_crosstalk_is_in_a2_only_and_adds_a1() -> None:
    v = 0.1
    res = simulate_batch([Case(NOMINAL), SEALED["accelerometer_crosstalk"].apply(Case(NOMINAL), v)])
    changed = [ch for j, ch in enumerate(CHANNELS) if res.channels[0, j].tobytes() != res.channels[1, j].tobytes()]
    assert changed == ["a2"]
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


def test_the_progressive_contact_is_stiffer_by_one_plus_the_value_at_x_ref() -> None:
    """X_REF (0.01 rad) is the nominal plant's largest penetration (0.0107 rad), rounded."""
    assert X_REF == 0.01
    P = parameter_vector(SEALED["clutch_progressive_contact"].apply(Case(NOMINAL), 0.5))
    b, k12 = NOMINAL.b, NOMINAL.k12
    for d, sign in ((b + X_REF, 1.0), (-b - X_REF, -1.0)):
        assert kern.contact_push(d, 0.0, P, True) == pytest.approx(sign * k12 * X_REF * 1.5, rel=1e-12)
        assert kern.contact_push(d, 0.0, P, False) == pytest.approx(sign * k12 * X_REF, rel=1e-12)  # guard off
    base, strong = simulate_batch(
        [Case(NOMINAL), SEALED["clutch_progressive_contact"].apply(Case(NOMINAL), 1.0)]
    ).event_times
    assert strong < base  # the stiffer contact pushes the motor back sooner


def test_sealed_family_is_outside_the_catalogue_held_back_and_held_out_one_effect_per_locus() -> None:
    for other in (CATALOGUE, HELD_BACK, HELD_OUT):
        assert not set(SEALED) & set(other)
    assert sorted(e.locus for e in SEALED.values()) == sorted(LOCI)
    fields_before = {(e.target, e.field) for e in (*CATALOGUE.values(), *HELD_BACK.values(), *HELD_OUT.values())}
    assert not {(e.target, e.field) for e in SEALED.values()} & fields_before  # new terms, not new values
    assert all(e.neutral == 0.0 and e.bounds[0] == 0.0 < e.bounds[1] for e in SEALED.values())
    assert MODEL_VERSION == "1.3"


def test_the_family_is_registered_as_sealed_for_blind_runs() -> None:
    from app.cli.main import build_parser

    assert FAMILIES["sealed"] is SEALED
    assert all(locus_of(n) == e.locus for n, e in SEALED.items())
    args = build_parser().parse_args(["validate", "--held-back", "sealed", "--mix", "held_back=1"])
    assert args.held_back == "sealed"  # parsed only: nothing is run


def test_reference_knows_every_sealed_effect_at_its_neutral_value() -> None:
    assert {n: e.neutral for n, e in SEALED.items()} == dict(SEALED_NEUTRAL)
    case = Case(
        NOMINAL.replace(u_flicker=0.01, x_leak=0.02, tau_S1=0.03, prog12=0.04, tau_dry2=0.05, b_3=0.06),
        SensorParameters(xtalk2=0.07),
    )
    _, effects = reference_inputs(case)
    assert {n: effects[n] for n in SEALED} == {
        "supply_flicker": 0.01,
        "leakage_reactance": 0.02,
        "motor_stribeck": 0.03,
        "clutch_progressive_contact": 0.04,
        "resilient_dry_friction": 0.05,
        "load_quadratic_drag": 0.06,
        "accelerometer_crosstalk": 0.07,
    }


def test_the_rule_is_stated_in_the_module_and_in_the_docs() -> None:
    from engine.simulation import sealed

    assert sealed.__doc__ is not None and RULE in sealed.__doc__
    assert RULE in " ".join((DOCS / "model-changes.md").read_text().split())


def test_the_case_generator_draws_held_back_cases_from_the_sealed_family() -> None:
    from engine.validation.cases import generate_cases

    n = len(SEALED)  # its pool gives every effect once per round
    cases, key = generate_cases(n, 5, CATALOGUE, SEALED, {"held_back": 1.0}, absorption=False)
    assert len(cases) == n
    assert {k.kind for k in key} == {"held_back"}
    assert sorted(t.name for k in key for t in k.effects) == sorted(SEALED)
    assert all(t.locus == SEALED[t.name].locus for k in key for t in k.effects)
    with pytest.raises(ValueError, match="never be in the catalogue"):
        generate_cases(1, 5, CATALOGUE + SEALED, SEALED, {"held_back": 1.0}, absorption=False)


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"u_flicker": -0.01}, "u_flicker"),
        ({"u_flicker": 0.9}, "u_flicker"),
        ({"x_leak": -0.1}, "x_leak"),
        ({"tau_S1": float("nan")}, "finite"),
        ({"prog12": -1.0}, "prog12"),
        ({"tau_dry2": -0.1}, "tau_dry2"),
        ({"b_3": -1.0}, "b_3"),
    ],
)
def test_an_absurd_sealed_value_is_refused_with_its_name(changes: dict[str, float], match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        PlantParameters(**changes).validate()


def test_an_absurd_crosstalk_is_refused() -> None:
    with pytest.raises(ParameterError, match="xtalk2"):
        SensorParameters(xtalk2=1.5).validate()
