"""The candidate fits: the seeded fits' difference step (pass 1) and the re-seeded pass (1b): fits from
the nominal calibration's global starts."""

from __future__ import annotations

import importlib
from dataclasses import replace

import numpy as np
import pytest

from engine.diagnosis.calibration import CalibrationResult, calibrate
from engine.diagnosis.candidate import SEEDED_FITS, Candidate, CandidateSettings, fit_candidate, refit_from_starts
from engine.diagnosis.space import default_space
from engine.records import Record
from engine.simulation import CATALOGUE, EffectLibrary, PlantParameters, simulate
from engine.simulation.noise import noise_std

candidates_module = importlib.import_module("engine.diagnosis.candidates")


def _noisy_window(plant: PlantParameters, effects: dict[str, float], snr_db: float, seed: int) -> Record:
    """The test window of a simulated record with white noise of ``snr_db`` per channel."""
    clean = simulate(plant, effects=effects)
    rng = np.random.default_rng(seed)
    channels = {k: v + rng.standard_normal(v.size) * noise_std(v, snr_db)[0] for k, v in clean.channels.items()}
    return Record(channels, clean.sample_interval, clean.event_index, conditions={"c1": 0.2}).test_window()[0]


def test_a_fit_from_the_nominal_starts_reaches_the_basin_the_nominal_fit_was_dragged_out_of() -> None:
    """Seed-137 case0004 in miniature: a Coulomb friction of 0.09 pu at K 13.4 mm drags the nominal fit to
    K 3.6 mm, where the seeded fit of the friction stays at zero; from a start near the early window's
    (K 14.6 mm) the refit finds the friction and fits to the noise."""
    plant = PlantParameters(K=0.0134, J1=0.724, c=0.833, c1=0.2)
    record = _noisy_window(plant, {"motor_coulomb_friction": 0.09}, 45.0, seed=3)
    space = default_space(record)
    cs = CandidateSettings()
    nominal = calibrate(record, space, cs.seeded, seeds=[{"K": 0.0035, "J1": 0.643, "c": 0.567}], polish=False)
    assert nominal.values["K"] < 0.005  # the wrong basin of the missing friction
    friction = CATALOGUE["motor_coulomb_friction"]
    seeded = fit_candidate(record, nominal, space, friction, cs, polish=False)
    assert seeded.calibration is not None and seeded.calibration.reduced_chi2 > 100  # stays there

    nominal.starts = [{"K": 0.0146, "J1": 0.70, "c": 0.9}]
    again = refit_from_starts(record, nominal, space, friction, cs)
    assert again.calibration is not None and again.calibration.reduced_chi2 < 1.2
    assert again.value == pytest.approx(0.09, rel=0.05)
    assert again.calibration.values["K"] == pytest.approx(0.0134, rel=0.05)

    # with the seeded fit and a start far from both as further seeds, refining only the seed that
    # simulates best on the full record (reseed_seed_fits = 1) still reaches the basin, and costs
    # fewer simulations than refining every seed
    nominal.starts = [{"K": 0.0146, "J1": 0.70, "c": 0.9}, {"K": 0.002, "J1": 1.1, "c": 1.9}]
    fits = {
        n: refit_from_starts(record, nominal, space, friction, replace(cs, reseed_seed_fits=n), seeded.calibration)
        for n in (1, None)
    }
    for fit in fits.values():
        assert fit.calibration is not None and fit.calibration.reduced_chi2 < 1.2
        assert fit.value == pytest.approx(0.09, rel=0.05)
    assert fits[1].calibration is not None and fits[None].calibration is not None
    assert fits[1].calibration.n_simulations < fits[None].calibration.n_simulations


def _fake_cal(reduced_chi2: float, starts: list[dict[str, float]] | None = None) -> CalibrationResult:
    n = 10_000
    return CalibrationResult(
        values={"K": 0.005, "J1": 0.8, "c": 1.0},
        uncertainties={},
        fixed={},
        chi2=reduced_chi2 * n,
        chi2_per_channel={"omega1": reduced_chi2 * n},
        n_data=n,
        noise={"omega1": 1.0},
        sigma={"omega1": 1.0},
        effect=None,
        n_simulations=0,
        seconds=0.0,
        starts=starts or [],
    )


def _candidate(name: str, reduced_chi2: float) -> Candidate:
    cal = _fake_cal(reduced_chi2)
    cal.values[name] = 1.0
    e = CATALOGUE[name]
    return Candidate(name, 1.0, 0.01, e.unit, cal, cal.bic, strength=10.0, locus=e.locus)


