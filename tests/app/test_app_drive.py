"""A drive description on the service and the command line: simulate on the user's drive, refuse a bad one."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from app import cli
from engine.simulation.drive import REFERENCE_DRIVE, load_drive

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "drive-60hz-conveyor.toml"


@pytest.fixture(scope="module")
def example() -> dict[str, Any]:
    return load_drive(EXAMPLE).to_dict()


def test_simulate_on_a_described_drive_keeps_its_protocol_and_provenance(
    client: httpx.Client, example: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    r = client.post("/v1/simulate", json={"K": 0.004, "drive": example})
    assert r.status_code == 200, r.text
    rec = r.json()
    drive = load_drive(EXAMPLE)
    assert rec["drive"] == {"fingerprint": drive.fingerprint, "description": example}
    assert rec["sample_interval"] == drive.sample_interval and rec["event_index"] == drive.event_index
    assert all(len(v) == drive.n_samples for v in rec["channels"].values())
    # the drive's nominal J1, c, c1 and its base torque are the record's conditions
    assert rec["conditions"] == {
        "J1": drive.J1,
        "c": drive.c,
        "c1": drive.c1,
        "K": 0.004,
        "base_torque": pytest.approx(drive.torque_base),
    }
    assert rec["channels"]["v2"][:2000] != sim_record["channels"]["v2"][:2000]
    # the empty description is the reference plant: the same samples as without one
    ref = client.post("/v1/simulate", json={"K": 0.005, "drive": {}}).json()
    assert ref["channels"] == sim_record["channels"]
    assert ref["drive"]["fingerprint"] == REFERENCE_DRIVE.fingerprint
    assert "drive" not in sim_record


def test_the_csv_form_names_the_drive_in_a_header(client: httpx.Client, example: dict[str, Any]) -> None:
    r = client.post("/v1/simulate", json={"K": 0.004, "drive": example}, headers={"Accept": "text/csv"})
    assert r.status_code == 200, r.text
    assert r.headers["X-Drive-Fingerprint"] == load_drive(EXAMPLE).fingerprint
    assert r.headers["X-Sample-Interval"] == repr(5e-5) and r.headers["X-Event-Index"] == "96"
    plain = client.post("/v1/simulate", json={"K": 0.004}, headers={"Accept": "text/csv"})
    assert "X-Drive-Fingerprint" not in plain.headers


def test_a_request_span_overrides_the_drive_protocol(client: httpx.Client, example: dict[str, Any]) -> None:
    r = client.post("/v1/simulate/batch", json={"cases": [{"K": 0.003}], "sample_interval": 1e-4, "drive": example})
    assert r.status_code == 200, r.text
    rec = r.json()["data"][0]
    # the request's 0.1 ms instead of the drive's 50 us, over the drive's span: 4.8 ms before, 200 ms from the event
    assert rec["sample_interval"] == 1e-4 and rec["event_index"] == 48
    assert len(rec["channels"]["a1"]) == 48 + 2000
    assert rec["drive"]["description"]["protocol"]["sample_interval"] == 5e-5


@pytest.mark.parametrize(
    ("drive", "message"),
    [
        ({"motor": {"x_m": 2.0, "x_s": 1.9}}, "x_m = 2.0 must be smaller than motor.x_s"),
        ({"mechanics": {"J1": 0.0}}, "mechanics.J1 = 0.0 must be positive"),
        ({"mechanic": {"J1": 1.0}}, "unknown section 'mechanic'"),
    ],
)
def test_a_bad_description_is_refused_with_what_to_fix(client: httpx.Client, drive: dict, message: str) -> None:
    r = client.post("/v1/simulate", json={"K": 0.005, "drive": drive})
    assert r.status_code == 422
    assert message in r.json()["detail"]


def test_omega1_in_pu_is_refused_for_another_drive(client: httpx.Client, example: dict[str, Any]) -> None:
    r = client.post("/v1/simulate", json={"K": 0.004, "drive": example, "units": {"omega1": "pu"}})
    assert r.status_code == 422 and "give omega1 in rad/s or rpm" in r.json()["detail"]


def test_cli_simulate_with_a_drive_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "conveyor.json"
    assert cli.main(["simulate", "--drive", str(EXAMPLE), "--out", str(out)]) == 0
    rec = json.loads(out.read_text("utf-8"))
    drive = load_drive(EXAMPLE)
    assert rec["drive"]["fingerprint"] == drive.fingerprint
    assert rec["conditions"]["K"] == drive.K  # no --K: the drive's nominal width
    assert rec["event_index"] == drive.event_index and len(rec["channels"]["omega1"]) == drive.n_samples
    omega1 = np.array(rec["channels"]["omega1"])
    assert np.all(np.isfinite(omega1)) and np.max(np.abs(omega1)) < drive.omega_b
    assert math.isclose(rec["conditions"]["base_torque"], drive.torque_base)


def test_cli_refuses_a_bad_drive_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[mechanics]\nk12 = -5\n", encoding="utf-8")
    assert cli.main(["simulate", "--drive", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "mechanics.k12 = -5.0 must be positive" in err


def _train(capsys: pytest.CaptureFixture[str], *extra: str) -> dict[str, Any]:
    argv = ["train", "--channel", "v2", "--c", "1.0", "--kind", "paper", "--max-epochs", "200", *extra]
    code = cli.main(argv)
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def test_a_pattern_set_identifies_only_records_of_its_own_drive(
    env: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    drive = load_drive(EXAMPLE)
    own = _train(capsys, "--drive", str(EXAMPLE), "--J1", "0.95", "0.9")
    assert own["params"]["drive"]["fingerprint"] == drive.fingerprint
    reference = _train(capsys, "--J1", "0.87", "0.8482")
    assert "drive" not in reference["params"]
    rec = tmp_path / "conveyor.json"
    assert cli.main(["simulate", "--drive", str(EXAMPLE), "--K", "0.005", "--out", str(rec)]) == 0
    capsys.readouterr()

    # the drive's record with the drive's set: identified, and the answer names the drive
    code = cli.main(["identify", str(rec), "--channel", "v2", "--drive", str(EXAMPLE), "--any-set"])
    out, err = capsys.readouterr()
    assert code == 0, err
    answer = json.loads(out)
    assert answer["pattern_set"] == own["id"] and answer["drive"] == drive.fingerprint
    # its plausibility checks read the drive's own envelopes: its own record is nothing to warn about
    assert answer["warnings"] == []
    # the continuous width is calibrated on the drive's plant and box (K sought; J1, c, c1 from the record)
    code = cli.main(["identify", str(rec), "--channel", "v2", "--drive", str(EXAMPLE), "--any-set", "--continuous"])
    out, err = capsys.readouterr()
    assert code == 0, err
    width = json.loads(out)["continuous"]
    assert width["interval_95"][0] <= 0.005 <= width["interval_95"][1] and width["K"] == pytest.approx(0.005, rel=1e-3)
    # named across drives, either way: refused, saying which drives
    code = cli.main(
        ["identify", str(rec), "--channel", "v2", "--drive", str(EXAMPLE), "--pattern-set", reference["id"]]
    )
    err = capsys.readouterr().err
    assert code == 2 and "a set identifies only records of its own drive" in err and drive.fingerprint[:12] in err
    ref_rec = tmp_path / "reference.json"
    assert cli.main(["simulate", "--K", "0.005", "--out", str(ref_rec)]) == 0
    capsys.readouterr()
    code = cli.main(["identify", str(ref_rec), "--channel", "v2", "--pattern-set", own["id"]])
    assert code == 2 and "trained for drive " + drive.fingerprint[:12] in capsys.readouterr().err
    # the record states its drive in full: without --drive it is identified on that drive, with its set
    code = cli.main(["identify", str(rec), "--channel", "v2", "--any-set"])
    out, err = capsys.readouterr()
    assert code == 0 and "identifying on the drive the record states" in err, err
    assert json.loads(out)["pattern_set"] == own["id"] and json.loads(out)["drive"] == drive.fingerprint
    # ... but a record that states only the fingerprint of another drive is refused for the reference drive
    only = tmp_path / "fingerprint-only.json"
    only.write_text(json.dumps({**json.loads(rec.read_text("utf-8")), "drive": {"fingerprint": drive.fingerprint}}))
    code = cli.main(["identify", str(only), "--channel", "v2", "--any-set"])
    assert code == 2 and "give the record's own drive description with --drive" in capsys.readouterr().err
    # the automatic choice for the reference drive never picks the drive's set
    code = cli.main(["identify", str(ref_rec), "--channel", "v2", "--any-set"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert json.loads(out)["pattern_set"] == reference["id"]
    assert json.loads(out)["warnings"] == []
    # listing by drive
    assert cli.main(["pattern-sets", "list", "--drive", str(EXAMPLE)]) == 0
    assert [s["id"] for s in json.loads(capsys.readouterr().out)["data"]] == [own["id"]]
    assert cli.main(["pattern-sets", "list"]) == 0
    assert len(json.loads(capsys.readouterr().out)["data"]) == 2


def test_diagnosis_runs_on_the_request_drive_and_keeps_it(
    client: httpx.Client, example: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    """A described drive's record is diagnosed on that drive, given in the request or, in full, by the record; one
    that states another drive, only its fingerprint, or an edited description is refused."""
    drive = load_drive(EXAMPLE)
    rec = client.post("/v1/simulate", json={"K": 0.004, "drive": example, "sample_interval": 1e-4}).json()
    record = {k: rec[k] for k in ("sample_interval", "event_index", "channels")}
    record["conditions"] = {k: v for k, v in rec["conditions"].items() if k not in ("K", "J1", "c")}  # K is sought
    r = client.post("/v1/diagnose", json={"record": record, "drive": example, "effects": ["load_inertia"]})
    assert r.status_code == 200, r.text
    answer = r.json()
    assert answer["drive"]["fingerprint"] == drive.fingerprint
    assert answer["verdict"]["status"] == "no_gap" and answer["warnings"] == []
    assert answer["width"]["from"] == "nominal" and answer["width"]["K"] == pytest.approx(0.004, rel=1e-3)
    # bounds are checked against the drive's plant before any work
    r = client.post("/v1/diagnose", json={"record": record, "drive": example, "bounds": {"J1": [0.5, 30.0]}})
    assert r.status_code == 422 and "J1" in r.json()["detail"]
    # a record that states another drive is refused for the reference plant
    reference = {k: sim_record[k] for k in ("sample_interval", "event_index", "channels", "conditions")}
    stated = {**reference, "drive": {"fingerprint": drive.fingerprint}}
    r = client.post("/v1/diagnose", json={"record": stated})
    assert r.status_code == 422 and "the record was made on drive" in r.json()["detail"]
    # a record that states its drive in full is diagnosed on it without a drive in the request
    r = client.post("/v1/diagnose", json={"record": {**record, "drive": rec["drive"]}, "effects": ["load_inertia"]})
    assert r.status_code == 200, r.text
    assert r.json()["drive"]["fingerprint"] == drive.fingerprint
    assert r.json()["width"]["K"] == pytest.approx(answer["width"]["K"], rel=1e-9)
    # ... but not when its description no longer gives its fingerprint
    edited = {**rec["drive"], "description": {**rec["drive"]["description"], "name": "x", "mechanics": {"J2": 9.0}}}
    r = client.post("/v1/diagnose", json={"record": {**record, "drive": edited}, "effects": ["load_inertia"]})
    assert r.status_code == 422 and "was it edited?" in r.json()["detail"], r.text


def test_identify_over_http_compares_the_record_drive(client: httpx.Client, example: dict[str, Any]) -> None:
    rec = client.post("/v1/simulate", json={"K": 0.004, "drive": example}).json()
    body = {k: rec[k] for k in ("sample_interval", "event_index", "channels", "conditions", "drive")}
    only = {**body, "drive": {"fingerprint": rec["drive"]["fingerprint"]}}  # a fingerprint, not the description
    r = client.post("/v1/identify", json={"record": only, "channel": "v2"})
    assert r.status_code == 422 and "give the record's own drive description (drive)" in r.json()["detail"]
    # the description in full: read on its own drive (whose pattern sets this service may not hold)
    r = client.post("/v1/identify", json={"record": body, "channel": "v2"})
    assert r.status_code == 404 and f"drive {rec['drive']['fingerprint'][:12]}" in r.json()["detail"], r.text
    # a speed in pu would be read with MODEL.md's base speed, not this drive's
    in_pu = {**body, "channels": {"omega1": body["channels"]["omega1"]}, "units": {"omega1": "pu"}}
    r = client.post("/v1/identify", json={"record": in_pu, "channel": "omega1", "drive": example})
    assert r.status_code == 422 and "give omega1 in rad/s or rpm" in r.json()["detail"]


def test_cli_diagnose_and_batch_on_a_described_drive(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    records = tmp_path / "records"
    rec = records / "conveyor.json"
    args = ["simulate", "--drive", str(EXAMPLE), "--K", "0.005", "--sample-interval", "1e-4", "--snr-db", "40"]
    assert cli.main([*args, "--seed", "5", "--known", "c1", "--out", str(rec)]) == 0
    capsys.readouterr()
    answer_path = tmp_path / "answer.json"
    code = cli.main(
        ["diagnose", str(rec), "--drive", str(EXAMPLE), "--effects", "load_inertia", "--out", str(answer_path)]
    )
    _, err = capsys.readouterr()
    assert code == 0, err
    answer = json.loads(answer_path.read_text("utf-8"))
    assert answer["drive"]["fingerprint"] == load_drive(EXAMPLE).fingerprint
    assert answer["verdict"]["status"] == "no_gap"
    assert answer["width"]["interval_95"][0] <= 0.005 <= answer["width"]["interval_95"][1]
    # without --drive, the record's own description (a simulated record states it in full)
    assert cli.main(["diagnose", str(rec), "--effects", "load_inertia", "--out", str(tmp_path / "own.json")]) == 0
    assert "diagnosing on the drive the record states" in capsys.readouterr().err
    own = json.loads((tmp_path / "own.json").read_text("utf-8"))
    assert own["drive"] == answer["drive"] and own["width"]["K"] == pytest.approx(answer["width"]["K"], rel=1e-9)
    # the batch: diagnosed on the drive with --drive; refused in the summary without it
    assert (
        cli.main(
            ["diagnose-batch", str(records), "--out", str(tmp_path / "a"), "--workers", "0", "--drive", str(EXAMPLE)]
        )
        == 0
    )
    batch = json.loads((tmp_path / "a" / "conveyor.json").read_text("utf-8"))
    assert batch["drive"]["fingerprint"] == answer["drive"]["fingerprint"]
    assert batch["verdict"]["status"] == "no_gap"
    # without --drive: each record on the drive it states in full; one stating only the fingerprint of a drive,
    # or a description that does not give its fingerprint, is refused in the summary
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    data = json.loads(rec.read_text("utf-8"))
    (mixed / "conveyor.json").write_text(json.dumps(data))
    (mixed / "fingerprint-only.json").write_text(
        json.dumps({**data, "drive": {"fingerprint": data["drive"]["fingerprint"]}})
    )
    description = {**data["drive"]["description"], "mechanics": {"J2": 9.0}}
    (mixed / "edited.json").write_text(json.dumps({**data, "drive": {**data["drive"], "description": description}}))
    assert cli.main(["diagnose-batch", str(mixed), "--out", str(tmp_path / "b"), "--workers", "0"]) == 0
    rows = {r["record"]: r for r in csv.DictReader((tmp_path / "b" / "summary.csv").open(encoding="utf-8"))}
    assert rows["conveyor"]["status"] == batch["verdict"]["status"]
    own_batch = json.loads((tmp_path / "b" / "conveyor.json").read_text("utf-8"))
    assert own_batch["drive"] == batch["drive"] and own_batch["width"] == batch["width"]
    assert rows["fingerprint-only"]["status"] == "refused"
    assert "the record was made on drive" in rows["fingerprint-only"]["detail"]
    assert rows["edited"]["status"] == "refused" and "was it edited?" in rows["edited"]["detail"]


def test_training_over_http_refuses_a_bad_description_before_queueing(client: httpx.Client) -> None:
    r = client.post("/v1/pattern-sets", json={"channel": "v2", "c": 1.0, "drive": {"motor": {"pole_pairs": 0.5}}})
    assert r.status_code == 422 and "motor.pole_pairs must be a whole number" in r.json()["detail"]


def test_an_asset_history_holds_one_drive(tmp_path: Path) -> None:
    """A measurement of another drive than the asset's newest one is refused before it is stored."""
    from datetime import UTC, datetime, timedelta

    from app.db.diagnoses import DiagnosisRepository
    from app.db.identifications import IdentificationRepository
    from app.services.assets import asset_drive, check_asset_drive, store_identification
    from app.services.diagnoses import new_record
    from app.services.diagnosis_requests import DiagnosisRequest
    from app.services.errors import IncompatibleError
    from engine.storage import PatternStore

    store = PatternStore(tmp_path / "assets.sqlite3")
    conveyor = load_drive(EXAMPLE).fingerprint
    day = datetime(2026, 11, 1, tzinfo=UTC)
    assert asset_drive(store, "line-1") is None
    check_asset_drive(store, "line-1", conveyor)  # nothing stored: any drive
    store_identification(store, "line-1", day, "v2", {"drive": conveyor, "width": 0.004})
    assert asset_drive(store, "line-1") == conveyor
    store_identification(store, "line-1", day + timedelta(days=1), "v2", {"drive": conveyor, "width": 0.0041})
    with pytest.raises(IncompatibleError, match="an asset's history is one machine's"):  # a reference identification
        store_identification(store, "line-1", day + timedelta(days=2), "v2", {"drive": REFERENCE_DRIVE.fingerprint})
    assert len(IdentificationRepository(store).newest("line-1", limit=10)) == 2  # nothing stored
    # a diagnosis request of the reference plant for that asset: refused before its record is stored
    v2 = np.sin(np.arange(2048) / 100.0).tolist()
    body = {"record": {"sample_interval": 1e-4, "event_index": 48, "channels": {"v2": v2}, "asset": "line-1"}}
    with pytest.raises(IncompatibleError, match="holds measurements of drive"):
        new_record(store, DiagnosisRequest("json", json.dumps(body).encode()))
    assert DiagnosisRepository(store).newest("line-1", limit=5) == []
    # another asset is free
    check_asset_drive(store, "line-2", REFERENCE_DRIVE.fingerprint)


