"""The speed quantum read from the record's own lattice of omega1 values (engine.diagnosis.quantisation).

Records are simulated here (MODEL.md's plant with the catalogue's effects, white noise of the
stated SNR), never taken from a validation run.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.diagnosis.quantisation import LATTICE_MIN_LEVELS, lattice_quantum, quanta
from engine.records import Record
from engine.simulation import CATALOGUE, PlantParameters, simulate
from engine.simulation.noise import noise_std

BOUNDS = CATALOGUE["speed_quantization"].bounds
PLANT = PlantParameters(K=0.007, J1=0.95, c=1.3)


def noisy_omega(record: Record, snr_db: float, seed: int) -> np.ndarray:
    w = np.asarray(record["omega1"], dtype=float)
    rng = np.random.default_rng(seed)
    return w + rng.standard_normal(w.size) * noise_std(w, snr_db)[0]


@pytest.fixture(scope="module")
def clean() -> Record:
    return simulate(PLANT)


@pytest.mark.parametrize(("q", "snr_db", "seed"), [(0.12, 45.0, 1), (0.3, 40.0, 2), (0.45, 35.0, 3)])
def test_a_rounded_speed_shows_its_quantum(q: float, snr_db: float, seed: int) -> None:
    w = noisy_omega(simulate(PLANT, effects={"speed_quantization": q}), snr_db, seed)
    lat = lattice_quantum(w, BOUNDS)
    assert lat is not None
    assert lat.q == pytest.approx(q, rel=0.01)
    assert lat.r > 0.9
    assert lat.levels >= LATTICE_MIN_LEVELS


def test_a_sensor_offset_after_the_rounding_does_not_hide_the_lattice() -> None:
    """An offset shifts every level by the same phase: R(q) is the modulus, blind to it."""
    rec = simulate(PLANT, effects={"speed_quantization": 0.25})
    w = noisy_omega(rec, 40.0, 4) + 0.0731
    lat = lattice_quantum(w, BOUNDS)
    assert lat is not None and lat.q == pytest.approx(0.25, rel=0.01)


@pytest.mark.parametrize(("snr_db", "seed"), [(30.0, 5), (40.0, 6), (50.0, 7)])
def test_an_unrounded_speed_shows_no_lattice(clean: Record, snr_db: float, seed: int) -> None:
    """The drive at rest before switch-on and its steady state are plateaus, concentrated at any q:
    each counts as one level, so they do not make a lattice."""
    assert lattice_quantum(noisy_omega(clean, snr_db, seed), BOUNDS) is None


def test_noise_as_large_as_the_quantum_hides_it() -> None:
    rec = simulate(PLANT, effects={"speed_quantization": 0.1})
    w = np.asarray(rec["omega1"]) + np.random.default_rng(8).standard_normal(rec.n_samples) * 0.1
    assert lattice_quantum(w, BOUNDS) is None


def test_a_record_spanning_too_few_quanta_shows_none() -> None:
    w = 0.4 * np.round(np.linspace(0.0, 1.5, 2000) / 0.4)  # four levels
    assert lattice_quantum(w, BOUNDS) is None
    assert lattice_quantum(np.zeros(100), BOUNDS) is None
    assert lattice_quantum(np.array([]), BOUNDS) is None


def test_the_dense_scan_adds_quanta_around_the_lattice_spacing(clean: Record) -> None:
    w = noisy_omega(simulate(PLANT, effects={"speed_quantization": 0.2}), 40.0, 9)
    q = quanta(w, BOUNDS, 400)
    near = q[np.abs(q - 0.2) < 0.004]
    assert near.size >= 50  # the lattice band, besides the ~3 of the even grid
    assert np.all(np.diff(q) > 0) and q[0] == BOUNDS[0] and q[-1] == BOUNDS[1]
    plain = quanta(noisy_omega(clean, 40.0, 9), BOUNDS, 400)
    assert plain.size == 400
