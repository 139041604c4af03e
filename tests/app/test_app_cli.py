"""The ``backlash`` command (app/cli/): subcommands mirror the endpoints; records as JSON or CSV files."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from servicekit import SMALL_TRAINING, clean_env

from app import cli
from engine.constants import CHANNELS, N_SAMPLES
from engine.simulation import HELD_BACK


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _train(capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    j1 = [str(v) for v in SMALL_TRAINING["J1_values"]]
    code, out, err = run(
        capsys,
        "train",
        "--channel",
        "v2",
        "--c",
        "1.0",
        "--J1",
        *j1,
        "--kind",
        "paper",
        "--max-epochs",
        str(SMALL_TRAINING["max_epochs"]),
    )
    assert code == 0, err
    assert "[100%] done" in err
    return json.loads(out)


def test_simulate_train_identify_round_trip(env: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    csv_path, json_path = tmp_path / "rec.csv", tmp_path / "rec.json"
    assert run(capsys, "simulate", "--K", "0.005", "--out", str(csv_path))[0] == 0
    assert run(capsys, "simulate", "--K", "0.005", "--out", str(json_path))[0] == 0
    lines = csv_path.read_text().splitlines()
    assert lines[0].split(",") == list(CHANNELS) and len(lines) == N_SAMPLES + 1
    rec = json.loads(json_path.read_text())
    assert rec["conditions"]["K"] == 0.005 and rec["event_time"] > 0

    stored = _train(capsys)
    assert env.exists()
    assert (stored["channel"], stored["c"], stored["J1_values"]) == ("v2", 1.0, SMALL_TRAINING["J1_values"])

    code, out, err = run(capsys, "identify", str(csv_path), "--channel", "v2", "--c", "1.0", "--any-set")
    assert code == 0, err
    from_csv = json.loads(out)
    assert (from_csv["index"], from_csv["width"], from_csv["pattern_set"]) == (3, 0.005, stored["id"])
    assert (from_csv["selection"], from_csv["c_source"]) == ("exact", "record")
    code, out, _ = run(capsys, "identify", str(json_path), "--channel", "v2", "--pattern-set", stored["id"])
    assert code == 0 and json.loads(out)["D"] == from_csv["D"]
    assert from_csv["continuous"] is None
    code, out, err = run(capsys, "identify", str(json_path), "--channel", "v2", "--continuous", "--any-set")
    assert code == 0, err
    cont = json.loads(out)["continuous"]
    assert abs(cont["K"] - 0.005) < 1e-5 and cont["nearest_width"] == 0.005 and cont["sigma_K"] > 0


def test_simulate_to_stdout_with_effects_and_batch(
    env: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run(capsys, "simulate", "--K", "0.0075", "--J1", "0.8", "--effect", "motor_coulomb_friction=0.02")
    assert code == 0
    assert json.loads(out)["conditions"] == {"J1": 0.8, "c": 1.0, "c1": 0.2, "K": 0.0075}
    cases = tmp_path / "cases.json"
    cases.write_text(json.dumps([{"K": 0.0025}, {"K": 0.01, "effects": {"supply_voltage": 0.9}}]))
    code, out, _ = run(capsys, "simulate", "--cases", str(cases))
    assert code == 0
    batch = json.loads(out)
    assert batch["count"] == 2 and [d["conditions"]["K"] for d in batch["data"]] == [0.0025, 0.01]


def test_pattern_sets_list_show_delete(env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    stored = _train(capsys)
    code, out, _ = run(capsys, "pattern-sets", "list", "--channel", "v2")
    assert code == 0 and [s["id"] for s in json.loads(out)["data"]] == [stored["id"]]
    code, out, _ = run(capsys, "pattern-sets", "show", stored["id"])
    assert code == 0 and json.loads(out)["arrays"]["patterns"] == [6, 15]
    code, _, err = run(capsys, "pattern-sets", "delete", stored["id"])
    assert code == 0 and stored["id"] in err
    code, _, err = run(capsys, "pattern-sets", "show", stored["id"])
    assert code == 2 and "no pattern set with id" in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["simulate", "--K", "0.5"], "K = 0.5 m is outside the accepted range"),
        (["simulate", "--K", "0.005", "--effect", "magic=1"], "unknown effect 'magic'"),
        (["simulate"], "give the backlash width with --K"),
        (["train", "--channel", "v2", "--c", "1.0", "--J1", "0.87", "0.87"], "repeat a value"),
        (
            ["train", "--channel", "v2", "--c", "1.0", "--kind", "template", "--max-epochs", "3"],
            "has no parameter(s) 'max_epochs'",
        ),
        (["identify", "missing.csv", "--channel", "v2"], "cannot read record file"),
        (["identify", "record.txt", "--channel", "v2"], "must end in .json or .csv"),
        (["identify", "short.csv", "--channel", "v2", "--event-index", "1"], "4.7 ms before the event and 199.8"),
        (["identify", "full.csv", "--channel", "v2"], "holds neither m_el nor a1"),
        (
            ["identify", "full.csv", "--channel", "v2", "--event-index", "48"],
            "train a pattern set first (backlash train",
        ),
        (
            ["identify", "full.csv", "--channel", "v2", "--event-index", "48", "--unit", "v2=knots"],
            "unknown unit 'knots' for channel 'v2'; accepted units: m/s, mm/s",
        ),
        (
            ["identify", "full.csv", "--channel", "v2", "--event-index", "48", "--unit", "v2=m/s", "--unit", "v2=mm/s"],
            "--unit gives channel 'v2' two units",
        ),
        (
            ["identify", "timed.csv", "--channel", "v2", "--event-index", "48", "--sample-interval", "1e-4"],
            "contradicts the time column 't'",
        ),
        (["identify", "nan.json", "--channel", "v2"], "the JSON holds NaN, which is not a number"),
        (["diagnose", "full.csv", "--event-index", "48", "--effects", "magic"], "unknown effect 'magic'"),
        (["diagnose", "--plant", "emps", "record.txt"], "an EMPS record is a .mat file"),
        (["diagnose", "--plant", "emps", "full.csv"], "unknown column(s) ['v2']"),
        (["diagnose", "--plant", "emps", "full.csv", "--effects", "stribeck"], "--effects and --bound apply to"),
        (["simulate", "--K", "0.005", "--unit", "omega1=rpmm"], "unknown unit 'rpmm' for channel 'omega1'"),
        (["simulate", "--K", "0.005", "--sample-interval", "2e-3"], "outside the accepted range"),
        (["simulate", "--K", "0.005", "--after", "0.1"], "100 ms after it missing"),
    ],
)
def test_user_errors_exit_2_with_a_message(
    env: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    message: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    Path("record.txt").write_text("x")
    Path("short.csv").write_text("v2\n1\n2\n3\n")
    Path("full.csv").write_text("v2\n" + "0.5\n" * N_SAMPLES)
    Path("timed.csv").write_text("t,v2\n" + "".join(f"{k * 5e-5!r},0.5\n" for k in range(4 * N_SAMPLES)))
    Path("nan.json").write_text('{"channels": {"v2": [NaN]}}')
    code, out, err = run(capsys, *argv)
    assert code == 2, err
    assert message in err and err.startswith("backlash: error:")
    assert out == ""


def test_identify_without_a_store_creates_none_and_messages_name_cli_commands(
    env: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Outside the repository, identify leaves no empty store behind; the CLI's messages name CLI commands."""
    from engine.storage import PatternStore

    monkeypatch.chdir(tmp_path)
    Path("full.csv").write_text("v2\n" + "0.5\n" * N_SAMPLES)
    code, _, err = run(capsys, "identify", "full.csv", "--channel", "v2", "--event-index", "48")
    assert code == 2 and f"no pattern store at {env}" in err and "backlash train --channel v2" in err
    assert not env.exists() and not (tmp_path / "data").exists()  # nothing created
    PatternStore(env)  # an empty store (created on opening): now the set is missing
    code, _, err = run(capsys, "identify", "full.csv", "--channel", "v2", "--event-index", "48")
    assert code == 2 and "no pattern set for channel 'v2'" in err
    assert "backlash train --channel v2 --c 1" in err and "--any-set" in err and "POST" not in err


