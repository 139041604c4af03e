"""The drive description (engine.simulation.drive): defaults, loaders, refusals, fingerprint, simulation."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from engine import constants as const
from engine.records import PROTOCOL_GRID
from engine.simulation import Case, ParameterError, PlantParameters, simulate_batch
from engine.simulation.drive import REFERENCE_DRIVE, SECTIONS, DriveDescription, load_drive, parse_drive
from engine.simulation.simulator import DEFAULT_SOLVER, parameter_vector

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "drive-60hz-conveyor.toml"


def test_empty_description_is_the_reference_plant() -> None:
    drive = DriveDescription.from_mapping({})
    assert drive == REFERENCE_DRIVE
    assert drive.plant() == PlantParameters()
    assert drive.grid() == PROTOCOL_GRID
    assert drive.solver() == DEFAULT_SOLVER
    assert (drive.w_b, drive.omega_b, drive.tm_per_j) == (const.W_B, const.OMEGA_B, const.TM_PER_J)
    assert drive.is_reference
    np.testing.assert_array_equal(parameter_vector(drive.nominal_case()), parameter_vector(Case()))


def test_empty_description_simulates_the_reference_records_bit_for_bit() -> None:
    plants = [REFERENCE_DRIVE.plant(K=K) for K in (0.0025, 0.009)]
    described = simulate_batch(plants, grid=REFERENCE_DRIVE.grid(), solver=REFERENCE_DRIVE.solver())
    reference = simulate_batch([PlantParameters(K=0.0025), PlantParameters(K=0.009)])
    np.testing.assert_array_equal(described.channels, reference.channels)
    np.testing.assert_array_equal(described.event_times, reference.event_times)


def test_toml_and_json_give_the_same_description_and_fingerprint(tmp_path: Path) -> None:
    toml = 'name = "a"\n[supply]\nfrequency = 60\n[motor]\npole_pairs = 3\n[mechanics]\nJ1 = 1.2\nr = 0.15\n'
    data = {"name": "b", "mechanics": {"r": 0.15, "J1": 1.2}, "motor": {"pole_pairs": 3}, "supply": {"frequency": 60.0}}
    (tmp_path / "d.toml").write_text(toml, encoding="utf-8")
    (tmp_path / "d.json").write_text(json.dumps(data), encoding="utf-8")
    a, b = load_drive(tmp_path / "d.toml"), load_drive(tmp_path / "d.json")
    assert a.fingerprint == b.fingerprint  # the name is a label, not content
    assert a.fingerprint != REFERENCE_DRIVE.fingerprint
    assert a.omega_b == pytest.approx(2 * math.pi * 60 / 3)
    assert a.x_s == const.X_S  # missing keys keep MODEL.md's values
    assert DriveDescription.from_mapping(a.to_dict()) == a  # round trip
    assert parse_drive(json.dumps(a.to_dict()), "json") == a


def test_every_value_enters_the_fingerprint() -> None:
    protocol = {
        "sample_interval": {"sample_interval": 2e-4},
        "n_samples": {"n_samples": 4096},
        "event_index": {"event_index": 60, "n_samples": 4096},  # a longer record, so the event can move
        "t_event_max": {"t_event_max": 2.0},
    }
    seen = {REFERENCE_DRIVE.fingerprint}
    for section, keys in SECTIONS.items():
        for key in keys:
            if section == "protocol":
                content: dict[str, float] = protocol[key]
            elif key == "pole_pairs":
                content = {key: 3}
            elif key == "x_m":
                content = {key: 1.80}
            else:
                content = {key: (getattr(REFERENCE_DRIVE, key) or 200.0) * 1.01}
            seen.add(DriveDescription.from_mapping({section: content}).fingerprint)
    assert len(seen) == 1 + sum(len(k) for k in SECTIONS.values())


def test_base_torque_and_power_set_the_time_constants() -> None:
    by_torque = DriveDescription(base_torque=100.0)
    assert by_torque.tm_per_j == pytest.approx(const.OMEGA_B / 100.0)
    t1 = by_torque.plant().T1
    assert t1 == pytest.approx(const.J1_NOMINAL * const.OMEGA_B / 100.0)
    by_power = DriveDescription(base_power=100.0 * const.OMEGA_B)
    assert by_power.tm_per_j == pytest.approx(by_torque.tm_per_j)
    assert REFERENCE_DRIVE.torque_base == pytest.approx(const.OMEGA_B / const.TM_PER_J)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"mechanics": {"J1": -1.0}}, "mechanics.J1 = -1.0 must be positive"),
        ({"mechanics": {"d2": -0.1}}, "mechanics.d2 = -0.1 must be >= 0"),
        ({"mechanics": {"k12": float("nan")}}, "mechanics.k12 must be finite"),
        ({"mechanics": {"r": "0.1"}}, "mechanics.r must be a number"),
        ({"motor": {"x_m": 1.92}}, "leakages x_s - x_m and x_r - x_m must be positive"),
        ({"motor": {"pole_pairs": 2.5}}, "motor.pole_pairs must be a whole number"),
        ({"motor": {"pole_pairs": 0}}, "motor.pole_pairs = 0 must be positive"),
        ({"supply": {"frequency": 0}}, "supply.frequency = 0.0 must be positive"),
        ({"base": {"base_torque": 100.0, "base_power": 1e4}}, "not both"),
        ({"protocol": {"n_samples": 100}}, "[protocol]"),
        ({"protocol": {"n_samples": 10**9}}, "exceeds the 1000000 samples a record may hold"),
        ({"motor": {"pole_pairs": 10**400}}, "motor.pole_pairs = 1"),
        ({"mechanics": {"J1": 50.0}}, "J1 = 50.0 kg m^2 is outside the accepted range"),
        ({"mechanical": {}}, "unknown section 'mechanical'; known sections: name, supply, motor"),
        ({"mechanics": {"J3": 1.0}}, "unknown key(s) ['J3'] in [mechanics]; known: J1, J2, T3"),
        ({"mechanics": 1.0}, "[mechanics] must be a table"),
    ],
)
def test_impossible_values_are_refused_saying_what_to_fix(data: dict, message: str) -> None:
    with pytest.raises(ParameterError) as err:
        DriveDescription.from_mapping(data)
    assert message in str(err.value)


def test_malformed_files_are_refused_naming_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[motor\nr_s = 1", encoding="utf-8")
    with pytest.raises(ParameterError, match=r"bad\.toml: drive description: malformed TOML"):
        load_drive(bad)
    with pytest.raises(ParameterError, match=r"must end in \.toml or \.json"):
        load_drive(tmp_path / "d.yaml")
    with pytest.raises(ParameterError, match="cannot read drive description"):
        load_drive(tmp_path / "missing.toml")
    with pytest.raises(ParameterError, match="NaN is not a number JSON allows"):
        parse_drive('{"mechanics": {"J1": NaN}}', "json")


def test_plant_carries_the_base_values_into_the_kernel() -> None:
    drive = DriveDescription(frequency=60.0, pole_pairs=3, base_torque=300.0)
    P = parameter_vector(drive.nominal_case())
    from engine.simulation import _kernel as kern

    assert P[kern.P_W_B] == pytest.approx(2 * math.pi * 60)
    assert P[kern.P_OMEGA_B] == pytest.approx(2 * math.pi * 60 / 3)
    assert P[kern.P_T1] == pytest.approx(const.J1_NOMINAL * (2 * math.pi * 20) / 300.0)


def test_plant_refuses_impossible_base_values() -> None:
    with pytest.raises(ParameterError, match=r"pole_pairs = 1\.5 must be a whole number"):
        PlantParameters(pole_pairs=1.5).validate()  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="tm_per_j"):
        PlantParameters(tm_per_j=0.0).validate()


def test_the_documented_example_drive_simulates_a_plausible_record() -> None:
    drive = load_drive(EXAMPLE)
    assert not drive.is_reference
    assert drive.frequency == 60.0 and drive.pole_pairs == 3
    result = simulate_batch([drive.plant()], grid=drive.grid(), solver=drive.solver())
    record = result.record(0)
    assert record.n_samples == drive.n_samples and record.event_index == drive.event_index
    t_e = float(result.event_times[0])
    assert 0.0 < t_e < drive.t_event_max
    m_el, omega1 = record["m_el"], record["omega1"]
    assert np.all(m_el[drive.event_index :] == 0.0)  # switched off at the event
    assert np.max(np.abs(m_el[: drive.event_index])) > 0.0
    # at the event the motor turns far below its synchronous speed Omega_b = 2 pi 60 / 3 rad/s, and the
    # carriage has been set moving (a few tenths of m/s at most at this radius)
    assert abs(omega1[drive.event_index]) < 0.2 * drive.omega_b
    assert 0.01 < np.max(np.abs(record["v2"])) < 1.0
    # and the speed is not the reference drive's: the base values enter
    reference = simulate_batch([PlantParameters()]).record(0)
    assert not np.allclose(reference["omega1"][:100], omega1[:100])


def test_training_inertias_scale_to_the_drive() -> None:
    assert REFERENCE_DRIVE.j1_grid() == const.J1_GRID  # bit for bit: MODEL.md's grid
    grid = DriveDescription(J1=1.74).j1_grid()
    assert grid[0] == 1.74 and grid == pytest.approx([2 * v for v in const.J1_GRID])


def test_training_widths_and_c_groups_scale_to_the_drive() -> None:
    assert REFERENCE_DRIVE.k_grid() == const.K_GRID and REFERENCE_DRIVE.c_groups() == const.C_GROUPS  # bit for bit
    drive = DriveDescription(K=0.004, c=1.05)
    assert drive.k_grid() == pytest.approx([0.8 * v for v in const.K_GRID])
    assert drive.c_groups() == pytest.approx([1.05 * v for v in const.C_GROUPS])
    assert DriveDescription(c=0.0, c1=0.0).c_groups() == const.C_GROUPS  # no absorber: the paper's groups


def test_a_drive_pattern_set_identifies_on_the_drive_widths() -> None:
    """Both identifier kinds train on the drive's scaled widths and answer one of them."""
    from engine.identification.training import identifier_from_pattern_set, simulate_training_grid, train_pattern_set

    drive = DriveDescription(K=0.004, c=1.05)
    grid = simulate_training_grid(1.05, drive.j1_grid()[:2], drive=drive)
    assert sorted({case.plant.K for case in grid.cases}) == pytest.approx(sorted(drive.k_grid()))
    for kind in ("template", "paper"):
        params = {"max_epochs": 200} if kind == "paper" else None
        pattern_set = train_pattern_set("v2", 1.05, kind, drive.j1_grid()[:2], params=params, grid=grid, drive=drive)
        identifier = identifier_from_pattern_set(pattern_set)
        assert list(identifier.widths_) == pytest.approx(list(drive.k_grid())), kind
        x = grid.channel("v2")[3 * 2]  # the fourth width, the nominal J1
        assert identifier.identify(x).width in identifier.widths_
