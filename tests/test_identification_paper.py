"""Tests of engine.identification.paper (the paper's wavelet-neural identifier).

Data are synthetic (no simulator): per width K a damped sinusoid on an offset,
whose frequency and decay grow with K, with +-3 % variation standing in for the
seven J1 cases. On these records the paper's normalisation falls in case 2 of
eq. (5) with h2 > 0, so the networks converge in a few epochs. Shifted down by
3.5 (``negative()``) they still take case 2 but with h2 < 0: there the printed
target exp(-h2) exceeds 1 + delta1 and the default exp(-|h2|) does not.
"""

from __future__ import annotations

import io
import json
import logging

import numpy as np
import pytest

from engine.constants import K_GRID
from engine.identification import NotFittedError, PaperIdentifier, normalisation_terms, normalise
from engine.identification._network import initial_weights, train, train_explicit
from engine.identification.normalisation import TERM_NAMES
from engine.identification.paper import ARRAYS_FORMAT_VERSION

N = 2048


def synthetic(n_j1: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """Records (6 * n_j1, 2048) and widths, width-major like engine.simulation.paper_grid."""
    t = np.arange(N) * 1e-4
    X, y = [], []
    for K in K_GRID:
        for p in range(n_j1):
            s = 1.0 + 0.01 * (p - n_j1 // 2)
            f = (30.0 + 400.0 * K / 0.01) * s  # Hz
            tau = 0.02 + 2.0 * K  # s
            X.append(0.5 + np.exp(-t / tau) * np.sin(2 * np.pi * f * t) * (t > 0.0048))
            y.append(K)
    return np.asarray(X), np.asarray(y)


def negative(X: np.ndarray) -> np.ndarray:
    """The synthetic records shifted so that eq. (5) gives h2 < 0 (case 2, h2 about -0.094)."""
    return X - 3.5


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray]:
    return synthetic()


@pytest.fixture(scope="module")
def fitted(data) -> PaperIdentifier:
    X, y = data
    return PaperIdentifier("v2", max_epochs=300).fit(X, y)


# --- estimator contract -------------------------------------------------------


def test_init_stores_only_params() -> None:
    ident = PaperIdentifier("not-a-channel", learning_rate=-1.0)  # no validation in __init__
    params = ident.get_params()
    assert vars(ident) == params
    assert params == {
        "channel": "not-a-channel",
        "wavelet": None,
        "level": 10,
        "mode": "periodization",
        "n_hidden": 15,
        "learning_rate": -1.0,
        "delta1": 0.08,
        "max_epochs": 500,
        "target": "abs",
        "test_rows": "match",
        "widths": None,
    }
    assert not [k for k in vars(ident) if k.endswith("_")]


def test_fit_returns_self_and_sets_learned_attributes(data) -> None:
    X, y = data
    ident = PaperIdentifier("v2", max_epochs=50)
    assert ident.fit(X, y) is ident
    assert ident.patterns_.shape == (6, 15)
    np.testing.assert_array_equal(ident.widths_, K_GRID)
    assert ident.epochs_.shape == (6,) and ident.epochs_.dtype.kind == "i"
    assert ident.wavelet_ == "sym5"
    assert ident.h1_ < ident.k1_ and ident.h2_ <= ident.k2_
    assert ident.target_ == pytest.approx(np.exp(-abs(ident.h2_)))
    np.testing.assert_array_equal(ident.pattern_rows_, 7)
    assert ident.get_params()["max_epochs"] == 50  # params untouched by fit


def test_set_params_and_unknown_param() -> None:
    ident = PaperIdentifier("v2").set_params(delta1=0.07)
    assert ident.delta1 == 0.07
    with pytest.raises(ValueError, match="unknown"):
        ident.set_params(epochs=3)


@pytest.mark.parametrize("method", ["predict", "d_vectors", "identify_batch", "to_arrays"])
def test_use_before_fit_raises(method: str, data) -> None:
    X, _ = data
    ident = PaperIdentifier("v2")
    with pytest.raises(NotFittedError):
        getattr(ident, method)(*([] if method == "to_arrays" else [X[:1]]))
    assert issubclass(NotFittedError, ValueError)


# --- input validation ---------------------------------------------------------------


def test_bad_input_raises(data) -> None:
    X, y = data
    ident = PaperIdentifier("v2", max_epochs=5)
    with pytest.raises(ValueError, match="shape"):
        ident.fit(X[:, :2000], y)
    with pytest.raises(ValueError, match="shape"):
        ident.fit(X[0], y[:1])
    Xn = X.copy()
    Xn[3, 17] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        ident.fit(Xn, y)
    with pytest.raises(ValueError, match="lacks width"):
        ident.fit(X[y != K_GRID[2]], y[y != K_GRID[2]])
    with pytest.raises(ValueError, match="not in K_GRID"):
        ident.fit(X, np.where(y == K_GRID[0], 0.003, y))
    with pytest.raises(ValueError, match="one width per record"):
        ident.fit(X, y[:-1])
    with pytest.raises(ValueError, match="channel"):
        PaperIdentifier("torque").fit(X, y)
    with pytest.raises(ValueError, match="max_epochs"):
        PaperIdentifier("v2", max_epochs=0).fit(X, y)
    with pytest.raises(ValueError, match="target"):
        PaperIdentifier("v2", target="exp").fit(X, y)
    with pytest.raises(ValueError, match="test_rows"):
        PaperIdentifier("v2", test_rows="all").fit(X, y)


def test_bad_test_record_raises(fitted) -> None:
    with pytest.raises(ValueError, match="one record"):
        fitted.identify(np.zeros((2, N)))
    x = np.zeros(N)
    x[5] = np.inf
    with pytest.raises(ValueError, match="non-finite"):
        fitted.identify(x)


# --- identification -------------------------------------------------------------------


def test_identify_result_and_argmin(fitted, data) -> None:
    X, _ = data
    r = fitted.identify(X[10])
    assert r.D.shape == (6,)
    # D(i) = sum_j |Wt(j) - Ww(i, j)|, recomputed from the record's own network (balanced data: 7 rows each)
    x1 = normalise(fitted._features(X[10][None, :]), fitted.h1_, fitted.k1_, fitted.h2_, fitted.k2_)
    wt = fitted._train(np.repeat(x1, int(fitted.pattern_rows_[0]), axis=0), "test").weights.W3[0]
    np.testing.assert_allclose(r.D, np.abs(wt[None, :] - fitted.patterns_).sum(axis=1), rtol=1e-12)
    assert r.index == int(np.argmin(r.D)) + 1
    assert r.width == K_GRID[r.index - 1]
    assert 1 <= r.epochs <= fitted.max_epochs
    # D is the L1 distance between the record's W4 and each pattern row
    assert r.D[r.index - 1] == pytest.approx(r.D.min())


def test_batch_matches_single_records(fitted, data) -> None:
    """Test records are normalised with the stored constants: no dependence on the batch."""
    X, _ = data
    idx = [0, 13, 41]
    Dbatch = fitted.d_vectors(X[idx])
    assert Dbatch.shape == (3, 6)
    for row, i in zip(Dbatch, idx, strict=True):
        np.testing.assert_array_equal(row, fitted.identify(X[i]).D)
    np.testing.assert_array_equal(fitted.predict(X[idx]), [K_GRID[int(np.argmin(d))] for d in Dbatch])


def test_deterministic(data) -> None:
    X, y = data
    a = PaperIdentifier("v2", max_epochs=100).fit(X, y)
    b = PaperIdentifier("v2", max_epochs=100).fit(X, y)
    np.testing.assert_array_equal(a.patterns_, b.patterns_)
    np.testing.assert_array_equal(a.d_vectors(X[:4]), b.d_vectors(X[:4]))


def test_identity_one_record_per_width(data) -> None:
    """With one record per width the pattern networks and the test network see the same
    data with the same procedure: each training record must find its own width at D = 0,
    strictly ahead of every other width (the records differ, so the patterns do)."""
    X, y = data
    one = np.arange(len(y)) % 7 == 3
    ident = PaperIdentifier("v2", max_epochs=300).fit(X[one], y[one])
    for r, k in zip(ident.identify_batch(X[one]), y[one], strict=True):
        assert r.width == k
        assert r.D[r.index - 1] == 0.0
        assert np.sort(r.D)[1] > 0.0


def test_identity_training_records_mostly_win(fitted, data) -> None:
    """On the synthetic set (7 records per width) most training records win at their own width."""
    X, y = data
    # measured: 32 of 42 (0.76); deterministic, the floor leaves room for floating-point ties only
    assert np.mean(fitted.predict(X) == y) >= 0.7


# --- persistence -------------------------------------------------------------------------


def test_round_trip_arrays_gives_identical_D(fitted, data) -> None:
    X, _ = data
    params, arrays = fitted.get_params(), fitted.to_arrays()
    # through the formats a pattern store uses: JSON for params, .npz for arrays
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    buf.seek(0)
    loaded = dict(np.load(buf))
    restored = PaperIdentifier.from_arrays(json.loads(json.dumps(params)), loaded)
    np.testing.assert_array_equal(restored.d_vectors(X[::7]), fitted.d_vectors(X[::7]))
    np.testing.assert_array_equal(restored.patterns_, fitted.patterns_)
    np.testing.assert_array_equal(restored.pattern_rows_, fitted.pattern_rows_)
    assert restored.terms_ == fitted.terms_ and restored.case_ == fitted.case_
    assert restored.target_ == fitted.target_
    assert set(arrays["terms"].shape) == {len(TERM_NAMES)}


def test_from_arrays_rejects_mismatch(fitted) -> None:
    arrays = fitted.to_arrays()
    with pytest.raises(ValueError, match="unknown parameter"):
        PaperIdentifier.from_arrays({**fitted.get_params(), "colour": 1}, arrays)
    with pytest.raises(ValueError, match="shape"):
        PaperIdentifier.from_arrays({**fitted.get_params(), "n_hidden": 10}, arrays)
    with pytest.raises(ValueError, match="format_version"):
        PaperIdentifier.from_arrays(fitted.get_params(), {**arrays, "format_version": np.asarray(99)})
    # version 1 (before pattern_rows and the target / test_rows readings) is refused by its version
    v1 = {k: v for k, v in arrays.items() if k != "pattern_rows"}
    with pytest.raises(ValueError, match="format_version 1"):
        PaperIdentifier.from_arrays(fitted.get_params(), {**v1, "format_version": np.asarray(1)})
    with pytest.raises(ValueError, match="lack"):
        PaperIdentifier.from_arrays(fitted.get_params(), v1)
    assert ARRAYS_FORMAT_VERSION == 2
    with pytest.raises(ValueError, match="lack"):
        PaperIdentifier.from_arrays(fitted.get_params(), {k: v for k, v in arrays.items() if k != "patterns"})


# --- readings: target (notes D9) and test-network rows (notes D10) -----------------------------


def test_target_abs_is_reachable_and_as_printed_stays_available(data, caplog) -> None:
    """h2 < 0: the printed T = exp(-h2) > 1 + delta1 (no network converges, warning);
    the default T = exp(-|h2|) < 1 is reached in a few epochs."""
    X, y = data
    Xn = negative(X)
    with caplog.at_level(logging.WARNING, logger="engine.identification"):
        printed = PaperIdentifier("v2", max_epochs=20, target="as_printed").fit(Xn, y)
    assert printed.case_ == 2 and printed.h2_ < 0
    assert printed.target_ == pytest.approx(np.exp(-printed.h2_)) and printed.target_ > 1 + printed.delta1
    np.testing.assert_array_equal(printed.epochs_, 20)
    assert any("exceeds the sigmoid's range" in m for m in caplog.messages)
    assert not printed.identify(Xn[0]).converged

    ident = PaperIdentifier("v2", max_epochs=20).fit(Xn, y)
    assert ident.target == "abs" and ident.h2_ == printed.h2_
    assert ident.target_ == pytest.approx(np.exp(-abs(ident.h2_))) and 0.0 < ident.target_ < 1.0
    assert np.all(ident.epochs_ < 20) and np.all(ident.pattern_rms_ < ident.delta1)
    assert ident.identify(Xn[0]).converged
    # the reading travels with the parameters
    restored = PaperIdentifier.from_arrays(printed.get_params(), printed.to_arrays())
    assert restored.target_ == printed.target_


def test_test_network_gets_the_pattern_networks_updates_per_epoch(data) -> None:
    """test_rows="match": a test record's network is trained on the record replicated to the
    pattern networks' row count (7 here), i.e. 7 weight updates per epoch as each pattern
    network. If each pattern network is trained on 7 copies of one record, the test network of
    that record *is* that pattern network: D = 0 at its width, same epochs. The literal
    single-row network (test_rows="single") makes 1 update per epoch, so it needs more epochs."""
    X, y = data
    one = np.arange(len(y)) % 7 == 3
    match = PaperIdentifier("v2").fit(np.repeat(X[one], 7, axis=0), np.repeat(y[one], 7))
    np.testing.assert_array_equal(match.pattern_rows_, 7)
    single = PaperIdentifier.from_arrays({**match.get_params(), "test_rows": "single"}, match.to_arrays())
    for x, k in zip(X[one], y[one], strict=True):
        rm, rs = match.identify(x), single.identify(x)
        assert rm.width == k and rm.D[rm.index - 1] == 0.0
        assert rm.epochs == match.epochs_[rm.index - 1]
        assert rs.epochs > rm.epochs


def test_test_network_row_counts_follow_each_pattern(data, monkeypatch) -> None:
    """Unbalanced training data: one test network per distinct pattern row count."""
    X, y = data
    keep = ~((y == K_GRID[0]) & (np.arange(len(y)) % 7 >= 5))  # width 1: 5 records, the others 7
    ident = PaperIdentifier("v2", max_epochs=50).fit(X[keep], y[keep])
    np.testing.assert_array_equal(ident.pattern_rows_, [5, 7, 7, 7, 7, 7])
    seen: list[int] = []
    original = PaperIdentifier._train

    def spy(self, X1, label):
        seen.append(X1.shape[0])
        assert np.all(X1[0] == X1)  # the record, replicated
        return original(self, X1, label)

    monkeypatch.setattr(PaperIdentifier, "_train", spy)
    ident.identify(X[0])
    assert sorted(seen) == [5, 7]
    seen.clear()
    ident.set_params(test_rows="single").identify(X[0])
    assert seen == [1]


# --- training ---------------------------------------------------------------------------------


@pytest.mark.parametrize("max_epochs, delta1", [(500, 0.05), (6, 1e-9)])
def test_gram_form_training_equals_explicit_reference(max_epochs: int, delta1: float) -> None:
    """train (Gram form, compiled) and train_explicit (numpy, W1 updated explicitly) agree,
    also from a first layer that is not row-constant."""
    rng = np.random.default_rng(1)
    X1 = rng.uniform(-0.05, 0.1, size=(4, 256))
    T = np.full(6, 0.8)
    w0 = initial_weights(np.resize([0.02, -0.01, 0.03, 0.005], 15), 256, 15, 6)
    w0.W1 += rng.normal(0.0, 0.01, size=w0.W1.shape)
    a = train(w0, X1, T, 0.9, delta1, max_epochs)
    b = train_explicit(w0, X1, T, 0.9, delta1, max_epochs)
    assert (a.epochs, a.converged) == (b.epochs, b.converged)
    assert a.rms == pytest.approx(b.rms, rel=1e-12)
    for wa, wb in zip(
        (a.weights.W1, a.weights.W2, a.weights.W3), (b.weights.W1, b.weights.W2, b.weights.W3), strict=True
    ):
        np.testing.assert_allclose(wa, wb, rtol=1e-12, atol=1e-14)


def test_epoch_cap_respected_and_logged(data, caplog) -> None:
    X, y = data
    with caplog.at_level(logging.WARNING, logger="engine.identification"):
        ident = PaperIdentifier("v2", delta1=1e-12, max_epochs=4).fit(X, y)
        r = ident.identify(X[0])
    np.testing.assert_array_equal(ident.epochs_, 4)
    assert r.epochs == 4 and not r.converged
    assert sum("epoch cap" in m for m in caplog.messages) == 7  # 6 patterns + 1 test record


def test_training_reduces_rms_and_stops_below_delta1() -> None:
    rng = np.random.default_rng(0)
    X1 = rng.uniform(0.0, 0.05, size=(3, 64))
    T = np.full(6, 0.9)
    w0 = initial_weights(np.resize([0.01, 0.02, 0.03], 15), 64, 15, 6)
    res = train(w0, X1, T, learning_rate=0.9, delta1=0.05, max_epochs=500)
    assert res.converged and res.rms < 0.05 and res.epochs < 500
    assert w0.W3[0, 0] == 0.01  # initial weights untouched


def test_initial_weights_cycle_m1() -> None:
    w = initial_weights(np.resize([1.0, 2.0, 3.0], 15), 8, 15, 6)
    np.testing.assert_array_equal(w.W1[:, 0], np.resize([1.0, 2.0, 3.0], 15))
    np.testing.assert_array_equal(w.W3[:, 5], [1, 2, 3, 1, 2, 3])
    assert np.all(w.W2[:, :1] == w.W2)


# --- normalisation -----------------------------------------------------------------------------


def test_normalise_maps_training_range_onto_h2_k2() -> None:
    N_ = np.array([[-2.0, 0.0, 6.0]])
    X1 = normalise(N_, h1=-2.0, k1=6.0, h2=0.1, k2=0.5)
    np.testing.assert_allclose(X1, [[0.1, 0.2, 0.5]])
    with pytest.raises(ValueError):
        normalise(N_, 1.0, 1.0, 0.0, 1.0)


def test_normalisation_terms_hand_checked() -> None:
    """h-terms of eqs. (3)-(5) on ramps whose running means are known by hand.

    Row i (width index i + 1) holds ``(i + 1) * j`` for ``j < 1280`` and 0 after, so the
    mean of its first n samples is ``(i + 1) (n - 1) / 2`` and the mean over rows of the
    scale is 3.5.
    """
    j = np.arange(N, dtype=float)
    base = np.where(j < 1280, j, 0.0)
    rows = np.arange(1, 7)[:, None] * base[None, :]
    t = normalisation_terms(rows, np.arange(1, 7))
    assert (t["h1"], t["k1"], t["h16"]) == (0.0, 6 * 1279.0, 6 * 1279.0)
    # N1 means 49.5, 99.5, .., 249.5: (a-b)-(b-c)-(c-d)-(d-e) = 100; summed differences = a - e = -200
    assert t["h5"] == pytest.approx(3.5 * 100.0)
    assert t["h21"] == pytest.approx(3.5 * -200.0)
    # N2 means 127.5, 255.5, .., 639.5: chained differences = 256 (per row times the scale)
    assert t["h6"] == pytest.approx(3.5 * 256.0)
    assert (t["h19"], t["h20"], t["m5"]) == pytest.approx((256.0, 6 * 256.0, 3.5 * 256.0))
    assert t["h11"] == pytest.approx((256 + 700) - (1536 + 700) - (896 + 700))
    assert t["m1"] == pytest.approx(1279 * 1280 / 2 / N)  # mean of the smallest-width row
    assert t["m2"] == pytest.approx(3.5 * 1279 * 1280 / 2 / N)
    # samples above the row mean: j >= 400 (880 of them) in every row
    assert (t["h17"], t["h18"], t["h14"]) == pytest.approx((6 * 1279.0 * 880,) * 3)
    assert t["h15"] == 0.0 and t["h9"] == 0.0 and t["h10"] == 6 * 1279.0
    sd = base.std()
    count_sd = int(np.count_nonzero(base > sd))
    assert (t["h13"], t["h8"], t["m3"], t["h12"]) == pytest.approx((6 * 1279.0 * count_sd,) * 4)
    assert t["h7"] == pytest.approx(t["h13"])  # h13 + (m3 - h8) with m3 == h8
    # h7 > h8 is false only if h13 <= h8: here h7 == h8, so case 1 (h7 <= h8) applies
    assert t["case"] == 1.0
    assert (t["h3"], t["h4"]) == pytest.approx((3.5 * (100 - 256), 3.5 * (256 - 100)))
    assert (t["h2"], t["k2"]) == pytest.approx((-3.5 * 156, 3.5 * 156))


def test_branch_two_of_eq5_on_synthetic_data(fitted) -> None:
    """The synthetic set takes branch 2: h3 = m1 / h11, h4 = m1 h11 / h11 = m1; T = exp(-h2) < 1."""
    t = fitted.terms_
    assert fitted.case_ == 2
    assert t["h7"] > t["h8"] and t["h9"] <= t["h10"]
    assert (t["h3"], t["h4"]) == pytest.approx((t["m1"] / t["h11"], t["m1"]))
    assert (fitted.h2_, fitted.k2_) == (min(t["h3"], t["h4"]), max(t["h3"], t["h4"]))
    assert 0.0 < fitted.target_ < 1.0


def test_tie_at_minimum_is_logged(fitted, data, caplog) -> None:
    X, _ = data
    tied = PaperIdentifier.from_arrays(
        fitted.get_params(), {**fitted.to_arrays(), "patterns": np.tile(fitted.patterns_[2], (6, 1))}
    )
    with caplog.at_level(logging.WARNING, logger="engine.identification"):
        r = tied.identify(X[0])
    assert r.index == 1 and np.all(r.D[0] == r.D)
    assert any("tie" in m for m in caplog.messages)


def test_ties_of_a_batch_are_logged_once(fitted, data, caplog) -> None:
    """Issue 53 (``make run`` printed 638 tie warnings): a batch with ties at D's minimum logs one line that counts
    them, not one per record."""
    X, _ = data
    tied = PaperIdentifier.from_arrays(
        fitted.get_params(), {**fitted.to_arrays(), "patterns": np.tile(fitted.patterns_[2], (6, 1))}
    )
    with caplog.at_level(logging.WARNING, logger="engine.identification"):
        results = tied.identify_batch(X[:3])
    assert all(r.index == 1 for r in results)
    ties = [m for m in caplog.messages if "tie" in m]
    assert len(ties) == 1 and "on 3 of 3 test records" in ties[0], ties
