"""GET /healthz, /docs and the OpenAPI document (app/api/routes/health.py, app/api/openapi.py)."""

from __future__ import annotations

import httpx

from engine.constants import MODEL_VERSION


def test_healthz_answers_ok(client: httpx.Client) -> None:
    r = client.get("/healthz")
    assert r.status_code == 200
    body = r.json()
    assert body["status"] == "ok"
    assert body["model_version"] == MODEL_VERSION
    assert isinstance(body["pattern_sets"], int)


def test_docs_page_is_served(client: httpx.Client) -> None:
    r = client.get("/docs")
    assert r.status_code == 200
    assert "swagger" in r.text.lower()


def test_openapi_documents_every_endpoint_and_both_body_forms(client: httpx.Client) -> None:
    doc = client.get("/openapi.json").json()
    paths = doc["paths"]
    expected = {
        "/healthz": {"get"},
        "/v1/simulate": {"post"},
        "/v1/simulate/batch": {"post"},
        "/v1/pattern-sets": {"get", "post"},
        "/v1/pattern-sets/{set_id}": {"get", "delete"},
        "/v1/jobs/{job_id}": {"get"},
        "/v1/identify": {"post"},
        "/v1/diagnose": {"post"},
    }
    for path, methods in expected.items():
        assert methods <= set(paths[path]), path
    identify_body = paths["/v1/identify"]["post"]["requestBody"]["content"]
    assert set(identify_body) == {"application/json", "text/csv"}
    ref = identify_body["application/json"]["schema"]["$ref"].rsplit("/", 1)[-1]
    schemas = doc["components"]["schemas"]
    assert ref in schemas and "RecordIn" in schemas  # referenced models are resolvable
