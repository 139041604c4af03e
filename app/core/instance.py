"""One service process per database file: its jobs are its own.

At start a service marks the jobs a previous process left queued or running as interrupted
(:meth:`app.jobs.JobManager.recover`), and at shutdown the ones it leaves; a second service on the
same file would interrupt the first one's live jobs. An exclusive advisory lock (``flock``) on the
database file itself, held for the process's life and released by the kernel when it dies, however
it dies, refuses that start with a message instead.

The lock belongs to the file, not to a name of it: every path that leads to the file (a hard link,
a symbolic link, another spelling, a bind mount of its folder) meets the same lock. It is taken
before the store is opened, so a refused start never opens, let alone migrates, the file.

``flock`` and SQLite's own (POSIX, ``fcntl``) locks do not interact on a local file system, which
the database must be on (``BACKLASH_DB_PATH``). Closing the lock's descriptor drops the POSIX locks
this process holds on the file, so it is closed only when no connection of the process is in use:
at the very end of a shutdown, or after a start that failed.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
from typing import IO

__all__ = ["ServiceAlreadyRunning", "ServiceLockError", "hold_database"]

#: The kernel's table of file locks (Linux): the holder of a lock by device and inode.
PROC_LOCKS = Path("/proc/locks")


class ServiceLockError(RuntimeError):
    """The service cannot take its database file's lock; the message says why and what to do."""


class ServiceAlreadyRunning(ServiceLockError):
    """Another service process holds the database file."""


def hold_database(db_path: Path) -> IO[bytes]:
    """Take the service lock of the database file ``db_path`` (created, empty, if missing); keep the returned file
    open for as long as the service runs, and close it to give the lock back.

    Raises
    ------
    ServiceAlreadyRunning
        Another process holds the file, under this name or another (its pid is in the message when the kernel
        tells it).
    ServiceLockError
        The file cannot be opened for writing (the message has the reason).
    """
    path = Path(db_path).expanduser()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        raise ServiceLockError(f"cannot open the database file {path} to lock it: {exc.strerror or exc}") from None
    handle = os.fdopen(fd, "rb+", buffering=0)
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = _holder(os.fstat(handle.fileno()))
        handle.close()
        raise ServiceAlreadyRunning(
            f"another backlash service ({holder}) serves the database file {path} (under this name or another: "
            "a hard or symbolic link leads to the same file); stop it, or give this one another BACKLASH_DB_PATH "
            "(one service process per database file)"
        ) from None
    except BaseException:
        handle.close()
        raise
    return handle


def _holder(st: os.stat_result) -> str:
    """``pid N`` of the process holding an ``flock`` on the file of ``st`` (from :data:`PROC_LOCKS`), or
    ``pid unknown``."""
    device = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    try:
        lines = PROC_LOCKS.read_text().splitlines()
    except OSError:
        return "pid unknown"
    for line in lines:
        fields = line.split()
        # "1: FLOCK  ADVISORY  WRITE 1234 08:01:5678 0 EOF" (a blocked waiter's line has "->" after the number)
        if "->" in fields or len(fields) < 6 or fields[1] != "FLOCK":
            continue
        if fields[5] == device and fields[4].isdigit():
            return f"pid {fields[4]}"
    return "pid unknown"
