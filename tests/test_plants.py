"""The plant interface (issue 11): both plants behind it, the EMPS reproduction on the shipped records, the reader.

Reference data: the EMPS benchmark's two records as distributed (``engine/plants/emps/data``,
Janot, Gautier, Brunot, "Data Set and Reference Models of EMPS"); the published figures are the
report's (section 3.5, eq. 11), copied in :data:`PUBLISHED_ERRORS`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from engine.diagnosis.plant_gap import (
    PlantObjective,
    absorbed_effects,
    calibrate,
    correlation_time,
    diagnose_plant,
    fit,
    integrated_time,
    rank_effects,
)
from engine.diagnosis.plant_plausibility import interval_evidence
from engine.plants import Plant, get_plant, relative_error
from engine.plants.backlash_drive import BacklashDrivePlant
from engine.plants.base import retimed_instants
from engine.plants.emps import PUBLISHED, EmpsPlant, EmpsRecord, load_csv, load_mat
from engine.plants.emps.reproduction import PUBLISHED_ERRORS, TOLERANCE, reproduce
from engine.records import Record, RecordError
from engine.simulation import PlantParameters, simulate

DATA = Path(__file__).resolve().parents[1] / "engine" / "plants" / "emps" / "data"


@pytest.fixture(scope="module")
def emps() -> EmpsPlant:
    return EmpsPlant()


@pytest.fixture(scope="module")
def records() -> dict[str, EmpsRecord]:
    return {name: load_mat(DATA / f"{name}.mat") for name in PUBLISHED_ERRORS}


@pytest.fixture(scope="module")
def drive_record() -> Record:
    sim = simulate(PlantParameters(J1=0.9))
    return Record(dict(sim.channels), conditions={"K": PlantParameters().K, "c": 1.0, "c1": 0.2})


def test_both_plants_implement_the_interface_and_their_catalogues_name_their_own_loci() -> None:
    for plant in (get_plant("emps"), get_plant("backlash_drive")):
        assert isinstance(plant, Plant)
        assert plant.catalogue
        for e in plant.catalogue.values():
            assert e.locus in plant.loci, (plant.name, e.name)
            assert e.bounds[0] < e.bounds[1]
        for p in plant.calibrated:
            assert p.lo <= p.nominal <= p.hi, (plant.name, p.name)
    with pytest.raises(KeyError, match="known plants"):
        get_plant("nope")


def test_the_emps_catalogue_holds_the_effects_the_issue_lists(emps: EmpsPlant) -> None:
    assert {
        "coulomb_asymmetry",
        "viscous_asymmetry",
        "stribeck",
        "flexibility",
        "drive_gain",
        "offset_change",
        "position_friction",
        "actuator_delay",
    } <= set(emps.catalogue)


@pytest.mark.parametrize("plant_name", ["emps", "backlash_drive"])
def test_a_plant_simulates_every_channel_on_the_record_grid_and_refuses_unknown_names(
    plant_name: str, emps: EmpsPlant, records: dict[str, EmpsRecord], drive_record: Record
) -> None:
    plant: Plant = emps if plant_name == "emps" else BacklashDrivePlant()
    record = records["DATA_EMPS"] if plant_name == "emps" else drive_record
    measured = plant.measured(record)
    sim = plant.simulate(record, {})
    assert set(sim) == set(measured)
    for name, y in sim.items():
        assert y.shape == measured[name].shape and np.all(np.isfinite(y))
    # every effect moves the simulation away from the nominal one somewhere in its range
    for name, e in plant.catalogue.items():
        ends = [plant.simulate(record, {name: v}) for v in e.bounds if v != e.neutral]
        assert any(not np.allclose(moved[c], sim[c]) for moved in ends for c in sim), name
    with pytest.raises(KeyError):
        plant.simulate(record, {"no_such_parameter": 1.0})


def test_the_backlash_drive_behind_the_interface_recovers_its_inertia(drive_record: Record) -> None:
    plant = BacklashDrivePlant()
    (J1,) = [p for p in plant.calibrated if p.name == "J1"]
    out = fit(plant, drive_record, [J1])  # the record fixes K, c and c1
    assert out.values["J1"] == pytest.approx(0.9, rel=2e-3)


def test_the_generic_diagnosis_names_an_effect_on_the_backlash_drive(drive_record: Record) -> None:
    """The diagnosis of the interface on the other plant: calibrate, where, which, how far.

    Four catalogue effects at four loci keep the test quick; the record is the reference test at
    J1 = 0.9 with a rotor resistance 30 % high and the record's own conditions fixing K, c, c1."""
    plant = BacklashDrivePlant()
    keep = ("rotor_resistance_drift", "load_inertia", "sensor_gain", "measurement_delay")
    plant.catalogue = {n: plant.catalogue[n] for n in keep}  # type: ignore[misc]
    truth = {"J1": 0.9, "rotor_resistance_drift": 1.3}
    record = plant.synthesize(drive_record, truth, np.random.default_rng(3))
    report = diagnose_plant(plant, record)
    answer = report.to_dict(plant)
    assert answer["plant"] == "backlash_drive"
    assert answer["verdict"]["effect"] == "rotor_resistance_drift"
    assert answer["verdict"]["locus"] == "motor_electrical"
    assert answer["verdict"]["value"] == pytest.approx(1.3, abs=0.05)
    assert report.named is not None and report.named.fit.values["J1"] == pytest.approx(0.9, rel=0.02)
    assert set(answer["calibration"]["values"]) == {"J1"}  # the record's conditions fix K, c and c1
    before, after = answer["relative_error"]["before"], answer["relative_error"]["after"]
    assert set(before) == set(plant.measured(record))
    assert max(after.values()) < 0.2 * max(before.values())
    assert answer["where"] and answer["where"][0]["channel"] in before
    # near the event: the backlash test's transient, 5 ms before to 50 ms after t_e (backlash_drive.EVENT_SPAN),
    # of a record from 4.8 ms before to 200 ms after it: 54.8 of 204.8 ms, to within the span's end samples
    assert record.time[0] == pytest.approx(-4.8e-3)
    assert record.n_samples * record.sample_interval == pytest.approx(0.2048)
    assert answer["event_share"]["samples"]["share"] == pytest.approx(54.8 / 204.8, abs=2.0 / record.n_samples)


