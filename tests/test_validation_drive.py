"""Blind validation, protocol 2, on a described drive (engine.validation with ``drive``; ``validate --drive``).

The reference drive draws bit for bit the cases it drew before drives were described; a described drive
draws its cases from its own box, with its c1, on its plant and grid; a run remembers its drive and is
resumed only on it; the diagnosis (on Dask workers too) is given the drive; the report names it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from engine.constants import C1_NOMINAL, OPERATING_RANGE, PLAUSIBLE_RANGE
from engine.diagnosis.diagnose import DiagnosisSettings
from engine.diagnosis.space import drive_bounds
from engine.records import PROTOCOL_GRID, Record
from engine.simulation import CATALOGUE, HELD_BACK, Case, EffectLibrary, PlantParameters, simulate_batch
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription, load_drive
from engine.simulation.simulator import DEFAULT_SOLVER
from engine.validation.blind import drive_of_run
from engine.validation.cases import BlindCase, generate_cases
from engine.validation.key import KeyEntry, on_operating_range
from engine.validation.layout import RunLayout
from engine.validation.protocol import C1_CONDITION, OPERATING_BOX, c1_condition, operating_box, operating_range
from engine.validation.report import markdown
from engine.validation.run import _fingerprint, prepare_cases, run_validation

ROOT = Path(__file__).resolve().parents[1]
CONVEYOR = ROOT / "docs" / "examples" / "drive-60hz-conveyor.toml"
ALL_KINDS = {"single": 1, "pair": 1, "triple": 1, "held_back": 1, "clean": 1}


@pytest.fixture(scope="module")
def conveyor() -> DriveDescription:
    return load_drive(CONVEYOR)


def _assert_same_draws(a: tuple[list[BlindCase], list[KeyEntry]], b: tuple[list[BlindCase], list[KeyEntry]]) -> None:
    """Two draws of cases are identical: the records' arrays bit for bit, the grids, conditions and keys."""
    (cases_a, key_a), (cases_b, key_b) = a, b
    assert [c.case_id for c in cases_a] == [c.case_id for c in cases_b]
    for ca, cb in zip(cases_a, cases_b, strict=True):
        ra, rb = ca.record, cb.record
        assert (ra.sample_interval, ra.event_index, dict(ra.conditions)) == (
            rb.sample_interval,
            rb.event_index,
            dict(rb.conditions),
        )
        assert list(ra.channels) == list(rb.channels)
        for ch in ra.channels:
            assert np.array_equal(ra.channels[ch], rb.channels[ch]), (ca.case_id, ch)
    assert key_a == key_b
    assert [k.to_dict() for k in key_a] == [k.to_dict() for k in key_b]


# -- (a) the reference drive draws what it drew before --------------------------------------------


def test_the_reference_drive_is_the_protocol_as_it_was() -> None:
    """Every ingredient of a draw on the reference drive is the pre-drive one, to the bit."""
    assert operating_box(REFERENCE_DRIVE) == OPERATING_BOX == PLAUSIBLE_RANGE
    assert list(operating_box(REFERENCE_DRIVE)) == ["K", "J1", "c"]  # the order the point is drawn in
    assert {k: drive_bounds(REFERENCE_DRIVE)[k] for k in OPERATING_BOX} == OPERATING_BOX
    assert operating_range(REFERENCE_DRIVE) == OPERATING_RANGE
    assert c1_condition(REFERENCE_DRIVE) == C1_CONDITION == C1_NOMINAL
    assert REFERENCE_DRIVE.grid() == PROTOCOL_GRID and REFERENCE_DRIVE.solver() == DEFAULT_SOLVER
    point = {"K": 0.0043, "J1": 0.91, "c": 1.37, "c1": C1_CONDITION}
    assert REFERENCE_DRIVE.plant(**point) == PlantParameters(K=0.0043, J1=0.91, c=1.37, c1=C1_CONDITION)


@pytest.mark.parametrize(("n_cases", "seed", "absorption"), [(10, 3, False), (2, 7, True)])
def test_the_reference_drive_draws_bit_for_bit_the_cases_of_no_drive(n_cases: int, seed: int, absorption: bool) -> None:
    mix = ALL_KINDS if not absorption else {"single": 1, "pair": 1}
    none = generate_cases(n_cases, seed, CATALOGUE, HELD_BACK, mix, absorption)
    reference = generate_cases(n_cases, seed, CATALOGUE, HELD_BACK, mix, absorption, drive=REFERENCE_DRIVE)
    renamed = DriveDescription(name="the same plant, another name")  # a fresh description of the reference
    again = generate_cases(n_cases, seed, CATALOGUE, HELD_BACK, mix, absorption, drive=renamed)
    _assert_same_draws(none, reference)
    _assert_same_draws(none, again)
    for case, k in zip(*none, strict=True):
        assert k.on_box == on_operating_range(k.K, k.J1, k.c)  # the reference range, as before
        assert case.record.grid == PROTOCOL_GRID and case.record.conditions == {"c1": C1_CONDITION}
        assert all(lo <= getattr(k, p) <= hi for p, (lo, hi, _) in OPERATING_BOX.items())
    if absorption:
        assert all(e.strength_refit > 3 for k in none[1] for e in k.effects)


