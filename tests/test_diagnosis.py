"""End-to-end gap diagnosis (engine.diagnosis.diagnose) and its blind validation (engine.diagnosis.validation)."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import asdict

import numpy as np
import pytest
from scipy.special import expit

from engine.constants import CHANNELS
from engine.diagnosis import diagnose
from engine.diagnosis.confidence import calibrated_confidence
from engine.diagnosis.diagnose import DiagnosisSettings, decide, fit_statistic
from engine.diagnosis.validation import (
    STRENGTH_THRESHOLD,
    AnswerEntry,
    generate_cases,
    run_validation,
    same_physics_names,
    score,
    write_cases,
)
from engine.records import Record
from engine.simulation import CATALOGUE, EffectLibrary, PlantParameters, simulate
from engine.simulation.noise import noise_std

PLANT = PlantParameters(K=0.006, J1=0.82, c=1.1)


def noisy(record: Record, snr_db: float, seed: int) -> Record:
    rng = np.random.default_rng(seed)
    ch = {k: v + rng.standard_normal(v.size) * noise_std(v, snr_db)[0] for k, v in record.channels.items()}
    return Record(ch, conditions={"c1": 0.2})


@pytest.fixture(scope="module")
def rotor_case():
    """The record of docs INVERSE-PROBLEM.md: r_r x 1.3 at K = 0.006, J1 = 0.82, c = 1.1, 45 dB."""
    rec = noisy(simulate(PLANT, effects={"rotor_resistance_drift": 1.3}), 45.0, seed=11)
    return rec, diagnose(rec)


def test_strong_single_effect_is_ranked_first_and_explained(rotor_case):
    _, res = rotor_case
    assert res.verdict.status == "explained"
    assert res.verdict.effect == "rotor_resistance_drift"
    assert res.candidates[0].effect == "rotor_resistance_drift"
    assert res.verdict.value == pytest.approx(1.3, rel=0.01)
    assert 0 < res.verdict.uncertainty < 0.05
    assert res.verdict.confidence > 0.8
    # the calibration with the effect recovers the operating point
    cal = res.candidates[0].calibration
    assert cal.values["K"] == pytest.approx(PLANT.K, rel=0.01)
    assert cal.values["J1"] == pytest.approx(PLANT.J1, rel=0.01)
    # how far: the gap shrinks by far more than 5x and the fit is at the noise
    assert res.candidates[0].shrinkage > 5
    assert res.gap_after.rms_over_noise < 1.05 < res.gap_before.rms_over_noise
    # where: the cells are sorted by excess and their shares add up to one
    assert [c.excess for c in res.cells] == sorted((c.excess for c in res.cells), reverse=True)
    assert sum(c.share for c in res.cells) == pytest.approx(1.0)


def test_result_is_json_ready_in_the_shape_of_issue_4(rotor_case):
    rec, res = rotor_case
    d = json.loads(json.dumps(res.to_dict()))
    assert {"calibration", "cells", "candidates", "verdict", "records", "gap"} <= set(d)
    assert set(d["verdict"]) >= {"status", "effect", "value", "confidence"}
    # explained: the score is the documented product (adequacy of the fit x posterior weight x strength),
    # the confidence its calibrated probability (engine.diagnosis.confidence)
    best, s = res.candidates[0], DiagnosisSettings()
    total, worst = fit_statistic(best.calibration)
    adequacy = expit(
        min((s.max_reduced_chi2 - total) / s.chi2_scatter, (s.max_channel_chi2 - worst) / (2 * s.chi2_scatter))
    )
    sure = expit((best.strength - s.min_strength) / s.strength_scatter)
    assert d["verdict"]["score"] == pytest.approx(adequacy * best.weight * sure, rel=1e-12)
    nominal_chi2 = d["calibration"]["reduced_chi2"]
    stated = calibrated_confidence("explained", d["verdict"]["score"], nominal_chi2=nominal_chi2)
    assert d["verdict"]["confidence"] == pytest.approx(stated)
    before = Record.from_dict(d["records"]["before"])
    after = Record.from_dict(d["records"]["after"])
    assert set(before.channels) == set(CHANNELS)
    # the fit with the effect reproduces the record far better than the nominal one

    def err(sim: Record) -> float:
        return float(np.mean([(np.mean((rec[c] - sim[c]) ** 2) / np.var(rec[c])) for c in CHANNELS]))

    assert err(after) < 0.01 * err(before)
    cell = d["cells"][0]
    assert {"channel", "level", "band_hz", "window", "window_ms", "share"} <= set(cell)
    assert len(d["candidates"]) == len(CATALOGUE)
    # where the time went: the stages that ran, in order, within the diagnosis's wall time
    names = [x["stage"] for x in d["stages"]]
    assert names[0] == "nominal calibration" and names[-3:] == ["decision", "plausibility", "gap after the fix"]
    assert all(x["seconds"] >= 0 for x in d["stages"]) and sum(x["seconds"] for x in d["stages"]) <= d["seconds"]


def test_clean_record_gives_no_gap():
    rec = noisy(simulate(PlantParameters(K=0.0042, J1=0.9, c=0.95)), 40.0, seed=12)
    seen = []

    def hook(record, result):  # the identification hook sees the finished result
        seen.append(result.verdict.status)
        return {"width_before": result.calibration.values["K"]}

    res = diagnose(rec, identify=hook)
    assert res.verdict.status == "no_gap", res.verdict.reason
    assert seen == ["no_gap"] and res.to_dict()["identification"]["width_before"] == res.calibration.values["K"]
    assert res.verdict.effect is None
    assert res.after is None
    assert res.gap_before.rms_over_noise < 1.05


#: Effects that could stand in for a load inertia left out of the library: the other parameter of the
#: drive train, the load's absorber, the sensors' gain and delay.
LOAD_INERTIA_RIVALS = ("resilient_stiffness", "absorber_discontinuity", "sensor_gain", "measurement_delay")


@pytest.mark.parametrize(
    "whole_catalogue",
    [
        pytest.param(False, id="rivals", marks=pytest.mark.slow),  # 40-60 s
        pytest.param(True, id="catalogue", marks=pytest.mark.slow),
    ],
)
def test_left_out_effect_is_unexplained(whole_catalogue: bool) -> None:
    """An effect outside the library is not named as one inside it (both under ``make test-slow``: its
    closest rivals only, with single, pair and triple search, and the whole rest of the catalogue). The
    default run's left-out effect is tests/test_headline.py's (a held-back effect, its locus and missing
    term), beside the held-back loci of tests/test_locus.py."""
    rec = noisy(simulate(PlantParameters(K=0.0075, J1=0.78, c=1.3), effects={"load_inertia": 1.6}), 40.0, seed=13)
    library = (
        CATALOGUE.without("load_inertia")
        if whole_catalogue
        else EffectLibrary([CATALOGUE[n] for n in LOAD_INERTIA_RIVALS])
    )
    res = diagnose(rec, library)
    assert res.verdict.status == "unexplained", res.verdict.reason
    assert "load_inertia" not in [c.effect for c in res.candidates]


def test_generated_cases_are_blind_and_follow_the_strength_rule(tmp_path):
    cases, key = generate_cases(12, seed=3)
    key_path = write_cases(cases, key, tmp_path)
    assert key_path.parent != tmp_path / "cases"
    for c, k in zip(cases, key, strict=True):
        d = json.loads((tmp_path / "cases" / f"{c.case_id}.json").read_text())
        # the diagnosis sees the record and the library only: no truth, no event time
        assert set(d) == {"case_id", "record", "library"}
        assert d["record"]["conditions"] == {"c1": 0.2}
        assert "event_time" not in d["record"]
        assert (k.effect in d["library"]) == (k.kind == "effect") or k.kind == "clean"
        assert k.counts == (k.effect is not None and k.strength > STRENGTH_THRESHOLD)
        expected = "no_gap" if not k.counts else "explained" if k.kind == "effect" else "unexplained"
        assert k.expected_status == expected
        assert 30.0 <= k.snr_db <= 50.0
    assert {k.kind for k in key} == {"effect", "left_out", "clean"}


def test_a_left_out_effect_takes_its_same_physics_twin_out_of_the_library():
    """Protocol 1's leave-out (revision of 2026-11-26): a left-out time shift leaves both shifts out."""
    cases, key = generate_cases(20, seed=5, fractions={"effect": 0.0, "left_out": 1.0, "clean": 0.0})
    names = set(CATALOGUE)
    assert {"measurement_delay", "trigger_offset"} <= {k.effect for k in key}  # a round covers the catalogue
    for c, k in zip(cases, key, strict=True):
        twins = {n for n in names if same_physics_names(n, str(k.effect))}
        assert set(c.library) == names - twins
        assert len(twins) == (2 if k.effect in ("measurement_delay", "trigger_offset") else 1)