def test_an_asset_history_holds_one_plant(tmp_path: Path) -> None:
    """An asset measured on another plant (EMPS, the BRFD, an uploaded plant) is not the backlash drive's: a
    drive's record for it is refused, and another plant's for a drive's asset, each naming both machines."""
    from app.db.diagnoses import DiagnosisRepository
    from app.db.records import RecordRepository
    from app.services.assets import asset_drive, check_asset_drive, machine_key
    from app.services.diagnoses import new_record
    from app.services.diagnosis_requests import DiagnosisRequest
    from app.services.errors import IncompatibleError
    from engine.storage import PatternStore

    store = PatternStore(tmp_path / "plants.sqlite3")
    DiagnosisRepository(store).create(job_id="j1", record_id="r1", plant="emps", asset="axis-1", measured_at=None)
    assert asset_drive(store, "axis-1") == machine_key("emps") == "plant:emps"
    v2 = np.sin(np.arange(2048) / 100.0).tolist()
    body = {"record": {"sample_interval": 1e-4, "event_index": 48, "channels": {"v2": v2}, "asset": "axis-1"}}
    with pytest.raises(IncompatibleError, match="holds measurements of plant emps, and this one is of drive "):
        new_record(store, DiagnosisRequest("json", json.dumps(body).encode()))
    check_asset_drive(store, "axis-1", machine_key("emps"))  # the same plant again is taken
    with pytest.raises(IncompatibleError, match="of plant emps, and this one is of plant fmu-0123456789abcdef"):
        check_asset_drive(store, "axis-1", machine_key("fmu-0123456789abcdef"))
    body["record"]["asset"] = "line-9"  # a drive's asset (queued, as submit() stores it): another plant's refused
    queued = new_record(store, DiagnosisRequest("json", json.dumps(body).encode()))
    with store.writing() as conn:
        RecordRepository.insert(conn, queued)
    DiagnosisRepository(store).create(
        job_id="j2", record_id=queued.record.id, plant="backlash_drive", asset="line-9", measured_at=None
    )
    assert asset_drive(store, "line-9") == machine_key("backlash_drive") == REFERENCE_DRIVE.fingerprint
    with pytest.raises(IncompatibleError, match=r"holds measurements of drive \w{12}, and this one is of plant brfd"):
        check_asset_drive(store, "line-9", machine_key("brfd"))


