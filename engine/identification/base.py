"""Types shared by every backlash-width identifier, as scikit-learn's ``base.py``.

An identifier is an estimator for one channel: ``__init__`` only stores its
parameters, ``fit(X, y, groups)`` learns from raw training records and returns
``self``, learned state ends in ``_``, and ``identify`` answers with an
:class:`IdentificationResult` (the paper's D vector, the index ``nr5`` and the
width). :class:`Identifier` is the protocol that
:func:`engine.identification.training.make_identifier` returns and that the
pattern store persists through ``to_arrays`` / ``from_arrays``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, Self, runtime_checkable

import numpy as np

__all__ = ["IdentificationResult", "Identifier", "NotFittedError", "check_wavelet"]


class NotFittedError(ValueError, AttributeError):
    """The identifier is used before :meth:`PaperIdentifier.fit` (same bases as scikit-learn's)."""


@dataclass(frozen=True)
class IdentificationResult:
    """Outcome of identifying one record.

    Attributes
    ----------
    D : ndarray, shape (6,)
        ``D(i) = sum_j |Wt(j) - Ww(i, j)|`` for the widths in ``K_GRID`` order [-].
    index : int
        ``nr5``: 1-based index of the smallest ``D`` (paper's convention).
    width : float
        Identified backlash zone width ``K_GRID[index - 1]`` [m].
    epochs : int
        Epochs the record's own network needed (the cap if it did not converge).
        If the pattern networks were trained on different numbers of rows
        (unbalanced training data, ``test_rows="match"``), the record trains
        one network per row count; these fields describe the one compared
        with the winning pattern.
    rms : float
        RMS output error of the record's network after training [-].
    converged : bool
        Whether that network reached ``RMS < delta1``.
    """

    D: np.ndarray
    index: int
    width: float
    epochs: int
    rms: float
    converged: bool


@runtime_checkable
class Identifier(Protocol):
    """What every identifier kind offers (``PaperIdentifier``, ``TemplateIdentifier``).

    Attributes
    ----------
    channel : str
        Channel the records hold, one of ``engine.constants.CHANNELS``.
    """

    channel: str

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Constructor parameters by name (scikit-learn convention)."""
        ...

    def validate_params(self) -> None:
        """Raise ``ValueError`` saying what to fix unless every constructor parameter is acceptable."""
        ...

    def fit(self, X: Any, y: Any, groups: Any = None) -> Self:
        """Learn from raw records X (n_records, 2048) of widths y [m]; groups (e.g. J1) where used. Returns self."""
        ...

    def identify(self, x: Any) -> IdentificationResult:
        """Identify one record (2048 raw samples)."""
        ...

    def identify_batch(self, X: Any) -> list[IdentificationResult]:
        """Identify each row of X (n_records, 2048)."""
        ...

    def d_vectors(self, X: Any) -> np.ndarray:
        """D vectors (n_records, 6) [-], ``K_GRID`` order."""
        ...

    def predict(self, X: Any) -> np.ndarray:
        """Identified widths K [m], shape (n_records,)."""
        ...

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Learned state as named arrays (for the pattern store)."""
        ...

    @classmethod
    def from_arrays(cls, params: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> Self:
        """Rebuild a fitted identifier from :meth:`get_params` and :meth:`to_arrays`."""
        ...


def check_wavelet(wavelet: str | None, level: object, mode: str | None = None) -> None:
    """Raise ``ValueError`` unless ``wavelet`` (None: the channel's default) is a discrete wavelet of PyWavelets,
    ``level`` an integer from 1 to 11 (a 2048-sample record halves at most 11 times) and ``mode`` (if given) one
    of PyWavelets' signal extension modes; the message names the accepted values."""
    import pywt

    if wavelet is not None and wavelet not in pywt.wavelist(kind="discrete"):
        raise ValueError(f"wavelet {wavelet!r} is not a discrete wavelet of PyWavelets (e.g. sym5, db4, coif3)")
    if not (isinstance(level, int) and not isinstance(level, bool) and 1 <= level <= 11):
        raise ValueError(f"level must be an integer from 1 to 11, got {level!r}")
    if mode is not None and mode not in pywt.Modes.modes:
        raise ValueError(f"mode must be one of {', '.join(pywt.Modes.modes)}, got {mode!r}")