def test_scorer_takes_a_same_physics_twin_for_the_effect(tmp_path):
    """A measurement delay named as a trigger offset is right (top-1 and top-2); another effect is not."""
    key = [
        AnswerEntry(cid, "effect", "measurement_delay", 4e-4, 0.005, 0.85, 1.0, 40.0, 30.0, True, "explained", eff)
        for cid, eff in (("a", "measurement_delay"), ("b", "measurement_delay"))
    ]
    (tmp_path / "key").mkdir()
    (tmp_path / "results").mkdir()
    (tmp_path / "key" / "answer_key.json").write_text(json.dumps([asdict(k) for k in key]))
    for cid, named in (("a", "trigger_offset"), ("b", "sensor_lowpass")):
        res = {
            "verdict": {"status": "explained", "effect": named, "value": 4e-4, "confidence": 0.5},
            "candidates": [{"effect": named, "value": 4e-4, "uncertainty": 1e-5, "shrinkage": 50.0}],
            "ranking": [named, "sensor_gain"],
            "wall_seconds": 1.0,
        }
        (tmp_path / "results" / f"{cid}.json").write_text(json.dumps(res))
    rep = score(tmp_path)
    assert rep.top1 == 0.5 and rep.top2 == 0.5 and rep.rank1 == 0.5
    assert same_physics_names("trigger_offset", "measurement_delay") and not same_physics_names(
        "trigger_offset", "sensor_gain"
    )