def test_a_diagnosis_on_a_drive_refuses_omega1_in_pu(client: httpx.Client, example: dict[str, Any]) -> None:
    """omega1 in pu would be read with MODEL.md's base speed, not the drive's: refused before any work."""
    rec = client.post("/v1/simulate", json={"K": 0.004, "drive": example, "sample_interval": 1e-4}).json()
    record = {"sample_interval": 1e-4, "event_index": rec["event_index"], "units": {"omega1": "pu"}}
    record["channels"] = {"omega1": rec["channels"]["omega1"]}
    r = client.post("/v1/diagnose", json={"record": record, "drive": example})
    assert r.status_code == 422 and "give omega1 in rad/s or rpm" in r.json()["detail"]


def test_a_queued_diagnosis_already_holds_its_assets_drive(tmp_path: Path, example: dict[str, Any]) -> None:
    """A diagnosis counts from its submission: while the first measurement of an asset (on a described drive) is
    still queued, with no answer yet, a measurement of another drive for the same asset is refused."""
    from app.db.diagnoses import DiagnosisRepository
    from app.db.records import RecordRepository
    from app.services.assets import asset_drive
    from app.services.diagnoses import new_record
    from app.services.diagnosis_requests import DiagnosisRequest
    from app.services.errors import IncompatibleError
    from engine.storage import PatternStore

    store = PatternStore(tmp_path / "queued.sqlite3")
    v2 = np.sin(np.arange(2048) / 100.0).tolist()
    record = {"sample_interval": 1e-4, "event_index": 48, "channels": {"v2": v2}, "asset": "line-3"}
    queued = new_record(store, DiagnosisRequest("json", json.dumps({"record": record, "drive": example}).encode()))
    with store.writing() as conn:  # stored and queued as submit() does, its job never run
        RecordRepository.insert(conn, queued)
    DiagnosisRepository(store).create(
        job_id="queued", record_id=queued.record.id, plant="backlash_drive", asset="line-3", measured_at=None
    )
    assert asset_drive(store, "line-3") == load_drive(EXAMPLE).fingerprint
    with pytest.raises(IncompatibleError, match="holds measurements of drive"):
        new_record(store, DiagnosisRequest("json", json.dumps({"record": record}).encode()))
    # the same drive again is taken
    new_record(store, DiagnosisRequest("json", json.dumps({"record": record, "drive": example}).encode()))


