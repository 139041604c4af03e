"""Tests of engine.features.wavelet: layout, references, Parseval, reconstruction, bands, errors."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import pywt

from engine.constants import CHANNEL_WAVELETS, CHANNELS
from engine.features import channel_features, level_slices, wavelet_coefficients, wavelet_reconstruct

N = 2048
TS = 1e-4


def reference_signal() -> np.ndarray:
    """The deterministic signal the stored references below were computed from.

    ``x[k] = exp(-t/0.05) sin(2 pi 60 t) + 0.25 cos(2 pi 1000 t) + 0.1 k / 2048``
    with ``t = k * 1e-4 s``, ``k = 0 .. 2047``.
    """
    k = np.arange(N)
    t = k * TS
    return np.exp(-t / 0.05) * np.sin(2 * np.pi * 60 * t) + 0.25 * np.cos(2 * np.pi * 1000 * t) + 0.1 * k / N


# Stored reference: computed once with PyWavelets 1.8.0, numpy 2.4, by
#   c = wavelet_coefficients(reference_signal(), w)   (mode="periodization", level=10)
#   c[:16]          -> cA10 (2), cD10 (2), cD9 (4), cD8 (8)
#   c[256:260]      -> first 4 of cD3
#   c[1024:1028]    -> first 4 of cD1
REFERENCE = {
    "sym5": {
        0: [
            1.0415847083820997,
            2.9769162546763153,
            -0.7970502271284446,
            -0.6203894284059243,
            -0.5157436763011267,
            0.17185883485011433,
            0.255362654348649,
            -0.9879377355582857,
            -1.3818386772723086,
            -0.12402834076678547,
            -0.03832268677156104,
            0.025324717207688727,
            -0.027696787847818597,
            -0.008949512127911865,
            0.3396907494089381,
            -1.2724326554191239,
        ],
        256: [0.20263995680010452, 0.6817729696585848, 0.2080596359712271, -0.5171757993994588],
        1024: [0.03697800134921071, 0.010793089799456312, 0.0029415574609316783, -0.00766203598926974],
    },
    "db6": {
        0: [
            1.063360218126681,
            2.9551407449366605,
            0.6420889127173934,
            0.7020615635397479,
            0.273263347501175,
            -0.13124097528639203,
            0.37211242449346055,
            1.5334240696386425,
            0.44846258936618205,
            -0.34752135096877473,
            0.11011686279824572,
            -0.03921387221533029,
            0.03303728919202085,
            -0.026211503489792072,
            0.23835473049968509,
            2.1810107620114856,
        ],
        256: [0.5066758776129342, 0.3855573435824482, -0.4238771077694928, -0.6086775885734039],
        1024: [-0.005449648380861763, -0.0034171916938142105, -0.004680778734992679, 0.000727041643219889],
    },
}


@pytest.mark.parametrize("wavelet", ["sym5", "db6"])
def test_stored_reference(wavelet: str) -> None:
    c = wavelet_coefficients(reference_signal(), wavelet)
    assert c.shape == (N,)
    for start, values in REFERENCE[wavelet].items():
        np.testing.assert_allclose(c[start : start + len(values)], values, rtol=1e-10, atol=1e-13)


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
    assert all(a.slice.stop == b.slice.start for a, b in zip(bands, bands[1:]))
    assert bands[0].f_low == 0.0 and bands[0].f_high == pytest.approx(10000 / 2**11)
    cd1 = bands[-1]
    assert (cd1.f_low, cd1.f_high) == (2500.0, 5000.0)
    assert all(a.f_high == pytest.approx(b.f_low) for a, b in zip(bands, bands[1:]))


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