# -- (b) a described drive's cases ----------------------------------------------------------------


def test_a_described_drive_draws_its_cases_on_its_own_plant_box_and_grid(conveyor: DriveDescription) -> None:
    cases, key = generate_cases(10, 4, CATALOGUE, HELD_BACK, ALL_KINDS, absorption=False, drive=conveyor)
    box = operating_box(conveyor)
    assert box == {k: drive_bounds(conveyor)[k] for k in ("K", "J1", "c")} != OPERATING_BOX
    assert box["K"][:2] == pytest.approx((0.0008, 0.012))  # MODEL.md's 1-15 mm times 4 mm / 5 mm
    scaled = operating_range(conveyor)
    assert scaled["J1"][:2] == pytest.approx((0.75 * 0.95 / 0.87, 0.93 * 0.95 / 0.87))
    for case, k in zip(cases, key, strict=True):
        record = case.record
        assert (record.sample_interval, record.event_index) == (5e-5, 96)
        assert all(v.shape == (4096,) for v in record.channels.values())
        assert record.conditions == {"c1": conveyor.c1} and conveyor.c1 != C1_CONDITION
        assert all(lo <= getattr(k, p) <= hi for p, (lo, hi, _) in box.items()), k
        assert k.on_box == on_operating_range(k.K, k.J1, k.c, conveyor)
        again = KeyEntry.from_dict(json.loads(json.dumps(k.to_dict())))
        assert again.on_range is k.on_range is k.on_box  # the drive's range is kept in the key
    # the records are the drive's: a clean case is its plant's simulation plus noise, not the reference's
    clean = next(i for i, k in enumerate(key) if k.kind == "clean")
    k, record = key[clean], cases[clean].record
    point = {"K": k.K, "J1": k.J1, "c": k.c, "c1": conveyor.c1}
    own = simulate_batch([Case(conveyor.plant(**point))], solver=conveyor.solver(), grid=conveyor.grid())
    reference = PlantParameters(K=k.K, J1=k.J1, c=k.c, c1=conveyor.c1)
    other = simulate_batch([Case(reference)], solver=conveyor.solver(), grid=conveyor.grid())
    for ch, data in record.channels.items():
        row = list(("a1", "m_el", "omega1", "a2", "v2")).index(ch)
        scale = float(np.sqrt(np.mean(own.channels[0, row] ** 2)))
        left = float(np.sqrt(np.mean((data - own.channels[0, row]) ** 2)))
        off = float(np.sqrt(np.mean((data - other.channels[0, row]) ** 2)))
        assert left < 0.1 * scale and off > 3 * left, ch  # noise at >= 20 dB SNR; the reference plant is far off


def test_a_described_drive_passes_the_absorption_rule_on_its_own_plant(conveyor: DriveDescription) -> None:
    _, key = generate_cases(1, 3, CATALOGUE, HELD_BACK, {"single": 1}, drive=conveyor)
    assert all(3 < e.strength_refit < float("inf") for e in key[0].effects), key


# -- (c) the manifest: a run is resumed only on its drive ------------------------------------------


def test_a_run_remembers_its_drive_and_refuses_another(tmp_path: Path, conveyor: DriveDescription) -> None:
    mix = {"single": 1, "clean": 1}
    layout = RunLayout(tmp_path / "conveyor")
    assert prepare_cases(layout, 3, 1, mix, CATALOGUE, HELD_BACK, absorption=False, drive=conveyor)
    manifest = layout.read_manifest()
    assert manifest is not None and manifest["drive"] == conveyor.provenance()
    assert layout.read_key()[0]["drive"] == conveyor.provenance()
    assert drive_of_run(layout) == conveyor
    # the same drive (whatever its name) keeps the cases; the reference or another drive is refused
    assert not prepare_cases(layout, 3, 1, mix, CATALOGUE, HELD_BACK, absorption=False, drive=conveyor)
    renamed = DriveDescription.from_mapping({**conveyor.to_dict(), "name": "conveyor 3"})
    assert not prepare_cases(layout, 3, 1, mix, CATALOGUE, HELD_BACK, absorption=False, drive=renamed)
    stamp = layout.case_path("case0000").stat().st_mtime_ns
    heavier = DriveDescription.from_mapping(
        {**conveyor.to_dict(), "mechanics": {**conveyor.to_dict()["mechanics"], "J1": 1.2}}
    )
    for other in (None, REFERENCE_DRIVE, heavier):
        with pytest.raises(
            FileExistsError, match=r"holds a validation run on drive .*60 Hz conveyor.*give the same drive"
        ):
            prepare_cases(layout, 3, 1, mix, CATALOGUE, HELD_BACK, absorption=False, drive=other)
    assert layout.case_path("case0000").stat().st_mtime_ns == stamp
    # a run on the reference holds no drive (its manifest is as before drives) and refuses a described drive
    ref = RunLayout(tmp_path / "reference")
    assert prepare_cases(ref, 3, 1, mix, CATALOGUE, HELD_BACK, absorption=False, drive=REFERENCE_DRIVE)
    held = ref.read_manifest()
    assert held is not None and "drive" not in held and drive_of_run(ref) == REFERENCE_DRIVE
    counts = held["counts"]
    assert held["fingerprint"] == _fingerprint(3, 1, counts, CATALOGUE, HELD_BACK, False)  # the pre-drive hash
    assert held["fingerprint"] == _fingerprint(3, 1, counts, CATALOGUE, HELD_BACK, False, REFERENCE_DRIVE)
    assert held["fingerprint"] != _fingerprint(3, 1, counts, CATALOGUE, HELD_BACK, False, conveyor)
    assert not prepare_cases(ref, 3, 1, mix, CATALOGUE, HELD_BACK, absorption=False)
    with pytest.raises(FileExistsError, match=r"MODEL\.md reference plant.*not on '60 Hz conveyor"):
        prepare_cases(ref, 3, 1, mix, CATALOGUE, HELD_BACK, absorption=False, drive=conveyor)


