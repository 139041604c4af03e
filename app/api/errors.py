"""The one place where exceptions become HTTP answers.

User errors from the engine and the service layer get a 4xx whose ``detail`` is
the exception's message (which says what to fix); server-side problems get a 5xx
with a message that does not leak internals (the log has the details).
Every error answer has the shape of :class:`app.schemas.common.ErrorPublic`.
"""

from __future__ import annotations

import logging
from typing import Any

import fastapi.routing
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match

from app.records_io import RecordFormatError
from app.services.errors import (
    ConflictError,
    ForbiddenError,
    IncompatibleError,
    InvalidInputError,
    NotFoundError,
    QueueFullError,
    StorageFullError,
    TimeLimitError,
    TooLargeError,
)
from engine.diagnosis import CalibrationError
from engine.diagnosis.space import BoundsError
from engine.plants.fmu.archive import FmuArchiveError
from engine.plants.fmu.description import DescriptionError
from engine.plants.fmu.runner import FmuSimulationError
from engine.records import RecordError
from engine.simulation import ParameterError, SimulationError, UnknownEffectError
from engine.storage import (
    CorruptPatternSet,
    InvalidPatternSet,
    PatternSetExists,
    PatternSetNotFound,
    PatternStoreError,
)

logger = logging.getLogger(__name__)

#: User errors: exception type -> status; the answer's detail is the exception's message.
USER_ERRORS: dict[type[Exception], int] = {
    RecordFormatError: 400,
    RecordError: 422,
    UnknownEffectError: 422,
    ParameterError: 422,
    SimulationError: 422,
    CalibrationError: 422,
    BoundsError: 422,
    InvalidPatternSet: 422,
    InvalidInputError: 422,
    IncompatibleError: 422,
    DescriptionError: 422,
    FmuArchiveError: 422,
    FmuSimulationError: 422,
    NotFoundError: 404,
    ForbiddenError: 403,
    TooLargeError: 413,
    PatternSetExists: 409,
    QueueFullError: 429,
    ConflictError: 409,
    TimeLimitError: 504,
    StorageFullError: 507,
}

#: Server-side errors: exception type -> (status, public message); details go to the log.
SERVER_ERRORS: dict[type[Exception], tuple[int, str]] = {
    PatternSetNotFound: (404, "pattern set not found; GET /v1/pattern-sets lists the stored ones"),
    CorruptPatternSet: (500, "a stored pattern set is corrupt (it fails its checksum); delete it and train it again"),
    PatternStoreError: (503, "the pattern store is busy or unavailable; retry shortly"),
}

#: How many field errors a validation answer lists.
MAX_LISTED_ERRORS = 20
#: Longest ``detail`` of an error answer [characters]: a message that quotes what the request sent stays short.
MAX_DETAIL_CHARS = 2000
#: Longest name of a field in a validation answer [characters].
MAX_NAME_CHARS = 100


def shorten(text: str, limit: int = MAX_DETAIL_CHARS) -> str:
    """``text``, cut to ``limit`` characters with a note of how many were left out."""
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text) - limit} more characters)"


