"""Where the pattern store lives when no path is given."""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs

__all__ = ["DEFAULT_STORE_PATH", "STORE_PATH_ENV", "default_store_path"]

#: Environment variable that overrides the default database path.
STORE_PATH_ENV = "BACKLASH_DB_PATH"
#: Database path used when neither an explicit path nor ``STORE_PATH_ENV`` is given: the user's data
#: directory (``platformdirs``; ``~/.local/share/backlash`` on Linux), the same wherever the CLI runs.
DEFAULT_STORE_PATH = platformdirs.user_data_path("backlash") / "patterns.sqlite3"


def default_store_path() -> Path:
    """Return the database path to use when none is given.

    Returns
    -------
    Path
        ``$BACKLASH_DB_PATH`` if set, else :data:`DEFAULT_STORE_PATH`.
    """
    env = os.environ.get(STORE_PATH_ENV)
    return Path(env) if env else DEFAULT_STORE_PATH
