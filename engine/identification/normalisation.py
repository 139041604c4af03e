"""The paper's normalisation of the wavelet coefficients, eqs. (2)-(5) of section 3.1.

The training rows of a pattern set (all six widths together) fix the
normalisation of eq. (2): ``h1, k1`` (range of the coefficient matrix ``N``)
and ``h2, k2`` (target range, chosen by the case analysis of eqs. (3)-(5) from
the auxiliary variables ``h3 .. h21``, ``m1 .. m5`` and the matrices
``N1 .. N5``). These constants are stored with the pattern set and applied
unchanged to every test record by :class:`~engine.identification.paper.PaperIdentifier`.

The text of section 3.1 is garbled in many places; every reading chosen here
is listed, one entry per ambiguity, in ``docs/paper-notes.md``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "M3_WIDTHS",
    "N1_WINDOWS",
    "N2_WINDOWS",
    "N4_EXTREME_WIDTHS",
    "TERM_NAMES",
    "normalisation_terms",
    "normalise",
]

#: Window lengths [samples] of the running means in matrix N1 (paper: 100 .. 500).
N1_WINDOWS: tuple[int, ...] = (100, 200, 300, 400, 500)
#: Window lengths [samples] of the running means in matrix N2 (paper: 256 .. 1280).
N2_WINDOWS: tuple[int, ...] = (256, 512, 768, 1024, 1280)
#: Width indices (1-based, into K_GRID) whose N3 values enter the mean m3.
M3_WIDTHS: tuple[int, ...] = (1, 2, 3)
#: Width indices (1-based) whose N4 values give h17 (max) and h18 (min).
N4_EXTREME_WIDTHS: tuple[int, ...] = (3, 4, 5, 6)
#: Names of the scalar normalisation terms, in the order stored by ``to_arrays``.
TERM_NAMES: tuple[str, ...] = (
    "h1",
    "k1",
    "h2",
    "k2",
    "h3",
    "h4",
    "h5",
    "h6",
    "h7",
    "h8",
    "h9",
    "h10",
    "h11",
    "h12",
    "h13",
    "h14",
    "h15",
    "h16",
    "h17",
    "h18",
    "h19",
    "h20",
    "h21",
    "m1",
    "m2",
    "m3",
    "m5",
)


def _running_means(N: np.ndarray, windows: tuple[int, ...]) -> np.ndarray:
    """Means of the first ``n`` coefficients of each row for each window ``n``; shape (R, len(windows))."""
    csum = np.cumsum(N, axis=1)
    return np.stack([csum[:, n - 1] / n for n in windows], axis=-1)


def _chained_differences(v: np.ndarray) -> np.ndarray:
    """Paper's ``(v1 - v2) - (v2 - v3) - (v3 - v4) - (v4 - v5)`` along the last axis (eqs. 3, 4 and N5)."""
    return (v[..., 0] - v[..., 1]) - (v[..., 1] - v[..., 2]) - (v[..., 2] - v[..., 3]) - (v[..., 3] - v[..., 4])


def _summed_differences(v: np.ndarray) -> np.ndarray:
    """Paper's ``(v1 - v2) + (v2 - v3) + (v3 - v4) + (v4 - v5)`` along the last axis (h21)."""
    return (v[..., 0] - v[..., 1]) + (v[..., 1] - v[..., 2]) + (v[..., 2] - v[..., 3]) + (v[..., 3] - v[..., 4])


def _count_sum(h16: float, mask: np.ndarray) -> np.ndarray:
    """Paper's cyclic summation ``sum h16 over the samples where a condition holds``, per row."""
    return h16 * np.count_nonzero(mask, axis=-1).astype(float)


