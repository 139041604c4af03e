"""The paper's three-layer backpropagation network (section 3.1, Fig. 3).

A fully connected ``n_in - n_hidden - n_hidden - n_out`` network (2048-15-15-6
in the paper) with sigmoid neurons in all three layers and **no bias terms**
(the paper's ``Z_(d)(i) = sum_j X_(d)(j) W_(d)(i,j)`` has none). It is trained
by plain per-sample backpropagation (Osowski, 1996)::

    sigma_3 = Y3 (1 - Y3) (T - Y3)
    sigma_2 = Y2 (1 - Y2) (W3^T sigma_3)
    sigma_1 = Y1 (1 - Y1) (W2^T sigma_2)
    W_d    += l * outer(sigma_d, X_d)            (d = 1, 2, 3)

with all ``sigma`` computed from the weights before the step. One epoch
presents every training sample once, in the order given. After each epoch the
RMS of the output errors ``E = T - Y3`` over all samples and outputs is
evaluated with the updated weights; training stops when ``RMS < delta1`` or
after ``max_epochs`` epochs (then a warning is logged and the result says
``converged=False``).

How it is computed (exactly the same arithmetic in exact arithmetic)
---------------------------------------------------------------------
Every first-layer update adds ``l * outer(sigma_1, x_r)`` for one of the ``n``
training rows ``x_r``, so at any time ``W1 = W1_0 + A @ X`` for a small
coefficient matrix ``A`` (n_hidden x n), and the first layer's input is
``W1 @ x_r = (X @ W1_0^T)[r] + A @ G[:, r]`` with the Gram matrix ``G = X X^T``.
:func:`train` therefore precomputes ``P = X @ W1_0^T`` and ``G`` once (the
only O(n_in) work) and runs the per-sample loop on ``A`` with a compiled
(numba) kernel: a step costs O(n_hidden * (n + n_hidden)) instead of
O(n_hidden * n_in), so a network that runs to the epoch cap costs little.
``W1`` is rebuilt at the end. :func:`train_explicit` is the direct numpy
implementation of the same algorithm, kept as the reference the tests compare
against.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.special import expit

logger = logging.getLogger(__name__)


@dataclass
class Weights:
    """Weights of the three layers.

    Attributes
    ----------
    W1 : ndarray, shape (n_hidden, n_in)
    W2 : ndarray, shape (n_hidden, n_hidden)
    W3 : ndarray, shape (n_out, n_hidden)
    """

    W1: np.ndarray
    W2: np.ndarray
    W3: np.ndarray

    def copy(self) -> Weights:
        """Deep copy (training modifies weights in place)."""
        return Weights(self.W1.copy(), self.W2.copy(), self.W3.copy())


@dataclass(frozen=True)
class TrainResult:
    """Outcome of :func:`train`.

    Attributes
    ----------
    weights : Weights
        Weights after the last epoch.
    epochs : int
        Epochs run (``max_epochs`` when the cap was hit).
    rms : float
        RMS output error after the last epoch [-].
    converged : bool
        ``rms < delta1`` was reached within ``max_epochs``.
    """

    weights: Weights
    epochs: int
    rms: float
    converged: bool


def initial_weights(row_values: np.ndarray, n_in: int, n_hidden: int, n_out: int) -> Weights:
    """Weights initialised row by row from a vector of values (paper: ``W_(d)(i,j) = m1(i)``).

    Parameters
    ----------
    row_values : ndarray, shape (max(n_hidden, n_out),)
        Value given to every weight of row i of each layer.
    n_in, n_hidden, n_out : int
        Layer sizes.

    Returns
    -------
    Weights
        ``W1[i, :] = W2[i, :] = row_values[i]`` for ``i < n_hidden`` and
        ``W3[i, :] = row_values[i]`` for ``i < n_out``.
    """
    v = np.asarray(row_values, dtype=float)
    need = max(n_hidden, n_out)
    if v.shape != (need,):
        raise ValueError(f"row_values must have shape ({need},), got {v.shape}")
    return Weights(
        W1=np.repeat(v[:n_hidden, None], n_in, axis=1),
        W2=np.repeat(v[:n_hidden, None], n_hidden, axis=1),
        W3=np.repeat(v[:n_out, None], n_hidden, axis=1),
    )


def forward(w: Weights, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Layer outputs for a batch.

    Parameters
    ----------
    w : Weights
    X : ndarray, shape (n_samples, n_in)

    Returns
    -------
    Y1, Y2, Y3 : ndarray
        Sigmoid outputs, shapes (n_samples, n_hidden), (n_samples, n_hidden), (n_samples, n_out).
    """
    Y1 = expit(X @ w.W1.T)
    Y2 = expit(Y1 @ w.W2.T)
    Y3 = expit(Y2 @ w.W3.T)
    return Y1, Y2, Y3


def rms_error(w: Weights, X: np.ndarray, T: np.ndarray) -> float:
    """RMS of ``E = T - Y3`` over all samples and outputs (paper's RMS_1, pooled)."""
    _, _, Y3 = forward(w, X)
    return float(np.sqrt(np.mean((T[None, :] - Y3) ** 2)))


# --------------------------------------------------------------------------
# compiled kernel (Gram form)
# --------------------------------------------------------------------------


@njit(cache=True, fastmath=False)
def _sigmoid(z: float) -> float:
    """``1 / (1 + exp(-z))`` without overflow (as scipy's expit)."""
    if z >= 0.0:
        return 1.0 / (1.0 + math.exp(-z))
    e = math.exp(z)
    return e / (1.0 + e)


