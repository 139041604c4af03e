"""The residual of a model's unrounded speed against a rounded record's cells (engine.diagnosis.quantisation.CellResidual),
the channel residuals of the objective that carry it (engine.diagnosis.objective), and the noise a fit's strengths
are measured in (engine.diagnosis.candidate.strength_noise). Records are simulated here."""

from __future__ import annotations

import importlib
from types import SimpleNamespace

import numpy as np
import pytest

from engine.constants import CHANNELS
from engine.diagnosis import quantisation
from engine.diagnosis.candidate import SEEDED_FITS, strength_noise
from engine.diagnosis.noise import NOISE_FLOOR_REL, estimate_noise, noise_weights
from engine.diagnosis.objective import Objective
from engine.diagnosis.quantisation import CellResidual
from engine.diagnosis.space import default_space
from engine.records import Record
from engine.simulation import CATALOGUE, PlantParameters, SolverSettings, simulate
from engine.simulation.noise import noise_std
from engine.validation.noise import NoiseSpec, render_noise

sets_module = importlib.import_module("engine.diagnosis.sets")

Q = 0.3


def test_a_value_inside_its_recorded_cell_costs_nothing_and_one_outside_costs_its_distance() -> None:
    cells = CellResidual(Q, 0.01)
    data = np.full(7, 2 * Q)  # recorded level k = 2: the cell [0.45, 0.75)
    x = np.array([[0.6, 0.5, 0.7, 0.75 + 0.003, 0.75 + 0.03, 0.45 - 0.03, 0.6 + 10 * Q]])
    r = cells(x, data)[0]
    assert r[0] == 0.0
    assert abs(r[1]) < 1e-6 and abs(r[2]) < 1e-6  # inside, more than 5 widths from the edges
    assert r[3] > 0 and r[5] < 0  # above the cell: positive, below: negative
    assert r[4] == pytest.approx(0.03 / (0.01 * Q), rel=0.1)  # 10 widths out: about the distance over the width
    assert r[5] == pytest.approx(-r[4], rel=1e-9)
    assert np.isfinite(r[6]) and r[6] > r[4]  # far away: finite, larger


def test_the_residual_is_continuous_across_a_cell_edge() -> None:
    cells = CellResidual(Q, 0.05)
    edge = 1.5 * Q
    x = edge + np.linspace(-3e-3, 3e-3, 61)[None, :]
    r = cells(x, np.full(61, Q))[0]  # recorded level 1: its upper edge at 1.5 q
    assert np.all(np.diff(r) > 0)  # rising through the edge
    assert np.max(np.abs(np.diff(r))) < 0.2  # no jump at the edge


def test_a_residual_that_takes_the_quantum_uses_each_rows_value() -> None:
    cells = CellResidual(Q, 0.05, takes="speed_quantization")
    data = np.array([3 * Q, 3 * Q])
    x = np.full((2, 2), 3.6 * Q)
    r = cells(x, data, np.array([Q, 1.15 * Q]))
    assert np.all(r[0] > 1.0)  # 3.6 q lies above cell 3 of q, [2.5 q, 3.5 q) ...
    assert np.allclose(r[1], 0.0, atol=1e-5)  # ... and 7 widths inside cell round(3 / 1.15) = 3 of 1.15 q


def test_impossible_cells_are_refused() -> None:
    with pytest.raises(ValueError, match="q > 0 and width > 0"):
        CellResidual(0.0, 0.1)
    with pytest.raises(ValueError, match="q > 0 and width > 0"):
        CellResidual(Q, 0.0)


def test_the_objective_simulates_without_the_quantum_a_channel_residual_takes() -> None:
    rec = simulate(PlantParameters(K=0.007, J1=0.95, c=1.3), effects={"speed_quantization": Q})
    space = default_space(rec).with_effect(CATALOGUE["speed_quantization"])
    cells = CellResidual(Q, 0.1, takes="speed_quantization")
    obj = Objective(rec, space, noise_weights(rec, estimate_noise(rec)), {"omega1": cells})
    assert obj.taken == ("speed_quantization",)
    u = space.unit({"K": 0.007, "J1": 0.95, "c": 1.3, "c1": 0.2, "speed_quantization": Q})
    solver = SolverSettings(max_step=5e-5)
    sims, _ = obj.simulate(u[None], solver)
    omega = sims[0, obj.names.index("omega1")]
    assert not np.allclose(omega, Q * np.round(omega / Q))  # unrounded: the quantum was left out
    n = obj.n_simulations
    other_q = u.copy()
    other_q[-1] = 0.9
    c2 = obj.chi2(np.stack([u, other_q]), [rec.n_samples], solver)[:, 0]
    assert obj.n_simulations == n  # another q needs no simulation
    assert c2[0] < c2[1]  # the true q fits the recorded cells better


