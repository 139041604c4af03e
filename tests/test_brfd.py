"""The BRFD friction damper as the third plant (issue 15): reader, model, width, diagnosis.

Reference data: three records of the BRFD data set as distributed (``engine/plants/brfd/data``;
Coble, Huggins, Cao, Ricles, Downey, "Dataset-Friction-Damper-with-Backlash", ARTS Lab 2022,
CC BY-SA 4.0).
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

from engine.diagnosis.plant_gap import PlantObjective, calibrate, diagnose_plant, fit
from engine.diagnosis.plant_transfer import held_out
from engine.identification.plant_width import fit_width
from engine.plants import Plant, get_plant
from engine.plants.brfd import BrfdPlant, BrfdRecord, load_csv, load_json
from engine.plants.brfd.record import FORCE_UNITS, LENGTH_UNITS, record_from_arrays
from engine.records import RecordError

DATA = Path(__file__).resolve().parents[1] / "engine" / "plants" / "brfd" / "data"
SINE_1HZ = "dataset-2_1Hz30lbtension1amplitude"
SINE_2HZ = "dataset-2_2Hz30lbtension0.5amplitude"
QUAKE = "dataset-2_ImperialValleyDBE"


@pytest.fixture(scope="module")
def brfd() -> BrfdPlant:
    return BrfdPlant()


@pytest.fixture(scope="module")
def records(brfd: BrfdPlant) -> dict[str, BrfdRecord]:
    return {name: brfd.example(name) for name in brfd.examples}


def test_the_json_is_read_as_distributed_and_converted_to_si_once(records: dict[str, BrfdRecord]) -> None:
    raw = np.asarray(json.loads(gzip.decompress((DATA / f"{SINE_1HZ}.json.gz").read_bytes()))["data"])
    rec = records[SINE_1HZ]
    assert rec.n == raw.shape[0] and rec.ts == pytest.approx(1 / 1024)
    np.testing.assert_allclose(rec.x, raw[:, 1] * 0.0254)
    np.testing.assert_allclose(rec.force, raw[:, 2] * 4448.2216152605)
    assert 0.025 < rec.x.max() < 0.026  # the 1 in amplitude, in metres
    assert rec.tension == 30.0


def test_the_csv_form_reads_the_same_record(records: dict[str, BrfdRecord]) -> None:
    rec = records[SINE_2HZ]
    lines = ["# displacement units = in", "# friction force units = kip", "time,displacement,friction_force"]
    lines += [
        f"{float(t)!r},{float(x) / LENGTH_UNITS['in']!r},{float(f) / FORCE_UNITS['kip']!r}"
        for t, x, f in zip(rec.t, rec.x, rec.force, strict=True)
    ]
    again = load_csv("\n".join(lines).encode(), name="csv")
    np.testing.assert_allclose(again.x, rec.x, rtol=1e-12)
    np.testing.assert_allclose(again.force, rec.force, rtol=1e-12)


def test_a_record_that_cannot_be_read_correctly_is_refused_with_what_to_fix() -> None:
    obj = json.loads(gzip.decompress((DATA / f"{SINE_2HZ}.json.gz").read_bytes()))
    cases = {
        "displacement units": ({**obj, "displacement units": "furlong"}, "displacement unit"),
        "dt": ({**obj, "dt": 0.002}, "'dt' says"),
        "columns": ({**obj, "data": [row[:2] for row in obj["data"]]}, "at least the columns"),
        "short": ({**obj, "data": obj["data"][:100]}, "at least 1024"),
        "time": ({**obj, "data": [obj["data"][0], *obj["data"][2:]]}, "not uniform"),
        "no units": ({k: v for k, v in obj.items() if k != "displacement units"}, "does not say its 'displacement"),
    }
    for label, (bad, message) in cases.items():
        with pytest.raises(RecordError, match=message):
            load_json(json.dumps(bad).encode(), name=label)
    with pytest.raises(RecordError, match="not valid JSON"):
        load_json(b"{not json", name="broken")
    with pytest.raises(RecordError, match="units"):
        load_csv(b"time,displacement,friction_force\n0,0,0\n", name="no units")


def test_a_record_sampled_too_slowly_for_the_input_filter_is_refused(brfd: BrfdPlant) -> None:
    t = np.arange(2000) / 50.0  # 50 Hz: below twice the 30 Hz input filter
    rec = record_from_arrays(t, 0.01 * np.sin(t), 1e3 * np.sin(t), "slow")
    with pytest.raises(RecordError, match="needs more than 60 Hz"):
        brfd.simulate(rec, {})


def test_the_plant_implements_the_interface_and_every_effect_moves_the_force(
    brfd: BrfdPlant, records: dict[str, BrfdRecord]
) -> None:
    plant: Plant = get_plant("brfd")
    assert isinstance(plant, Plant)
    rec = records[SINE_2HZ]
    sim = plant.simulate(rec, {})
    assert set(sim) == {"force"} and sim["force"].shape == rec.force.shape
    for name, e in plant.catalogue.items():
        assert e.locus in plant.loci
        moved = [plant.simulate(rec, {name: v})["force"] for v in e.bounds if v != e.neutral]
        assert any(not np.allclose(m, sim["force"]) for m in moved), name
    assert plant.events(rec).size == 14  # 3.5 s of a 2 Hz sine: two reversals a period
    with pytest.raises(KeyError):
        plant.simulate(rec, {"no_such_parameter": 1.0})


def test_the_nominal_model_calibrated_on_a_sine_test_follows_its_force(
    brfd: BrfdPlant, records: dict[str, BrfdRecord]
) -> None:
    """The friction level matches the loop's plateau (measured: about +-10 kN at 30 lb, 1 in, 1 Hz)."""
    rec = records[SINE_1HZ]
    obj = PlantObjective(brfd, rec)
    cal = calibrate(brfd, rec, objective=obj)
    plateau = float(np.percentile(np.abs(rec.force[brfd.scored(rec)]), 75))
    assert cal.values["Fc"] == pytest.approx(plateau, rel=0.2)
    error = obj.relative_errors(cal.values)["force"]
    assert error < 30.0 and error < obj.relative_errors({})["force"]