def test_the_integrated_time_is_one_on_white_noise_and_the_ar1_value_on_correlated_noise() -> None:
    """AR(1) with coefficient phi has tau = (1 + phi) / (1 - phi) (19 for phi = 0.9)."""
    rng = np.random.default_rng(5)
    white = rng.standard_normal(20_000)
    assert integrated_time(white) == pytest.approx(1.0, abs=0.15)
    ar = np.zeros_like(white)
    for i in range(1, ar.size):
        ar[i] = 0.9 * ar[i - 1] + white[i]
    assert integrated_time(ar) == pytest.approx(19.0, rel=0.2)
    assert correlation_time([white, 3.0 * ar]) > 0.9 * integrated_time(ar)  # weighted by energy


def test_every_plant_ships_an_example_record_it_can_simulate() -> None:
    for name in ("backlash_drive", "emps"):
        plant = get_plant(name)
        assert plant.examples
        record = plant.example(seconds=2.0)
        sim = plant.simulate(record, {})
        assert set(sim) == {c.name for c in plant.channels}
        with pytest.raises(KeyError):
            plant.example("no_such_record")


#: Our position errors [%] as docs/emps.md records them ("The published errors, reproduced", the row
#: "ours", commit 5dd8218): several times below the published ones (reproduction's module docstring).
RECORDED_POSITION_ERRORS = {"DATA_EMPS": 0.0016, "DATA_EMPS_PULSES": 0.0026}


@pytest.mark.parametrize("name", list(PUBLISHED_ERRORS))
def test_the_published_rigid_model_reproduces_the_published_errors(
    name: str, emps: EmpsPlant, records: dict[str, EmpsRecord]
) -> None:
    ours = reproduce(emps, records[name])
    for channel, published in PUBLISHED_ERRORS[name].items():
        if channel == "position":
            # below the published figure (see reproduction.TOLERANCE: the solvers differ at the 10 um level),
            # and the figure docs/emps.md records, within the same tolerance: not zero, not any value below
            assert ours[channel] < published, (channel, ours[channel], published)
            recorded = RECORDED_POSITION_ERRORS[name]
            assert ours[channel] == pytest.approx(recorded, rel=TOLERANCE), (channel, ours[channel], recorded)
        else:
            assert ours[channel] == pytest.approx(published, rel=TOLERANCE), (channel, ours[channel], published)