def normalisation_terms(N: np.ndarray, width_index: np.ndarray) -> dict[str, float]:
    """All scalar terms of eqs. (2)-(5), computed on a set of training rows.

    Parameters
    ----------
    N : ndarray, shape (R, 2048)
        Wavelet coefficients of the training records, one row per record
        (all widths, all J1 cases of the pattern set).
    width_index : ndarray of int, shape (R,)
        1-based index into ``K_GRID`` of each row's width; all of 1..6 present.

    Returns
    -------
    dict of str to float
        ``h1 .. h21``, ``k1``, ``k2``, ``m1``, ``m2``, ``m3``, ``m5`` (see
        :data:`TERM_NAMES`) and ``case`` (1, 2 or 3: which branch of eq. (5)
        chose ``h3, h4``). Per-record quantities that the paper indexes by
        ``p`` alone (``N1``, ``N2`` in h5/h6/h21, ``m2(p)``, ``h12``, ``h14``)
        are evaluated on every record and averaged over the records.

    Raises
    ------
    ValueError
        Case 2 with ``h11 == 0`` (``h3 = m1 / h11`` undefined).
    """
    N = np.asarray(N, dtype=float)
    wi = np.asarray(width_index)
    t: dict[str, float] = {}
    # h1, k1: range of N (eq. 2); h16: "the biggest value of the matrix N"
    t["h1"] = float(N.min())
    t["k1"] = float(N.max())
    h16 = t["h16"] = float(N.max())
    # per-record statistics
    m4 = N.mean(axis=1)  # m4(p)(i): row means
    sd1 = np.sqrt(np.mean((N - m4[:, None]) ** 2, axis=1))  # d1(p)(i): row standard deviations
    N1 = _running_means(N, N1_WINDOWS)  # N1(p)(k)
    N2 = _running_means(N, N2_WINDOWS)  # N2(p)(i,k)
    N3 = _count_sum(h16, sd1[:, None] < N)  # N3(p)(i)
    N4 = _count_sum(h16, m4[:, None] < N)  # N4(p)(i)
    N5 = _chained_differences(N2)  # N5(p)(i)
    # eqs. (3), (4) and h21 on the means of N1, N2 over the records
    n1, n2 = N1.mean(axis=0), N2.mean(axis=0)
    t["h5"] = float(_chained_differences(n1))
    t["h6"] = float(_chained_differences(n2))
    t["h21"] = float(_summed_differences(n1))
    # h7 <= h8 test
    t["h13"] = float(N3.max())
    t["h8"] = float(N3.min())
    t["m3"] = float(N3[np.isin(wi, M3_WIDTHS)].mean())
    t["h7"] = t["h13"] + (t["m3"] - t["h8"])
    # h9 <= h10 test
    sel = np.isin(wi, N4_EXTREME_WIDTHS)
    t["h17"] = float(N4[sel].max())
    t["h18"] = float(N4[sel].min())
    t["h15"] = abs(t["h17"] - t["h18"])
    m2_p = N.mean(axis=1)  # m2(p): mean of the tested matrix, per record
    t["h14"] = float(np.mean(_count_sum(h16, m2_p[:, None] < N)))
    t["h9"] = abs(t["h14"] - t["h18"])
    t["h10"] = max(t["h15"], h16)
    # h11 from N5
    t["h19"] = float(N5.min())
    t["h20"] = float(N5.max())
    t["m5"] = float(N5.mean())
    t["h11"] = (t["h19"] - t["h21"]) - (t["h20"] - t["h21"]) - (t["m5"] - t["h21"])
    # h12 from d2(p)
    sd2 = np.sqrt(np.mean((N - m2_p[:, None]) ** 2, axis=1))
    t["h12"] = float(np.mean(_count_sum(h16, sd2[:, None] < N)))
    # means
    t["m1"] = float(m4[wi == 1].mean())  # m1: rows of the smallest width
    t["m2"] = float(N.mean())
    # eq. (5)
    if t["h7"] <= t["h8"]:
        case, h3, h4 = 1, t["h5"] - t["h6"], t["h6"] - t["h5"]
    elif t["h9"] <= t["h10"]:
        if t["h11"] == 0.0:
            raise ValueError("normalisation case 2 needs h3 = m1 / h11 but h11 = 0 for these training records")
        case, h3, h4 = 2, t["m1"] / t["h11"], t["m1"] * t["h11"] / t["h11"]
    else:
        case, h3, h4 = 3, t["h12"], t["m2"]
    t["h3"], t["h4"] = float(h3), float(h4)
    t["h2"], t["k2"] = min(t["h3"], t["h4"]), max(t["h3"], t["h4"])
    t["case"] = float(case)
    return t


def normalise(N: np.ndarray, h1: float, k1: float, h2: float, k2: float) -> np.ndarray:
    """Eq. (2): map ``[h1, k1]`` (min, max of the training N) linearly onto ``[h2, k2]``.

    ``X1 = (N - k1) / (h1 - k1) * (h2 - k2) + k2``. Test values outside
    ``[h1, k1]`` land outside ``[h2, k2]``; they are not clipped.
    """
    if h1 == k1:
        raise ValueError("cannot normalise: the training coefficients are all equal (h1 == k1)")
    return (np.asarray(N, dtype=float) - k1) / (h1 - k1) * (h2 - k2) + k2
