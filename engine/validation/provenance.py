"""Which code a validation ran on: the git commit and description of the source tree, when git can tell."""

from __future__ import annotations

import logging
import subprocess
from pathlib import Path

logger = logging.getLogger(__name__)

__all__ = ["code_version"]

#: The source tree whose version is reported (the repository holding the ``engine`` package).
SOURCE_ROOT: Path = Path(__file__).resolve().parents[2]
#: Longest wait for one git command [s].
GIT_TIMEOUT_S: float = 10.0


def _git(*args: str) -> str | None:
    try:
        out = subprocess.run(
            ["git", "-C", str(SOURCE_ROOT), *args],
            capture_output=True,
            text=True,
            timeout=GIT_TIMEOUT_S,
            check=True,
        )
    except (OSError, subprocess.SubprocessError) as exc:
        logger.debug("git %s failed: %s", " ".join(args), exc)
        return None
    return out.stdout.strip() or None


def code_version() -> dict[str, str | bool | None]:
    """The code version of the source tree, without failing when git or the repository is absent.

    Returns
    -------
    dict
        ``commit`` (full hash or None), ``describe`` (``git describe --always --dirty --tags``
        or None) and ``dirty`` (uncommitted changes to tracked files; None when unknown).
    """
    commit = _git("rev-parse", "HEAD")
    describe = _git("describe", "--always", "--dirty", "--tags")
    dirty = None if describe is None else describe.endswith("-dirty")
    return {"commit": commit, "describe": describe, "dirty": dirty}
