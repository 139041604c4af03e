"""One service process per database file: its jobs are its own.

At start a service marks the jobs a previous process left queued or running as interrupted
(:meth:`app.jobs.JobManager.recover`); a second service on the same file would interrupt the
first one's live jobs. An exclusive advisory lock on ``<db>.service-lock`` (held for the
process's life, released by the kernel when it dies, however it dies) refuses that start with a
message instead.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
from typing import IO


class ServiceAlreadyRunning(RuntimeError):
    """Another service process holds the database file."""


def hold_database(db_path: Path) -> IO[str]:
    """Take the service lock of ``db_path``; keep the returned file open for as long as the service runs.

    Raises
    ------
    ServiceAlreadyRunning
        Another process holds it (its pid is in the message when it wrote one).
    """
    lock_path = Path(str(db_path) + ".service-lock")
    handle = open(lock_path, "a+")  # noqa: SIM115 (held open on purpose)
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.seek(0)
        holder = handle.read().strip() or "unknown"
        handle.close()
        raise ServiceAlreadyRunning(
            f"another backlash service (pid {holder}) serves {db_path}; stop it, or give this one another "
            "BACKLASH_DB_PATH (one service process per database file)"
        ) from None
    handle.seek(0)
    handle.truncate()
    handle.write(str(os.getpid()))
    handle.flush()
    return handle
