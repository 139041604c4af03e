"""The linearised fits (step 2 of the method).

Roughness-penalised least squares with the penalty weight chosen by BIC (:func:`penalised_fit`),
unpenalised least squares (:func:`linear_fit`), and the orthonormal bases and projections that
take unpenalised columns out of a fit (:func:`orth`, :func:`project`); residuals in chi2 units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from engine.diagnosis.locus._report import LocusSettings


@dataclass
class Fit:
    rss: float
    dof: float
    bic: float
    x: np.ndarray  # knot values (NaN where the locus has no response)
    resolution: np.ndarray  # per knot, in [0, 1]


def orth(M: np.ndarray, n: int) -> np.ndarray:
    """Orthonormal basis (n, rank) of the column space of M (n, m); columns without a response are dropped.

    A plain QR would turn a zero column (e.g. a supply step after the switch-off, when the motor
    is off) into an arbitrary direction, and projecting that out would remove part of the data.
    """
    if M.shape[1] == 0:
        return np.zeros((n, 0))
    U, sv, _ = np.linalg.svd(M, full_matrices=False)
    rank = int(np.sum(sv > 1e-9 * max(float(sv.max(initial=0.0)), 1e-300)))
    return U[:, :rank]


def project(Q: np.ndarray, M: np.ndarray) -> np.ndarray:
    """M less its part in the span of Q's orthonormal columns."""
    return M - Q @ (Q.T @ M) if Q.shape[1] else M


def penalised_fit(A: np.ndarray, r: np.ndarray, k: int, settings: LocusSettings) -> Fit:
    """Roughness-penalised least squares of r on A, lambda by the penalised fit (BIC with effective dof).

    Worked in the Gram matrix: with the penalty ``pen = L L^T`` and ``B = A L^-T``, the
    eigen-decomposition ``B^T B = V diag(s^2) V^T`` gives, for every lambda, the shrink factors
    ``f = s^2 / (s^2 + lambda)``, the effective dof ``sum(f)`` and the residual
    ``|r|^2 - sum((2 f - f^2) c^2)`` with ``c = V^T B^T r / s``.
    """
    n, m_all = A.shape
    ln_n = math.log(max(n, 2))
    norms = np.linalg.norm(A, axis=0)
    keep = np.flatnonzero(norms > 1e-9 * max(float(norms.max(initial=0.0)), 1e-300))
    x_all = np.full(m_all, np.nan)
    res_all = np.zeros(m_all)
    rr = float(r @ r)
    if keep.size == 0:
        return Fit(rr, 0.0, rr + k * ln_n, x_all, res_all)
    Ak = A[:, keep]
    m = keep.size
    D = np.diff(np.eye(m), axis=0)
    pen = D.T @ D + settings.ridge * np.eye(m)
    L = np.linalg.cholesky(pen)  # pen = L L^T
    Linv_T = np.linalg.inv(L).T  # x = L^-T w
    G = Linv_T.T @ (Ak.T @ Ak) @ Linv_T
    s2, V = np.linalg.eigh(0.5 * (G + G.T))
    s2 = np.clip(s2, 0.0, None)
    g = V.T @ (Linv_T.T @ (Ak.T @ r))  # = s * c
    ok = s2 > 1e-12 * max(float(s2.max(initial=0.0)), 1e-300)
    c2 = np.where(ok, g**2 / np.where(ok, s2, 1.0), 0.0)
    top = float(s2.max(initial=1.0))
    best: tuple[float, float, float, float] | None = None
    for lam in top * np.logspace(-10, 2, settings.n_lambda):
        f = np.where(ok, s2 / (s2 + lam), 0.0)
        rss = rr - float(np.sum((2.0 * f - f**2) * c2))
        dof = float(np.sum(f))
        bic = rss + (dof + k) * ln_n
        if best is None or bic < best[0]:
            best = (bic, rss, dof, lam)
    assert best is not None
    bic, rss, dof, lam = best
    f = np.where(ok, s2 / (s2 + lam), 0.0)
    w = V @ np.where(ok, g / (s2 + lam), 0.0)
    x = Linv_T @ w
    # resolution: diagonal of (A^T A + lam pen)^-1 A^T A = L^-T V diag(f) V^T L^T
    R = Linv_T @ (V * f) @ (V.T @ L.T)
    x_all[keep] = x
    res_all[keep] = np.clip(np.diag(R), 0.0, 1.0)
    return Fit(max(rss, 0.0), dof, bic, x_all, res_all)


def linear_fit(A: np.ndarray, r: np.ndarray, k: int) -> tuple[float, float, np.ndarray]:
    """Unpenalised least squares: (rss, bic, coefficients)."""
    n = A.shape[0]
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    res = r - A @ coef
    rank = int(np.linalg.matrix_rank(A)) if A.size else 0
    rss = float(res @ res)
    return rss, rss + (rank + k) * math.log(max(n, 2)), coef


#: Most candidates :func:`sparse_extension` adds to a fit.
MAX_EXTENSION_TERMS: int = 2


def sparse_extension(
    A: np.ndarray, C: np.ndarray, r: np.ndarray, k: int, max_terms: int = MAX_EXTENSION_TERMS
) -> tuple[float, float, np.ndarray, list[int], np.ndarray]:
    """Least squares of r on A, extended by the few columns of a dictionary C the data ask for.

    Forward selection: the candidate of C that lowers the residual most is added while the drop
    exceeds ``ln n + 2 ln p`` (BIC's price of a column plus the price of choosing it among p
    candidates: the risk-inflation criterion of Foster and George, 1994, so that the best of p
    columns of pure noise, whose drop is about ``2 ln p``, is not taken), up to ``max_terms``.

    Returns
    -------
    rss : float
    bic : float
        ``rss + (rank(A) + k) ln n + m (ln n + 2 ln p)`` with m the columns taken.
    coef : ndarray
        Coefficients of A's columns.
    chosen : list of int
        Indices of the columns of C taken, in the order taken.
    coef_chosen : ndarray
        Their coefficients.
    """
    n, p = A.shape[0], C.shape[1]
    ln_n = math.log(max(n, 2))
    rss, bic, coef = linear_fit(A, r, k)
    if p == 0:
        return rss, bic, coef, [], np.zeros(0)
    price = ln_n + 2.0 * math.log(p)
    chosen: list[int] = []
    design = A
    for _ in range(max_terms):
        Q = orth(design, n)
        res = project(Q, r[:, None])[:, 0]
        Cp = project(Q, C)
        norms = np.einsum("ij,ij->j", Cp, Cp)
        drop = np.where(
            norms > 1e-12 * max(float(norms.max(initial=0.0)), 1e-300),
            (Cp.T @ res) ** 2 / np.maximum(norms, 1e-300),
            0.0,
        )
        drop[chosen] = 0.0
        j = int(np.argmax(drop))
        if drop[j] <= price:
            break
        chosen.append(j)
        design = np.hstack([A, C[:, chosen]])
    if not chosen:
        return rss, bic, coef, [], np.zeros(0)
    rss2, bic2, coef2 = linear_fit(design, r, k)
    return rss2, bic2 + len(chosen) * 2.0 * math.log(p), coef2[: A.shape[1]], chosen, coef2[A.shape[1] :]
