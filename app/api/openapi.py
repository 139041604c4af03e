"""OpenAPI documentation of the routes that read their body themselves (JSON or a record's CSV form)."""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from pydantic import BaseModel

from app.api.middleware import API_KEY_HEADER
from app.schemas.common import ErrorPublic
from engine.constants import CHANNELS

#: Body models documented by :func:`body_schema`; added to the components by :func:`install_openapi`.
_BODY_MODELS: dict[str, type[BaseModel]] = {}

_ZEROS = ",".join("0.0" for _ in CHANNELS)
_CSV_EXAMPLE = "\n".join(
    [
        "t," + ",".join(CHANNELS),
        "0.0," + _ZEROS,
        "5e-05," + _ZEROS,
        "...(one row per sample, at least 4.8 ms before the event and 200 ms from it on)",
        "",
    ]
)


def body_schema(
    model: type[BaseModel], csv: bool = False, alternatives: tuple[type[BaseModel], ...] = ()
) -> dict[str, Any]:
    """``openapi_extra`` for a route whose body is ``model`` as JSON (or one of ``alternatives``; or, with
    ``csv``, a record's CSV form)."""
    refs = []
    for m in (model, *alternatives):
        _BODY_MODELS[m.__name__] = m
        refs.append({"$ref": f"#/components/schemas/{m.__name__}"})
    schema: dict[str, Any] = refs[0] if len(refs) == 1 else {"oneOf": refs}
    content: dict[str, Any] = {"application/json": {"schema": schema}}
    if csv:
        content["text/csv"] = {
            "schema": {
                "type": "string",
                "description": "Header row of channel names (optionally t, the time of each sample [s], which "
                "then defines the sample interval), then one row per sample, as many as recorded; the sample "
                "interval (without t), the event index (omitted: located), the units and the known conditions "
                "as query parameters.",
            },
            "example": _CSV_EXAMPLE,
        }
    return {"requestBody": {"required": True, "content": content}}


_ERROR_REF = {"$ref": f"#/components/schemas/{ErrorPublic.__name__}"}
#: FastAPI's own schema of a validation error; the service answers :class:`ErrorPublic` instead.
_FASTAPI_VALIDATION_SCHEMAS = ("HTTPValidationError", "ValidationError")

#: Error answers (status -> description) of every operation with a request body (app/api/errors.py,
#: app/api/middleware.py), documented where the route does not document them itself.
BODY_ERRORS: dict[str, str] = {
    "400": "Malformed body (JSON or CSV), or an invalid Content-Length header",
    "408": "The body stalled: nothing arrived for BACKLASH_READ_TIMEOUT seconds",
    "413": "Request body larger than BACKLASH_MAX_BODY_BYTES (bodies of parameters, not records: 4 MiB)",
    "415": "Content-Type not accepted by this operation",
    "422": "Invalid request: the first offending fields, or what the engine refused and why",
}
#: Error answers of every operation with parameters.
PARAMETER_ERRORS: dict[str, str] = {"422": BODY_ERRORS["422"]}
#: Error answers of every operation.
COMMON_ERRORS: dict[str, str] = {"500": "Unexpected failure (the answer does not leak internals; see the server log)"}
#: Error answer of every operation that needs the API key, when the service has one.
API_KEY_ERRORS: dict[str, str] = {"401": f"Missing or wrong API key (header {API_KEY_HEADER})"}


def _error_response(description: str) -> dict[str, Any]:
    return {"description": description, "content": {"application/json": {"schema": dict(_ERROR_REF)}}}


def _replace_validation_refs(node: Any) -> None:
    """Point every reference to FastAPI's validation-error schema at :class:`ErrorPublic` (in place)."""
    if isinstance(node, dict):
        ref = node.get("$ref")
        if isinstance(ref, str) and ref.rsplit("/", 1)[-1] in _FASTAPI_VALIDATION_SCHEMAS:
            node["$ref"] = _ERROR_REF["$ref"]
        for value in node.values():
            _replace_validation_refs(value)
    elif isinstance(node, list):
        for value in node:
            _replace_validation_refs(value)


def document_errors(schema: dict[str, Any], api_key: bool) -> None:
    """Document the error answers of every operation in ``schema`` (in place), all of :class:`ErrorPublic`'s shape.

    The exception handlers (app/api/errors.py) and the middleware answer every error, validation errors
    included, as :class:`ErrorPublic`; FastAPI's generated 422 (``HTTPValidationError``) is replaced by it, and
    the statuses an operation can answer but its route does not list (:data:`BODY_ERRORS`,
    :data:`PARAMETER_ERRORS`, :data:`COMMON_ERRORS`; :data:`API_KEY_ERRORS` with ``api_key``) are added.
    A route's own description of a status is kept.

    Parameters
    ----------
    schema : dict
        The OpenAPI document (``get_openapi``'s), changed in place.
    api_key : bool
        Whether the service requires an API key (every path but ``/healthz`` may then answer 401).
    """
    _replace_validation_refs(schema.get("paths", {}))
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    for name in _FASTAPI_VALIDATION_SCHEMAS:
        components.pop(name, None)
    components.setdefault(
        ErrorPublic.__name__, ErrorPublic.model_json_schema(ref_template="#/components/schemas/{model}")
    )
    for path, item in schema.get("paths", {}).items():
        for method, operation in item.items():
            if method not in ("get", "put", "post", "delete", "options", "head", "patch", "trace"):
                continue
            errors = dict(COMMON_ERRORS)
            if operation.get("parameters"):
                errors.update(PARAMETER_ERRORS)
            if "requestBody" in operation:
                errors.update(BODY_ERRORS)
            if api_key and path != "/healthz":
                errors.update(API_KEY_ERRORS)
            responses = operation.setdefault("responses", {})
            for status, description in errors.items():
                answer = responses.setdefault(status, _error_response(description))
                answer.setdefault("content", {"application/json": {"schema": dict(_ERROR_REF)}})
        # statuses in the order a reader looks for them
        for operation in item.values():
            if isinstance(operation, dict) and "responses" in operation:
                operation["responses"] = dict(sorted(operation["responses"].items()))


def install_openapi(app: FastAPI) -> None:
    """Make ``app.openapi()`` include the body models of :func:`body_schema` and every error answer
    (:func:`document_errors`)."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema:
            return app.openapi_schema
        schema = get_openapi(title=app.title, version=app.version, description=app.description, routes=app.routes)
        components = schema.setdefault("components", {}).setdefault("schemas", {})
        for name, model in _BODY_MODELS.items():
            js = model.model_json_schema(ref_template="#/components/schemas/{model}")
            for sub, sub_schema in js.pop("$defs", {}).items():
                components.setdefault(sub, sub_schema)
            components.setdefault(name, js)
        api_key = getattr(app.state, "settings", None) is not None and app.state.settings.api_key is not None
        document_errors(schema, api_key)
        if api_key:
            schema["components"]["securitySchemes"] = {
                "APIKeyHeader": {"type": "apiKey", "in": "header", "name": API_KEY_HEADER}
            }
            schema["security"] = [{"APIKeyHeader": []}]
        app.openapi_schema = schema
        return schema

    app.openapi = openapi  # type: ignore[method-assign]


__all__ = ["body_schema", "document_errors", "install_openapi"]
