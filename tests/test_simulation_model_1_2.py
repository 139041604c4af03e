"""Model 1.2: the held-out family HELD_OUT (docs/model-changes.md, version 1.2).

Simulation only. HELD_OUT is kept for scoring: nothing here diagnoses, locates or validates a
record of these effects (the case generator is run without its absorption rule, which refits).

* every new term is exactly neutral at zero: the records are bit for bit those without it, also
  inside the kernel's extended path (``P_EXTENDED``), which model 1.1's terms switch on;
* the kernel agrees with the independent scipy reference (engine.simulation.reference) for every
  held-out effect at its upper bound and in the combinations where two terms meet (saturation and
  the switch-off torque, the preload spring and the zone's offset, the encoder and the sensor
  low-pass, the unbalance and a supply input);
* at half its upper bound every effect is visible at 40 dB on the nominal plant;
* the family is disjoint from the catalogue and from HELD_BACK, one effect per locus, and the
  case generator of protocol 2 draws held-back cases from it.

Measured with the default SolverSettings against the reference (DOP853, rtol 1e-9), worst over
the cases, in % of peak-to-peak: effects at their upper bound 0.0137 % (a1, magnetic_saturation
0.5), |dt_e| 1.0e-8 s (clutch_preload_spring 0.02); combinations 0.0228 % (a1, saturation with
the switch-off decay at 0.2), |dt_e| 9.5e-9 s. Guards as for model 1.1: 0.04 % and 5e-8 s.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest

from engine.constants import CHANNELS, MODEL_VERSION
from engine.simulation import (
    CATALOGUE,
    HELD_BACK,
    HELD_OUT,
    LOCI,
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
from engine.simulation.held_out import RULE
from engine.simulation.reference import HELD_OUT_NEUTRAL, reference_inputs, reference_simulate
from engine.simulation.simulator import parameter_vector

SPEC_REL = 0.005
SPEC_EVENT_TIME = 1e-6
GUARD_REL = 4e-4
GUARD_EVENT_TIME = 5e-8
PLANT = {"K": 0.005, "J1": 0.87, "c": 1.0}
NOMINAL = PlantParameters(**PLANT)
LIBRARY = CATALOGUE + HELD_BACK + HELD_OUT
DOCS = Path(__file__).resolve().parents[1] / "docs"

#: Where two terms meet: each case by effect name and value (the reference takes the same names).
COMBINATIONS: dict[str, dict[str, float]] = {
    "saturation-and-switch-off-decay": {"magnetic_saturation": 0.5, "switch_off_decay": 0.2},
    "preload-and-zone-offset": {"clutch_preload_spring": 0.02, "clutch_offset": -0.004},
    "encoder-and-lowpass": {"speed_encoder_eccentricity": 0.2, "sensor_lowpass": 1000.0},
    "every-held-out-effect": {n: e.bounds[1] for n, e in HELD_OUT.items()},
}
_SUPPLY_INPUT = {"locus": "supply", "t0": 0.01, "dt": 0.01, "values": [0.04, -0.03, 0.05, 0.02, -0.05] * 4}


@cache
def _compare(kind: str, name: str) -> tuple[np.ndarray, float, np.ndarray, float]:
    """(kernel record, kernel t_e, reference record, reference t_e) of one case."""
    plant, disturbance = NOMINAL, None
    if kind == "effect":
        effects = {name: HELD_OUT[name].bounds[1]}
    elif kind == "combination":
        effects = COMBINATIONS[name]
    else:  # the unbalance on top of a supply input: u includes the input's factor
        effects = {"supply_unbalance": HELD_OUT["supply_unbalance"].bounds[1]}
        disturbance = _SUPPLY_INPUT
        spec = _SUPPLY_INPUT
        plant = NOMINAL.replace(disturbance=Disturbance("supply", spec["t0"], spec["dt"], tuple(spec["values"])))
    sim = simulate_batch([Case(plant)], effects, library=LIBRARY)
    ref = reference_simulate(PLANT, effects, disturbance=disturbance)
    return sim.channels[0], float(sim.event_times[0]), ref.channels, ref.event_time


CASES = (
    [("effect", n) for n in HELD_OUT]
    + [("combination", n) for n in COMBINATIONS]
    + [("input", "supply_unbalance-and-supply-input")]
)


@pytest.mark.parametrize(("kind", "name"), CASES, ids=[f"{k}-{n}" for k, n in CASES])
def test_kernel_meets_the_spec_and_the_guard_against_the_reference(kind: str, name: str) -> None:
    kernel, te_k, ref, te_r = _compare(kind, name)
    rel = np.max(np.abs(kernel - ref), axis=1) / np.ptp(ref, axis=1)
    assert abs(te_k - te_r) < min(SPEC_EVENT_TIME, GUARD_EVENT_TIME)
    assert np.all(rel < min(SPEC_REL, GUARD_REL)), dict(zip(CHANNELS, rel.round(6), strict=True))


def test_every_held_out_effect_is_neutral_at_its_neutral_value_and_acts_otherwise() -> None:
    """Alone, and on top of a held-back effect (which switches the kernel's extended path on)."""
    for base in (Case(NOMINAL), HELD_BACK["motor_cogging"].apply(Case(NOMINAL), 0.03)):
        cases = [base]
        for e in HELD_OUT.values():
            cases += [e.apply(base, e.neutral), e.apply(base, e.bounds[1])]
        res = simulate_batch(cases)
        plain = res.channels[0]
        for i, name in enumerate(HELD_OUT):
            neutral, strong = res.channels[1 + 2 * i], res.channels[2 + 2 * i]
            assert neutral.tobytes() == plain.tobytes(), f"{name} at its neutral value changed the record"
            assert res.event_times[1 + 2 * i] == res.event_times[0]
            assert np.max(np.abs(strong - plain)) > 1e-3, f"{name} at its bound left the record unchanged"


def test_the_extended_path_with_every_term_zero_is_model_1_0_bit_for_bit() -> None:
    """Forcing P_EXTENDED on with every 1.1 and 1.2 term zero changes no bit: each term is guarded."""
    cases = [Case(NOMINAL), Case(PlantParameters(K=0.0025, J1=0.7612, c=0.8), SensorParameters(1e-3, 1000.0))]
    P = np.stack([parameter_vector(c) for c in cases])
    assert np.all(P[:, kern.P_EXTENDED] == 0.0)
    forced = P.copy()
    forced[:, kern.P_EXTENDED] = 1.0
    runs = []
    for vectors in (P, forced):
        out = np.zeros((len(cases), kern.N_CHANNELS, 2048))
        t_e = np.zeros(len(cases))
        status = np.zeros(len(cases), dtype=np.int64)
        kern.simulate_serial(vectors, out, t_e, status)
        assert np.all(status == kern.OK)
        runs.append((out, t_e))
    assert runs[0][0].tobytes() == runs[1][0].tobytes()
    assert runs[0][1].tobytes() == runs[1][1].tobytes()


def test_each_held_out_value_switches_the_extended_path_on_in_its_own_slot() -> None:
    slots = {
        "u_neg": kern.P_U_NEG,
        "sat": kern.P_SAT,
        "b_2": kern.P_B_2,
        "k_pre": kern.P_K_PRE,
        "hard2": kern.P_HARD2,
        "k_3": kern.P_K_3,
        "ecc1": kern.P_ECC1,
    }
    assert sorted(slots.values()) == list(range(kern.P_T_SWITCH_OFF + 1, kern.P_ECC1 + 1))  # appended after 1.1's
    for e in HELD_OUT.values():
        P = parameter_vector(e.apply(Case(NOMINAL), 0.5 * e.bounds[1]))
        assert P[kern.P_EXTENDED] == 1.0
        assert P[slots[e.field]] == 0.5 * e.bounds[1]
        assert np.count_nonzero(P[kern.P_U_NEG :]) == 1


def test_half_the_upper_bound_is_visible_at_40_db_on_the_nominal_plant() -> None:
    """The bounds' rule (docs/model-changes.md, 1.2): > 3 noise RMS on two channels at half the bound.

    The speed encoder's error is in omega1 only, by definition: one channel for it.
    """
    base = Case(NOMINAL)
    res = simulate_batch([base] + [e.apply(base, 0.5 * e.bounds[1]) for e in HELD_OUT.values()])
    plain = res.channels[0]
    sd = noise_std(plain, 40.0)[:, 0]
    for i, (name, e) in enumerate(HELD_OUT.items(), 1):
        rms = np.sqrt(np.mean((res.channels[i] - plain) ** 2, axis=1)) / sd
        need = 1 if e.locus == "sensors" else 2
        assert np.sum(rms > 3.0) >= need, (name, dict(zip(CHANNELS, rms.round(1), strict=True)))


def test_every_held_out_effect_at_its_upper_bound_keeps_the_event_across_the_plausible_box() -> None:
    corners = [PlantParameters(K=K, J1=J1, c=c) for K in (0.001, 0.015) for J1 in (0.6, 1.2) for c in (0.5, 2.0)]
    res = simulate_batch([e.apply(Case(p), e.bounds[1]) for p in corners for e in HELD_OUT.values()])
    assert np.all(np.isfinite(res.event_times))  # simulate_batch raises on a missing event


def test_simulate_takes_held_out_effects_by_name_from_their_library() -> None:
    rec = simulate(NOMINAL, {"resilient_hardening": 0.5}, library=HELD_OUT)
    direct = simulate(NOMINAL.replace(hard2=0.5))
    for ch in CHANNELS:
        assert rec.channels[ch].tobytes() == direct.channels[ch].tobytes()
    enc = simulate(NOMINAL, {"speed_encoder_eccentricity": 0.1}, library=HELD_OUT)
    assert (
        enc.channels["omega1"].tobytes()
        == simulate(Case(NOMINAL, SensorParameters(ecc1=0.1))).channels["omega1"].tobytes()
    )
    with pytest.raises(UnknownEffectError):
        simulate(NOMINAL, {"resilient_hardening": 0.5})  # not in the catalogue


def test_the_encoder_error_is_in_omega1_only() -> None:
    res = simulate_batch([Case(NOMINAL), HELD_OUT["speed_encoder_eccentricity"].apply(Case(NOMINAL), 0.2)])
    changed = [ch for j, ch in enumerate(CHANNELS) if res.channels[0, j].tobytes() != res.channels[1, j].tobytes()]
    assert changed == ["omega1"]


def test_held_out_family_is_outside_the_catalogue_and_held_back_one_effect_per_locus() -> None:
    assert not set(HELD_OUT) & set(CATALOGUE)
    assert not set(HELD_OUT) & set(HELD_BACK)
    assert sorted(e.locus for e in HELD_OUT.values()) == sorted(LOCI)
    fields_before = {(e.target, e.field) for e in (*CATALOGUE.values(), *HELD_BACK.values())}
    assert not {(e.target, e.field) for e in HELD_OUT.values()} & fields_before  # new terms, not new values
    assert all(e.neutral == 0.0 and e.bounds[0] == 0.0 < e.bounds[1] for e in HELD_OUT.values())
    assert MODEL_VERSION != "1.1"  # 1.2 bumped it (1.3 since the sealed family)


def test_reference_knows_every_held_out_effect_at_its_neutral_value() -> None:
    assert {n: e.neutral for n, e in HELD_OUT.items()} == dict(HELD_OUT_NEUTRAL)
    case = Case(
        NOMINAL.replace(u_neg=0.01, sat=0.02, b_2=0.03, k_pre=0.004, hard2=0.05, k_3=0.06), SensorParameters(ecc1=0.07)
    )
    _, effects = reference_inputs(case)
    assert {n: effects[n] for n in HELD_OUT} == {
        "supply_unbalance": 0.01,
        "magnetic_saturation": 0.02,
        "motor_windage": 0.03,
        "clutch_preload_spring": 0.004,
        "resilient_hardening": 0.05,
        "load_position_spring": 0.06,
        "speed_encoder_eccentricity": 0.07,
    }


def test_the_rule_is_stated_in_the_module_and_in_the_docs() -> None:
    from engine.simulation import held_out

    assert held_out.__doc__ is not None and RULE in held_out.__doc__
    assert RULE in " ".join((DOCS / "model-changes.md").read_text().split())


def test_the_case_generator_draws_held_back_cases_from_the_held_out_family() -> None:
    from engine.validation.cases import generate_cases

    n = len(HELD_OUT)  # its pool gives every effect once per round
    cases, key = generate_cases(n, 5, CATALOGUE, HELD_OUT, {"held_back": 1.0}, absorption=False)
    assert len(cases) == n
    assert {k.kind for k in key} == {"held_back"}
    assert sorted(t.name for k in key for t in k.effects) == sorted(HELD_OUT)
    assert all(t.locus == HELD_OUT[t.name].locus for k in key for t in k.effects)
    with pytest.raises(ValueError, match="never be in the catalogue"):
        generate_cases(1, 5, CATALOGUE + HELD_OUT, HELD_OUT, {"held_back": 1.0}, absorption=False)


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"u_neg": -0.01}, "u_neg"),
        ({"sat": -0.1}, "sat"),
        ({"b_2": float("nan")}, "finite"),
        ({"k_pre": 2.0}, "k_pre"),
        ({"hard2": -1.0}, "hard2"),
        ({"k_3": -0.1}, "k_3"),
    ],
)
def test_an_absurd_held_out_value_is_refused_with_its_name(changes: dict[str, float], match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        PlantParameters(**changes).validate()


def test_an_absurd_encoder_eccentricity_is_refused() -> None:
    with pytest.raises(ParameterError, match="ecc1"):
        SensorParameters(ecc1=0.9).validate()
