"""A CSV table of numbers under one header line: the shared reader of the plants' CSV record forms.

The BRFD's and the FMU plants' CSV records (:mod:`engine.plants.brfd.record`,
:mod:`engine.plants.fmu.record`) are one header line and one row of numbers per sample, with comment
lines (``#``) anywhere; what each plant asks of the columns (their names, their units) is its own.
"""

from __future__ import annotations

import io

import numpy as np

from engine.records.errors import RecordError

__all__ = ["numeric_rows", "table_lines"]


def table_lines(text: str) -> list[str]:
    """The lines of a CSV text that are neither blank nor comments (``#``): the header, then the rows."""
    return [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]


def numeric_rows(rows: list[str], n_columns: int, label: str) -> np.ndarray:
    """The CSV ``rows`` (after the header) as numbers, shape ``(n, n_columns)``.

    Raises
    ------
    RecordError
        A row that is not numbers, or rows whose width is not the header's ``n_columns``.
    """
    try:
        table = np.loadtxt(io.StringIO("\n".join(rows)), delimiter=",", ndmin=2)
    except ValueError as exc:
        raise RecordError(f"{label}: a CSV row cannot be read as numbers ({exc})") from None
    if table.shape[1] != n_columns:
        raise RecordError(f"{label}: rows have {table.shape[1]} values but the header names {n_columns} columns")
    return table
