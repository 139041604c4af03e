"""Files written whole or not at all: a temporary file in the same directory, renamed over the target.

A reader (or a run resumed after an interruption) then sees either the old file or the new one,
never a half-written one: the validation runs of both protocols count a result file as a finished
diagnosis (:mod:`engine.validation.layout`, :mod:`engine.diagnosis.validation`).
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

__all__ = ["write_json_atomic", "write_text_atomic"]


def _file_mode() -> int:
    """The mode ``open(path, "w")`` gives a new file: 0o666 less the process's umask."""
    umask = os.umask(0)  # read it the only way POSIX allows, and put it back
    os.umask(umask)
    return 0o666 & ~umask


#: Mode of the files written here (``tempfile.mkstemp`` makes 0o600, readable by the owner only).
_FILE_MODE = _file_mode()


def write_text_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same directory, renamed over it.

    The content reaches the disk (``fsync``) before the rename, and the file gets the mode a plain
    ``open(path, "w")`` would give it.

    Parameters
    ----------
    path : Path
        Target file; its directory must exist.
    text : str
        The content.
    """
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_json_atomic(path: Path, data: Any, indent: int | None = None) -> None:
    """Write ``data`` as JSON (NaN and infinities refused) to ``path`` atomically (:func:`write_text_atomic`)."""
    write_text_atomic(path, json.dumps(data, indent=indent, allow_nan=False))