def test_no_force_is_transmitted_inside_the_play(brfd: BrfdPlant, records: dict[str, BrfdRecord]) -> None:
    rec = records[SINE_2HZ]
    values = {"Fc": 8000.0, "sigma0": 4e6, "backlash": 0.004}
    contact = brfd.contact(rec, values)
    force = brfd.simulate(rec, values)["force"]
    assert 0.02 < float(np.mean(~contact)) < 0.5  # some, not most, of a 0.5 in sine is in the 4 mm play
    assert np.all(force[~contact] == 0.0)
    assert np.all(brfd.contact(rec, {"Fc": 8000.0, "sigma0": 4e6}))  # no play, always in contact


def test_a_synthetic_play_is_recovered_with_the_calibration(brfd: BrfdPlant, records: dict[str, BrfdRecord]) -> None:
    rec = records[SINE_2HZ]
    truth = {"Fc": 9000.0, "sigma0": 3e6, "backlash": 0.004}
    synthetic = brfd.synthesize(rec, truth, np.random.default_rng(2))
    obj = PlantObjective(brfd, synthetic)
    cal = calibrate(brfd, synthetic, objective=obj)
    b = brfd.catalogue["backlash"].as_parameter()
    out = fit(brfd, synthetic, [b, *brfd.calibrated], start={**cal.values, "backlash": 0.002}, objective=obj)
    assert out.values["backlash"] == pytest.approx(0.004, abs=max(3 * out.uncertainty["backlash"], 2e-4))
    assert out.values["sigma0"] == pytest.approx(3e6, rel=0.1)


