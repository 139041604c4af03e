"""Per-case row files: one JSON object per line, as the development replays print them.

The replays of ``lab/scripts/`` (``rediagnose.py``, ``locus_cases.py``) print one JSON row per case
and a summary line; :func:`json_rows` reads such a file for the scripts that score or fit on it
(``lab/scripts/summarise_rows.py``, ``bench/confidence_reliability.py --locus-rows``), naming the
file and line of a row it cannot read rather than skipping it.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

__all__ = ["json_rows"]


def json_rows(path: Path | str, required: Sequence[str] = ()) -> Iterator[tuple[int, dict[str, Any]]]:
    """The case rows of a row file, with their line numbers; blank lines and summary lines left out.

    Parameters
    ----------
    path : Path or str
        The file.
    required : sequence of str
        Keys every case row must hold.

    Yields
    ------
    line : int
        1-based line number.
    row : dict
        A row with a ``case`` key.

    Raises
    ------
    ValueError
        A line that is not a JSON object, or a case row without a required key (file and line named).
    """
    for i, line in enumerate(Path(path).read_text().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}:{i}: not a JSON row ({exc.msg})") from exc
        if not isinstance(row, dict):
            raise ValueError(f"{path}:{i}: not a JSON object")
        if "case" not in row:
            continue  # a summary line
        missing = [k for k in required if k not in row]
        if missing:
            raise ValueError(f"{path}:{i}: the row has no {', '.join(missing)}")
        yield i, row
