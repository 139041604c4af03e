"""The array codec: named numpy arrays to and from one checksummed ``.npz`` blob.

The blob is an in-memory ``.npz`` written with ``allow_pickle=False`` (bit-exact, dtype and
shape preserved, never pickle); the store keeps it next to its SHA-256, which
:func:`decode_arrays` checks on every read.
"""

from __future__ import annotations

import hashlib
import io
import logging
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from engine.storage.errors import CorruptPatternSet, InvalidPatternSet

logger = logging.getLogger(__name__)

__all__ = ["array_metadata", "decode_arrays", "encode_arrays", "sha256", "validate_arrays"]

_ARRAY_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}$")
_ARRAY_KINDS = "biufc"  # bool, signed/unsigned int, float, complex


def validate_arrays(arrays: object) -> dict[str, np.ndarray]:
    """Check that ``arrays`` can be stored: a non-empty mapping of allowed names to finite numeric arrays.

    Parameters
    ----------
    arrays : object
        What a :class:`~engine.storage.PatternSet` holds as ``arrays``.

    Returns
    -------
    dict of str to ndarray
        The arrays (``numpy.asarray`` of each value), in the given order.

    Raises
    ------
    InvalidPatternSet
        A bad name, a non-numeric dtype, an empty array or a non-finite value; the message
        says which array and where.
    """
    if not isinstance(arrays, Mapping) or not arrays:
        raise InvalidPatternSet('arrays must be a non-empty dict of name -> numpy array, e.g. {"patterns": ...}')
    clean: dict[str, np.ndarray] = {}
    for name, value in arrays.items():
        if not isinstance(name, str) or not _ARRAY_NAME_RE.match(name):
            raise InvalidPatternSet(
                f"array name {name!r} is not allowed; use 1-64 characters from [A-Za-z0-9_.-] "
                "not starting with '.' or '-'"
            )
        arr = np.asarray(value)
        if arr.dtype.kind not in _ARRAY_KINDS:
            raise InvalidPatternSet(
                f"array {name!r} has dtype {arr.dtype}; only bool, integer, float and complex arrays can be stored"
            )
        if arr.size == 0:
            raise InvalidPatternSet(f"array {name!r} is empty (shape {arr.shape}); store at least one value")
        if arr.dtype.kind in "fc":
            finite = np.isfinite(arr)
            if not finite.all():
                bad = np.argwhere(~finite)[0]
                where = tuple(int(i) for i in bad)
                raise InvalidPatternSet(
                    f"array {name!r} holds a non-finite value ({arr[where]!r}) at index {where}; "
                    "training must produce finite values"
                )
        clean[name] = arr
    return clean


def array_metadata(arrays: Mapping[str, np.ndarray]) -> dict[str, dict[str, object]]:
    """The dtype (``numpy.dtype.str``) and shape of each array, as stored next to the blob."""
    return {name: {"dtype": arr.dtype.str, "shape": list(arr.shape)} for name, arr in arrays.items()}


def encode_arrays(arrays: Mapping[str, np.ndarray]) -> bytes:
    """The ``.npz`` blob of ``arrays`` (``allow_pickle=False``; validate them first)."""
    buf = io.BytesIO()
    np.savez(buf, allow_pickle=False, **arrays)
    return buf.getvalue()


def sha256(blob: bytes) -> str:
    """The hex SHA-256 of ``blob``, the checksum stored with it."""
    return hashlib.sha256(blob).hexdigest()


def decode_arrays(blob: bytes, expected_sha256: str, set_id: str, path: Path) -> dict[str, np.ndarray]:
    """The arrays in ``blob``, after checking its checksum.

    Parameters
    ----------
    blob : bytes
        An ``.npz`` blob made by :func:`encode_arrays`.
    expected_sha256 : str
        Its stored checksum.
    set_id : str
        Id of the pattern set it belongs to, for messages.
    path : Path
        The database file, for messages.

    Returns
    -------
    dict of str to ndarray

    Raises
    ------
    CorruptPatternSet
        The checksum differs or the blob cannot be decoded.
    """
    digest = sha256(blob)
    if digest != expected_sha256:
        logger.error("pattern set %s in %s fails its checksum", set_id, path)
        raise CorruptPatternSet(
            f"pattern set {set_id!r} in {path} is corrupt: its arrays' SHA-256 is {digest}, "
            f"expected {expected_sha256}; delete it and train it again"
        )
    try:
        with np.load(io.BytesIO(blob), allow_pickle=False) as npz:
            return {name: npz[name] for name in npz.files}
    except (ValueError, OSError, zipfile.BadZipFile, KeyError) as exc:
        raise CorruptPatternSet(f"pattern set {set_id!r} in {path}: cannot decode its arrays: {exc}") from exc