def test_calibration_on_the_estimation_record_improves_on_the_published_parameters(
    emps: EmpsPlant, records: dict[str, EmpsRecord]
) -> None:
    """Our calibration minimises the simulation error, the authors' IDIM-LS an equation error: they
    need not agree, but ours must fit the record at least as well, and the mass (the best
    excited parameter) must agree closely."""
    rec = records["DATA_EMPS"]
    obj = PlantObjective(emps, rec)
    cal = calibrate(emps, rec, objective=obj)
    published = obj.vector(PUBLISHED)
    assert cal.cost < float(published @ published)
    assert cal.values["M"] == pytest.approx(PUBLISHED["M"], rel=0.02)
    for k, v in PUBLISHED.items():
        assert cal.values[k] == pytest.approx(v, rel=0.2, abs=1.0), k


def test_the_diagnosis_names_a_known_effect_on_a_synthetic_emps_record(
    emps: EmpsPlant, records: dict[str, EmpsRecord]
) -> None:
    """A record of the EMPS plant itself with viscous asymmetry: it must be the named effect."""
    real = records["DATA_EMPS"]
    n = 6000  # the first 6 s keep the test quick
    short = dataclasses.replace(
        real, t=real.t[:n], qm=real.qm[:n], qg=real.qg[:n], vir=real.vir[:n], pulses=real.pulses[:n]
    )
    truth = {**PUBLISHED, "viscous_asymmetry": 30.0}
    x = emps.states(short, truth)
    synthetic = dataclasses.replace(short, qm=x["position"], vir=x["force"] / short.gtau)
    obj = PlantObjective(emps, synthetic)
    cal = calibrate(emps, synthetic, objective=obj)
    # a drive gain error is the calibration scaled by 1 / (1 + eps); a Coulomb asymmetry and an offset
    # change are constant forces while moving: a refitted calibration absorbs all three
    absorbed = absorbed_effects(emps, cal, obj)
    assert set(absorbed) == {"drive_gain", "offset_change", "coulomb_asymmetry"}
    _, named = rank_effects(emps, synthetic, cal, objective=obj, absorbed=absorbed)
    assert named is not None and named.effects[0] == "viscous_asymmetry"
    assert named.fit.values["viscous_asymmetry"] == pytest.approx(30.0, rel=0.05)
    assert named.share > 0.9


def test_relative_error_is_the_authors_eq_11_and_refuses_a_zero_signal() -> None:
    y = np.array([3.0, 4.0])
    assert relative_error(y, np.array([3.0, 3.0])) == pytest.approx(20.0)
    with pytest.raises(ValueError, match="zero"):
        relative_error(np.zeros(3), np.ones(3))


# -- the reader ------------------------------------------------------------------------


def _csv(record: EmpsRecord, gains: bool = True, columns: str = "t,qm,qg,vir,pulses_N") -> str:
    head = f"# kp = {record.kp!r}\n# kv = {record.kv!r}\n# gtau = {record.gtau!r}\n" if gains else ""
    rows = np.column_stack([record.t, record.qm, record.qg, record.vir, record.pulses])
    return head + columns + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in rows)


def test_the_csv_form_reads_the_same_record_as_the_mat_file(records: dict[str, EmpsRecord]) -> None:
    mat = records["DATA_EMPS_PULSES"]
    csv = load_csv(_csv(mat).encode(), name="pulses.csv")
    for field in ("t", "qm", "qg", "vir", "pulses"):
        np.testing.assert_array_equal(getattr(csv, field), getattr(mat, field))
    assert (csv.kp, csv.kv, csv.gtau) == (mat.kp, mat.kv, mat.gtau)
    assert csv.has_pulses and not records["DATA_EMPS"].has_pulses


