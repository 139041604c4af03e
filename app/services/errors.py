"""Errors raised by the service layer; :mod:`app.api.errors` maps each to an HTTP status in one place."""

from __future__ import annotations

from collections.abc import Iterable

#: How many names a message lists before "and N more".
NAMES_SHOWN = 5


class ServiceError(Exception):
    """Base class; the message says what happened and what to do.

    Parameters
    ----------
    message : str
        The message, naming HTTP routes where it says what to do (the API's answer).
    cli : str, optional
        The same message naming CLI commands instead, for the ``backlash`` command line.
    """

    def __init__(self, message: str, cli: str | None = None) -> None:
        super().__init__(message)
        self.cli_message = cli


class NotFoundError(ServiceError, LookupError):
    """Something the request names (pattern set, job) does not exist."""


class IncompatibleError(ServiceError, ValueError):
    """The request combines things that do not fit together (e.g. a record and a pattern set of another channel)."""


class QueueFullError(ServiceError):
    """Too many jobs are queued or running, or too many synchronous diagnoses run at once (429).

    Parameters
    ----------
    message : str
        What happened and what to do.
    retry_after : int
        Seconds after which a retry may succeed (the answer's ``Retry-After`` header).
    """

    def __init__(self, message: str, retry_after: int = 30) -> None:
        super().__init__(message)
        self.retry_after = int(retry_after)


class ConflictError(ServiceError):
    """The request does not fit the current state of what it names (e.g. cancelling a finished job): 409."""


class StorageFullError(ServiceError):
    """A configured bound on what the service stores is reached (e.g. ``BACKLASH_MAX_PATTERN_SETS``): 507; the
    message says what to delete or which setting to raise."""


class ForbiddenError(ServiceError):
    """The request asks for something this service is set up not to do (e.g. FMU plants while they are off): 403;
    the message names the setting an operator changes."""


class TooLargeError(ServiceError):
    """A sent file is larger than the service accepts (e.g. an FMU beyond ``BACKLASH_MAX_FMU_BYTES``): 413."""


class TimeLimitError(ServiceError):
    """A synchronous computation ran past its time limit and was stopped (504); the message says what to use."""


class InvalidInputError(ServiceError, ValueError):
    """A value in the request is not acceptable; the message says which and why."""


def some_names(names: Iterable[str], shown: int = NAMES_SHOWN) -> str:
    """The first ``shown`` of ``names`` (sorted, quoted) and how many more: a message stays short however many
    names a request sends."""
    ordered = sorted(set(names))
    listed = ", ".join(repr(n[:100]) for n in ordered[:shown])
    return listed if len(ordered) <= shown else f"{listed} and {len(ordered) - shown} more"