def test_bad_usage_is_argparse_exit_2(env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main(["simulate", "--K", "0.005", "--effect", "no-equals-sign"])
    assert exc.value.code == 2
    assert "NAME=VALUE" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:  # the identifier kinds are choices: argparse lists them
        cli.main(["train", "--channel", "v2", "--c", "1.0", "--kind", "magic"])
    assert (
        exc.value.code == 2 and "invalid choice: 'magic' (choose from 'paper', 'template')" in capsys.readouterr().err
    )
    with pytest.raises(SystemExit) as exc:
        cli.main(["simulate", "--K", "0.005", "--unit", "omega1:rpm"])
    assert exc.value.code == 2
    assert "write a unit as CHANNEL=UNIT" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["simulate", "--K", "nan"])
    assert "not a finite number" in capsys.readouterr().err


class FakeLongJobs:
    """The engine entry points of ``run`` and ``validate``, replaced by recorders (see :func:`long_jobs`)."""

    def __init__(self) -> None:
        self.main_job: list[Path] = []
        self.validation: list[dict[str, Any]] = []
        self.validation_v2: list[dict[str, Any]] = []
        self.scored: list[Path] = []

    def run(self, out_dir: Path, **dask: Any) -> Any:
        self.main_job.append(out_dir)
        self.dask = dask
        return types.SimpleNamespace(report=lambda: "## Paper's Tables 1-4\n| K | nr5 |")

    def run_validation(self, **kwargs: Any) -> Any:
        self.validation.append(kwargs)
        return types.SimpleNamespace(table=lambda: "| top-1 | 0.95 |")

    def run_validation_v2(self, **kwargs: Any) -> dict[str, Any]:
        self.validation_v2.append(kwargs)
        return {"summary": "| v2 |"}

    def score_identification(self, out_dir: Path) -> dict[str, Any]:
        self.scored.append(out_dir)
        return {"before": 0.5, "after": 0.9}