def test_scorer_counts_what_it_should(tmp_path):
    """The scorer on hand-made results: one right and one wrong answer of each kind."""
    truth = [
        ("a", "effect", "load_inertia", 1.5, 50.0, "explained", "load_inertia"),
        ("b", "effect", "supply_voltage", 0.9, 40.0, "explained", "supply_voltage"),
        ("c", "left_out", "contact_damping", 5.0, 20.0, "unexplained", None),
        ("d", "left_out", "contact_damping", 5.0, 20.0, "unexplained", None),
        ("e", "clean", None, None, 0.0, "no_gap", None),
        ("f", "effect", "motor_viscous_friction", 0.01, 1.0, "no_gap", None),  # weak draw: scored as clean
    ]
    verdicts = {
        "a": ("explained", "load_inertia", ["load_inertia", "contact_damping"], 1.55, 100.0),
        "b": ("explained", "rotor_resistance_drift", ["rotor_resistance_drift", "supply_voltage"], 0.95, 3.0),
        "c": ("unexplained", None, ["resilient_stiffness"], None, None),
        "d": ("explained", "resilient_stiffness", ["resilient_stiffness"], None, None),
        "e": ("no_gap", None, [], None, None),
        "f": ("explained", "motor_viscous_friction", ["motor_viscous_friction"], None, None),
    }
    key = [
        AnswerEntry(cid, kind, eff, val, 0.005, 0.85, 1.0, 40.0, st, st > STRENGTH_THRESHOLD, es, ee)
        for cid, kind, eff, val, st, es, ee in truth
    ]
    (tmp_path / "key").mkdir()
    (tmp_path / "results").mkdir()
    (tmp_path / "key" / "answer_key.json").write_text(json.dumps([asdict(k) for k in key]))
    for cid, (status, eff, ranking, value, shrink) in verdicts.items():
        cands = [
            {
                "effect": n,
                "value": value if n == (key[ord(cid) - 97].effect) else 1.0,
                "uncertainty": 0.1,
                "shrinkage": shrink if n == key[ord(cid) - 97].effect else 1.0,
            }
            for n in ranking
        ]
        res = {
            "verdict": {"status": status, "effect": eff, "value": None, "confidence": 0.9},
            "candidates": cands,
            "ranking": ranking,
            "wall_seconds": 1.0,
        }
        (tmp_path / "results" / f"{cid}.json").write_text(json.dumps(res))
    rep = score(tmp_path)
    assert rep.n_by_expected == {"explained": 2, "unexplained": 2, "no_gap": 2}
    assert rep.top1 == 0.5 and rep.top2 == 1.0 and rep.rank1 == 0.5
    assert rep.abstention == 0.5
    assert rep.false_alarm == 0.5
    assert rep.confusion["supply_voltage"] == {"rotor_resistance_drift": 1}
    assert rep.confusion["no_gap"] == {"no_gap": 1, "motor_viscous_friction": 1}
    assert rep.shrinkage["median"] == pytest.approx(51.5)
    assert rep.value_error["median_rel_range"] == pytest.approx(0.05 / 1.5)  # load_inertia range 0.5..2
    assert "top-1" in rep.table() and "truth" in rep.confusion_table()


