"""Errors raised by the service layer; :mod:`app.api.errors` maps each to an HTTP status in one place."""

from __future__ import annotations


class ServiceError(Exception):
    """Base class; the message says what happened and what to do."""


class NotFoundError(ServiceError, LookupError):
    """Something the request names (pattern set, job) does not exist."""


class IncompatibleError(ServiceError, ValueError):
    """The request combines things that do not fit together (e.g. a record and a pattern set of another channel)."""


class QueueFullError(ServiceError):
    """Too many training jobs are queued or running."""


class InvalidInputError(ServiceError, ValueError):
    """A value in the request is not acceptable; the message says which and why."""
