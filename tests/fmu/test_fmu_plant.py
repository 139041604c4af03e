"""A plant from an FMU and its description (engine/plants/fmu): description, record, generic effects, diagnosis.

The worked example is the quarter car of ``engine/plants/fmu/examples/quarter_car`` (its FMU built from C
in pytest's temporary folder). The end-to-end case diagnoses a synthetic record with one catalogue effect
through the CLI, as a user would (``backlash diagnose record.csv --plant plant.toml``).
"""

from __future__ import annotations

import json
import shutil
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from engine.plants import get_plant, is_description
from engine.plants.base import Plant
from engine.plants.fmu import EXAMPLES_DIR, DescriptionError, FmuPlant, FmuSimulationError
from engine.plants.fmu.build import FmuBuildError, build_fmu, source_digest
from engine.plants.fmu.description import parse_description
from engine.plants.fmu.generic import apply_actuators, apply_sensors, generic_effects
from engine.plants.fmu.record import load_record
from engine.records import RecordError

QUARTER_CAR = EXAMPLES_DIR / "quarter_car"
DESCRIPTION = QUARTER_CAR / "plant.toml"


def _document() -> dict[str, Any]:
    return tomllib.loads(DESCRIPTION.read_text())


@pytest.fixture(scope="module")
def build_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fmu-build")


@pytest.fixture(scope="module")
def plant(build_dir: Path) -> FmuPlant:
    return FmuPlant(parse_description(_document()), QUARTER_CAR, build_dir, processes=1)


def _plant(build_dir: Path, **changes: Any) -> FmuPlant:
    doc = _document()
    doc.update(changes)
    return FmuPlant(parse_description(doc), QUARTER_CAR, build_dir, processes=1)


# --- build -----------------------------------------------------------------------------------------------


def test_build_is_cached_by_the_sources_digest(build_dir: Path, tmp_path: Path) -> None:
    first = build_fmu(QUARTER_CAR, build_dir)
    assert build_fmu(QUARTER_CAR, build_dir) == first  # the same sources: the same file, not rebuilt
    copy = tmp_path / "qc"
    shutil.copytree(QUARTER_CAR, copy)
    source = copy / "sources" / "model.c"
    source.write_text(source.read_text() + "\n/* changed */\n")
    assert source_digest(copy) != source_digest(QUARTER_CAR)
    assert build_fmu(copy, build_dir) != first


def test_build_refuses_a_folder_that_is_no_source_fmu(tmp_path: Path) -> None:
    with pytest.raises(FmuBuildError, match=r"modelDescription\.xml and a sources/ folder"):
        build_fmu(tmp_path, tmp_path / "out")


def test_build_reports_the_compiler_error(tmp_path: Path) -> None:
    copy = tmp_path / "qc"
    shutil.copytree(QUARTER_CAR, copy)
    (copy / "sources" / "model.c").write_text("this is not C\n")
    with pytest.raises(FmuBuildError, match="failed"):
        build_fmu(copy, tmp_path / "out")


# --- description ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"colour": "red"}, "colour: Extra inputs are not permitted"),
        ({"loci": ["body", "body"]}, "loci named twice"),
        ({"loci": ["body", "sensors"]}, "generic effects' loci"),
        ({"calibrated": [{"name": "m_s", "nominal": 900.0, "lo": 200.0, "hi": 500.0}]}, "outside"),
        ({"effects": [{"name": "x", "neutral": 0.0, "bounds": [0.0, 1.0], "locus": "roof"}]}, "locus 'roof'"),
        ({"channels": []}, "at least 1"),
    ],
)
def test_description_refuses_what_it_cannot_use(change: dict[str, Any], message: str) -> None:
    doc = _document()
    doc.update(change)
    with pytest.raises(DescriptionError, match=message):
        parse_description(doc)


def test_description_names_a_variable_the_fmu_lacks_or_has_otherwise(build_dir: Path) -> None:
    doc = _document()
    doc["effects"] = [
        *doc["effects"],
        {"name": "roll", "variable": "phi", "neutral": 0.0, "bounds": [0, 1], "locus": "body"},
    ]
    with pytest.raises(DescriptionError, match="no parameter variable 'phi'"):
        FmuPlant(parse_description(doc), QUARTER_CAR, build_dir)
    doc = _document()
    doc["channels"][0] = {**doc["channels"][0], "variable": "m_s"}
    with pytest.raises(DescriptionError, match="is a parameter, not a output"):
        FmuPlant(parse_description(doc), QUARTER_CAR, build_dir)
    doc = _document()
    doc["channels"][0] = {**doc["channels"][0], "unit": "g"}
    with pytest.raises(DescriptionError, match="the FMU declares 'm/s2'"):
        FmuPlant(parse_description(doc), QUARTER_CAR, build_dir)