@pytest.mark.slow  # 2.5 min; protocol 2's (also slow): tests/test_validation_v2.py::test_tiny_end_to_end_run_with_the_real_diagnosis
def test_small_blind_validation(tmp_path):
    """A small blind run of protocol 1 end to end: generate, diagnose without the key, score."""
    rep = run_validation(
        4, seed=5, out_dir=tmp_path, workers=2, fractions={"effect": 0.5, "left_out": 0.25, "clean": 0.25}
    )
    assert rep.n_cases == 4
    assert (tmp_path / "report.md").exists() and (tmp_path / "report.json").exists()
    # every case is answered right (measured: the same four answers on every run; the draw is that of the
    # 16-effect catalogue of issue 9)
    answers = [(r["kind"], r["effect"], r["expected"], r["status"], r["named"]) for r in rep.per_case]
    assert answers == [
        ("clean", None, "no_gap", "no_gap", None),
        ("effect", "contact_damping", "explained", "explained", "contact_damping"),
        ("left_out", "sensor_offset", "unexplained", "unexplained", None),
        ("effect", "trigger_offset", "explained", "explained", "trigger_offset"),
    ], rep.per_case
    # identification before/after on the same finished run (reads the key only now)
    from engine.evaluation.identification import identification_markdown, score_identification

    ident = score_identification(tmp_path)
    n = ident["n"]
    assert (
        n["twin"] == n["before"] == n["after"] == n["oracle"] == sum(r["expected"] == "explained" for r in rep.per_case)
    )
    assert n["clean"] == sum(r["kind"] == "clean" for r in rep.per_case)
    acc = ident["accuracy"]
    for split in ("clean", "twin", "before", "after", "oracle"):
        per_channel = [v for ch, v in acc[split].items() if ch != "mean"]
        assert sorted(acc[split]) == sorted([*CHANNELS, "mean"])
        assert all(v * n[split] == pytest.approx(round(v * n[split])) for v in per_channel)  # k of n records
        assert acc[split]["mean"] == pytest.approx(np.mean(per_channel))
    # measured (deterministic): 6 of the 10 channel identifications of the clean twins are right, 5 before the
    # fix and 6 after it (7 before it with the search box of issue 9: the calibrated c, which picks the nominal
    # patterns, moved in the wider box of issue 10); the clean case (37.7 dB) is identified on a1, m_el and v2 only
    assert (acc["twin"]["mean"], acc["before"]["mean"], acc["after"]["mean"]) == pytest.approx((0.6, 0.5, 0.6))
    assert acc["clean"] == pytest.approx({"a1": 1.0, "m_el": 1.0, "omega1": 0.0, "a2": 0.0, "v2": 1.0, "mean": 0.6})
    # the paired difference is the difference of the channel means (same cases in both splits)
    assert ident["paired"]["after_minus_twin"] == pytest.approx(100 * (acc["after"]["mean"] - acc["twin"]["mean"]))
    # so is the diagnosis's share: after the fix minus the true effect's patterns
    assert ident["paired"]["after_minus_oracle"] == pytest.approx(100 * (acc["after"]["mean"] - acc["oracle"]["mean"]))
    assert "clean twins" in identification_markdown(ident)


def test_clean_twin_keeps_the_noise_and_removes_the_effect():
    from engine.evaluation.identification import clean_twins

    truth = {"K": 0.0047, "J1": 0.8, "c": 1.25, "effect": "supply_voltage", "value": 0.9}
    plant = PlantParameters(K=truth["K"], J1=truth["J1"], c=truth["c"])
    with_eff, clean = simulate(plant, effects={"supply_voltage": 0.9}), simulate(plant)
    rng = np.random.default_rng(3)
    noise = {k: rng.standard_normal(v.size) * 0.01 * np.std(v) for k, v in with_eff.channels.items()}
    rec = Record({k: v + noise[k] for k, v in with_eff.channels.items()}, conditions={"c1": 0.2})
    twin = clean_twins([truth], [rec])[0]
    for k in rec.channels:
        np.testing.assert_allclose(twin[k] - clean[k], noise[k], rtol=0, atol=1e-9 * np.std(clean[k]))
        assert not np.allclose(twin[k], rec[k])


