"""Nearest-template identifier: our stronger alternative to the paper's method.

Idea
----
The paper compresses a record into 15 weights of a network trained on it and
compares those. We compare the records themselves, in the wavelet domain,
restricted to the early part of the record: the backlash width sets *when*
the first impacts after the event happen (the motor coasts across the zone,
2b / (Omega_b |w_1 - w_2|)), which makes the early window vary smoothly with K,
whereas the later impact sequence depends chaotically on J1 and c
(INVERSE-PROBLEM.md). Because the periodized DWT is orthogonal, a distance
over the coefficients whose support starts before sample W is a distance over
the early window with the wavelet's time-frequency localisation.

Fit stores the training records' coefficients (the "templates") per width.
For a record, D(i) is the distance to the nearest template of width i
(normalised by the training coefficients' RMS), so D plays the same role as
the paper's D vector and ``index = argmin D``. The window W is chosen in
``fit`` by leave-one-group-out cross-validation on the *training* records only
(groups = J1 values), so no evaluation data ever tunes it.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from engine.constants import CHANNEL_WAVELETS, CHANNELS, K_GRID, N_SAMPLES, WAVELET_LEVEL
from engine.features.wavelet import level_slices, wavelet_coefficients
from engine.identification.base import IdentificationResult, NotFittedError, check_wavelet

logger = logging.getLogger(__name__)

#: Candidate early windows [samples from the start of the record].
DEFAULT_WINDOWS: tuple[int, ...] = (300, 600, 1000, 2048)


def window_mask(window: int, n: int = N_SAMPLES, level: int = WAVELET_LEVEL) -> np.ndarray:
    """Boolean mask over the coefficient layout: coefficients whose support starts before ``window``.

    Coefficient m of detail level j (or of the approximation at ``level``)
    covers samples [m 2^j, (m + 1) 2^j) of the periodized transform.
    """
    mask = np.zeros(n, dtype=bool)
    for band in level_slices(n, level):
        size = band.slice.stop - band.slice.start
        step = n // size
        starts = np.arange(size) * step
        mask[band.slice] = starts < window
    return mask


class TemplateIdentifier:
    """Nearest-template backlash-width identifier for one channel.

    Parameters
    ----------
    channel : str
        Channel of the records, one of ``CHANNELS``.
    wavelet : str or None, default None
        Wavelet; None uses the paper's wavelet of the channel.
    level : int, default 10
        Decomposition level.
    windows : sequence of int, default (300, 600, 1000, 2048)
        Candidate early windows [samples]; ``fit`` picks one by
        leave-one-group-out cross-validation when groups are given.
    window : int or None, default None
        Fixed window [samples]; overrides the cross-validated choice.

    Attributes
    ----------
    wavelet_ : str
    window_ : int
        Window in use [samples].
    cv_scores_ : dict of int to float
        Cross-validated accuracy of each candidate window on the training records.
    templates_ : ndarray, shape (n_train, 2048)
        Wavelet coefficients of the training records.
    template_widths_ : ndarray, shape (n_train,)
        Width K of each template [m].
    widths_ : ndarray, shape (6,)
        Identifiable widths, ``K_GRID`` order [m].
    scale_ : float
        RMS of the training coefficients inside the window [channel unit].
    """

    _PARAM_NAMES = ("channel", "wavelet", "level", "windows", "window")

    def __init__(
        self,
        channel: str,
        wavelet: str | None = None,
        level: int = WAVELET_LEVEL,
        windows: Sequence[int] = DEFAULT_WINDOWS,
        window: int | None = None,
    ) -> None:
        self.channel = channel
        self.wavelet = wavelet
        self.level = level
        self.windows = windows
        self.window = window

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Constructor parameters (JSON-ready)."""
        params = {name: getattr(self, name) for name in self._PARAM_NAMES}
        params["windows"] = [int(w) for w in params["windows"]]
        return params

    def validate_params(self) -> None:
        """Raise ``ValueError`` with what to fix unless every parameter is acceptable: a known channel, a discrete
        wavelet and level of PyWavelets, windows of 1 to 2048 samples, ``window`` one of them (or None)."""
        if self.channel not in CHANNELS:
            raise ValueError(f"unknown channel {self.channel!r}; known channels: {', '.join(CHANNELS)}")
        check_wavelet(self.wavelet, self.level)
        windows = list(self.windows)
        if not windows or not all(
            isinstance(w, int) and not isinstance(w, bool) and 1 <= w <= N_SAMPLES for w in windows
        ):
            raise ValueError(f"windows must be integers from 1 to {N_SAMPLES} samples, got {self.windows!r}")
        if self.window is not None and self.window not in windows:
            raise ValueError(f"window must be one of the windows {windows} or None, got {self.window!r}")

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self.get_params().items())})"

    # -- helpers -------------------------------------------------------------

    def _coefficients(self, X: Any) -> np.ndarray:
        if self.channel not in CHANNELS:
            raise ValueError(f"unknown channel {self.channel!r}; known channels: {', '.join(CHANNELS)}")
        arr = np.asarray(X, dtype=float)
        if arr.ndim == 1:
            arr = arr[None, :]
        if arr.ndim != 2 or arr.shape[1] != N_SAMPLES:
            raise ValueError(f"records must have shape (n_records, {N_SAMPLES}), got {arr.shape}")
        wavelet = self.wavelet or CHANNEL_WAVELETS[self.channel]
        return wavelet_coefficients(arr, wavelet, level=self.level)

    @staticmethod
    def _nearest_by_width(C: np.ndarray, T: np.ndarray, T_widths: np.ndarray, widths: np.ndarray) -> np.ndarray:
        """D (n, n_widths): distance of each row of C to the nearest template of each width."""
        d2 = np.maximum((C**2).sum(1)[:, None] + (T**2).sum(1)[None, :] - 2.0 * C @ T.T, 0.0)
        D = np.full((C.shape[0], widths.size), np.inf)
        for i, K in enumerate(widths):
            cols = np.isclose(T_widths, K)
            if cols.any():
                D[:, i] = np.sqrt(d2[:, cols].min(axis=1))
        return D

    def _check_fitted(self) -> None:
        if not hasattr(self, "templates_"):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit(X, y) first")

    # -- estimator API -----------------------------------------------------------

    def fit(self, X: Any, y: Any, groups: Any = None) -> TemplateIdentifier:
        """Store templates and choose the window.

        Parameters
        ----------
        X : array_like, shape (n_records, 2048)
            Raw channel samples (channel unit).
        y : array_like, shape (n_records,)
            Width K of each record [m]; every width of ``K_GRID`` must be present.
        groups : array_like, shape (n_records,), optional
            Group of each record (e.g. its J1) for leave-one-group-out choice of the window.

        Returns
        -------
        self
        """
        C = self._coefficients(X)
        y = np.asarray(y, dtype=float).ravel()
        if y.shape[0] != C.shape[0]:
            raise ValueError(f"X has {C.shape[0]} records but y has {y.shape[0]} widths")
        widths = np.asarray(K_GRID)
        missing = [float(K) for K in widths if not np.isclose(y, K).any()]
        if missing:  # another grid (a described drive's, scaled), or a grid short of widths
            widths = np.unique(y)
            if widths.size != len(K_GRID):
                raise ValueError(
                    f"training widths must be the {len(K_GRID)} of K_GRID (missing {missing}) or {len(K_GRID)} other "
                    f"distinct widths (a drive's scaled grid), got {widths.size}: {widths.tolist()}"
                )
        candidates = [int(w) for w in ([self.window] if self.window is not None else self.windows)]
        if not candidates or any(not (1 <= w <= N_SAMPLES) for w in candidates):
            raise ValueError(f"windows must lie in [1, {N_SAMPLES}] samples, got {candidates}")
        self.cv_scores_: dict[int, float] = {}
        if groups is not None and len(candidates) > 1:
            g = np.asarray(groups, dtype=float).ravel()
            if g.shape[0] != C.shape[0]:
                raise ValueError("groups must give one value per record")
            for w in candidates:
                m = window_mask(w, N_SAMPLES, self.level)
                hits = []
                for gv in np.unique(g):
                    te = g == gv
                    D = self._nearest_by_width(C[te][:, m], C[~te][:, m], y[~te], widths)
                    hits.append(np.isclose(widths[D.argmin(1)], y[te]))
                self.cv_scores_[w] = float(np.mean(np.concatenate(hits)))
            # best CV accuracy; ties go to the longer window (more information)
            self.window_ = max(candidates, key=lambda w: (self.cv_scores_[w], w))
        else:
            self.window_ = candidates[-1] if self.window is None else int(self.window)
        mask = window_mask(self.window_, N_SAMPLES, self.level)
        self.wavelet_ = self.wavelet or CHANNEL_WAVELETS[self.channel]
        self.templates_ = C
        self.template_widths_ = y
        self.widths_ = widths
        self.scale_ = float(np.sqrt(np.mean(C[:, mask] ** 2))) or 1.0
        self.n_features_in_ = N_SAMPLES
        logger.debug("template identifier %s: window %d, cv %s", self.channel, self.window_, self.cv_scores_)
        return self

    def d_vectors(self, X: Any) -> np.ndarray:
        """D vectors (n_records, 6): normalised distance to the nearest template of each width [-]."""
        self._check_fitted()
        C = self._coefficients(X)
        m = window_mask(self.window_, N_SAMPLES, self.level)
        D = self._nearest_by_width(C[:, m], self.templates_[:, m], self.template_widths_, self.widths_)
        return D / (self.scale_ * np.sqrt(m.sum()))

    def identify_batch(self, X: Any) -> list[IdentificationResult]:
        D = self.d_vectors(X)
        out = []
        for d in D:
            i = int(np.argmin(d))
            out.append(
                IdentificationResult(
                    D=d, index=i + 1, width=float(self.widths_[i]), epochs=0, rms=float(d[i]), converged=True
                )
            )
        return out

    def identify(self, x: Any) -> IdentificationResult:
        """Identify one record (``epochs`` is 0: nothing is trained per record)."""
        return self.identify_batch(np.asarray(x, dtype=float)[None, :] if np.ndim(x) == 1 else x)[0]

    def predict(self, X: Any) -> np.ndarray:
        """Identified widths K [m], shape (n_records,)."""
        D = self.d_vectors(X)
        return self.widths_[D.argmin(axis=1)]

    # -- persistence -----------------------------------------------------------------

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Learned state as named arrays (for the pattern store)."""
        self._check_fitted()
        return {
            "templates": self.templates_,
            "template_widths": self.template_widths_,
            "widths": self.widths_,
            "window": np.array([self.window_]),
            "scale": np.array([self.scale_]),
        }

    @classmethod
    def from_arrays(cls, params: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> TemplateIdentifier:
        """Rebuild a fitted identifier from :meth:`get_params` and :meth:`to_arrays`."""
        known = {k: v for k, v in params.items() if k in cls._PARAM_NAMES}
        est = cls(**known)
        try:
            est.templates_ = np.asarray(arrays["templates"], dtype=float)
            est.template_widths_ = np.asarray(arrays["template_widths"], dtype=float)
            est.widths_ = np.asarray(arrays["widths"], dtype=float)
            est.window_ = int(np.asarray(arrays["window"]).ravel()[0])
            est.scale_ = float(np.asarray(arrays["scale"]).ravel()[0])
        except KeyError as exc:
            raise ValueError(f"stored template identifier lacks array {exc}") from None
        est.wavelet_ = est.wavelet or CHANNEL_WAVELETS[est.channel]
        est.cv_scores_ = {}
        est.n_features_in_ = N_SAMPLES
        return est
