"""Bad input gets a 4xx whose message says what to fix; the server stays up; nothing stored changes.

One parametrised table over every endpoint (app/api/errors.py maps the exceptions).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import httpx
import pytest
from servicekit import SMALL_TRAINING

from engine.constants import CHANNELS, EVENT_INDEX, N_SAMPLES

JSON = {"Content-Type": "application/json"}
CSV = {"Content-Type": "text/csv"}

Rec = dict[str, Any]


def _v2(rec: Rec) -> list[float]:
    return rec["channels"]["v2"]


def _identify(record: Rec, **extra: Any) -> dict[str, Any]:
    return {"json": {"record": record, "channel": "v2", **extra}}


def _v2_only(rec: Rec, **extra: Any) -> Rec:
    """The v2 channel of ``rec`` at its event index (v2 alone cannot locate the event)."""
    return {"channels": {"v2": _v2(rec)}, "event_index": EVENT_INDEX, **extra}


def _raw_identify(rec: Rec, token: str) -> dict[str, Any]:
    """A JSON body whose v2 channel holds a bare token (NaN, Infinity) that Python's json accepts."""
    samples = ", ".join([token] + [repr(v) for v in _v2(rec)[1:]])
    return {"content": '{"channel": "v2", "record": {"channels": {"v2": [' + samples + "]}}}", "headers": JSON}


def _csv(rec: Rec, rows: list[str] | None = None, header: str = "v2") -> str:
    return "\n".join([header, *(rows if rows is not None else map(repr, _v2(rec)))]) + "\n"


def _csv_request(text: str | bytes, **params: Any) -> dict[str, Any]:
    return {"content": text, "headers": CSV, "params": {"channel": "v2", **params}}