def test_a_toml_path_is_a_plant_of_the_registry() -> None:
    assert is_description(str(DESCRIPTION)) and not is_description("emps")
    plant = get_plant(str(DESCRIPTION))
    assert isinstance(plant, Plant)
    assert plant.name == "quarter_car"
    assert plant.loci == ("body", "suspension", "wheel", "rig", "sensors", "actuators")
    # the description's effects and the generic ones, each at a declared locus
    assert {"damper_friction", "a_body_gain", "x_susp_delay", "z_road_saturation"} <= set(plant.catalogue)
    assert all(e.locus in plant.loci for e in plant.catalogue.values())
    assert set(plant.entries) == {"z_r", "F_body", "F_wheel"}


# --- records --------------------------------------------------------------------------------------------


def test_the_example_record_is_reproduced_to_its_noise(plant: FmuPlant) -> None:
    record = plant.example()
    sim, meas, noise = plant.simulate(record, {}), plant.measured(record), plant.noise(record)
    for name in meas:
        rms = float(np.sqrt(np.mean((sim[name] - meas[name]) ** 2)))
        assert 0.8 < rms / noise[name].sigma < 1.25, name  # white noise only: the model is the record's


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda lines: [lines[0].replace("x_susp", "x_spring"), *lines[1:]], r"lacks the column\(s\) \['x_susp'\]"),
        (
            lambda lines: [lines[0], lines[1].replace(lines[1].split(",")[2], "nan", 1), *lines[2:]],
            "not finite at row 1",
        ),
        (lambda lines: [lines[0], lines[2], lines[1], *lines[3:]], "time does not increase"),
        (lambda lines: [lines[0].replace("a_body", "a_body [g]"), *lines[1:]], "is in 'g'"),
        (lambda lines: [lines[0], "1,2,x,4,5", *lines[2:]], "cannot be read as numbers"),
    ],
)
def test_a_record_the_plant_cannot_read_is_refused(plant: FmuPlant, tmp_path: Path, edit: Any, message: str) -> None:
    lines = (QUARTER_CAR / "record.csv").read_text().splitlines()
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(edit(lines)) + "\n")
    with pytest.raises(RecordError, match=message):
        load_record(bad, plant.description)


def test_a_header_with_the_descriptions_units_is_read(plant: FmuPlant, tmp_path: Path) -> None:
    lines = (QUARTER_CAR / "record.csv").read_text().splitlines()
    lines[0] = "t [s],z_road [m],a_body [m/s2],x_susp [m],a_wheel [m/s2]"
    good = tmp_path / "units.csv"
    good.write_text("\n".join(lines) + "\n")
    assert np.array_equal(load_record(good, plant.description).columns["a_body"], plant.example().columns["a_body"])


# --- generic effects ------------------------------------------------------------------------------------


def test_generic_sensor_and_actuator_effects_do_what_they_say(plant: FmuPlant) -> None:
    effects = generic_effects(plant.description)
    t = np.arange(0.0, 1.0, 1e-3)
    y = {"a_body": np.sin(2 * np.pi * 5 * t)}
    gain = apply_sensors(effects, {"a_body_gain": 1.1, "a_body_offset": 0.5}, t, y)["a_body"]
    assert np.allclose(gain, 1.1 * y["a_body"] + 0.5)
    delayed = apply_sensors(effects, {"a_body_delay": 0.002}, t, y)["a_body"]
    assert np.allclose(delayed[10:], y["a_body"][8:-2])
    q = apply_sensors(effects, {"a_body_quantisation": 0.2}, t, y)["a_body"]
    assert np.allclose(q / 0.2, np.round(q / 0.2)) and np.max(np.abs(q - y["a_body"])) <= 0.1 + 1e-12
    lagged = apply_sensors(effects, {"a_body_lag": 0.01}, t, y)["a_body"]  # 5 Hz through a 16 Hz pole
    assert 0.9 < np.ptp(lagged[200:]) / np.ptp(y["a_body"][200:]) < 0.97
    u = {"z_road": np.linspace(-1.0, 1.0, t.size)}
    sat = apply_actuators(effects, {"z_road_saturation": 0.25}, t, u)["z_road"]
    assert sat.min() == pytest.approx(-0.75) and sat.max() == pytest.approx(0.75)
    assert apply_sensors(effects, {}, t, y) is y  # neutral values change nothing