# -- (d) the diagnosis is given the drive; the report and the CLI ---------------------------------

SEEN: list[str | None] = []


def drive_diagnosis(
    record: Record, library: EffectLibrary, settings: DiagnosisSettings, drive: DriveDescription | None = None
) -> dict[str, Any]:
    """A cheap stand-in of the diagnosis that notes the drive it is given (None: called without one)."""
    SEEN.append(None if drive is None else drive.fingerprint)
    return {"verdict": {"status": "no_gap", "effect": None, "value": None, "effects": [], "locus": None}}


def test_the_diagnosis_is_given_the_drive_and_the_report_names_it(tmp_path: Path, conveyor: DriveDescription) -> None:
    SEEN.clear()
    mix = {"single": 1, "clean": 1}
    doc = run_validation(2, 5, tmp_path / "c", mix=mix, diagnose_fn=drive_diagnosis, absorption=False, drive=conveyor)
    assert [conveyor.fingerprint, conveyor.fingerprint] == SEEN
    assert doc["drive"]["name"] == conveyor.name and doc["drive"]["fingerprint"] == conveyor.fingerprint
    assert doc["drive"]["operating_box"] == {k: list(v) for k, v in operating_box(conveyor).items()}
    md = (tmp_path / "c" / "report.md").read_text()
    assert f"- drive: {conveyor.name}, fingerprint `{conveyor.fingerprint[:12]}`" in md
    assert json.loads((tmp_path / "c" / "report.json").read_text())["drive"] == doc["drive"]
    # the reference: the diagnosis is called as before (no drive), the report names none
    SEEN.clear()
    doc = run_validation(2, 5, tmp_path / "r", mix=mix, diagnose_fn=drive_diagnosis, absorption=False)
    assert SEEN == [None, None] and "drive" not in doc
    assert "- drive:" not in markdown(doc)


def test_cli_validate_refuses_drive_with_protocol_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from app.cli.main import main

    assert main(["validate", "--protocol", "1", "--drive", str(CONVEYOR), "--out", str(tmp_path / "v1")]) == 2
    assert "--drive applies to protocol 2 only" in capsys.readouterr().err
    assert not (tmp_path / "v1").exists()
    bad = tmp_path / "bad.toml"
    bad.write_text("[mechanics]\nJ1 = -1.0\n")
    assert main(["validate", "--drive", str(bad), "--out", str(tmp_path / "bad")]) != 0
    assert "J1" in capsys.readouterr().err and not (tmp_path / "bad").exists()


@pytest.mark.slow  # 37 s: three cases through the real diagnosis
def test_cli_validate_on_a_described_drive_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two cases (one single effect, one clean) of the conveyor through the real diagnosis on a Dask worker.

    The drive must reach the worker: on the reference plant the clean case's records would leave a gap of
    hundreds of noise RMS. Measured (seed 21): the single case (rotor resistance drift x 1.14) is explained by
    that effect at 1.14, the clean case is no_gap (chi2/n 1.01), about 15 s.
    """
    from app.cli.main import main
    from engine.validation.report import case_rows

    out = tmp_path / "run"
    argv = ["validate", "--drive", str(CONVEYOR), "--cases", "2", "--seed", "21", "--mix", "single=1,clean=1"]
    assert main([*argv, "--workers", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    drive = load_drive(CONVEYOR)
    assert f"- drive: {drive.name}, fingerprint `{drive.fingerprint[:12]}`" in printed
    doc = json.loads((out / "report.json").read_text())
    assert doc["drive"]["fingerprint"] == drive.fingerprint and doc["n_cases"] == 2
    rows = {r["kind"]: r for r in case_rows(doc)}
    assert rows["clean"]["status"] == "no_gap" and rows["clean"]["chi2n_before"] < 1.5, rows
    ((truth, _),) = rows["single"]["truth"]
    assert rows["single"]["status"] == "explained" and rows["single"]["effects"][0][0] == truth, rows
    # resumed on the same drive: nothing to do; on the reference plant: refused
    assert main([*argv, "--workers", "0", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["validate", "--cases", "2", "--seed", "21", "--mix", "single=1,clean=1", "--out", str(out)]) == 2
    assert "give the same drive" in capsys.readouterr().err