def test_a_channel_residual_must_name_a_recorded_channel_and_a_fitted_effect() -> None:
    full = simulate(PlantParameters(K=0.007, J1=0.95, c=1.3))
    rec = full.with_channels({n: full[n] for n in ("m_el", "omega1")})
    space = default_space(rec)
    with pytest.raises(ValueError, match="does not hold"):
        Objective(rec, space, noise_weights(rec, estimate_noise(rec)), {"a2": CellResidual(Q, 0.1)})
    with pytest.raises(ValueError, match="does not fit"):
        Objective(
            rec,
            space,
            noise_weights(rec, estimate_noise(rec)),
            {"omega1": CellResidual(Q, 0.1, takes="speed_quantization")},
        )


def _fit_of(sim: np.ndarray) -> SimpleNamespace:
    return SimpleNamespace(simulation=sim)


def test_strengths_are_measured_in_the_noise_a_fit_leaves_when_the_estimate_is_larger() -> None:
    rec = simulate(PlantParameters(K=0.007, J1=0.95, c=1.3))
    rng = np.random.default_rng(3)
    clean = np.stack([np.asarray(rec[n]) for n in CHANNELS])
    sd = 0.01 * np.sqrt(np.mean(clean**2, axis=1))
    noisy = rec.with_channels(
        {n: clean[j] + sd[j] * rng.standard_normal(clean.shape[1]) for j, n in enumerate(CHANNELS)}
    )
    fit = _fit_of(clean)  # a fit that leaves exactly the noise
    estimate = {n: 2.0 * sd[j] for j, n in enumerate(CHANNELS)}  # an estimate twice too large
    got = strength_noise(noisy, fit, estimate)
    for j, n in enumerate(CHANNELS):
        assert got[n] == pytest.approx(sd[j], rel=0.05)
    smaller = {n: 0.5 * sd[j] for j, n in enumerate(CHANNELS)}  # below what the fit leaves: kept
    assert strength_noise(noisy, fit, smaller) == pytest.approx(smaller)


def test_the_noise_of_a_perfect_fit_is_floored_and_a_fit_on_another_grid_changes_nothing() -> None:
    rec = simulate(PlantParameters(K=0.007, J1=0.95, c=1.3))
    clean = np.stack([np.asarray(rec[n]) for n in CHANNELS])
    estimate = dict.fromkeys(CHANNELS, 1.0)
    got = strength_noise(rec, _fit_of(clean), estimate)  # noiseless record, exact fit: the floor
    for j, n in enumerate(CHANNELS):
        assert got[n] == pytest.approx(NOISE_FLOOR_REL * np.sqrt(np.mean(clean[j] ** 2)))
    assert strength_noise(rec, _fit_of(clean[:, :-1]), estimate) == estimate
    assert strength_noise(rec, SimpleNamespace(simulation=None), estimate) == estimate


def test_fitting_q_with_the_plant_on_the_cells_unsticks_a_quantum_beside_a_low_pass(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The shape of seed-151 case0058 (development data): a low-pass and a quantum seen on m_el and
    omega1 only, coloured noise. Scanning q at a fixed fit and refitting at a fixed q stalls with c
    far off (q trades against the plant's scale of omega1); the joint fit on the recorded cells
    brings c back and lowers the rounded model's chi-square."""
    plant = PlantParameters(K=0.003, J1=0.66, c=1.05, c1=0.2)
    clean = simulate(plant, effects={"sensor_lowpass": 1520.0, "speed_quantization": 0.267})
    names = ("m_el", "omega1")
    x = np.stack([np.asarray(clean[n]) for n in names])
    std = np.array([noise_std(v, 36.0)[0] for v in x])
    spec = NoiseSpec(dict.fromkeys(names, 36.0), order=1, cutoff_hz=790.0)
    x = x + render_noise(x.shape, std, spec, clean.sample_interval, np.random.default_rng(3))
    rec, _ = Record(
        dict(zip(names, x, strict=True)), clean.sample_interval, clean.event_index, conditions={"c1": 0.2}
    ).test_window()
    space = default_space(rec)
    noise = estimate_noise(rec)
    members = [CATALOGUE["sensor_lowpass"], CATALOGUE["speed_quantization"]]
    seeds = [{"K": 0.003, "J1": 0.67, "c": 1.15, "sensor_lowpass": 1500.0}]  # where the old fits stall
    new = sets_module._fit_set(rec, space, members, SEEDED_FITS, noise, seeds, True)
    monkeypatch.setattr(quantisation, "CELL_WIDTHS", ())
    old = sets_module._fit_set(rec, space, members, SEEDED_FITS, noise, seeds, True)
    assert new is not None and old is not None
    assert new.reduced_chi2 < 0.7 * old.reduced_chi2
    assert abs(new.values["c"] - 1.05) < 0.02 < abs(old.values["c"] - 1.05)
    assert new.values["speed_quantization"] == pytest.approx(0.267, rel=0.02)  # q still trades a little against J1
