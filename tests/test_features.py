"""Tests of engine.features.wavelet: layout, analytic and independent references, Parseval, reconstruction, bands, errors."""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest
import pywt

from engine.constants import CHANNEL_WAVELETS, CHANNELS
from engine.features import channel_features, level_slices, wavelet_coefficients, wavelet_reconstruct

N = 2048
TS = 1e-4


def reference_signal() -> np.ndarray:
    """A deterministic test signal with a decaying 60 Hz tone, a 1 kHz tone and a ramp.

    ``x[k] = exp(-t/0.05) sin(2 pi 60 t) + 0.25 cos(2 pi 1000 t) + 0.1 k / 2048``
    with ``t = k * 1e-4 s``, ``k = 0 .. 2047``.
    """
    k = np.arange(N)
    t = k * TS
    return np.exp(-t / 0.05) * np.sin(2 * np.pi * 60 * t) + 0.25 * np.cos(2 * np.pi * 1000 * t) + 0.1 * k / N


def periodized_dwt(x: np.ndarray, wavelet: str, level: int) -> np.ndarray:
    """Independent periodized multilevel DWT (Mallat's algorithm) from the filter coefficients alone.

    One level maps a periodic signal a of even length n onto
    ``cA[k] = sum_j lo[j] a[(2k + L/2 - j) mod n]`` and the same with the
    high-pass ``hi`` for cD (L: filter length; ``L/2`` is PyWavelets' alignment
    of the periodized transform, the only convention taken from it), and
    recurses on cA. Layout ``[cA_level, cD_level, ..., cD1]``.
    """
    w = pywt.Wavelet(wavelet)
    lo, hi = np.asarray(w.dec_lo), np.asarray(w.dec_hi)
    L = len(lo)
    a = np.asarray(x, dtype=float)
    details = []
    for _ in range(level):
        n = len(a)
        idx = (2 * np.arange(n // 2)[:, None] + L // 2 - np.arange(L)[None, :]) % n  # (n/2, L)
        details.append(a[idx] @ hi)
        a = a[idx] @ lo
    return np.concatenate([a, *reversed(details)])


@pytest.mark.parametrize("wavelet", ["sym5", "db6", "haar", "db2"])
@pytest.mark.parametrize("level", [1, 3, 10])
def test_matches_independent_filter_bank(wavelet: str, level: int) -> None:
    """Same coefficients as a from-scratch filter bank, including the paper's level 10 and the layout."""
    x = reference_signal()
    np.testing.assert_allclose(
        wavelet_coefficients(x, wavelet, level=level), periodized_dwt(x, wavelet, level), rtol=0, atol=1e-12
    )


@pytest.mark.parametrize(("wavelet", "moments"), [("sym5", 5), ("db6", 6)])
def test_vanishing_moments(wavelet: str, moments: int) -> None:
    """A polynomial of degree below the number of vanishing moments leaves no level-1 detail.

    Checked away from the wrap-around, where the periodized record jumps from
    its end to its start, on a short record (64 samples, t in [0, 1)) so that
    one degree more leaves a clearly visible detail (measured: 5.5e-8 for sym5,
    5.0e-9 for db6, against at most 3.3e-12 below: the precision of the stored
    filter coefficients).
    """
    n = 64
    t = np.arange(n) / n
    half = pywt.Wavelet(wavelet).dec_len // 2
    interior = slice(n // 2 + half, n - half)  # cD1 without the coefficients that wrap around
    for degree in range(moments):
        c = wavelet_coefficients(t**degree, wavelet, level=1)
        np.testing.assert_allclose(c[interior], 0.0, atol=1e-10, err_msg=f"degree {degree}")
    c = wavelet_coefficients(t**moments, wavelet, level=1)
    assert np.min(np.abs(c[interior])) > 1e-9


def test_haar_ramp_analytic() -> None:
    """Haar of a ramp x[k] = k: every level-j detail is -2**(3j/2 - 2); cA10[k] = 32 (1024 k + 511.5)."""
    c = wavelet_coefficients(np.arange(N, dtype=float), "haar")
    bands = {b.name: b for b in level_slices()}
    np.testing.assert_allclose(c[bands["cA10"].slice], [32 * 511.5, 32 * (1024 + 511.5)], rtol=1e-14)
    for j in range(1, 11):
        np.testing.assert_allclose(c[bands[f"cD{j}"].slice], -(2.0 ** (1.5 * j - 2)), rtol=1e-12, err_msg=f"cD{j}")


def test_haar_constant_analytic() -> None:
    """Independent reference: Haar of a constant a gives cA10 = a * 2**5 (twice) and zero details."""
    c = wavelet_coefficients(np.full(N, 3.0), "haar")
    np.testing.assert_allclose(c[:2], [3.0 * 32, 3.0 * 32])
    np.testing.assert_allclose(c[2:], 0.0, atol=1e-12)


def test_haar_impulse_analytic() -> None:
    """Haar of a unit impulse at 0: cD1[0] = 1/sqrt(2), cD_j[0] = 2**(-j/2), cA10[0] = 2**-5."""
    x = np.zeros(N)
    x[0] = 1.0
    c = wavelet_coefficients(x, "haar")
    bands = {b.name: b for b in level_slices()}
    assert c[bands["cA10"].slice][0] == pytest.approx(2.0**-5)
    for j in range(1, 11):
        block = c[bands[f"cD{j}"].slice]
        assert block[0] == pytest.approx(2.0 ** (-j / 2)), j
        np.testing.assert_allclose(block[1:], 0.0, atol=1e-15)


@pytest.mark.parametrize("wavelet", ["sym5", "db6"])
def test_layout_matches_wavedec(wavelet: str) -> None:
    """Same numbers as the plain 1-D pywt.wavedec list, concatenated coarsest first."""
    x = reference_signal()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        parts = pywt.wavedec(x, wavelet, mode="periodization", level=10)
    assert [len(p) for p in parts] == [2, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024]
    np.testing.assert_array_equal(wavelet_coefficients(x, wavelet), np.concatenate(parts))


@pytest.mark.parametrize("wavelet", ["sym5", "db6"])
def test_parseval(wavelet: str) -> None:
    x = np.random.default_rng(1).standard_normal((5, N)) * [[1.0], [10.0], [0.1], [3.0], [1e3]]
    c = wavelet_coefficients(x, wavelet)
    np.testing.assert_allclose((c**2).sum(axis=1), (x**2).sum(axis=1), rtol=1e-12)


@pytest.mark.parametrize("wavelet", ["sym5", "db6"])
def test_perfect_reconstruction(wavelet: str) -> None:
    x = np.random.default_rng(2).standard_normal((3, N))
    c = wavelet_coefficients(x, wavelet)
    np.testing.assert_allclose(wavelet_reconstruct(c, wavelet), x, atol=1e-10)


def test_batch_equals_rows_and_axis() -> None:
    x = np.random.default_rng(3).standard_normal((4, N))
    batch = wavelet_coefficients(x, "sym5")
    for r in range(4):
        np.testing.assert_array_equal(batch[r], wavelet_coefficients(x[r], "sym5"))
    np.testing.assert_array_equal(wavelet_coefficients(x.T, "sym5", axis=0).T, batch)


def test_no_level_warning_but_others_pass() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        wavelet_coefficients(reference_signal(), "sym5")  # level 10 > dwt_max_level = 7: silenced on purpose


@pytest.mark.parametrize("channel", CHANNELS)
def test_channel_features_use_paper_wavelet(channel: str) -> None:
    x = reference_signal()
    np.testing.assert_array_equal(channel_features(x, channel), wavelet_coefficients(x, CHANNEL_WAVELETS[channel]))


def test_level_slices_layout_and_bands() -> None:
    bands = level_slices()
    assert [b.name for b in bands] == ["cA10"] + [f"cD{j}" for j in range(10, 0, -1)]
    assert bands[0].slice == slice(0, 2) and bands[-1].slice == slice(1024, 2048)
    assert sum(b.size for b in bands) == N
    assert all(a.slice.stop == b.slice.start for a, b in itertools.pairwise(bands))
    assert bands[0].f_low == 0.0 and bands[0].f_high == pytest.approx(10000 / 2**11)
    cd1 = bands[-1]
    assert (cd1.f_low, cd1.f_high) == (2500.0, 5000.0)
    assert all(a.f_high == pytest.approx(b.f_low) for a, b in itertools.pairwise(bands))


@pytest.mark.parametrize(("freq", "name"), [(60.0, "cD7"), (1000.0, "cD3"), (3500.0, "cD1")])
def test_band_holds_the_energy_of_a_tone(freq: float, name: str) -> None:
    """A tone in the middle of a band puts most of its energy in that band's block."""
    t = np.arange(N) * TS
    c = wavelet_coefficients(np.sin(2 * np.pi * freq * t), "db6")
    energy = {b.name: float((c[b.slice] ** 2).sum()) for b in level_slices()}
    assert max(energy, key=energy.get) == name


@pytest.mark.parametrize(
    ("x", "kwargs"),
    [
        (np.zeros(2000), {}),  # not a multiple of 2**10
        (np.zeros(1024), {"level": 11}),  # level > log2(n)
        (np.zeros(N), {"level": 0}),
        (np.zeros((2, 3, N)), {}),  # 3-D
        (np.zeros(N), {"axis": 1}),
    ],
)
def test_impossible_input_raises(x: np.ndarray, kwargs: dict) -> None:
    with pytest.raises(ValueError):
        wavelet_coefficients(x, "sym5", **kwargs)


def test_nan_raises() -> None:
    x = reference_signal()
    x[100] = np.nan
    with pytest.raises(ValueError, match="finite"):
        wavelet_coefficients(x, "sym5")


def test_unknown_wavelet_and_channel_raise() -> None:
    with pytest.raises(ValueError, match="wavelet"):
        wavelet_coefficients(reference_signal(), "nope7")
    with pytest.raises(ValueError, match="channel"):
        channel_features(reference_signal(), "torque")