@pytest.mark.parametrize(
    ("seeded_chi2n", "starts", "reseeded"),
    [
        (5.0, [{"K": 0.01, "J1": 0.7, "c": 1.5}], True),  # none fits: every candidate but the quantum again
        (1.0, [{"K": 0.01, "J1": 0.7, "c": 1.5}], False),  # the best seeded fit is at the noise: no pass 1b
        (5.0, [], False),  # a nominal fit without a global search has no starts
    ],
)
def test_the_candidates_are_refitted_from_the_starts_only_when_no_seeded_fit_reaches_the_noise(
    monkeypatch: pytest.MonkeyPatch, seeded_chi2n: float, starts: list[dict[str, float]], reseeded: bool
) -> None:
    names = ["load_inertia", "sensor_gain", "speed_quantization"]
    library = EffectLibrary([CATALOGUE[n] for n in names])
    seeded = {"load_inertia": seeded_chi2n + 2.0, "sensor_gain": seeded_chi2n, "speed_quantization": seeded_chi2n + 1}
    refitted: list[str] = []

    def fake_fit(record, nominal, space, effect, settings, polish=True, global_search=False, extra_seeds=()):
        return _candidate(effect.name, seeded[effect.name])

    def fake_refit(record, nominal, space, effect, settings, previous=None):
        refitted.append(effect.name)
        return _candidate(effect.name, 1.0 if effect.name == "load_inertia" else 50.0)

    monkeypatch.setattr(candidates_module, "fit_candidate", fake_fit)
    monkeypatch.setattr(candidates_module, "refit_from_starts", fake_refit)
    settings = CandidateSettings(n_escalate=0, n_jobs=1)
    cands = candidates_module.fit_candidates(None, _fake_cal(20.0, starts), None, library, settings, escalate=False)
    if reseeded:
        assert sorted(refitted) == ["load_inertia", "sensor_gain"]  # the quantum is fitted by scans
        assert cands[0].effect == "load_inertia" and cands[0].calibration.reduced_chi2 == 1.0
        assert next(c for c in cands if c.effect == "sensor_gain").calibration.reduced_chi2 == seeded_chi2n  # kept
    else:
        assert refitted == []
        assert cands[0].effect == "sensor_gain"


