"""The sensor library's periodic interference (engine.diagnosis.locus._interference).

Synthetic whitened residuals: a sinusoid of constant amplitude and phase in some channels is
taken, on those channels, at its frequency; noise alone and a ringing transient are not.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.diagnosis.locus._interference import is_motion, periodic_extension, segment_gain

N_CH, N_S, TS = 3, 2048, 1e-4
T = TS * np.arange(N_S)


def _offsets() -> np.ndarray:
    """An offset column per channel, as the sensor library's design holds."""
    design = np.zeros((N_CH * N_S, N_CH))
    for j in range(N_CH):
        design[j * N_S : (j + 1) * N_S, j] = 1.0
    return design


def _extension(e: np.ndarray):
    return periodic_extension(_offsets(), e.ravel(), T, N_CH, 0, np.zeros((N_CH * N_S, 0)), 4.0)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_noise_alone_takes_no_interference(seed: int) -> None:
    e = np.random.default_rng(seed).standard_normal((N_CH, N_S))
    assert _extension(e) is None


def test_a_hum_in_two_channels_is_taken_there_with_its_frequency_and_amplitude() -> None:
    rng = np.random.default_rng(7)
    e = rng.standard_normal((N_CH, N_S))
    e[0] += 3.0 * np.sin(2 * np.pi * 50.0 * T + 0.3)
    e[2] += 1.5 * np.sin(2 * np.pi * 50.0 * T - 1.1)
    hum = _extension(e)
    assert hum is not None
    assert hum.frequency_hz == pytest.approx(50.0, abs=0.1)
    assert set(hum.channels) == {0, 2}
    amplitude = dict(zip(hum.channels, np.hypot(hum.coef[:, 0], hum.coef[:, 1]), strict=True))
    assert amplitude[0] == pytest.approx(3.0, rel=0.05)
    assert amplitude[2] == pytest.approx(1.5, rel=0.05)
    assert hum.rss < float(np.sum(e**2)) and hum.penalty > 0


def test_a_ringing_transient_is_left_to_the_plant() -> None:
    """A decaying oscillation at 120 Hz, far above the noise: its amplitude changes from one stretch
    of the window to the next, so no channel is stationary and nothing is taken."""
    rng = np.random.default_rng(3)
    e = rng.standard_normal((N_CH, N_S))
    ring = 20.0 * np.exp(-T / 0.04) * np.sin(2 * np.pi * 120.0 * T)
    e[0] += ring
    e[1] += 0.5 * ring
    whole, gain = segment_gain(e, T, 120.0, 4)
    assert gain[0] > 0.3 * whole[0]
    assert _extension(e) is None


@pytest.mark.parametrize("phase", [0.0, 1.0, 2.0])
def test_a_sinusoid_below_the_band_is_not_an_interference(phase: float) -> None:
    """Two periods over the window (10 Hz, the band starts at 4 periods): a drift, which the loci's
    inputs hold as well; it is not taken at a neighbouring frequency of the band either."""
    rng = np.random.default_rng(5)
    e = rng.standard_normal((N_CH, N_S))
    e[1] += 5.0 * np.sin(2 * np.pi * 10.0 * T + phase)
    assert _extension(e) is None


def test_a_phasor_and_its_derivative_are_a_motion_and_unrelated_phasors_are_not() -> None:
    f, scale = 37.0, 0.2
    v = 0.3 - 0.7j
    assert is_motion(2j * np.pi * f * scale * v, v, f, scale)
    assert is_motion(1.1 * 2j * np.pi * f * scale * v, v, f, scale)  # within the tolerance
    assert not is_motion(-2j * np.pi * f * scale * v, v, f, scale)  # the wrong phase
    assert not is_motion(2 * np.pi * f * scale * v, v, f, scale)  # in phase: not a derivative
    assert not is_motion(1.0 + 0j, 0j, f, scale)


def test_a_periodic_motion_in_a_speed_and_its_acceleration_is_left_to_the_plant() -> None:
    """Channel 2 is channel 1's derivative (as a2 is v2's): a sinusoid at 37 Hz in both with the
    ratio of a motion is the plant moving (a periodic torque on the load), not an interference;
    the same sinusoids with an unrelated phase are."""
    rng = np.random.default_rng(11)
    w = 2 * np.pi * 37.0
    scale = 0.5  # whitened: derivative = scale * d(channel)/dt
    e = rng.standard_normal((N_CH, N_S))
    moving = e.copy()
    moving[1] += 2.0 * np.sin(w * T)
    moving[2] += scale * w * 2.0 * np.cos(w * T)
    motions = [(2, 1, scale)]
    args = (_offsets(), moving.ravel(), T, N_CH, 0, np.zeros((N_CH * N_S, 0)), 4.0)
    assert periodic_extension(*args, motions=motions) is None
    assert periodic_extension(*args) is not None  # without the relation it is one
    unrelated = e.copy()
    unrelated[1] += 2.0 * np.sin(w * T)
    unrelated[2] += scale * w * 2.0 * np.sin(w * T + 2.0)
    hum = periodic_extension(_offsets(), unrelated.ravel(), T, N_CH, 0, np.zeros((N_CH * N_S, 0)), 4.0, motions=motions)
    assert hum is not None and set(hum.channels) == {1, 2}