def test_an_entry_adds_to_the_fmu_input_and_unknown_names_are_refused(plant: FmuPlant) -> None:
    record = plant.example()
    push = np.where(record.t > 1.0, 200.0, 0.0)
    moved = plant.simulate(record, {}, {"F_body": push})["x_susp"]
    still = plant.simulate(record, {})["x_susp"]
    assert np.allclose(moved[record.t < 1.0], still[record.t < 1.0])
    assert np.max(np.abs(moved - still)) > 0.005  # 200 N on 20 kN/m: 10 mm of static deflection
    with pytest.raises(KeyError, match="unknown parameter"):
        plant.simulate(record, {"k_roll": 1.0})
    with pytest.raises(KeyError, match="unknown quarter_car entry"):
        plant.simulate(record, {}, {"F_roof": push})


def test_a_refusal_of_the_fmu_raises_with_its_message(plant: FmuPlant) -> None:
    with pytest.raises(FmuSimulationError, match="m_s"):
        plant.simulate(plant.example(), {"m_s": -1.0})


def test_the_calibration_start_is_the_best_of_a_global_search(build_dir: Path) -> None:
    searched = _plant(build_dir, calibration_search=32)
    record = searched.synthesize(searched.example(), {"m_s": 420.0, "c_s": 2600.0}, np.random.default_rng(3))
    start = searched.calibration_start(record)
    assert start is not None and abs(start["m_s"] - 420.0) < abs(300.0 - 420.0)
    assert _plant(build_dir).calibration_start(record) is None  # 0 points: the nominal values


def test_simulations_on_worker_processes_are_those_of_this_process(build_dir: Path) -> None:
    """The pool (engine/plants/fmu/pool.py) changes where a simulation runs, not what it gives."""
    here, pooled = _plant(build_dir), FmuPlant(parse_description(_document()), QUARTER_CAR, build_dir, processes=2)
    assert pooled.concurrent and not FmuPlant(parse_description(_document()), QUARTER_CAR, build_dir, 1).concurrent
    record = here.example()
    values, push = {"damper_friction": 40.0, "a_body_lag": 1e-3}, {"F_wheel": np.full(record.n, 50.0)}
    a, b = here.simulate(record, values, push), pooled.simulate(record, values, push)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    with pytest.raises(FmuSimulationError, match="m_s"):  # the worker's refusal, with the FMU's words
        pooled.simulate(record, {"m_s": -1.0})


# --- the whole diagnosis, as a user runs it -------------------------------------------------------------


def test_cli_diagnoses_an_fmu_plants_record(plant: FmuPlant, tmp_path: Path, build_dir: Path) -> None:
    """A synthetic rig test with a damper friction: the CLI names it, with its value, at the suspension."""
    from app.cli import main

    record = plant.synthesize(plant.example(), {"damper_friction": 60.0, "m_s": 320.0}, np.random.default_rng(7))
    keep = record.t < 1.2  # the bump and the sweep's first second: enough to show the friction, half the time
    path = tmp_path / "rig.csv"
    names = ["z_road", "a_body", "x_susp", "a_wheel"]
    table = np.column_stack([record.t[keep], *(record.columns[n][keep] for n in names)])
    np.savetxt(path, table, delimiter=",", header="t," + ",".join(names), comments="")
    out = tmp_path / "answer.json"
    assert main(["diagnose", str(path), "--plant", str(DESCRIPTION), "--out", str(out)]) == 0
    answer = json.loads(out.read_text())
    assert answer["plant"] == "quarter_car"
    assert answer["status"] == "explained"
    named = answer["verdict"]["effects"][0]
    assert named["effect"] == "damper_friction" and named["locus"] == "suspension"
    assert abs(named["value"] - 60.0) < 3 * named["uncertainty"] + 1.0
    assert answer["gap"]["after"]["rms_over_noise"] < 1.2
