"""OpenAPI documentation of the routes that read their body themselves (JSON or a record's CSV form)."""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from pydantic import BaseModel

from app.api.middleware import API_KEY_HEADER
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


def install_openapi(app: FastAPI) -> None:
    """Make ``app.openapi()`` include the body models of :func:`body_schema`."""

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
        if getattr(app.state, "settings", None) is not None and app.state.settings.api_key is not None:
            schema["components"]["securitySchemes"] = {
                "APIKeyHeader": {"type": "apiKey", "in": "header", "name": API_KEY_HEADER}
            }
            schema["security"] = [{"APIKeyHeader": []}]
        app.openapi_schema = schema
        return schema

    app.openapi = openapi  # type: ignore[method-assign]


__all__ = ["body_schema", "install_openapi"]