@njit(cache=True, fastmath=False)
def _forward_one(P, G, A, W2, W3, r, y1, y2, y3):
    """Layer outputs for training row r, into y1, y2, y3."""
    H, n = A.shape
    for h in range(H):
        z = P[r, h]
        for k in range(n):
            z += A[h, k] * G[k, r]
        y1[h] = _sigmoid(z)
    for h in range(H):
        z = 0.0
        for k in range(H):
            z += W2[h, k] * y1[k]
        y2[h] = _sigmoid(z)
    for o in range(W3.shape[0]):
        z = 0.0
        for k in range(H):
            z += W3[o, k] * y2[k]
        y3[o] = _sigmoid(z)


@njit(cache=True, fastmath=False)
def _train_gram(P, G, A, W2, W3, T, lr, delta1, max_epochs):
    """Per-sample backpropagation in Gram form; updates A, W2, W3 in place.

    Returns (epochs, rms, converged).
    """
    H, n = A.shape
    O = W3.shape[0]
    y1 = np.empty(H)
    y2 = np.empty(H)
    y3 = np.empty(O)
    s1 = np.empty(H)
    s2 = np.empty(H)
    s3 = np.empty(O)
    rms = np.nan
    for epoch in range(1, max_epochs + 1):
        for r in range(n):
            _forward_one(P, G, A, W2, W3, r, y1, y2, y3)
            for o in range(O):
                s3[o] = y3[o] * (1.0 - y3[o]) * (T[o] - y3[o])
            for h in range(H):
                acc = 0.0
                for o in range(O):
                    acc += W3[o, h] * s3[o]
                s2[h] = y2[h] * (1.0 - y2[h]) * acc
            for h in range(H):
                acc = 0.0
                for k in range(H):
                    acc += W2[k, h] * s2[k]
                s1[h] = y1[h] * (1.0 - y1[h]) * acc
            for o in range(O):
                for k in range(H):
                    W3[o, k] += lr * s3[o] * y2[k]
            for h in range(H):
                for k in range(H):
                    W2[h, k] += lr * s2[h] * y1[k]
            for h in range(H):
                A[h, r] += lr * s1[h]
        sq = 0.0
        for r in range(n):
            _forward_one(P, G, A, W2, W3, r, y1, y2, y3)
            for o in range(O):
                sq += (T[o] - y3[o]) ** 2
        rms = math.sqrt(sq / (n * O))
        if rms < delta1:
            return epoch, rms, True
    return max_epochs, rms, False


def train(
    w0: Weights,
    X: np.ndarray,
    T: np.ndarray,
    learning_rate: float,
    delta1: float,
    max_epochs: int,
    label: str = "",
) -> TrainResult:
    """Per-sample backpropagation until ``RMS < delta1`` or ``max_epochs``.

    Parameters
    ----------
    w0 : Weights
        Initial weights (not modified).
    X : ndarray, shape (n_samples, n_in)
        Normalised inputs X1, one training row per sample, presented in this order.
    T : ndarray, shape (n_out,)
        Target of every output for every sample.
    learning_rate : float
        Learning coefficient l [-].
    delta1 : float
        Stop threshold on the RMS output error [-].
    max_epochs : int
        Epoch cap.
    label : str
        Names the network in log messages.

    Returns
    -------
    TrainResult
        Same algorithm as :func:`train_explicit` (see the module docstring); the
        two agree to rounding.
    """
    X = np.ascontiguousarray(X, dtype=float)
    if X.ndim != 2 or X.shape[0] == 0:
        raise ValueError(f"X must have shape (n_samples >= 1, n_in), got {X.shape}")
    P = np.ascontiguousarray(X @ w0.W1.T)  # (n, H): initial first-layer inputs
    G = np.ascontiguousarray(X @ X.T)  # (n, n): Gram matrix
    A = np.zeros((w0.W1.shape[0], X.shape[0]))  # W1 = W1_0 + A @ X
    W2, W3 = w0.W2.copy(), w0.W3.copy()
    epochs, rms, converged = _train_gram(
        P, G, A, W2, W3, np.asarray(T, dtype=float), float(learning_rate), float(delta1), int(max_epochs)
    )
    w = Weights(w0.W1 + A @ X, W2, W3)
    if not converged:
        logger.warning(
            "network %s hit the epoch cap max_epochs=%d with RMS=%.4g (delta1=%.4g); "
            "its weights are those after the last epoch",
            label or "(unnamed)",
            max_epochs,
            rms,
            delta1,
        )
    return TrainResult(w, int(epochs), float(rms), bool(converged))


# --------------------------------------------------------------------------
# reference implementation
# --------------------------------------------------------------------------


def _step(w: Weights, x: np.ndarray, T: np.ndarray, l: float) -> None:
    """One per-sample backpropagation step, in place."""
    y1 = expit(w.W1 @ x)
    y2 = expit(w.W2 @ y1)
    y3 = expit(w.W3 @ y2)
    s3 = y3 * (1.0 - y3) * (T - y3)
    s2 = y2 * (1.0 - y2) * (w.W3.T @ s3)
    s1 = y1 * (1.0 - y1) * (w.W2.T @ s2)
    w.W3 += l * np.outer(s3, y2)
    w.W2 += l * np.outer(s2, y1)
    w.W1 += l * np.outer(s1, x)


def train_explicit(
    w0: Weights,
    X: np.ndarray,
    T: np.ndarray,
    learning_rate: float,
    delta1: float,
    max_epochs: int,
) -> TrainResult:
    """Reference: the same training as :func:`train`, with explicit ``W1`` updates in numpy (slow).

    No logging; otherwise the same parameters and result as :func:`train`.
    """
    w = w0.copy()
    rms = float("nan")
    for epoch in range(1, max_epochs + 1):
        for x in X:
            _step(w, x, T, learning_rate)
        rms = rms_error(w, X, T)
        if rms < delta1:
            return TrainResult(w, epoch, rms, True)
    return TrainResult(w, max_epochs, rms, False)