def test_the_diagnosis_of_a_real_sine_test_names_the_play_first(
    brfd: BrfdPlant, records: dict[str, BrfdRecord]
) -> None:
    """Measured on the shipped 1 Hz test: the play closes the largest share of the nominal model's gap."""
    answer = diagnose_plant(brfd, records[SINE_1HZ]).to_dict(brfd)
    assert answer["verdict"]["effect"] == "backlash" and answer["verdict"]["locus"] == "linkage"
    width = answer["verdict"]["effects"][0]
    assert width["unit"] == "m" and width["value"] > 0.0 and width["uncertainty"] < width["value"] / 3
    assert answer["relative_error"]["after"]["force"] < answer["relative_error"]["before"]["force"]


def test_the_width_is_the_same_on_two_sine_tests_within_their_uncertainties(
    brfd: BrfdPlant, records: dict[str, BrfdRecord]
) -> None:
    """One device, one play: the 1 Hz / 1 in and the 2 Hz / 0.5 in tests, each fitted alone."""
    widths = []
    for name in (SINE_1HZ, SINE_2HZ):
        rec = records[name]
        obj = PlantObjective(brfd, rec)
        cal = calibrate(brfd, rec, objective=obj)
        b = brfd.catalogue["backlash"].as_parameter()
        out = fit(brfd, rec, [b, *brfd.calibrated], start={**cal.values, "backlash": 0.003}, objective=obj)
        widths.append((out.values["backlash"], out.uncertainty["backlash"]))
    (b1, s1), (b2, s2) = widths
    assert b1 > 3 * s1 and b2 > 3 * s2  # identifiable on each
    assert abs(b1 - b2) <= 2 * np.hypot(s1, s2), widths


def test_a_synthetic_play_is_identified_with_an_interval_that_holds_it(
    brfd: BrfdPlant, records: dict[str, BrfdRecord]
) -> None:
    synthetic = brfd.synthesize(
        records[SINE_2HZ], {"Fc": 9000.0, "sigma0": 3e6, "backlash": 0.003}, np.random.default_rng(4)
    )
    width = fit_width(brfd, [synthetic])
    assert width.identifiable, width.reasons
    assert width.interval[0] <= 0.003 <= width.interval[1]
    assert abs(width.K - 0.003) <= 3 * width.sigma_K
    answer = width.to_dict()
    assert answer["K"] == width.K and set(answer["correlation_with_K"]) == {"Fc", "sigma0"}


def test_a_width_the_data_cannot_fix_is_reported_not_identifiable_with_the_reason(
    brfd: BrfdPlant, records: dict[str, BrfdRecord]
) -> None:
    """Measured on the shipped earthquake record: the model error leaves the play's profile flat."""
    width = fit_width(brfd, [records[QUAKE].head(10.0)])
    assert not width.identifiable and width.reasons
    answer = width.to_dict()
    assert answer["K"] is None and answer["sigma_K"] is None and answer["best_fit_K"] == width.K


def test_two_records_fitted_jointly_share_one_width(brfd: BrfdPlant, records: dict[str, BrfdRecord]) -> None:
    width = fit_width(brfd, [records[SINE_1HZ], records[SINE_2HZ]])
    assert len(width.fitted) == 2 and set(width.correlation) == {"Fc[0]", "sigma0[0]", "Fc[1]", "sigma0[1]"}
    assert width.identifiable and width.interval[1] - width.interval[0] <= 0.004


def test_a_held_out_prediction_reports_the_nominal_and_the_named_model_on_records_not_fitted(
    brfd: BrfdPlant, records: dict[str, BrfdRecord]
) -> None:
    """Fit on the 1 Hz / 30 lb test, predict the 2 Hz / 30 lb test (the first 2 s of each keep it quick)."""
    train, test = [records[SINE_1HZ].head(2.0)], [records[SINE_2HZ].head(2.0)]
    out = held_out(brfd, train, test, ["backlash"])
    (name,) = out.relative_error
    row = out.relative_error[name]
    assert set(row) == {"nominal", "with_effects", "own_calibration"}
    assert set(out.nominal) == {"Fc", "sigma0"} and set(out.with_effects) == {"Fc", "sigma0", "backlash"}
    assert row["with_effects"]["force"] < row["nominal"]["force"]  # measured: the play carries over
    with pytest.raises(KeyError, match="no effect"):
        held_out(brfd, train, test, ["warp_drive"])