def test_pass_1b_left_to_the_caller_runs_only_when_asked_and_keeps_an_escalated_fit_marked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``fit_candidates(..., reseed=False)`` refits nothing from the starts; :func:`reseed_candidates`
    then does, and a candidate escalated in between stays marked escalated when its refit is better."""
    from dataclasses import replace as dc_replace

    names = ["load_inertia", "sensor_gain"]
    library = EffectLibrary([CATALOGUE[n] for n in names])
    refitted: list[str] = []

    def fake_fit(record, nominal, space, effect, settings, polish=True, global_search=False, extra_seeds=()):
        return _candidate(effect.name, {"load_inertia": 8.0, "sensor_gain": 5.0}[effect.name])

    def fake_refit(record, nominal, space, effect, settings, previous=None):
        refitted.append(effect.name)
        return _candidate(effect.name, 1.0 if effect.name == "sensor_gain" else 50.0)

    monkeypatch.setattr(candidates_module, "fit_candidate", fake_fit)
    monkeypatch.setattr(candidates_module, "refit_from_starts", fake_refit)
    settings = CandidateSettings(n_escalate=0, n_jobs=1)
    nominal = _fake_cal(20.0, [{"K": 0.01, "J1": 0.7, "c": 1.5}])
    cands = candidates_module.fit_candidates(None, nominal, None, library, settings, escalate=False, reseed=False)
    assert refitted == [] and cands[0].effect == "sensor_gain"
    cands = [dc_replace(c, escalated=c.effect == "sensor_gain") for c in cands]  # as the early escalation leaves it
    out = candidates_module.reseed_candidates(None, nominal, None, library, cands, settings)
    assert refitted == ["sensor_gain"]  # ranked first, it fits to the noise: the rest keep their fits
    assert out[0].effect == "sensor_gain" and out[0].calibration.reduced_chi2 == 1.0 and out[0].escalated
    assert cands[0].calibration.reduced_chi2 == 5.0  # the caller's candidates stay as given
    refitted.clear()
    at_noise = [_candidate("load_inertia", 1.0) if c.effect == "load_inertia" else c for c in cands]
    out = candidates_module.reseed_candidates(None, nominal, None, library, at_noise, settings)
    assert out[0].effect == "load_inertia"
    assert refitted == []  # one fits to the noise already: no pass 1b


@pytest.mark.parametrize("n_jobs", [1, 2])
@pytest.mark.parametrize("stop", [True, False])
def test_the_refits_from_the_starts_stop_at_the_first_that_fits_to_the_noise(
    monkeypatch: pytest.MonkeyPatch, n_jobs: int, stop: bool
) -> None:
    """Pass 1b collects its refits in ranking order and stops at the first at the noise (whatever n_jobs)."""
    names = ["sensor_gain", "load_inertia", "supply_voltage", "motor_viscous_friction"]
    library = EffectLibrary([CATALOGUE[n] for n in names])
    seeded = {n: 5.0 + i for i, n in enumerate(names)}  # ranked in this order
    refitted: list[str] = []

    def fake_fit(record, nominal, space, effect, settings, polish=True, global_search=False, extra_seeds=()):
        return _candidate(effect.name, seeded[effect.name])

    def fake_refit(record, nominal, space, effect, settings, previous=None):
        refitted.append(effect.name)
        return _candidate(effect.name, 1.0 if effect.name in ("load_inertia", "motor_viscous_friction") else 50.0)

    monkeypatch.setattr(candidates_module, "fit_candidate", fake_fit)
    monkeypatch.setattr(candidates_module, "refit_from_starts", fake_refit)
    settings = CandidateSettings(n_escalate=0, n_jobs=n_jobs, reseed_stop_at_noise=stop)
    starts = [{"K": 0.01, "J1": 0.7, "c": 1.5}]
    cands = candidates_module.fit_candidates(None, _fake_cal(20.0, starts), None, library, settings, escalate=False)
    by_name = {c.effect: c for c in cands}
    assert cands[0].effect == "load_inertia" and cands[0].calibration.reduced_chi2 == 1.0
    later = by_name["motor_viscous_friction"]
    if stop:  # ranked after the first at the noise: its seeded fit stands, and says so
        assert later.calibration.reduced_chi2 == seeded["motor_viscous_friction"]
        assert "stopped once load_inertia fitted to the noise" in later.note
        assert "sensor_gain" in refitted and (n_jobs > 1 or refitted == ["sensor_gain", "load_inertia"])
    else:
        assert later.calibration.reduced_chi2 == 1.0 and sorted(refitted) == sorted(names)


def test_a_seeded_fit_refining_only_its_best_seed_finds_the_effect_for_fewer_simulations() -> None:
    """Pass 1 with ``seed_fits`` 1 (an option, not the default): of the nominal fit with the effect at
    neutral and at its scanned best, only the one that simulates better on the full record is refined."""
    plant = PlantParameters(K=0.006, J1=0.9, c=1.2, c1=0.2)
    record = _noisy_window(plant, {"load_inertia": 1.3}, 40.0, seed=5)
    space = default_space(record)
    cs = CandidateSettings()
    nominal = calibrate(record, space, cs.seeded, seeds=[{"K": 0.006, "J1": 0.9, "c": 1.2}], polish=False)
    fits = {
        n: fit_candidate(record, nominal, space, CATALOGUE["load_inertia"], replace(cs, seed_fits=n), False)
        for n in (1, None)
    }
    for fit in fits.values():
        assert fit.calibration is not None and fit.calibration.reduced_chi2 < 1.2
        assert fit.value == pytest.approx(1.3, rel=0.03)
    assert fits[1].calibration is not None and fits[None].calibration is not None
    assert fits[1].calibration.n_simulations < fits[None].calibration.n_simulations


@pytest.fixture(scope="module")
def creeping() -> tuple[Record, CalibrationResult]:
    """Seed-173 case0228 (tests/data/README.md): a sensor gain of 1.0958 at K 4.6 mm, J1 0.80, c 1.13,
    coloured noise at 35 dB, and its nominal calibration (the diagnosis's settings)."""
    import gzip
    import json
    from pathlib import Path

    from engine.diagnosis.diagnose import NOMINAL_CALIBRATION

    path = Path(__file__).parent / "data" / "v2-seed173-case0228.json.gz"
    record = Record.from_dict(json.loads(gzip.decompress(path.read_bytes()))).test_window()[0]
    return record, calibrate(record, default_space(record), NOMINAL_CALIBRATION)


#: The seeded fits' settings before 2026-11-27: differences over 1e-4 of the box.
COARSE_SEEDED = replace(SEEDED_FITS, fd_step=1e-4)


def test_the_seeded_fit_reaches_the_noise_along_a_valley_the_coarse_step_creeps_in(creeping) -> None:
    """Along a valley narrower in K than 1e-4 of the box (0.03 % of K) a seeded fit differencing over
    that step creeps: chi2/n 2.0 after its 30 evaluations. The default seeded fits difference over
    1e-5 and the gain fits to the noise within the same 30."""
    record, nominal = creeping
    space = default_space(record)
    gain = CATALOGUE["sensor_gain"]
    coarse = fit_candidate(record, nominal, space, gain, CandidateSettings(seeded=COARSE_SEEDED), polish=False)
    assert coarse.calibration.reduced_chi2 > 1.5  # creeping
    fine = fit_candidate(record, nominal, space, gain, CandidateSettings(), polish=False)
    assert fine.calibration.reduced_chi2 < 1.05
    assert fine.value == pytest.approx(1.0958, rel=0.01)