def test_the_csv_form_takes_the_drive_as_a_query_parameter(client: httpx.Client, example: dict[str, Any]) -> None:
    """A described drive's record sent as CSV: ``?drive=`` holds its description as JSON, and the record is
    diagnosed and identified on that drive as its JSON form is; a fingerprint alone or a bad description is
    refused with what to give."""
    drive = load_drive(EXAMPLE)
    sim = client.post(
        "/v1/simulate",
        json={"K": 0.004, "drive": example, "sample_interval": 1e-4},
        headers={"Accept": "text/csv"},
    )
    assert sim.status_code == 200, sim.text
    params = {
        "sample_interval": sim.headers["X-Sample-Interval"],
        "event_index": sim.headers["X-Event-Index"],
        "c1": drive.c1,
        "drive": json.dumps(example),
    }
    csv_headers = {"Content-Type": "text/csv"}
    r = client.post("/v1/diagnose", content=sim.text, params=params, headers=csv_headers)
    assert r.status_code == 200, r.text
    answer = r.json()
    assert answer["drive"]["fingerprint"] == drive.fingerprint
    assert answer["width"]["K"] == pytest.approx(0.004, rel=1e-2) and answer["warnings"] == [], answer["warnings"]
    # identified on its own drive: this service holds no pattern set of it, and says which drive it looked for
    r = client.post("/v1/identify", content=sim.text, params={**params, "channel": "v2"}, headers=csv_headers)
    assert r.status_code == 404 and f"drive {drive.fingerprint[:12]}" in r.json()["detail"], r.text
    # a fingerprint is not a description; a description the engine refuses says which key
    for given, says in (
        (drive.fingerprint, "give the drive description itself as a JSON object"),
        (json.dumps({"motor": {"pole_pairs": 0.5}}), "motor.pole_pairs must be a whole number"),
    ):
        r = client.post("/v1/diagnose", content=sim.text, params={**params, "drive": given}, headers=csv_headers)
        assert r.status_code == 422 and says in r.json()["detail"], r.text
    # the parameter belongs to the CSV form
    r = client.post("/v1/diagnose", json={"record": {"channels": {"v2": [0.0] * 64}}}, params={"drive": "{}"})
    assert r.status_code == 422 and "drive" in r.json()["detail"]