def test_plots_are_written(rotor_case, tmp_path):
    from engine.diagnosis.plots import plot_gap_budget, plot_overlays, plot_residual_map

    rec, res = rotor_case
    for path in (
        plot_residual_map(res, tmp_path / "map.png"),
        plot_residual_map(res, tmp_path / "after.png", after=True),
        plot_overlays(rec, res, tmp_path / "overlay.png"),
        plot_gap_budget(res, tmp_path / "budget.png"),
    ):
        data = path.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_residual_maps_before_and_after_share_one_colour_scale(rotor_case, tmp_path, monkeypatch):
    """The maps before and after the fix are drawn with the same colour limits (issue 53): a closed gap looks
    cold next to the open one, instead of both being scaled to their own maximum."""
    from matplotlib.figure import Figure

    from engine.diagnosis.plots import plot_residual_map, residual_map_limits

    _, res = rotor_case
    limits = []
    save = Figure.savefig

    def spy(fig, *args, **kwargs):
        limits.append({im.get_clim() for ax in fig.axes for im in ax.get_images()})
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", spy)
    plot_residual_map(res, tmp_path / "map.png")
    plot_residual_map(res, tmp_path / "after.png", after=True)
    assert res.cells_after  # an explained record: the map after exists
    lo, hi = residual_map_limits(res)
    assert limits == [{(lo, hi)}, {(lo, hi)}]
    own_after = max(float(np.log10(max(c.energy, 1e-12) / max(c.noise_energy, 1e-12))) for c in res.cells_after)
    assert hi > own_after + 1  # the after map is not stretched to its own, much smaller, maximum


def test_gap_budget_plot_needs_a_named_effect(rotor_case, tmp_path):
    """A verdict that names no effect has no budget to draw: a clear error, no file."""
    from engine.diagnosis.plots import plot_gap_budget
    from engine.diagnosis.result import Verdict

    _, res = rotor_case
    bare = dataclasses.replace(res, verdict=Verdict.without_effect("unexplained", 0.9, "no fit"))
    with pytest.raises(ValueError, match="names no effect"):
        plot_gap_budget(bare, tmp_path / "budget.png")
    assert not (tmp_path / "budget.png").exists()


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="known shortfall, issue 50: two left-out effects of seed 11 are named as catalogued ones "
    "(case0005 motor viscous friction as motor Coulomb friction; case0008 supply voltage as rotor + stator "
    "resistance drift), the abstention misses the protocol-1 runs report (seed 227: the motor's electrical "
    "stand-in abstained 0/6, docs/validation/v1-seed227). Strict: the day the abstention holds, this fails "
    "and the marker goes.",
)
def test_blind_validation_ten_cases(tmp_path):
    """Ten blind cases (the benchmark runs 200): at most one wrong answer."""
    rep = run_validation(10, seed=11, out_dir=tmp_path, workers=2)
    wrong = [
        r
        for r in rep.per_case
        if not (r["status"] == r["expected"] and (r["named"] == r["effect"] or r["expected"] != "explained"))
    ]
    assert len(wrong) <= 1, wrong


@pytest.mark.slow  # 20 s
def test_candidate_fits_do_not_depend_on_the_number_of_threads():
    """Fitting candidates on two threads (each on one core) gives exactly the one-by-one result,
    escalation included (no candidate of this library explains the record, so every one is escalated)."""
    from engine.diagnosis import CandidateSettings, calibrate, default_space, fit_candidates
    from engine.simulation import EffectLibrary

    rec = noisy(simulate(PlantParameters(K=0.005, J1=0.86, c=1.2), effects={"load_inertia": 1.5}), 40.0, seed=21)
    lib = EffectLibrary([CATALOGUE[n] for n in ("measurement_delay", "contact_damping")])  # one per thread
    space = default_space(rec)
    nominal = calibrate(rec, space)
    runs = {n: fit_candidates(rec, nominal, space, lib, CandidateSettings(n_jobs=n)) for n in (1, 2)}
    assert all(c.calibration.stages for c in runs[1])
    for a, b in zip(runs[1], runs[2], strict=True):
        assert (a.effect, a.note) == (b.effect, b.note)
        assert a.value == pytest.approx(b.value, rel=1e-9, abs=1e-15) and a.bic == pytest.approx(b.bic, rel=1e-9)
    assert runs[1][0].calibration.reduced_chi2 > 1.1  # the escalation really ran


