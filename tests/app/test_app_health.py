"""GET /healthz, /docs and the OpenAPI document (app/api/routes/health.py, app/api/openapi.py)."""

from __future__ import annotations

import json
from pathlib import Path

import httpx

from app.core.config import Settings
from app.main import create_app
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
    schema = identify_body["application/json"]["schema"]
    refs = [s["$ref"] for s in schema.get("oneOf", [schema])]  # the drive's body, or another plant's
    schemas = doc["components"]["schemas"]
    assert {r.rsplit("/", 1)[-1] for r in refs} >= {"IdentifyCreate", "PlantIdentifyCreate"}
    assert all(r.rsplit("/", 1)[-1] in schemas for r in refs) and "RecordIn" in schemas  # resolvable


def test_openapi_documents_records_as_a_bench_gives_them(client: httpx.Client) -> None:
    import inspect

    from app.api.deps import CSV_QUERY, CSVRecordParams

    doc = client.get("/openapi.json").json()
    schemas = doc["components"]["schemas"]
    record_in = schemas["RecordIn"]["properties"]
    assert {"t", "units", "event_index", "sample_interval"} <= set(record_in)
    assert "accepted: a1: m/s^2, g;" in record_in["units"]["description"]
    assert "located from the data" in record_in["event_index"]["description"]
    assert "base_torque" in schemas["ConditionsIn"]["properties"]
    assert {"units", "event_location"} <= set(schemas["SimulationPublic"]["properties"])
    assert "exactly" not in json.dumps(schemas["SimulationPublic"])
    assert {"sample_interval", "before", "after", "units", "channels", "include_event_index"} <= set(
        schemas["SimulateCreate"]["properties"]
    )
    query = {p["name"]: p for p in doc["paths"]["/v1/identify"]["post"]["parameters"]}
    assert "CHANNEL:UNIT pairs separated by commas" in query["units"]["description"]
    assert "maximum" not in json.dumps(query["event_index"]["schema"])  # the engine checks the record's length
    # the names a JSON body must not come with are exactly the CSV form's query parameters
    assert set(CSV_QUERY) == set(inspect.signature(CSVRecordParams.__init__).parameters) - {"self"}


def test_openapi_documents_every_answer_with_its_model(tmp_path: Path) -> None:
    """Every success answer has a schema in each of its media types (a PNG's: a binary string); every error
    answer is ErrorPublic's (the shape the handlers send), FastAPI's own validation-error schema is gone, and
    with an API key every operation but /healthz documents 401."""
    for api_key in (None, "a-long-enough-key"):
        doc = create_app(Settings(db_path=tmp_path / "never-opened.sqlite3", api_key=api_key)).openapi()
        text = json.dumps(doc)
        assert "HTTPValidationError" not in text and "#/components/schemas/ValidationError" not in text
        error_ref = {"$ref": "#/components/schemas/ErrorPublic"}
        for path, item in doc["paths"].items():
            for method, op in item.items():
                where = f"{method.upper()} {path}"
                answers = op["responses"]
                assert "500" in answers, where
                if "requestBody" in op:
                    assert {"400", "413", "415", "422"} <= set(answers), where
                if op.get("parameters"):
                    assert "422" in answers, where
                assert ("401" in answers) == (api_key is not None and path != "/healthz"), where
                for status, answer in answers.items():
                    content = answer.get("content", {})
                    if status.startswith("2"):
                        for media, entry in content.items():
                            assert (entry or {}).get("schema"), f"{where} {status} {media}: no schema"
                    if status[0] in "45":
                        assert content["application/json"]["schema"] == error_ref, f"{where} {status}"
