"""The paper's wavelet-neural identifier of the backlash zone width (section 3.1).

Pipeline, for one channel and one group of operating conditions:

1. Every record (2048 raw samples of the channel) is replaced by its 2048
   periodized level-10 wavelet coefficients (:mod:`engine.features.wavelet`),
   one row of the paper's matrix ``N``.
2. The training rows, all six widths together, fix the normalisation of
   eq. (2) (:mod:`engine.identification.normalisation`): ``h1, k1`` (range of ``N``) and ``h2, k2`` (target range, chosen by
   the case analysis of eqs. (3)-(5) from the auxiliary variables
   ``h3 .. h21``, ``m1 .. m5`` and the matrices ``N1 .. N5``). These constants
   are stored and applied unchanged to every test record.
3. One network 2048-15-15-6 (sigmoid, no bias) per width is trained by
   per-sample backpropagation on that width's rows (the paper's ``N[7,2048]``:
   the seven J1 cases of one width), starting from weights set from the mean
   ``m1`` and with target ``T = exp(-|h2|)`` on every output (``target="abs"``,
   default; ``target="as_printed"`` uses the printed ``exp(-h2)``, which
   exceeds 1 whenever ``h2 < 0``). The first row of its output-layer weights,
   ``W4 = W3[0, :]``, is the width's pattern; the six patterns form ``Ww`` (6 x 15).
4. A test record trains its own network with the same procedure; with
   ``test_rows="match"`` (default) on the record replicated to as many rows as
   the pattern network it is compared with was trained on (the paper's
   ``N[7,2048]`` shape, so both see the same number of weight updates per
   epoch), with ``test_rows="single"`` on the record alone. With ``Wt`` its
   ``W4``, ``D(i) = sum_j |Wt(j) - Ww(i, j)|`` and the identified width is
   ``K[nr5]`` with ``nr5 = argmin D`` (1-based in the paper).

The width grid is a parameter (``widths``, default the paper's ``K_GRID``), so
the method can run on another plant (e.g. :mod:`engine.plants.brfd.patterns`);
it must hold exactly six strictly increasing widths, because the normalisation
picks rows by width index (``M3_WIDTHS = (1, 2, 3)``,
``N4_EXTREME_WIDTHS = (3, 4, 5, 6)``, ``m1`` on width 1). Any channel name is
accepted when ``wavelet`` is given; without it the channel must be one of
``CHANNEL_WAVELETS`` (the paper's wavelet per channel).

The text of section 3.1 is garbled in many places; every reading chosen here
is listed, one entry per ambiguity, in ``docs/paper-notes.md``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from engine.constants import CHANNEL_WAVELETS, K_GRID, N_SAMPLES, WAVELET_LEVEL
from engine.features.wavelet import wavelet_coefficients
from engine.identification._network import TrainResult, Weights, initial_weights, train
from engine.identification.base import IdentificationResult, NotFittedError, check_wavelet
from engine.identification.normalisation import TERM_NAMES, normalisation_terms, normalise

logger = logging.getLogger(__name__)

__all__ = ["ARRAYS_FORMAT_VERSION", "N_WIDTHS", "TARGETS", "TEST_ROWS", "PaperIdentifier"]

#: Version of the layout produced by :meth:`PaperIdentifier.to_arrays`
#: (2: adds ``pattern_rows``; the target and test-row readings are parameters). The ``widths``
#: array (in the layout since version 1) holds the grid the patterns were trained on; a layout
#: without it is read as ``K_GRID`` (or the ``widths`` parameter), so no new version was needed.
ARRAYS_FORMAT_VERSION: int = 2
#: Readings of the network target (docs/paper-notes.md, D9): ``exp(-|h2|)`` or the printed ``exp(-h2)``.
TARGETS: tuple[str, ...] = ("abs", "as_printed")
#: Readings of the test network's training data (docs/paper-notes.md, D10).
TEST_ROWS: tuple[str, ...] = ("match", "single")

#: Widths in a grid: the paper's six, which the normalisation's width indices (1..6) assume.
N_WIDTHS: int = len(K_GRID)
_N_OUT = N_WIDTHS  # the paper's 6 output neurons, one per width


def _init_row_values(m1_rows: np.ndarray, n_rows: int) -> np.ndarray:
    """Initial weight of each neuron row: the per-record means m1(p) cycled over the rows.

    Row i (0-based) gets ``m1_rows[i % len(m1_rows)]``.
    """
    return np.resize(np.asarray(m1_rows, dtype=float), n_rows)


# --------------------------------------------------------------------------
# the estimator
# --------------------------------------------------------------------------


#: Largest hidden layer accepted [neurons] (the paper's network has 15).
MAX_HIDDEN = 1000
#: Most training epochs accepted (the paper's cap is 500).
MAX_EPOCHS = 100_000


class PaperIdentifier:
    """The paper's wavelet-neural identifier of the backlash zone width, for one channel.

    Parameters
    ----------
    channel : str
        Channel the records hold: one of ``engine.constants.CHANNELS`` when
        ``wavelet`` is None; any name (e.g. another plant's channel) when it is given.
    wavelet : str or None, default None
        Wavelet name; None uses the paper's wavelet of the channel
        (``engine.constants.CHANNEL_WAVELETS``).
    level : int, default 10
        Wavelet decomposition level.
    mode : str, default "periodization"
        PyWavelets extension mode (only periodization keeps 2048 coefficients).
    n_hidden : int, default 15
        Neurons in each of the two hidden layers.
    learning_rate : float, default 0.9
        Learning coefficient l of the weight update [-] (paper: 0.6 .. 0.9).
    delta1 : float, default 0.08
        Training stops when the RMS output error falls below it [-] (paper: 0.07 .. 0.08).
    max_epochs : int, default 500
        Epoch cap per network (not in the paper; the paper's test networks
        needed 11 .. 39 epochs).
    target : {"abs", "as_printed"}, default "abs"
        Network target: ``T = exp(-|h2|)`` in (0, 1], reachable by a sigmoid
        (docs/paper-notes.md, D9), or the printed ``T = exp(-h2)``, which is
        above 1 whenever ``h2 < 0`` (then no network converges).
    test_rows : {"match", "single"}, default "match"
        Training data of a test record's network: the record replicated to
        the number of rows the compared pattern network was trained on, so
        both get the same number of weight updates per epoch and the same
        stop rule (docs/paper-notes.md, D10); or the record once ("single",
        the literal reading).
    widths : sequence of float or None, default None
        The six backlash widths K of the patterns [m] (the unit of the plant's play),
        strictly increasing; None uses the paper's ``K_GRID``. Exactly six: the
        normalisation of eqs. (2)-(5) selects rows by width index 1..6.

    Attributes
    ----------
    wavelet_ : str
        Wavelet actually used.
    widths_ : ndarray, shape (6,)
        Backlash widths K of the patterns, increasing (``widths``, default ``K_GRID``) [m].
    patterns_ : ndarray, shape (6, 15)
        Pattern matrix Ww: row i is W4 of the network trained on width i.
    epochs_ : ndarray of int, shape (6,)
        Epochs each pattern network ran.
    pattern_rows_ : ndarray of int, shape (6,)
        Training rows (records) each pattern network was trained on.
    pattern_rms_ : ndarray, shape (6,)
        Final RMS error of each pattern network [-].
    h1_, k1_, h2_, k2_ : float
        Normalisation constants of eq. (2), from the training rows.
    target_ : float
        Network target ``T`` [-]: ``exp(-|h2|)`` or ``exp(-h2)`` (see ``target``).
    init_weights_ : ndarray, shape (max(n_hidden, 6),)
        Initial value of every weight in each neuron row (from m1).
    terms_ : dict of str to float
        All normalisation terms (see :func:`normalisation_terms`).
    case_ : int
        Branch of eq. (5) that fixed ``h2, k2``.
    n_features_in_ : int
        Samples per record (2048).
    """

    def __init__(
        self,
        channel: str,
        wavelet: str | None = None,
        level: int = WAVELET_LEVEL,
        mode: str = "periodization",
        n_hidden: int = 15,
        learning_rate: float = 0.9,
        delta1: float = 0.08,
        max_epochs: int = 500,
        target: str = "abs",
        test_rows: str = "match",
        widths: tuple[float, ...] | None = None,
    ) -> None:
        self.channel = channel
        self.wavelet = wavelet
        self.level = level
        self.mode = mode
        self.n_hidden = n_hidden
        self.learning_rate = learning_rate
        self.delta1 = delta1
        self.max_epochs = max_epochs
        self.target = target
        self.test_rows = test_rows
        self.widths = widths

    # -- parameters --------------------------------------------------------

    _PARAM_NAMES = (
        "channel",
        "wavelet",
        "level",
        "mode",
        "n_hidden",
        "learning_rate",
        "delta1",
        "max_epochs",
        "target",
        "test_rows",
        "widths",
    )

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Constructor parameters (JSON-ready: ``widths`` given as an array comes back as a tuple)."""
        params = {name: getattr(self, name) for name in self._PARAM_NAMES}
        if isinstance(params["widths"], np.ndarray):
            params["widths"] = tuple(params["widths"].tolist())
        return params

    def set_params(self, **params: Any) -> PaperIdentifier:
        """Set constructor parameters; returns self."""
        unknown = set(params) - set(self._PARAM_NAMES)
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)}; valid: {', '.join(self._PARAM_NAMES)}")
        for k, v in params.items():
            setattr(self, k, v)
        return self

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    def validate_params(self) -> None:
        """Raise ``ValueError`` with what to fix unless every parameter is acceptable (also done by ``fit``).

        Beyond the types: the wavelet, level and mode exist in PyWavelets; ``n_hidden`` <= :data:`MAX_HIDDEN`
        and ``max_epochs`` <= :data:`MAX_EPOCHS` (larger networks or runs take hours or exhaust memory).
        """
        self._validate_params()

    def _validate_params(self) -> None:
        check_wavelet(self.wavelet, self.level, self.mode)
        if self.wavelet is None:
            if self.channel not in CHANNEL_WAVELETS:
                raise ValueError(
                    f"unknown channel {self.channel!r}; known channels: {', '.join(CHANNEL_WAVELETS)} "
                    "(another channel needs an explicit wavelet)"
                )
        else:
            if not (isinstance(self.channel, str) and self.channel):
                raise ValueError(f"channel must be a non-empty name, got {self.channel!r}")
            if not (isinstance(self.wavelet, str) and self.wavelet):
                raise ValueError(f"wavelet must be a wavelet name or None, got {self.wavelet!r}")
        self._grid()
        if not (isinstance(self.n_hidden, (int, np.integer)) and 1 <= self.n_hidden <= MAX_HIDDEN):
            raise ValueError(f"n_hidden must be an integer from 1 to {MAX_HIDDEN}, got {self.n_hidden!r}")
        if not (isinstance(self.max_epochs, (int, np.integer)) and 1 <= self.max_epochs <= MAX_EPOCHS):
            raise ValueError(f"max_epochs must be an integer from 1 to {MAX_EPOCHS}, got {self.max_epochs!r}")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise ValueError(f"learning_rate must be a positive number, got {self.learning_rate!r}")
        if not (math.isfinite(self.delta1) and self.delta1 > 0):
            raise ValueError(f"delta1 must be a positive number, got {self.delta1!r}")
        if self.target not in TARGETS:
            raise ValueError(f"target must be one of {', '.join(TARGETS)}, got {self.target!r}")
        if self.test_rows not in TEST_ROWS:
            raise ValueError(f"test_rows must be one of {', '.join(TEST_ROWS)}, got {self.test_rows!r}")

    def _grid(self) -> np.ndarray:
        """The validated width grid [m]: ``widths`` or ``K_GRID``, shape (6,).

        Raises
        ------
        ValueError
            Not six finite, strictly increasing values.
        """
        if self.widths is None:
            return np.asarray(K_GRID, dtype=float)
        try:
            grid = np.asarray(self.widths, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"widths must be a sequence of {N_WIDTHS} numbers [m], got {self.widths!r}") from None
        if grid.shape != (N_WIDTHS,):
            raise ValueError(
                f"widths must hold exactly {N_WIDTHS} widths (the normalisation of eqs. 2-5 selects rows by "
                f"width index 1..{N_WIDTHS}), got shape {grid.shape}: {self.widths!r}"
            )
        if not np.all(np.isfinite(grid)):
            raise ValueError(f"widths must be finite, got {grid.tolist()}")
        if not np.all(np.diff(grid) > 0.0):
            raise ValueError(
                f"widths must be strictly increasing (width 1 is the smallest in the normalisation), got {grid.tolist()}"
            )
        return grid

    # -- input handling ------------------------------------------------------

    def _features(self, X: Any, what: str = "X") -> np.ndarray:
        """Validated raw records -> wavelet coefficient rows N, shape (R, 2048)."""
        arr = np.asarray(X, dtype=float)
        if arr.ndim != 2 or arr.shape[1] != N_SAMPLES:
            raise ValueError(
                f"{what} must have shape (n_records, {N_SAMPLES}) of raw {self.channel} samples, got {arr.shape}"
            )
        if arr.shape[0] == 0:
            raise ValueError(f"{what} holds no records")
        if not np.all(np.isfinite(arr)):
            r, j = np.argwhere(~np.isfinite(arr))[0]
            raise ValueError(f"{what} holds a non-finite value (NaN or inf) in record {r}, sample {j}")
        wavelet = self.wavelet if self.wavelet is not None else CHANNEL_WAVELETS[self.channel]
        return wavelet_coefficients(arr, wavelet, mode=self.mode, level=self.level, axis=-1)

    @staticmethod
    def _width_index(y: Any, n_records: int, grid: np.ndarray, grid_name: str = "K_GRID") -> np.ndarray:
        """Widths [m] -> 1-based indices into ``grid`` (named ``grid_name`` in messages); all six must be present."""
        yy = np.asarray(y, dtype=float)
        if yy.shape != (n_records,):
            raise ValueError(f"y must hold one width per record, shape ({n_records},), got {yy.shape}")
        match = np.isclose(yy[:, None], grid[None, :], rtol=1e-9, atol=1e-12)
        bad = ~match.any(axis=1)
        if bad.any():
            raise ValueError(f"width(s) {sorted(set(yy[bad].tolist()))} m are not in {grid_name} {grid.tolist()}")
        idx = match.argmax(axis=1) + 1
        missing = sorted(set(range(1, _N_OUT + 1)) - set(idx.tolist()))
        if missing:
            raise ValueError(
                f"training data lacks width(s) {[float(grid[i - 1]) for i in missing]} m; "
                f"all six widths of {grid_name} {grid.tolist()} are needed"
            )
        return idx

    def _check_fitted(self) -> None:
        if not hasattr(self, "patterns_"):
            raise NotFittedError(
                f"this {type(self).__name__} is not fitted yet; call fit(X, y) or from_arrays(...) first"
            )

    # -- training ------------------------------------------------------------

    def _initial(self) -> Weights:
        return initial_weights(self.init_weights_, self.n_features_in_, self.n_hidden, _N_OUT)

    def _train(self, X1: np.ndarray, label: str) -> TrainResult:
        T = np.full(_N_OUT, self.target_)
        return train(self._initial(), X1, T, self.learning_rate, self.delta1, int(self.max_epochs), label)

    def fit(self, X: Any, y: Any, groups: Any = None) -> PaperIdentifier:
        """Learn the normalisation and the six width patterns.

        Parameters
        ----------
        X : array_like, shape (n_records, 2048)
            Raw time-domain samples of ``channel`` (its unit), one record per row:
            the training records of one pattern set (e.g. the 7 J1 cases x 6
            widths of one c group).
        y : array_like, shape (n_records,)
            Backlash width K of each record [m]; values of the width grid (``widths``,
            default ``K_GRID``), all six present.
        groups : array_like, optional
            Ignored: the paper's method has no use for the records' groups (J1); present so
            that every identifier offers the same ``fit`` (:class:`~engine.identification.base.Identifier`).

        Returns
        -------
        PaperIdentifier
            self.
        """
        self._validate_params()
        grid = self._grid()
        N = self._features(X)
        wi = self._width_index(y, N.shape[0], grid, "K_GRID" if self.widths is None else "the width grid")
        terms = normalisation_terms(N, wi)
        self.wavelet_ = self.wavelet if self.wavelet is not None else CHANNEL_WAVELETS[self.channel]
        self.n_features_in_ = N.shape[1]
        self.terms_ = {k: v for k, v in terms.items() if k != "case"}
        self.case_ = int(terms["case"])
        self.h1_, self.k1_, self.h2_, self.k2_ = terms["h1"], terms["k1"], terms["h2"], terms["k2"]
        self.target_ = self._target(self.h2_, warn=True)
        if self.h2_ == self.k2_:
            logger.warning(
                "normalisation range [h2, k2] collapsed to the point %.6g: every input is the same", self.h2_
            )
        m1_rows = N[wi == 1].mean(axis=1)
        self.init_weights_ = _init_row_values(m1_rows, max(self.n_hidden, _N_OUT))
        X1 = normalise(N, self.h1_, self.k1_, self.h2_, self.k2_)
        patterns, epochs, rms, rows = [], [], [], []
        for i, K in enumerate(grid.tolist(), start=1):
            res = self._train(X1[wi == i], f"{self.channel}/pattern K={K}")
            patterns.append(res.weights.W3[0].copy())
            epochs.append(res.epochs)
            rms.append(res.rms)
            rows.append(int(np.count_nonzero(wi == i)))
        self.widths_ = grid
        self.patterns_ = np.stack(patterns)
        self.epochs_ = np.asarray(epochs, dtype=int)
        self.pattern_rms_ = np.asarray(rms, dtype=float)
        self.pattern_rows_ = np.asarray(rows, dtype=int)
        logger.info(
            "%s: case %d, h2=%.4g, k2=%.4g, T=%.4g, pattern epochs %s",
            self.channel,
            self.case_,
            self.h2_,
            self.k2_,
            self.target_,
            self.epochs_.tolist(),
        )
        return self

    def _target(self, h2: float, warn: bool = False) -> float:
        """The network target from h2 (docs/paper-notes.md, D9).

        ``target="abs"``: ``T = exp(-|h2|)``, in (0, 1]. Not clipped: training
        stops once ``RMS < delta1``, so the output only has to come within
        ``delta1`` of T and a T at (or near) 1 is reached at ``Y3 ~ 1 - delta1``,
        far from saturation. ``target="as_printed"``: ``T = exp(-h2)``; with
        ``warn`` a warning is logged when it exceeds 1 by ``delta1`` or more
        (no network can then converge).
        """
        if self.target == "abs":
            return math.exp(-abs(h2))
        if -h2 > 700.0:
            raise ValueError(f"target T = exp(-h2) overflows for h2 = {h2:.6g}")
        T = math.exp(-h2)
        if warn and self.delta1 <= T - 1.0:
            logger.warning(
                "target T = exp(-h2) = %.4g exceeds the sigmoid's range (0, 1) by at least delta1 = %.4g: "
                "no network can converge and every training will run to max_epochs = %d",
                T,
                self.delta1,
                self.max_epochs,
            )
        return T

    def _test_row_counts(self) -> np.ndarray:
        """Rows the test network is trained on, per pattern (same order as ``patterns_``)."""
        if self.test_rows == "match":
            return self.pattern_rows_
        if self.test_rows == "single":
            return np.ones(_N_OUT, dtype=int)
        raise ValueError(f"test_rows must be one of {', '.join(TEST_ROWS)}, got {self.test_rows!r}")

    # -- identification ------------------------------------------------------

    def _test_result(self, x1: np.ndarray, label: str) -> tuple[IdentificationResult, list[float]]:
        """The record's result and the widths tied at D's minimum (empty without a tie)."""
        counts = self._test_row_counts()
        D = np.empty(_N_OUT)
        nets = {}
        for n in np.unique(counts):
            # the record as n identical rows: n weight updates per epoch, like a pattern network on n records
            res = nets[int(n)] = self._train(np.repeat(x1[None, :], int(n), axis=0), label)
            sel = counts == n
            D[sel] = np.abs(res.weights.W3[0][None, :] - self.patterns_[sel]).sum(axis=1)
        i = int(np.argmin(D))
        res = nets[int(counts[i])]
        tied = np.flatnonzero(D[i] == D)
        result = IdentificationResult(
            D=D, index=i + 1, width=float(self.widths_[i]), epochs=res.epochs, rms=res.rms, converged=res.converged
        )
        return result, [float(self.widths_[j]) for j in tied] if tied.size > 1 else []

    def identify_batch(self, X: Any) -> list[IdentificationResult]:
        """Identify every record of a batch.

        Parameters
        ----------
        X : array_like, shape (n_records, 2048)
            Raw samples of ``channel``.

        Returns
        -------
        list of IdentificationResult
        """
        self._check_fitted()
        X1 = normalise(self._features(X), self.h1_, self.k1_, self.h2_, self.k2_)
        out = [self._test_result(x1, f"{self.channel}/test record {r}") for r, x1 in enumerate(X1)]
        ties = [(r, result, tied) for r, (result, tied) in enumerate(out) if tied]
        if len(ties) == 1 and len(out) == 1:
            _, result, tied = ties[0]
            logger.warning(
                "%s/test record: D has a tie at its minimum %.3g between widths %s; reporting the first (nr5 = %d), "
                "as argmin does",
                self.channel,
                result.D[result.index - 1],
                tied,
                result.index,
            )
        elif ties:  # one line for the batch, not one per record (make run's evaluation printed 638)
            r, result, tied = ties[0]
            logger.warning(
                "%s: D has a tie at its minimum on %d of %d test records (the first: record %d, %.3g between widths "
                "%s); each reports the first width of its tie, as argmin does",
                self.channel,
                len(ties),
                len(out),
                r,
                result.D[result.index - 1],
                tied,
            )
        return [result for result, _ in out]

    def identify(self, x: Any) -> IdentificationResult:
        """Identify the width of one record.

        Parameters
        ----------
        x : array_like, shape (2048,)
            Raw samples of ``channel``.

        Returns
        -------
        IdentificationResult
        """
        arr = np.asarray(x, dtype=float)
        if arr.ndim != 1:
            raise ValueError(
                f"identify takes one record of shape ({N_SAMPLES},), got {arr.shape}; use identify_batch for many"
            )
        return self.identify_batch(arr[None, :])[0]

    def d_vectors(self, X: Any) -> np.ndarray:
        """D vectors of a batch, shape (n_records, 6), in ``widths_`` order."""
        return np.stack([r.D for r in self.identify_batch(X)])

    def predict(self, X: Any) -> np.ndarray:
        """Identified width of each record [m], shape (n_records,)."""
        return np.asarray([r.width for r in self.identify_batch(X)], dtype=float)

    # -- persistence ---------------------------------------------------------

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Everything learned, as named numpy arrays (pair with :meth:`get_params`).

        Returns
        -------
        dict of str to ndarray
            ``format_version``, ``patterns`` (6, 15), ``widths`` (6,),
            ``epochs`` (6,), ``pattern_rms`` (6,), ``pattern_rows`` (6,), ``init_weights``,
            ``terms`` (values in :data:`~engine.identification.normalisation.TERM_NAMES` order; holds h1, k1, h2, k2),
            ``case``, ``n_features_in``.
        """
        self._check_fitted()
        return {
            "format_version": np.asarray(ARRAYS_FORMAT_VERSION),
            "patterns": self.patterns_.copy(),
            "widths": self.widths_.copy(),
            "epochs": self.epochs_.copy(),
            "pattern_rms": self.pattern_rms_.copy(),
            "pattern_rows": self.pattern_rows_.copy(),
            "init_weights": self.init_weights_.copy(),
            "terms": np.asarray([self.terms_[k] for k in TERM_NAMES], dtype=float),
            "case": np.asarray(self.case_),
            "n_features_in": np.asarray(self.n_features_in_),
        }

    @classmethod
    def from_arrays(cls, params: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> PaperIdentifier:
        """Restore a fitted identifier from :meth:`get_params` and :meth:`to_arrays`.

        Parameters
        ----------
        params : mapping
            Constructor parameters (unknown keys raise).
        arrays : mapping of str to ndarray
            As produced by :meth:`to_arrays`. ``widths``, when present, must equal the
            parameters' grid (``widths``, default ``K_GRID``); when absent that grid is used.

        Returns
        -------
        PaperIdentifier
            Fitted; identifies exactly as the original.
        """
        unknown = set(params) - set(cls._PARAM_NAMES)
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)}; valid: {', '.join(cls._PARAM_NAMES)}")
        obj = cls(**dict(params))
        obj._validate_params()
        need = {
            "format_version",
            "patterns",
            "epochs",
            "pattern_rms",
            "pattern_rows",
            "init_weights",
            "terms",
            "case",
            "n_features_in",
        }  # "widths" is optional: without it the grid is the parameters' (default K_GRID)
        if "format_version" in arrays:  # checked first: an older layout also lacks newer arrays
            version = int(np.asarray(arrays["format_version"]))
            if version != ARRAYS_FORMAT_VERSION:
                raise ValueError(
                    f"arrays have format_version {version}; this code reads version {ARRAYS_FORMAT_VERSION}"
                )
        missing = need - set(arrays)
        if missing:
            raise ValueError(f"arrays lack {sorted(missing)}")
        shapes = {
            "patterns": (_N_OUT, obj.n_hidden),
            "widths": (_N_OUT,),
            "epochs": (_N_OUT,),
            "pattern_rms": (_N_OUT,),
            "pattern_rows": (_N_OUT,),
            "init_weights": (max(obj.n_hidden, _N_OUT),),
            "terms": (len(TERM_NAMES),),
        }
        for key, shape in shapes.items():
            if key not in arrays:  # only "widths" may be absent (see need)
                continue
            if np.shape(arrays[key]) != shape:
                raise ValueError(
                    f"array {key!r} has shape {np.shape(arrays[key])}, expected {shape} for n_hidden={obj.n_hidden}"
                )
        grid = obj._grid()
        if "widths" in arrays and not np.allclose(arrays["widths"], grid, rtol=0, atol=1e-12):
            raise ValueError(
                f"stored widths {np.asarray(arrays['widths']).tolist()} differ from the width grid {grid.tolist()} "
                f"of the parameters (widths={obj.widths!r})"
            )
        obj.wavelet_ = obj.wavelet if obj.wavelet is not None else CHANNEL_WAVELETS[obj.channel]
        obj.n_features_in_ = int(np.asarray(arrays["n_features_in"]))
        obj.terms_ = {k: float(v) for k, v in zip(TERM_NAMES, np.asarray(arrays["terms"], dtype=float), strict=True)}
        obj.case_ = int(np.asarray(arrays["case"]))
        obj.h1_, obj.k1_, obj.h2_, obj.k2_ = (obj.terms_[k] for k in ("h1", "k1", "h2", "k2"))
        obj.target_ = obj._target(obj.h2_)
        obj.init_weights_ = np.array(arrays["init_weights"], dtype=float)
        obj.widths_ = grid  # equal to the stored widths, checked above; K_GRID by default when not stored
        obj.patterns_ = np.array(arrays["patterns"], dtype=float)
        obj.epochs_ = np.array(arrays["epochs"], dtype=int)
        obj.pattern_rms_ = np.array(arrays["pattern_rms"], dtype=float)
        obj.pattern_rows_ = np.array(arrays["pattern_rows"], dtype=int)
        if np.any(obj.pattern_rows_ < 1):
            raise ValueError(f"array 'pattern_rows' must hold positive counts, got {obj.pattern_rows_.tolist()}")
        return obj