def test_a_running_fit_stops_when_cancelled(monkeypatch):
    """A calibration cancelled while it simulates (on the candidate fits' runner) stops before its next batch.

    The first simulation batch (the global search) signals that the fit has started and is held until the
    task has been cancelled; the fit must then raise ``Cancelled`` (a call that never started would raise
    ``CancelledError`` instead) without simulating anything more.
    """
    import threading

    import engine.diagnosis.objective as objective
    from engine.diagnosis import CalibrationSettings, calibrate
    from engine.parallel import Cancelled, Runner
    from engine.simulation import serial_kernel

    started, cancelled = threading.Event(), threading.Event()
    batches: list[int] = []
    real_run_cases = objective.run_cases

    def run_cases(cases, solver, grid, first=None):
        batches.append(len(cases))
        started.set()
        assert cancelled.wait(60), "the test never cancelled the fit"
        return real_run_cases(cases, solver, grid, first=first)

    monkeypatch.setattr(objective, "run_cases", run_cases)
    rec = noisy(simulate(PLANT), 40.0, seed=22)
    with Runner(2, thread_context=serial_kernel) as runner:
        task = runner.submit(calibrate, rec, None, CalibrationSettings(n_global=512, n_starts=8))
        assert started.wait(60), "the fit never started"
        assert not task.cancel()  # already running: it cannot be dropped, only stopped
        cancelled.set()
        with pytest.raises(Cancelled):  # stopped inside the fit, not run to the end
            task.result()
    assert batches == [512]  # the global search's batch, then nothing


def _cal(chi2_per_channel: dict[str, float], n_params: int):
    from engine.diagnosis import CalibrationResult

    values = {f"p{i}": 1.0 for i in range(n_params)}
    return CalibrationResult(
        values=values,
        uncertainties={},
        fixed={},
        chi2=sum(chi2_per_channel.values()),
        chi2_per_channel=dict(chi2_per_channel),
        n_data=2048 * len(chi2_per_channel),
        noise={},
        sigma={},
        effect=None,
        n_simulations=0,
        seconds=0.0,
    )


@pytest.mark.parametrize(
    ("nominal_omega1", "best_omega1", "strength", "expected", "confidence"),
    [
        # significant but weak residue nobody fits: not clearly beyond the noise; sure, since the
        # candidate's strength 1.2 is 6 scatters below 3
        # (weak_gap since issue 10: real, beyond the noise statistically, too weak to attribute)
        (2.3, 2.2, 1.2, "weak_gap", expit((3.0 - 1.2) / 0.3)),
        # the best candidate moves the record clearly: a real gap nobody explains; the best fit's
        # worst channel (2.2) is 25 scatters above 1.2
        (2.3, 2.2, 4.0, "unexplained", 1.0 - expit((1.2 - 2.2) / 0.04)),
        (12.0, 11.0, 1.0, "unexplained", 1.0),  # nominal misfit sqrt(11) > 3 noise RMS
        # a candidate fits (total chi2/n 1.0, 2.5 scatters below 1.05), the effect is clearly beyond the noise
        (12.0, 1.0, 5.0, "explained", expit((1.05 - 1.0) / 0.02) * expit((5.0 - 3.0) / 0.3)),
        # the same with an effect barely beyond the noise: explained, but with low confidence
        (12.0, 1.0, 3.1, "explained", expit((1.05 - 1.0) / 0.02) * expit((3.1 - 3.0) / 0.3)),
        (2.0, 1.0, 2.0, "weak_gap", 1.0 - expit((2.0 - 3.0) / 0.3)),  # a candidate fits, but the effect is weak
    ],
)
def test_decision_rule_uses_the_three_noise_rms_rule_in_every_branch(
    nominal_omega1, best_omega1, strength, expected, confidence
):
    from engine.diagnosis import Candidate

    flat = {"a1": 2048.0, "m_el": 2048.0, "a2": 2048.0, "v2": 2048.0}
    nominal = _cal({**flat, "omega1": 2048.0 * nominal_omega1}, 4)
    best_cal = _cal({**flat, "omega1": 2048.0 * best_omega1}, 5)
    assert nominal.bic - best_cal.bic >= 10  # evidence for the candidate in every row
    best = Candidate("supply_voltage", 0.999, 1e-4, "x", best_cal, best_cal.bic, strength=strength, weight=1.0)
    v = decide(nominal, [best], DiagnosisSettings())
    assert v.status == expected, v.reason
    # the decision's score; the stated confidence is its calibrated probability (engine.diagnosis.confidence)
    assert v.score == pytest.approx(confidence, rel=1e-12, abs=1e-15)
    # (an explained verdict's also allows for a stand-in at the nominal model's chi2/n: engine.diagnosis.open_world)
    stated = calibrated_confidence(expected, confidence, nominal_chi2=nominal.reduced_chi2)
    assert v.confidence == pytest.approx(stated, rel=1e-12)
