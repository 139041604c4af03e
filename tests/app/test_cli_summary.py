"""``backlash diagnose`` speaks to a person: a summary of the answer, the full JSON where asked for (issue 53, item 4)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from app.cli.main import main


@pytest.fixture
def record(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("BACKLASH_DB_PATH", str(tmp_path / "store.sqlite3"))
    monkeypatch.chdir(tmp_path)
    assert (
        main(["simulate", "--K", "0.0055", "--effect", "load_inertia=1.3", "--snr-db", "40", "--out", "rec.csv"]) == 0
    )
    return tmp_path / "rec.csv"


def test_diagnose_prints_a_summary_and_writes_the_full_answer_to_out(
    record: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    args = ["diagnose", str(record), "--effects", "load_inertia", "motor_coulomb_friction"]
    code = main([*args, "--out", "answer.json", "--plots", "plots"])
    out, err = capsys.readouterr()
    assert code == 0, err
    lines = out.splitlines()
    answer = json.loads((tmp_path / "answer.json").read_text())
    width = answer["width"]
    lo, hi = width["interval_95"]
    assert lines[0].startswith("verdict: explained (load_inertia), probability right ")
    assert lines[1] == (
        f"backlash width: {1e3 * width['K']:.4f} mm, 95 % interval {1e3 * lo:.4f}-{1e3 * hi:.4f} mm (from load_inertia)"
    )
    assert lo < 0.0055 < hi  # the true width, inside the interval the person reads
    assert lines[2].startswith("where the gap lies: ") and " ms from the event" in lines[2]
    assert lines[3].startswith("how far it shrinks: residual ") and "once load_inertia is added" in lines[3]
    plots = [line.removeprefix("plot: ") for line in lines if line.startswith("plot: ")]
    assert plots and all(Path(p).stat().st_size > 0 for p in plots)
    assert not out.lstrip().startswith("{")  # no JSON on stdout with --out
    assert "wrote the full answer to answer.json" in err

    code = main([*args, "--json"])  # the full answer on stdout, the summary on stderr
    out, err = capsys.readouterr()
    assert code == 0 and json.loads(out)["verdict"]["status"] == "explained"
    assert "verdict: explained (load_inertia)" in err


def test_help_pages_show_examples_and_choices(capsys: pytest.CaptureFixture[str]) -> None:
    for command in (
        "simulate",
        "diagnose",
        "identify",
        "train",
        "pattern-sets",
        "diagnose-batch",
        "validate",
        "run",
        "serve",
    ):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        out = capsys.readouterr().out
        assert "examples:\n  backlash " in out, command
    main_help = pytest.raises(SystemExit)
    with main_help:
        main(["--help"])
    assert "diagnose" in capsys.readouterr().out.split("positional arguments")[0]
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "load_inertia [0.5, 2] x" in out and "motor_coulomb_friction [0, 0.1] pu" in out
    with pytest.raises(SystemExit):
        main(["identify", "--help"])
    assert "--kind {paper,template}" in capsys.readouterr().out


def test_the_summary_states_the_missing_term_of_a_gap_the_catalogue_does_not_close() -> None:
    from app.output import summary_lines

    answer = {
        "status": "unexplained",
        "verdict": {"effects": [], "locus": "linkage", "locus_confidence": 0.97},
        "gap": {"before": {"rms_over_noise": 6.2}},
        "locus": {
            "locus": "linkage",
            "confidence": 0.97,
            "term": {"description": "a force input of about 900 N RMS at the linkage, following the displacement"},
            "note": "",
        },
    }
    lines = summary_lines(answer)
    assert lines[0] == "verdict: unexplained, locus linkage (locus 97 %)"
    assert lines[-1] == (
        "missing term: at the linkage (97 %), a force input of about 900 N RMS at the linkage, following the displacement"
    )
    answer["locus"] = {"locus": None, "confidence": 0.0, "term": {}, "note": "no part's term beats the model"}
    assert not any(line.startswith("missing term") for line in summary_lines(answer))
