"""The continuous width's 95 % profile-likelihood interval (engine.identification.width, issue 50 item 2).

On a simulated single-channel record (v2, c and c1 known: K and J1 fitted): the interval holds the
estimate and, on the clean record, the truth; it widens when part of the record's error is a
smooth disturbance instead of white noise of the same power; a misfit far above the noise warns.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from engine.constants import SAMPLE_INTERVAL, Z95
from engine.identification.width import MISFIT_WARN, WidthEstimate, estimate_width
from engine.records import Record
from engine.simulation import PlantParameters, simulate
from engine.simulation.noise import noise_std

TRUTH = PlantParameters(K=0.0063, J1=0.845, c=1.22)
CHANNEL = "v2"
#: Signal-to-noise ratio of the noisy records [dB].
SNR_DB = 40.0
#: Frequency of the smooth disturbance [Hz]: a few periods over the 0.2 s record, far below the
#: noise's band, so the noise estimate does not see it and the fit leaves it as correlated misfit.
DISTURBANCE_HZ = 35.0


def _record(x: np.ndarray) -> Record:
    return Record(channels={CHANNEL: x}, conditions={"c": TRUTH.c, "c1": 0.2})


def _sine(n: int, rms: float) -> np.ndarray:
    t = np.arange(n) * SAMPLE_INTERVAL
    return math.sqrt(2.0) * rms * np.sin(2.0 * math.pi * DISTURBANCE_HZ * t + 0.3)


@pytest.fixture(scope="module")
def clean() -> np.ndarray:
    return np.asarray(simulate(TRUTH)[CHANNEL], dtype=float)


@pytest.fixture(scope="module")
def white(clean: np.ndarray) -> WidthEstimate:
    """The record plus white noise of standard deviation ``sd`` (SNR_DB)."""
    sd = float(noise_std(clean, SNR_DB)[0])
    return estimate_width(_record(clean + np.random.default_rng(1).standard_normal(clean.size) * sd))


@pytest.fixture(scope="module")
def structured(clean: np.ndarray) -> WidthEstimate:
    """The same total error power, half of it a smooth sinusoid instead of white noise."""
    sd = float(noise_std(clean, SNR_DB)[0])
    half = sd / math.sqrt(2.0)
    noise = np.random.default_rng(1).standard_normal(clean.size) * half
    return estimate_width(_record(clean + noise + _sine(clean.size, half)))


def test_interval_holds_estimate_and_truth_on_the_clean_record(clean: np.ndarray) -> None:
    est = estimate_width(_record(clean))
    lo, hi = est.interval_95
    assert lo < est.K < hi
    assert 0.0 < hi - lo < 0.01 * TRUTH.K
    assert lo <= TRUTH.K <= hi
    assert est.sigma_K == pytest.approx((hi - lo) / (2.0 * Z95))
    assert est.identifiable and est.reason is None and est.warnings == []
    assert len(est.profile) >= 5  # a profile was scanned, both sides
    assert min(k for k, _ in est.profile) < est.K < max(k for k, _ in est.profile)
    d = json.loads(json.dumps(est.to_dict()))
    assert d["interval_95"] == [lo, hi] and d["identifiable"] is True and d["reason"] is None
    assert d["warnings"] == []


def test_interval_on_white_noise_is_finite_and_honest(white: WidthEstimate) -> None:
    lo, hi = white.interval_95
    assert lo <= white.K <= hi and 0.0 < hi - lo < 0.01 * TRUTH.K
    # one noise draw: the truth lies inside 95 % of the time (the benchmark's coverage), and never
    # several half-widths away
    assert abs(white.K - TRUTH.K) <= 1.5 * (hi - lo)
    assert white.tau < 1.5  # a fit to the noise: the residual is white
    assert white.warnings == []


def test_interval_widens_for_structured_error_of_the_same_power(
    white: WidthEstimate, structured: WidthEstimate
) -> None:
    w_white = white.interval_95[1] - white.interval_95[0]
    w_struct = structured.interval_95[1] - structured.interval_95[0]
    assert structured.tau > 2.0 * white.tau  # the disturbance left in the residual is correlated
    assert structured.scale > 2.0 * white.scale
    assert w_struct > 1.5 * w_white
    assert structured.interval_95[0] <= structured.K <= structured.interval_95[1]


def test_misfit_far_above_the_noise_warns(clean: np.ndarray) -> None:
    sd = float(noise_std(clean, SNR_DB)[0])
    noise = np.random.default_rng(2).standard_normal(clean.size) * sd
    est = estimate_width(_record(clean + noise + _sine(clean.size, 3.0 * sd)))
    assert est.calibration.reduced_chi2 > MISFIT_WARN
    codes = [w.code for w in est.warnings]
    assert codes == ["misfit"]
    assert est.warnings[0].channel == CHANNEL
    d = est.to_dict()
    assert d["warnings"][0]["code"] == "misfit" and "noise" in d["warnings"][0]["message"]
    assert est.interval_95[0] <= est.K <= est.interval_95[1]


# -- the edge search on known profiles (no simulation) --------------------------------------------


def test_edge_search_finds_a_quadratic_profile_s_crossing() -> None:
    from engine.identification.width import _edge

    K0, a, threshold = 0.005, 4.0e12, 3.84  # chi2 = a (K - K0)^2: the crossing at sqrt(threshold / a)
    calls: list[float] = []

    def profile(K: float) -> float:
        calls.append(K)
        return 100.0 + a * (K - K0) ** 2

    half = math.sqrt(threshold / a)
    for step in (0.01 * half, half, 30.0 * half):  # a Gauss-Newton sd far too small, right, far too large
        calls.clear()
        hi, at_edge = _edge(profile, K0, 100.0, step, 0.015, threshold)
        assert not at_edge and hi == pytest.approx(K0 + half, rel=1e-6)
        lo, _ = _edge(profile, K0, 100.0, step, 0.001, threshold)
        assert lo == pytest.approx(K0 - half, rel=1e-6)
        assert len(calls) <= 16  # a handful of refits per side


def test_edge_search_reports_a_profile_the_box_does_not_bound() -> None:
    from engine.identification.width import _edge

    edge, at_edge = _edge(lambda K: 50.0 + 1e2 * abs(K - 0.005), 0.005, 50.0, 1e-7, 0.015, 3.84)
    assert at_edge and edge == 0.015
    edge, at_edge = _edge(lambda K: 50.0, 0.005, 50.0, 1e-7, 0.001, 3.84)
    assert at_edge and edge == 0.001