def test_a_record_read_without_its_drive_is_told_which_drives_have_sets(tmp_path: Path) -> None:
    """With only a described drive's sets stored, a record read as the reference plant's (a CSV without its
    description, say) is told that sets of that drive exist and to give its description."""
    from app.services.errors import NotFoundError
    from app.services.identification import select_pattern_set
    from engine.identification.training import train_pattern_set
    from engine.records import Record
    from engine.storage import PatternStore

    drive = load_drive(EXAMPLE)
    store = PatternStore(tmp_path / "drive-sets.sqlite3")
    store.save(train_pattern_set("v2", drive.c, kind="template", J1_values=drive.j1_grid(), drive=drive))
    record = Record({"v2": np.zeros(2048)}, 1e-4, 48)
    with pytest.raises(NotFoundError) as refused:
        select_pattern_set(store, "v2", record)
    assert f"stored for drive(s) {drive.fingerprint[:12]}" in str(refused.value), refused.value
    assert "give its description (drive)" in str(refused.value) and "--drive FILE" in str(refused.value.cli_message)
    assert select_pattern_set(store, "v2", record, drive=drive).pattern_set.c == drive.c


def _csv(n: int, step: float | None = None) -> bytes:
    """A CSV record of ``n`` samples of v2 = 0, with a time column of ``step`` [s] when given."""
    rows = ["t,v2" if step else "v2", *(f"{k * step!r},0.0" if step else "0.0" for k in range(n))]
    return ("\n".join(rows) + "\n").encode()