@pytest.fixture
def long_jobs(monkeypatch: pytest.MonkeyPatch) -> FakeLongJobs:
    """``backlash run`` and ``validate`` call these instead of the engine's main job, validation and scoring."""
    from engine.diagnosis import validation
    from engine.evaluation import identification as scoring
    from engine.evaluation import main_job
    from engine.validation import report as report_v2
    from engine.validation import run as run_v2

    fake = FakeLongJobs()
    monkeypatch.setattr(run_v2, "run_validation", fake.run_validation_v2)
    monkeypatch.setattr(report_v2, "summary_markdown", lambda doc: doc["summary"])
    monkeypatch.setattr(main_job, "run", fake.run)
    monkeypatch.setattr(validation, "run_validation", fake.run_validation)
    monkeypatch.setattr(scoring, "score_identification", fake.score_identification)
    monkeypatch.setattr(scoring, "identification_markdown", lambda scored: f"| after | {scored['after']} |")
    return fake


def test_run_calls_the_main_job_and_prints_its_report(
    env: Path, long_jobs: FakeLongJobs, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run(capsys, "run", "--out", "somewhere")
    assert code == 0
    assert long_jobs.main_job == [Path("somewhere")]
    assert out == "## Paper's Tables 1-4\n| K | nr5 |\n"


def test_validate_calls_the_blind_validation(
    env: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    long_jobs: FakeLongJobs,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    Path("v").mkdir()
    code, out, _ = run(capsys, "validate", "--protocol", "1", "--cases", "12", "--seed", "3", "--out", "v")
    assert code == 0 and out.startswith("| top-1 | 0.95 |") and "| after | 0.9 |" in out
    assert long_jobs.validation == [
        {"n_cases": 12, "seed": 3, "out_dir": Path("v"), "workers": None, "scheduler": None}
    ]
    assert long_jobs.scored == [Path("v")] and Path("v/identification.md").read_text() == "| after | 0.9 |"
    assert json.loads(Path("v/identification.json").read_text()) == {"before": 0.5, "after": 0.9}


def test_validate_refuses_a_directory_that_holds_a_run(
    env: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "v" / "cases").mkdir(parents=True)
    old = tmp_path / "v" / "cases" / "case0000.json"
    old.write_text("{}")
    code, _, err = run(capsys, "validate", "--cases", "2", "--out", "v")
    assert code == 2 and "already holds a validation run" in err
    assert old.read_text() == "{}" and not (tmp_path / "v" / "key").exists()  # nothing touched


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["run"], {"main_job": [Path("out")], "validation": [], "validation_v2": []}),
        (
            ["validate", "--protocol", "1"],
            {
                "main_job": [],
                "validation": [
                    {"n_cases": 200, "seed": 53, "out_dir": Path("out/validation"), "workers": None, "scheduler": None}
                ],
                "validation_v2": [],
            },
        ),
        (
            ["validate"],
            {
                "main_job": [],
                "validation": [],
                "validation_v2": [
                    {
                        "n_cases": 300,
                        "seed": 97,
                        "out_dir": Path("out/validation"),
                        "workers": None,
                        "mix": None,
                        "held_back": HELD_BACK,  # model 1.1's family unless --held-back says otherwise
                        "scheduler": None,
                    }
                ],
            },
        ),
    ],
)
def test_long_jobs_take_their_documented_defaults(
    env: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    long_jobs: FakeLongJobs,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    expected: dict[str, list[Any]],
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out" / "validation").mkdir(parents=True)
    code, _, err = run(capsys, *argv)
    assert code == 0, err
    assert {
        "main_job": long_jobs.main_job,
        "validation": long_jobs.validation,
        "validation_v2": long_jobs.validation_v2,
    } == expected


@pytest.mark.parametrize("command", ["run", "validate"])
def test_long_jobs_refuse_unknown_arguments_before_starting(
    env: Path, long_jobs: FakeLongJobs, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main([command, "--bogus", "1"])
    assert exc.value.code == 2
    assert "unrecognized arguments: --bogus 1" in capsys.readouterr().err
    assert long_jobs.main_job == long_jobs.validation == long_jobs.validation_v2 == []  # nothing started


def test_bench_runs_the_benchmark_script(
    env: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)  # bench/ in the working directory comes first
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "bench_simulator.py").write_text(
        "import sys\n\ndef main():\n    sys.stdout.write('args=' + ' '.join(sys.argv[1:]) + '\\nspeedup: 42.0x\\n')\n"
    )
    code, out, _ = run(capsys, "bench", "--quick")
    assert code == 0
    assert out.splitlines() == ["args=--quick", "speedup: 42.0x"]


def test_console_script_is_installed(tmp_path: Path) -> None:
    exe = Path(sys.executable).with_name("backlash")
    assert exe.exists(), "the backlash console script is missing: pip install -e ."
    proc = subprocess.run(
        [str(exe), "--help"], env=clean_env(), cwd=tmp_path, capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0
    for command in ("simulate", "train", "identify", "diagnose", "serve", "run", "bench", "validate"):
        assert command in proc.stdout


def test_simulate_can_make_a_measured_like_record(
    env: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    assert run(capsys, "simulate", "--K", "0.006", "--out", "clean.json")[0] == 0
    assert run(capsys, "simulate", "--K", "0.006", "--snr-db", "30", "--known", "c1", "--out", "noisy.json")[0] == 0
    clean, noisy = (json.loads(Path(f).read_text()) for f in ("clean.json", "noisy.json"))
    assert noisy["conditions"] == {"c1": 0.2} and set(clean["conditions"]) == {"K", "J1", "c", "c1"}
    v_clean, v_noisy = np.array(clean["channels"]["v2"]), np.array(noisy["channels"]["v2"])
    snr = 10 * np.log10(np.var(v_clean) / np.var(v_noisy - v_clean))
    assert 28.0 < snr < 32.0


def test_simulate_as_a_bench_gives_it_and_read_it_back(
    env: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from app.records_io import read_record
    from engine.records import SampleGrid

    grid = SampleGrid.around_event(5e-5, 0.01, 0.3)
    render = ["--sample-interval", "5e-5", "--before", "0.01", "--after", "0.3"]
    units = ["--unit", "omega1=rpm", "--unit", "a1=g"]
    bench_csv, bench_json = tmp_path / "bench.csv", tmp_path / "bench.json"
    code, _, err = run(capsys, "simulate", "--K", "0.005", *render, *units, "--no-event-index", "--time-column",
                       "--out", str(bench_csv))  # fmt: skip
    assert code == 0, err
    lines = bench_csv.read_text().splitlines()
    assert lines[0] == "t,a1,m_el,omega1,a2,v2" and len(lines) == grid.n_samples + 1
    code, out, _ = run(capsys, "simulate", "--K", "0.005", *render, *units, "--no-event-index")
    stdout_rec = json.loads(out)
    assert "event_index" not in stdout_rec and stdout_rec["units"] == {"omega1": "rpm", "a1": "g"}
    assert run(capsys, "simulate", "--K", "0.005", *render, "--out", str(bench_json))[0] == 0

    model = read_record(bench_json)  # rad/s and m/s^2, the event index stated
    assert (model.n_samples, model.event_index, model.units) == (grid.n_samples, grid.event_index, {})
    from_csv = read_record(bench_csv, units={"omega1": "rpm", "a1": "g"})  # Ts from t, the event located
    assert from_csv.event_location is not None and from_csv.event_index == grid.event_index
    assert from_csv.sample_interval == pytest.approx(5e-5, rel=1e-9)
    for name in CHANNELS:
        np.testing.assert_allclose(from_csv[name], model[name], rtol=1e-12, atol=1e-12)
    assert float(lines[1 + 300].split(",")[3]) == pytest.approx(model["omega1"][300] * 60 / (2 * np.pi), rel=1e-12)


def test_simulate_noise_is_added_in_model_units(env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    noisy = ["simulate", "--K", "0.005", "--snr-db", "30", "--seed", "3", "--known", "c1"]
    code, out, _ = run(capsys, *noisy)
    assert code == 0
    plain = json.loads(out)
    assert plain["conditions"] == {"c1": 0.2}
    code, out, _ = run(capsys, *noisy, "--unit", "v2=mm/s", "--channels", "v2", "a2")
    assert code == 0
    mm_s = json.loads(out)
    assert set(mm_s["channels"]) == {"a2", "v2"}  # the same noise on a kept channel, whatever else is kept
    np.testing.assert_allclose(np.asarray(mm_s["channels"]["v2"]) * 1e-3, plain["channels"]["v2"], rtol=1e-12)
    assert mm_s["channels"]["a2"] == plain["channels"]["a2"]


def test_unit_help_lists_the_engines_units() -> None:
    from app.cli.common import UNITS_HELP
    from engine.records import UNITS

    for channel, units in UNITS.items():
        section = next(s for s in UNITS_HELP.split(";") if channel in s.split(":")[0])
        assert all(u in section for u in units), (channel, section)


def test_diagnose_a_brfd_record_as_distributed(env: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--plant brfd`` reads the data set's JSON file (here gzip-compressed as shipped) and writes the force overlay."""
    path = (
        Path(__file__).resolve().parents[2]
        / "engine"
        / "plants"
        / "brfd"
        / "data"
        / "dataset-2_2Hz30lbtension0.5amplitude.json.gz"
    )
    code, out, err = run(capsys, "diagnose", "--plant", "brfd", str(path), "--plots", str(tmp_path / "plots"))
    assert code == 0, err
    result = json.loads(out)
    assert result["plant"] == "brfd" and set(result["relative_error"]["before"]) == {"force"}
    assert result["event_share"]["samples"]["share"] > 0  # the reversals are the record's events
    assert (tmp_path / "plots" / "overlay_force.png").stat().st_size > 0
    assert (tmp_path / "plots" / "force_displacement.png").stat().st_size > 10_000  # the plant's own figure
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"data": [[0.0, 0.0, 0.0]] * 2000, "dt": 0.0009765625}))
    code, _, err = run(capsys, "diagnose", "--plant", "brfd", str(bad))
    assert code == 2 and "'dt' says" in err  # refused with what is wrong, not misread


def test_diagnose_an_emps_record_in_csv_form(env: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--plant emps`` reads the CSV form, answers in the plant's channels and writes its plots.

    The answer is the one docs/emps.md gives for every EMPS record: ``partly_explained``, a negative
    Stribeck term named (on these 2.5 s, measured: -12.9 +- 0.7 N, 12 % of the gap; the whole record,
    committed in docs/real-data/runs/pulses_self.json: -11.0 +- 0.5 N), the error falling on every channel.
    """
    from engine.diagnosis.plant_gap import MIN_SHARE
    from engine.plants.emps import load_mat

    rec = load_mat(Path(__file__).resolve().parents[2] / "engine" / "plants" / "emps" / "data" / "DATA_EMPS_PULSES.mat")
    n = 2500  # 2.5 s, two pulses: a quick diagnosis
    rows = "\n".join(
        ",".join(repr(float(x[k])) for x in (rec.t, rec.qm, rec.qg, rec.vir, rec.pulses)) for k in range(n)
    )
    path = tmp_path / "pulses.csv"
    path.write_text(f"# kp = {rec.kp!r}\n# kv = {rec.kv!r}\n# gtau = {rec.gtau!r}\nt,qm,qg,vir,pulses_N\n{rows}\n")
    code, out, err = run(capsys, "diagnose", "--plant", "emps", str(path), "--plots", str(tmp_path / "plots"))
    assert code == 0, err
    result = json.loads(out)
    assert result["plant"] == "emps" and result["record"] == "pulses.csv"
    before, after = result["relative_error"]["before"], result["relative_error"]["after"]
    assert set(before) == set(after) == {"position", "velocity", "acceleration", "force"}
    assert all(after[c] < before[c] for c in before), result["relative_error"]
    assert result["event_share"]["samples"]["share"] > 0  # the pulses are the record's events
    assert result["status"] == "partly_explained", result["verdict"]
    committed = json.loads((Path(__file__).resolve().parents[2] / "docs/real-data/runs/pulses_self.json").read_text())
    (ref,) = [e for e in committed["verdict"]["effects"] if e["effect"] == "stribeck"]
    top = result["verdict"]["effects"][0]
    assert (top["effect"], top["unit"]) == ("stribeck", "N") and top["value"] < 0, top
    assert abs(top["value"] - ref["value"]) <= 3 * float(np.hypot(top["uncertainty"], ref["uncertainty"]))
    assert result["verdict"]["share"] >= MIN_SHARE
    assert (tmp_path / "plots" / "overlay_acceleration.png").stat().st_size > 0


def test_identify_the_width_of_brfd_records_jointly(env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``identify --plant brfd --continuous`` with a second record of the same device."""
    data = Path(__file__).resolve().parents[2] / "engine" / "plants" / "brfd" / "data"
    one, two = (
        data / "dataset-2_1Hz30lbtension1amplitude.json.gz",
        data / "dataset-2_2Hz30lbtension0.5amplitude.json.gz",
    )
    code, out, err = run(capsys, "identify", "--plant", "brfd", str(one), "--joint", str(two), "--continuous")
    assert code == 0, err
    result = json.loads(out)
    cont = result["continuous"]
    assert result["plant"] == "brfd" and result["unit"] == "m" and len(cont["fitted"]) == 2
    assert cont["identifiable"] and cont["interval_95"][0] <= cont["K"] <= cont["interval_95"][1]
    paper = result["paper"]  # the seed's method, per record: a grid width and its D vector
    assert [p["record"] for p in paper] == result["records"]
    assert all(p["width"] in p["widths"] and len(p["D"]) == 6 for p in paper)
    code, _, err = run(capsys, "identify", "--plant", "brfd", str(one))
    assert code == 2 and "--continuous" in err


def test_diagnose_batch_writes_one_answer_per_record_and_a_summary_and_resumes(
    env: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two BRFD records and one unreadable file, on a one-worker local Dask cluster; then resumed."""
    import shutil

    data = Path(__file__).resolve().parents[2] / "engine" / "plants" / "brfd" / "data"
    src = tmp_path / "in"
    src.mkdir()
    for name in ("dataset-2_2Hz30lbtension0.5amplitude", "dataset-2_1Hz30lbtension1amplitude"):
        shutil.copy(data / f"{name}.json.gz", src)
    (src / "broken.json").write_text("{not json")
    out = tmp_path / "out"
    code, stdout, err = run(capsys, "diagnose-batch", str(src), "--out", str(out), "--plant", "brfd", "--workers", "1")
    assert code == 0, err
    answers = sorted(p.name for p in out.glob("*.json"))
    assert answers == ["dataset-2_1Hz30lbtension1amplitude.json", "dataset-2_2Hz30lbtension0.5amplitude.json"]
    rows = {r["record"]: r for r in csv.DictReader((out / "summary.csv").open())}
    assert rows["broken"]["status"] == "refused" and "not valid JSON" in rows["broken"]["detail"]
    one = json.loads((out / "dataset-2_1Hz30lbtension1amplitude.json").read_text())
    assert rows["dataset-2_1Hz30lbtension1amplitude"]["status"] == one["status"]
    assert "| record | status |" in stdout
    stamp = (out / "dataset-2_1Hz30lbtension1amplitude.json").stat().st_mtime_ns
    code, _, err = run(capsys, "diagnose-batch", str(src), "--out", str(out), "--plant", "brfd", "--workers", "1")
    assert code == 0, err
    assert (out / "dataset-2_1Hz30lbtension1amplitude.json").stat().st_mtime_ns == stamp  # not diagnosed again
    code, _, err = run(capsys, "diagnose-batch", str(tmp_path / "nothing-*.csv"), "--out", str(out))
    assert code == 2 and "no record files" in err
