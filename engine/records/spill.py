"""A long record's columns on disk while it is read: written a chunk at a time, read back a stretch at a time.

A record read in pieces (:mod:`engine.records.streamed`) is located before anything of it is kept
(:func:`engine.records.event.locate_event` reads the whole record, several times); its columns go to
one anonymous temporary file each (:func:`tempfile.TemporaryFile`: deleted when closed, or when the
process ends), as float64, 8 bytes per sample. Memory then holds a chunk, not the record; the disk holds
the record once, until :meth:`Spill.close`.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterable
from types import TracebackType
from typing import IO

import numpy as np

__all__ = ["Column", "Spill"]

_ITEM = np.dtype(np.float64).itemsize


class Column:
    """One column of a :class:`Spill`, as a :class:`~engine.records.series.Series`."""

    def __init__(self, file: IO[bytes]) -> None:
        self._file = file
        self._size = 0

    @property
    def size(self) -> int:
        """Samples written."""
        return self._size

    def append(self, values: np.ndarray) -> None:
        """Write ``values`` (1-D, float64) after the samples written so far."""
        data = np.ascontiguousarray(values, dtype=np.float64)
        self._file.seek(self._size * _ITEM)
        self._file.write(data.tobytes())
        self._size += data.shape[0]

    def read(self, start: int, stop: int) -> np.ndarray:
        """Samples ``start .. stop - 1`` (clipped to those written), a new array."""
        start, stop = max(start, 0), min(stop, self._size)
        if stop <= start:
            return np.empty(0)
        self._file.seek(start * _ITEM)
        data = self._file.read((stop - start) * _ITEM)
        if len(data) != (stop - start) * _ITEM:
            raise OSError(f"the temporary file of a record column ended before sample {stop}")
        return np.frombuffer(data, dtype=np.float64).copy()

    def close(self) -> None:
        """Delete the file."""
        self._file.close()


class Spill:
    """Temporary files of a record's columns, by name (a context manager: :meth:`close` deletes them).

    Parameters
    ----------
    names : iterable of str
        The columns.
    directory : str, optional
        Where the files go (default: :func:`tempfile.gettempdir`).
    """

    def __init__(self, names: Iterable[str], directory: str | None = None) -> None:
        self.columns: dict[str, Column] = {}
        try:
            for name in names:  # closed (and so deleted) by close()
                file = tempfile.TemporaryFile(prefix="backlash-record-", dir=directory)  # noqa: SIM115
                self.columns[name] = Column(file)
        except BaseException:
            self.close()
            raise

    def append(self, chunk: dict[str, np.ndarray]) -> None:
        """Write one chunk: every column's next samples (the same number each)."""
        for name, column in self.columns.items():
            column.append(chunk[name])

    @property
    def n_samples(self) -> int:
        """Samples per column written."""
        return next(iter(self.columns.values())).size if self.columns else 0

    def close(self) -> None:
        """Delete the files."""
        for column in self.columns.values():
            column.close()

    def __enter__(self) -> Spill:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self.close()