def test_a_record_without_interval_or_time_is_read_at_the_drive_protocol_interval(example: dict[str, Any]) -> None:
    """A diagnosis request (as the sync route and a job read it) with a described drive (its protocol at 50 us)
    and a record that gives neither sample_interval nor t: the record is read at the drive's interval, not at
    MODEL.md's 0.1 ms; without a drive at 0.1 ms; a given interval or a t column still wins. CSV and JSON."""
    from app.services.diagnosis_requests import DiagnosisRequest, parse

    drive = load_drive(EXAMPLE)
    assert drive.grid().sample_interval == 5e-5
    n, event = drive.n_samples, drive.event_index  # the test window at 50 us and at 0.1 ms
    params: dict[str, Any] = {"event_index": event, "drive": json.dumps(example)}

    def csv_interval(raw: bytes, **given: Any) -> float:
        return parse(DiagnosisRequest("csv", raw, {**params, **given})).record.sample_interval

    assert csv_interval(_csv(n)) == 5e-5
    assert csv_interval(_csv(n), drive=None) == 1e-4
    assert csv_interval(_csv(n), sample_interval=1e-4) == 1e-4
    assert csv_interval(_csv(n, 1e-4)) == pytest.approx(1e-4, rel=1e-9)
    record = {"event_index": event, "channels": {"v2": [0.0] * n}}

    def json_interval(body: dict[str, Any]) -> float:
        return parse(DiagnosisRequest("json", json.dumps(body).encode())).record.sample_interval

    assert json_interval({"record": record, "drive": example}) == 5e-5
    assert json_interval({"record": record}) == 1e-4
    assert json_interval({"record": {**record, "sample_interval": 1e-4}, "drive": example}) == 1e-4
    assert json_interval({"record": {**record, "t": (np.arange(n) * 1e-4).tolist()}, "drive": example}) == (
        pytest.approx(1e-4, rel=1e-9)
    )