def test_a_record_that_cannot_be_read_correctly_is_refused_with_what_to_fix(records: dict[str, EmpsRecord]) -> None:
    rec = records["DATA_EMPS"]
    with pytest.raises(RecordError, match="missing gain"):
        load_csv(_csv(rec, gains=False).encode())
    with pytest.raises(RecordError, match="unknown column"):
        load_csv(_csv(rec, columns="t,qm,qg,volts,pulses_N").encode())
    text = _csv(rec).replace("\n0.002", "\n0.0035", 1)
    with pytest.raises(RecordError, match="not uniform"):
        load_csv(text.encode())
    lines = _csv(rec).splitlines()
    lines[10] = lines[10].split(",", 1)[0] + ",nan," + lines[10].split(",", 2)[2]
    with pytest.raises(RecordError, match="not finite"):
        load_csv("\n".join(lines).encode())
    with pytest.raises(RecordError, match="not a readable MATLAB"):
        load_mat(b"this is not a mat file")
    with pytest.raises(RecordError, match=r"\.mat file"):
        EmpsPlant().read("record.txt")


def test_the_gap_budget_splits_a_set_share_along_the_forward_selection() -> None:
    from engine.diagnosis.plant_gap import EffectFit, Fit, gap_budget

    f = Fit({}, (), 0.0, {}, 0)
    pair = EffectFit(("a", "b"), f, 0.45, ("guide", "guide"), (0.30, 0.45))
    assert gap_budget(pair) == pytest.approx({"a": 0.30, "b": 0.15})
    assert sum(gap_budget(pair).values()) == pytest.approx(pair.share)


def test_the_synthetic_check_draws_visible_effects_and_keeps_the_truth_apart(records: dict[str, EmpsRecord]) -> None:
    from engine.plants.emps.model import ENCODER_QUANTUM
    from engine.validation.plant_check import MIN_EFFECT, CheckRow, draw_cases, summary

    plant = EmpsPlant()
    head = records["DATA_EMPS_PULSES"].head(3.0)
    assert head.n == 3001 and head.has_pulses
    cases = draw_cases(plant, head, 4, seed=3)
    assert cases == draw_cases(plant, head, 4, seed=3)  # reproducible from its seed
    assert len({c.effect for c in cases}) == len(cases)  # the catalogue in turn
    for c in cases:
        assert c.strength >= MIN_EFFECT
        lo, hi = plant.catalogue[c.effect].bounds
        assert lo <= c.value <= hi
    synthetic = plant.synthesize(
        head, {**cases[0].calibration, cases[0].effect: cases[0].value}, np.random.default_rng(0)
    )
    np.testing.assert_array_equal(synthetic.t, head.t)
    np.testing.assert_array_equal(synthetic.pulses, head.pulses)
    steps = np.diff(synthetic.qm) / ENCODER_QUANTUM  # read by the encoder: whole counts
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    row = CheckRow(cases[0], (cases[0].effect,), cases[0].value, "explained", 0.95, 1.0)
    assert row.top1 and row.found and "1/1 = 100 %" in summary([row])


def test_each_plant_reads_a_record_at_another_interval_or_says_why_not(
    emps: EmpsPlant, records: dict[str, EmpsRecord], drive_record: Record
) -> None:
    """Plant.retimed, which the sample-interval check reads: the drive's record at 10x its interval is its
    samples on the longer grid, an interval outside the accepted range is refused, and an EMPS record (the
    controller's grid only) is never re-read, so the check has nothing to compare there."""
    drive = BacklashDrivePlant()
    slow = drive.retimed(drive_record, 10.0)
    assert slow.sample_interval == pytest.approx(10 * drive_record.sample_interval)
    assert np.array_equal(slow["a1"], drive_record["a1"])
    with pytest.raises(ValueError):
        drive.retimed(drive_record, 1e3)
    record = next(iter(records.values())).head(2.0)
    with pytest.raises(ValueError, match="1 ms grid"):
        emps.retimed(record, 0.1)
    assert interval_evidence(emps, record, [{}], emps.noise(record)) == (0.0, 1.0)


def test_a_record_is_re_read_only_at_a_positive_interval_factor() -> None:
    """retimed_instants, behind every plant's retimed: the first instant kept, a factor <= 0 or not finite refused."""
    t = np.array([2.0, 2.5, 3.0])
    assert np.array_equal(retimed_instants(t, 10.0), [2.0, 7.0, 12.0])
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="positive number"):
            retimed_instants(t, bad)