# (id, method, path, request builder(record) -> httpx kwargs, status, substring of detail)
CASES: list[tuple[str, str, str, Callable[[Rec], dict[str, Any]], int, str]] = [
    # --- simulate ---
    (
        "K out of range",
        "POST",
        "/v1/simulate",
        lambda r: {"json": {"K": 0.5}},
        422,
        "K = 0.5 m is outside the accepted range",
    ),
    ("J1 out of range", "POST", "/v1/simulate", lambda r: {"json": {"K": 0.005, "J1": -1}}, 422, "J1 = -1.0"),
    (
        "unknown effect",
        "POST",
        "/v1/simulate",
        lambda r: {"json": {"K": 0.005, "effects": {"frobnicate": 1}}},
        422,
        "unknown effect 'frobnicate'; known effects: motor_coulomb_friction",
    ),
    (
        "effect out of range",
        "POST",
        "/v1/simulate",
        lambda r: {"json": {"K": 0.005, "effects": {"supply_voltage": 3.0}}},
        422,
        "outside its range [0.8, 1.1]",
    ),
    (
        "NaN parameter",
        "POST",
        "/v1/simulate",
        lambda r: {"content": '{"K": NaN}', "headers": JSON},
        422,
        "K: Input should be a finite number",
    ),
    (
        "Infinity parameter",
        "POST",
        "/v1/simulate",
        lambda r: {"content": '{"K": 0.005, "c": -Infinity}', "headers": JSON},
        422,
        "c: Input should be a finite number",
    ),
    ("missing K", "POST", "/v1/simulate", lambda r: {"json": {"J1": 0.87}}, 422, "K: Field required"),
    (
        "unknown field",
        "POST",
        "/v1/simulate",
        lambda r: {"json": {"K": 0.005, "k12": 1}},
        422,
        "k12: Extra inputs are not permitted",
    ),
    (
        "malformed JSON",
        "POST",
        "/v1/simulate",
        lambda r: {"content": '{"K": 0.005,', "headers": JSON},
        400,
        "malformed JSON",
    ),
    ("no body", "POST", "/v1/simulate", lambda r: {"headers": JSON}, 422, "needs a JSON body"),
    ("form body", "POST", "/v1/simulate", lambda r: {"data": {"K": "0.005"}}, 415, "Content-Type: application/json"),
    (
        "no backlash event",
        "POST",
        "/v1/simulate",
        lambda r: {"json": {"K": 0.0025, "effects": {"contact_stiffness": 0.1, "contact_damping": 20.0}}},
        422,
        "no backlash event",
    ),
    (
        "too many batch cases",
        "POST",
        "/v1/simulate/batch",
        lambda r: {"json": {"cases": [{"K": 0.005}] * 65}},
        422,
        "at most 64 are allowed",
    ),
    ("empty batch", "POST", "/v1/simulate/batch", lambda r: {"json": {"cases": []}}, 422, "at least 1 item"),
    # --- identify, JSON ---
    (
        "wrong length",
        "POST",
        "/v1/identify",
        lambda r: _identify({"channels": {"v2": _v2(r)[:-1]}, "event_index": EVENT_INDEX}),
        422,
        "the record covers 4.8 ms before the event and 199.9 ms from it on (2047 samples of 0.0001 s, event at "
        "sample 48); the backlash test needs at least 4.8 ms before and 200 ms after: 0.1 ms after it missing",
    ),
    (
        "NaN sample",
        "POST",
        "/v1/identify",
        lambda r: _raw_identify(r, "NaN"),
        422,
        "channel 'v2' holds a non-finite value (NaN or inf) at sample 0",
    ),
    (
        "Infinity sample",
        "POST",
        "/v1/identify",
        lambda r: _raw_identify(r, "Infinity"),
        422,
        "non-finite value (NaN or inf)",
    ),
    (
        "non-number sample",
        "POST",
        "/v1/identify",
        lambda r: _identify({"channels": {"v2": ["x"] * N_SAMPLES}}),
        422,
        "record.channels.v2.0: Input should be a valid number",
    ),
    (
        "unknown record channel",
        "POST",
        "/v1/identify",
        lambda r: _identify({"channels": {"v2": _v2(r), "v3": _v2(r)}}),
        422,
        "unknown channel 'v3'; known channels: " + ", ".join(CHANNELS),
    ),
    (
        "empty record",
        "POST",
        "/v1/identify",
        lambda r: _identify({"channels": {}}),
        422,
        "a record needs at least one channel",
    ),
    (
        "channel not in record",
        "POST",
        "/v1/identify",
        lambda r: {"json": {"record": _v2_only(r), "channel": "a2"}},
        422,
        "channel 'a2' is not in this record",
    ),
    (
        "unknown channel to identify",
        "POST",
        "/v1/identify",
        lambda r: {"json": {"record": r, "channel": "speed"}},
        422,
        "channel: Input should be 'a1', 'm_el'",
    ),
    (
        "unknown condition",
        "POST",
        "/v1/identify",
        lambda r: _identify({"channels": {"v2": _v2(r)}, "conditions": {"C": 1.0}}),
        422,
        "record.conditions.C: Extra inputs are not permitted",
    ),
    (
        "bad event_index",
        "POST",
        "/v1/identify",
        lambda r: _identify(_v2_only(r, event_index=5000)),
        422,
        "event_index must lie in [0, 2047]",
    ),
    (
        "sample interval out of range",
        "POST",
        "/v1/identify",
        lambda r: _identify(_v2_only(r, sample_interval=2e-3)),
        422,
        "sample_interval 0.002 s is outside the accepted range 1e-05 to 0.001 s",
    ),
    (
        "event not locatable",
        "POST",
        "/v1/identify",
        lambda r: _identify({"channels": {"v2": _v2(r)}}),
        422,
        "holds neither m_el nor a1, from which the event could be located (it holds v2); give event_index",
    ),
    (
        "unknown unit",
        "POST",
        "/v1/identify",
        lambda r: _identify({**r, "units": {"omega1": "rpmm"}}),
        422,
        "unknown unit 'rpmm' for channel 'omega1'; accepted units: rad/s, rpm, pu",
    ),
    (
        "unit of a channel not in the record",
        "POST",
        "/v1/identify",
        lambda r: _identify(_v2_only(r, units={"a1": "g"})),
        422,
        "units are given for channel 'a1', which the record does not hold",
    ),
    (
        "m_el in N*m without base torque",
        "POST",
        "/v1/identify",
        lambda r: _identify({**r, "units": {"m_el": "N*m"}}),
        422,
        "needs conditions.base_torque",
    ),
    (
        "record too short",
        "POST",
        "/v1/identify",
        lambda r: _identify({**r, "channels": {k: v[:1200] for k, v in r["channels"].items()}}),
        422,
        "the record covers 4.8 ms before the event and 115.2 ms from it on (1200 samples of 0.0001 s, event at "
        "sample 48); the backlash test needs at least 4.8 ms before and 200 ms after: 84.8 ms after it missing",
    ),
    (
        "time contradicting the sample interval",
        "POST",
        "/v1/identify",
        lambda r: _identify({**r, "t": [k * 2e-4 for k in range(N_SAMPLES)]}),
        422,
        "sample_interval 0.0001 s contradicts the time column 't' (step 0.0002 s); give one of them",
    ),
    (
        "time not uniform",
        "POST",
        "/v1/identify",
        lambda r: _identify({**_v2_only(r), "t": [k * 1e-4 + (5e-5 if k == 7 else 0.0) for k in range(N_SAMPLES)]}),
        422,
        "the time column 't' is not uniform: the step to sample",
    ),
    (
        "time of another length",
        "POST",
        "/v1/identify",
        lambda r: _identify({**_v2_only(r), "t": [k * 1e-4 for k in range(10)]}),
        422,
        "the time column 't' has 10 values and the channels 2048 samples",
    ),
    (
        "unknown pattern set",
        "POST",
        "/v1/identify",
        lambda r: _identify(r, pattern_set="nosuchset"),
        404,
        "no pattern set with id 'nosuchset'",
    ),
    (
        "pattern set of another channel",
        "POST",
        "/v1/identify",
        lambda r: {"json": {"record": r, "channel": "a1", "pattern_set": "<v2 set>"}},
        422,
        "was trained on channel 'v2', not 'a1'",
    ),
    (
        "no pattern set for the channel",
        "POST",
        "/v1/identify",
        lambda r: {"json": {"record": r, "channel": "omega1"}},
        404,
        "no pattern set for channel 'omega1'",
    ),
    (
        "CSV query with JSON body",
        "POST",
        "/v1/identify",
        lambda r: {**_identify(r), "params": {"sample_interval": 1e-4}},
        422,
        "apply only to a record sent as CSV",
    ),
    (
        "unsupported content type",
        "POST",
        "/v1/identify",
        lambda r: {"content": b"\x00\x01", "headers": {"Content-Type": "application/octet-stream"}},
        415,
        "send the JSON body as application/json, or the record's CSV form as text/csv",
    ),
    # --- identify, CSV ---
    (
        "CSV ragged row",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r, ["1.0,2.0"] + ["1.0"] * (N_SAMPLES - 1))),
        400,
        "malformed CSV: line 2 has 2 fields, the header has 1",
    ),
    (
        "CSV non-number",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r, ["1.0"] * 9 + ["abc"] + ["1.0"] * (N_SAMPLES - 10))),
        400,
        "line 11, column 'v2': 'abc' is not a number",
    ),
    (
        "CSV NaN",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r, ["1.0"] * 9 + ["nan"] + ["1.0"] * (N_SAMPLES - 10))),
        422,
        "non-finite value (NaN or inf) at sample 9",
    ),
    (
        "CSV too few rows",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r, ["1.0"] * 100), event_index=EVENT_INDEX),
        422,
        "the record covers 4.8 ms before the event and 5.2 ms from it on (100 samples of 0.0001 s, event at "
        "sample 48); the backlash test needs at least 4.8 ms before and 200 ms after: 194.8 ms after it missing",
    ),
    (
        "CSV unknown channel",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r, header="speed")),
        422,
        "unknown channel 'speed' in the CSV header",
    ),
    (
        "CSV duplicate column",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r, [f"{v!r},{v!r}" for v in _v2(r)], header="v2,v2")),
        400,
        "channel 'v2' appears twice",
    ),
    (
        "CSV without header",
        "POST",
        "/v1/identify",
        lambda r: _csv_request("\n".join(map(repr, _v2(r)))),
        400,
        "is not a header",
    ),
    ("CSV empty", "POST", "/v1/identify", lambda r: _csv_request(""), 400, "the CSV is empty"),
    ("CSV not UTF-8", "POST", "/v1/identify", lambda r: _csv_request(b"v2\n\xff\xfe\n"), 400, "not UTF-8"),
    (
        "CSV without channel",
        "POST",
        "/v1/identify",
        lambda r: {"content": _csv(r), "headers": CSV},
        422,
        "query parameter ?channel=",
    ),
    (
        "CSV event not locatable",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r)),
        422,
        "holds neither m_el nor a1",
    ),
    (
        "CSV unknown unit",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r), event_index=EVENT_INDEX, units="v2:furlong/s"),
        422,
        "unknown unit 'furlong/s' for channel 'v2'; accepted units: m/s, mm/s",
    ),
    (
        "CSV malformed units",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r), event_index=EVENT_INDEX, units="v2=mm/s"),
        422,
        "query parameter units: 'v2=mm/s' is not CHANNEL:UNIT; write CHANNEL:UNIT pairs separated by commas, "
        "e.g. omega1:rpm,a1:g",
    ),
    (
        "CSV unit given twice",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r), event_index=EVENT_INDEX, units="v2:mm/s,v2:m/s"),
        422,
        "channel 'v2' is given twice",
    ),
    (
        "CSV time contradicting sample_interval",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(
            _csv(r, [f"{k * 1e-4!r},{v!r}" for k, v in enumerate(_v2(r))], header="t,v2"),
            event_index=EVENT_INDEX,
            sample_interval=5e-5,
        ),
        422,
        "sample_interval 5e-05 s contradicts the time column 't'",
    ),
    (
        "CSV negative event_index",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r), event_index=-1),
        422,
        "query event_index: Input should be greater than or equal to 0",
    ),
    (
        "CSV event_index beyond the record",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r), event_index=N_SAMPLES),
        422,
        "event_index must lie in [0, 2047], got 2048",
    ),
    (
        "units query with JSON body",
        "POST",
        "/v1/identify",
        lambda r: {**_identify(r), "params": {"units": "omega1:rpm"}},
        422,
        "query parameter(s) units apply only to a record sent as CSV",
    ),
    (
        "CSV bad sample_interval",
        "POST",
        "/v1/identify",
        lambda r: _csv_request(_csv(r), sample_interval=-1),
        422,
        "query sample_interval: Input should be greater than 0",
    ),
    # --- pattern sets ---
    (
        "train unknown channel",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {"channel": "v9", "c": 1.0}},
        422,
        "channel: Input should be 'a1'",
    ),
    (
        "train c out of range",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {"channel": "v2", "c": 500}},
        422,
        "c = 500.0 pu is outside the accepted range",
    ),
    (
        "train unknown effect",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {**SMALL_TRAINING, "effects": {"magic": 1}}},
        422,
        "unknown effect 'magic'",
    ),
    (
        "train J1 out of range",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {**SMALL_TRAINING, "J1_values": [0.87, 100.0]}},
        422,
        "J1 = 100.0 kg m^2 is outside",
    ),
    (
        "train repeated J1",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {**SMALL_TRAINING, "J1_values": [0.87, 0.87]}},
        422,
        "repeat a value",
    ),
    (
        "train empty J1",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {**SMALL_TRAINING, "J1_values": []}},
        422,
        "J1_values: List should have at least 1 item",
    ),
    (
        "train unknown kind",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {**SMALL_TRAINING, "kind": "magic"}},
        422,
        "kind: Input should be",
    ),
    (
        "train parameter of another kind",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {"channel": "v2", "c": 1.0, "kind": "template", "l": 0.5}},
        422,
        "has no parameter(s) 'learning_rate'",
    ),
    (
        "train parameter given twice",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {**SMALL_TRAINING, "params": {"max_epochs": 5}}},
        422,
        "either as fields or in params",
    ),
    (
        "train zero epochs",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {**SMALL_TRAINING, "max_epochs": 0}},
        422,
        "max_epochs: Input should be greater than or equal to 1",
    ),
    (
        "train negative delta1",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"json": {**SMALL_TRAINING, "delta1": -0.1}},
        422,
        "delta1: Input should be greater than 0",
    ),
    (
        "train NaN l",
        "POST",
        "/v1/pattern-sets",
        lambda r: {"content": json.dumps({**SMALL_TRAINING, "l": float("nan")}), "headers": JSON},
        422,
        "l: Input should be a finite number",
    ),
    ("read unknown set", "GET", "/v1/pattern-sets/nosuchset", lambda r: {}, 404, "no pattern set with id 'nosuchset'"),
    ("delete unknown set", "DELETE", "/v1/pattern-sets/nosuchset", lambda r: {}, 404, "no pattern set with id"),
    (
        "list unknown channel",
        "GET",
        "/v1/pattern-sets",
        lambda r: {"params": {"channel": "x"}},
        422,
        "query channel: Input should be 'a1'",
    ),
    # --- jobs, diagnose, routing ---
    ("unknown job", "GET", "/v1/jobs/nosuchjob", lambda r: {}, 404, "no job with id 'nosuchjob'"),
    (
        "diagnose unknown effect",
        "POST",
        "/v1/diagnose",
        lambda r: {"json": {"record": _v2_only(r), "effects": ["magic"]}},
        422,
        "unknown effect 'magic'",
    ),
    (
        "diagnose too short",
        "POST",
        "/v1/diagnose",
        lambda r: {"json": {"record": {"channels": {"v2": [1.0] * 10}, "event_index": 5}}},
        422,
        "4.3 ms before the event and 199.5 ms after it missing",
    ),
    (
        "diagnose event too early",
        "POST",
        "/v1/diagnose",
        lambda r: {"json": {"record": _v2_only(r, event_index=20)}},
        422,
        "2.8 ms before the event missing",
    ),
    (
        "diagnose event not locatable",
        "POST",
        "/v1/diagnose",
        lambda r: {"json": {"record": {"channels": {"v2": _v2(r)}}}},
        422,
        "give event_index",
    ),
    (
        "diagnose CSV unknown unit",
        "POST",
        "/v1/diagnose",
        lambda r: {"content": _csv(r), "headers": CSV, "params": {"event_index": EVENT_INDEX, "units": "v2:knots"}},
        422,
        "unknown unit 'knots' for channel 'v2'",
    ),
    ("unknown path", "GET", "/v1/nothing", lambda r: {}, 404, "Not Found"),
    (
        "wrong method",
        "PUT",
        "/v1/simulate",
        lambda r: {"json": {"K": 0.005}},
        405,
        "PUT is not allowed on /v1/simulate; allowed: POST",
    ),
]


def _snapshot(client: httpx.Client) -> list[dict[str, Any]]:
    return client.get("/v1/pattern-sets").json()["data"]


@pytest.mark.parametrize(
    ("method", "path", "build", "status", "message"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_bad_input(
    client: httpx.Client,
    trained_set: dict[str, Any],
    sim_record: Rec,
    method: str,
    path: str,
    build: Callable[[Rec], dict[str, Any]],
    status: int,
    message: str,
) -> None:
    kwargs = build(sim_record)
    if "json" in kwargs and kwargs["json"].get("pattern_set") == "<v2 set>":
        kwargs["json"]["pattern_set"] = trained_set["pattern_set_id"]
    before = _snapshot(client)
    r = client.request(method, path, **kwargs)
    assert r.status_code == status, r.text
    body = r.json()
    assert message in body["detail"], body
    assert body["error"]
    assert client.get("/healthz").status_code == 200  # the server stays up
    assert _snapshot(client) == before  # nothing stored changed