def test_the_service_reads_a_record_without_interval_at_the_drive_protocol_interval(
    client: httpx.Client, example: dict[str, Any]
) -> None:
    """Over HTTP: a record too short for the test window is refused naming the interval it was read at, the drive's
    50 us with ``drive`` (identify, diagnose, diagnosis jobs; CSV and JSON), MODEL.md's 0.1 ms without."""
    routes: tuple[tuple[str, dict[str, Any]], ...] = (
        ("/v1/identify", {"channel": "v2"}),
        ("/v1/diagnose", {}),
        ("/v1/diagnoses", {}),
    )
    for path, extra in routes:
        query = {"event_index": 96, **extra}
        for given, ts in (({"drive": json.dumps(example)}, "5e-05"), ({}, "0.0001")):
            r = client.post(path, content=_csv(1000), params={**query, **given}, headers={"Content-Type": "text/csv"})
            assert r.status_code == 422 and f"1000 samples of {ts} s" in r.json()["detail"], (path, r.text)
        record = {"event_index": 96, "channels": {"v2": [0.0] * 1000}}
        for given, ts in (({"drive": example}, "5e-05"), ({}, "0.0001")):
            r = client.post(path, json={"record": record, **extra, **given})
            assert r.status_code == 422 and f"1000 samples of {ts} s" in r.json()["detail"], (path, r.text)