def error_body(detail: str, error: str, errors: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    body: dict[str, Any] = {"detail": shorten(detail), "error": error}
    if errors is not None:
        body["errors"] = errors
    return body


def _loc(loc: tuple[Any, ...] | list[Any]) -> str:
    parts = [str(p) for p in loc]
    if parts and parts[0] in ("body", "query", "path", "header"):
        where = parts[0]
        parts = parts[1:]
        return ".".join(parts) if where == "body" and parts else f"{where} {'.'.join(parts)}".strip()
    return ".".join(parts)


def validation_answer(errors: list[dict[str, Any]]) -> JSONResponse:
    """400 for malformed JSON, else 422, naming the first offending fields."""
    if any(e.get("type") == "json_invalid" for e in errors):
        e = next(e for e in errors if e.get("type") == "json_invalid")
        reason = str((e.get("ctx") or {}).get("error", e.get("msg", "")))
        if "recursion limit exceeded" in reason:  # pydantic's parser: arrays and objects nested too deeply
            reason = f"{reason} (arrays and objects nested too deeply; no request body nests that far)"
        return JSONResponse(
            error_body(f"malformed JSON: {reason}; send the request body as valid JSON", "RequestValidationError"),
            status_code=400,
        )
    if len(errors) == 1 and errors[0].get("type") == "missing" and tuple(errors[0].get("loc", ())) == ("body",):
        return JSONResponse(error_body("the request needs a JSON body", "RequestValidationError"), status_code=422)
    listed = [
        {
            "loc": [shorten(p, MAX_NAME_CHARS) if isinstance(p, str) else p for p in e.get("loc", ())],
            "msg": shorten(str(e.get("msg", "")), MAX_NAME_CHARS * 2),
            "type": e.get("type", ""),
        }
        for e in errors[:MAX_LISTED_ERRORS]
    ]
    parts = [f"{_loc(e['loc'])}: {e['msg']}" for e in listed[:3]]
    more = f" (and {len(errors) - 3} more)" if len(errors) > 3 else ""
    return JSONResponse(
        error_body("invalid request: " + "; ".join(parts) + more, "RequestValidationError", listed),
        status_code=422,
    )


async def _request_validation(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)  # registered for this class only
    errors = list(exc.errors())
    media = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if (
        media
        and media != "application/json"
        and not media.endswith("+json")
        and any(tuple(e.get("loc", ())) == ("body",) for e in errors)
    ):  # FastAPI reads a body of another media type as bytes, then fails to validate it
        return JSONResponse(
            error_body(
                f"unsupported Content-Type {media!r}: send the body as JSON with Content-Type: application/json",
                "UnsupportedMediaType",
            ),
            status_code=415,
        )
    return validation_answer(errors)


def allowed_methods(request: Request) -> list[str]:
    """Every method some route of the application answers at the request's path (HEAD wherever GET is).

    Starlette's 405 names the methods of the first route whose path matches; a path served by several routes
    (GET and DELETE of ``/v1/jobs/{id}``) would be said to allow only one of them.
    """
    scope = {**request.scope, "type": "http"}
    routes: list[Any] = list(request.app.router.routes)
    flatten = getattr(fastapi.routing, "iter_route_contexts", None)  # FastAPI >= 0.165 keeps included routers whole
    if flatten is not None:
        routes = list(flatten(routes))
    methods: set[str] = set()
    for route in routes:
        allowed = getattr(route, "methods", None)
        if allowed and route.matches(scope)[0] is not Match.NONE:
            methods |= set(allowed)
    if "GET" in methods:
        methods.add("HEAD")
    return sorted(methods)


async def _http_exception(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)  # registered for this class only
    if exc.status_code == 405:
        allowed = allowed_methods(request)
        method = "HEAD" if request.scope.get("head_request") else request.method
        detail = f"{method} is not allowed on {request.url.path}; allowed: {', '.join(allowed)}"
        return JSONResponse(
            error_body(detail, "MethodNotAllowed"), status_code=405, headers={"Allow": ", ".join(allowed)}
        )
    name = {
        401: "Unauthorized",
        404: "NotFound",
        405: "MethodNotAllowed",
        408: "RequestTimeout",
        413: "ContentTooLarge",
        415: "UnsupportedMediaType",
    }.get(exc.status_code, "HTTPException")
    return JSONResponse(error_body(str(exc.detail), name), status_code=exc.status_code, headers=exc.headers)


async def _user_error(request: Request, exc: Exception) -> JSONResponse:
    status = next(USER_ERRORS[cls] for cls in type(exc).__mro__ if cls in USER_ERRORS)
    message = shorten(str(exc))
    logger.info("%s %s -> %d %s: %s", request.method, request.url.path, status, type(exc).__name__, message)
    headers = {"Retry-After": str(exc.retry_after)} if isinstance(exc, QueueFullError) else None
    return JSONResponse(error_body(message, type(exc).__name__), status_code=status, headers=headers)


async def _server_error(request: Request, exc: Exception) -> JSONResponse:
    status, message = next(SERVER_ERRORS[cls] for cls in type(exc).__mro__ if cls in SERVER_ERRORS)
    logger.error("%s %s -> %d %s: %s", request.method, request.url.path, status, type(exc).__name__, exc)
    return JSONResponse(error_body(message, type(exc).__name__), status_code=status)


async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
    logger.exception("%s %s failed unexpectedly", request.method, request.url.path)
    return JSONResponse(
        error_body("internal server error; the server log has the details", "InternalServerError"), status_code=500
    )


def register_exception_handlers(app: FastAPI) -> None:
    """Install every handler on ``app`` (the most specific registered class wins)."""
    app.add_exception_handler(RequestValidationError, _request_validation)
    app.add_exception_handler(StarletteHTTPException, _http_exception)
    for cls in USER_ERRORS:
        app.add_exception_handler(cls, _user_error)
    for cls in SERVER_ERRORS:
        app.add_exception_handler(cls, _server_error)
    app.add_exception_handler(Exception, _unexpected)
