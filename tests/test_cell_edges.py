"""The flip tolerance of a speed quantum's fit (engine.diagnosis.cell_edges): a sample across a cell
edge that the fit cannot place counts at the record's level. Records are simulated here."""

from __future__ import annotations

import numpy as np
import pytest

from engine.constants import CHANNELS
from engine.diagnosis.calibration import calibrate
from engine.diagnosis.candidate import SEEDED_FITS
from engine.diagnosis.cell_edges import edge_spread, tolerant_levels
from engine.diagnosis.noise import estimate_noise
from engine.diagnosis.quantisation import fit_quantisation
from engine.diagnosis.space import default_space
from engine.records import Record
from engine.simulation import CATALOGUE, PlantParameters, SolverSettings, run_cases, simulate
from engine.simulation.noise import noise_std

Q = 0.25


def test_only_a_sample_just_across_the_nearer_edge_within_the_spread_takes_the_records_level() -> None:
    x = Q * np.array([2.499, 2.499, 2.501, 2.3, 2.499, 2.0, 2.499])
    y = Q * np.array([3.0, 3.0, 2.0, 3.0, 4.0, 2.0, 1.0])
    spread = np.array([0.01, 1e-4, 0.01, 0.01, 0.01, 0.01, 0.01])
    k = tolerant_levels(x, y, Q, spread)
    assert k.tolist() == [
        3.0,  # 0.001 q below the edge at 2.5 q, the record across it, spread 0.01 q: tolerated
        2.0,  # the same with a spread of 1e-4 q: 5 spreads, not tolerated
        2.0,  # 0.001 q above the edge, the record below it: tolerated
        2.0,  # 0.2 q from the edge: not tolerated
        2.0,  # the record two levels away: never
        2.0,  # in the cell: unchanged
        2.0,  # the record across the farther edge: not tolerated
    ]
    with pytest.raises(ValueError, match="q > 0"):
        tolerant_levels(x, y, 0.0, spread)


def test_the_spread_grows_with_the_quantums_uncertainty_and_needs_a_quantum() -> None:
    plant = PlantParameters(K=0.007, J1=0.95, c=1.3)
    rec = simulate(plant, effects={"speed_quantization": Q})
    space = default_space(rec)
    values = {"K": 0.007, "J1": 0.95, "c": 1.3}
    noise = {n: 1e-3 * float(np.std(rec[n])) for n in rec.channels}
    x, s0 = edge_spread(rec, space, values, noise, Q, 0.0, 2e-5)
    _, s1 = edge_spread(rec, space, values, noise, Q, 1e-3, 2e-5)
    ch, _, _ = run_cases([space.case(space.unit(values))], SolverSettings(max_step=2e-5), rec.grid)
    assert np.allclose(x, ch[0, CHANNELS.index("omega1")])
    assert np.all(np.isfinite(s0)) and np.all(s0 > 0)
    assert np.all(s1 >= s0) and np.max(s1 - s0) > 0
    with pytest.raises(ValueError, match="q > 0"):
        edge_spread(rec, space, values, noise, 0.0, 0.0, 2e-5)


def test_a_quantum_fit_with_the_tolerance_names_the_same_quantum_and_never_fits_worse() -> None:
    """The tolerance only changes the reported chi-square (and the rounded omega1), never q."""
    plant = PlantParameters(K=0.0062, J1=0.83, c=1.1, c1=0.2)
    clean = simulate(plant, effects={"speed_quantization": Q})
    rng = np.random.default_rng(3)
    channels = {k: v + rng.standard_normal(v.size) * noise_std(v, 45.0)[0] for k, v in clean.channels.items()}
    rec = Record(channels, clean.sample_interval, clean.event_index, conditions={"c1": 0.2}).test_window()[0]
    space = default_space(rec)
    noise = estimate_noise(rec)
    nominal = calibrate(rec, space, SEEDED_FITS, noise=noise, seeds=[{"K": 0.0062, "J1": 0.83, "c": 1.1}])
    fits = {
        tol: fit_quantisation(rec, nominal, space, CATALOGUE["speed_quantization"], 2000, SEEDED_FITS, SEEDED_FITS, tol)
        for tol in (True, False)
    }
    assert fits[True].values["speed_quantization"] == fits[False].values["speed_quantization"]
    assert fits[True].values["speed_quantization"] == pytest.approx(Q, rel=0.01)
    assert fits[True].chi2 <= fits[False].chi2
    sim = fits[True].simulation
    assert sim is not None
    q = fits[True].values["speed_quantization"]
    assert np.allclose(sim[CHANNELS.index("omega1")] / q, np.round(sim[CHANNELS.index("omega1")] / q))  # on levels