def test_cli_reads_a_record_file_without_interval_at_the_drive_protocol_interval(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--drive FILE``: a record file (CSV or JSON) with neither a sample interval nor t is read at the drive's
    protocol interval by diagnose, identify and diagnose-batch; at MODEL.md's 0.1 ms without --drive."""
    from app.services.batch import run_batch

    short_csv = tmp_path / "short.csv"
    short_csv.write_bytes(_csv(1000))
    short_json = tmp_path / "short.json"
    short_json.write_text(json.dumps({"event_index": 96, "channels": {"v2": [0.0] * 1000}}), encoding="utf-8")
    for command in (["diagnose"], ["identify", "--channel", "v2"]):
        for path in (short_csv, short_json):
            for drive, ts in ((["--drive", str(EXAMPLE)], "5e-05"), ([], "0.0001")):
                assert cli.main([*command, str(path), "--event-index", "96", *drive]) == 2
                err = capsys.readouterr().err
                assert f"1000 samples of {ts} s" in err, (command, path, err)
    (row,) = run_batch([short_json], tmp_path / "batch", drive=load_drive(EXAMPLE))
    assert row["status"] == "refused" and "1000 samples of 5e-05 s" in row["detail"], row
    (row,) = run_batch([short_json], tmp_path / "batch-reference")
    assert row["status"] == "refused" and "1000 samples of 0.0001 s" in row["detail"], row
