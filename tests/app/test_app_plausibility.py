"""The plausibility gate at the service's edge (issue 50, item 3): POST /v1/identify refuses values no
computation survives (422 naming channel and sample) and says in ``warnings`` when a record is not what the
plant can produce; ``backlash identify`` logs each warning."""

from __future__ import annotations

import json
import logging
import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from servicekit import SMALL_TRAINING, train

from app import cli
from app.services import identification
from engine.simulation import PlantParameters, simulate

RPM = 60.0 / (2.0 * math.pi)


@pytest.fixture(scope="module")
def omega1_set(client: httpx.Client) -> Iterator[dict[str, Any]]:
    """A small pattern set of channel omega1 at c = 1.0 (as the shared v2 set)."""
    out = train(client, {**SMALL_TRAINING, "channel": "omega1"})
    assert out["job"]["state"] == "done", out["job"]
    yield out
    client.delete(out["pattern_set_url"])


def test_a_record_x_1e200_is_refused_naming_channel_and_sample(
    client: httpx.Client, sim_record: dict[str, Any]
) -> None:
    big = {**sim_record, "channels": {c: [v * 1e200 for v in x] for c, x in sim_record["channels"].items()}}
    r = client.post("/v1/identify", json={"record": big, "channel": "v2", "any_set": True})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert re.search(r"channel '(a1|m_el|omega1|a2|v2)' holds \S+ \S+ at sample \d+", detail), detail
    assert "check the record's units" in detail
    # one sample is enough, and it is the one named
    one = {**sim_record, "channels": {**sim_record["channels"], "v2": list(sim_record["channels"]["v2"])}}
    one["channels"]["v2"][1500] = -2e13
    r = client.post("/v1/identify", json={"record": one, "channel": "v2", "any_set": True})
    assert r.status_code == 422 and "channel 'v2' holds -2e+13 m/s at sample 1500" in r.json()["detail"]


def test_a_clean_identify_answer_has_no_warnings(
    client: httpx.Client, trained_set: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    body = {"record": sim_record, "channel": "v2", "any_set": True}
    assert client.post("/v1/identify", json=body).json()["warnings"] == []
    res = client.post("/v1/identify", json={**body, "continuous": True}).json()
    assert res["warnings"] == [] and res["continuous"]["K"] == pytest.approx(0.005, rel=1e-3)
    interval = res["continuous"].get("interval_95")  # when the width estimate gives one (issue 50, item 2)
    assert interval is None or interval[0] <= res["continuous"]["K"] <= interval[1]


def test_omega1_in_rpm_gets_a_channel_scale_warning(
    client: httpx.Client, omega1_set: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    rpm_values = [v * RPM for v in sim_record["channels"]["omega1"]]
    rpm = {**sim_record, "channels": {**sim_record["channels"], "omega1": rpm_values}}
    r = client.post("/v1/identify", json={"record": rpm, "channel": "omega1", "any_set": True, "continuous": True})
    assert r.status_code == 200, r.text
    res = r.json()
    scale = [w for w in res["warnings"] if w["code"] == "channel_scale"]
    assert [w["channel"] for w in scale] == ["omega1"] and "is it in rpm?" in scale[0]["message"]
    assert ("misfit", "omega1") in {(w["code"], w["channel"]) for w in res["warnings"]}
    # without the continuous width (no fit) the range of the plant already gives it away
    plain = client.post("/v1/identify", json={"record": rpm, "channel": "omega1", "any_set": True}).json()
    assert [(w["code"], w["channel"]) for w in plain["warnings"]] == [("channel_scale", "omega1")]
    # declared as rpm, it is what the plant produces: no warning
    declared = {**rpm, "units": {"omega1": "rpm"}}
    res = client.post("/v1/identify", json={"record": declared, "channel": "omega1", "any_set": True}).json()
    assert res["warnings"] == []


def test_a_sample_interval_10x_too_long_is_suspected_without_the_continuous_width(
    client: httpx.Client, trained_set: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    """The issue's CSV: 0.1 ms samples declared at 1 ms. Without a fit, the load's rise time gives it away."""
    slow = {**sim_record, "sample_interval": 10 * sim_record["sample_interval"]}
    r = client.post("/v1/identify", json={"record": slow, "channel": "v2", "any_set": True})
    assert r.status_code == 200, r.text
    warnings = r.json()["warnings"]
    assert [(w["code"], w["channel"]) for w in warnings] == [("sample_interval", None)]
    assert "10x slower" in warnings[0]["message"] and "is the sample interval" in warnings[0]["message"]


def test_the_cli_logs_each_warning(
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    caplog: pytest.LogCaptureFixture,
) -> None:
    """``backlash identify`` writes the answer's warnings to the log at WARNING level, where a person sees them."""
    from engine.storage import PatternStore

    monkeypatch.setenv("BACKLASH_DB_PATH", str(tmp_path / "patterns.sqlite3"))
    PatternStore(tmp_path / "patterns.sqlite3")  # a store (empty: identify refuses to run without one)
    record = simulate(PlantParameters())
    data = record.to_dict()
    data["channels"]["v2"] = [v * 1000.0 for v in data["channels"]["v2"]]  # mm/s, read as m/s
    path = tmp_path / "mm.json"
    path.write_text(json.dumps(data))
    seen: dict[str, Any] = {}

    def answer(store: Any, rec: Any, channel: str, *args: Any, **kwargs: Any) -> dict[str, Any]:
        """The service's answer, its pattern-set part left out (no set stored here): only its warnings."""
        from engine.diagnosis import plausibility

        seen["record"] = rec
        return {"channel": channel, "warnings": [w.to_dict() for w in plausibility.check_record(rec)]}

    monkeypatch.setattr(identification, "identify_from_store", answer)
    with caplog.at_level(logging.WARNING):
        code = cli.main(["identify", str(path), "--channel", "v2"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert json.loads(out)["warnings"][0]["code"] == "channel_scale"
    logged = [r for r in caplog.records if r.levelno == logging.WARNING and r.name == "app.cli.identify"]
    assert len(logged) == 1 and logged[0].getMessage().startswith("v2: v2 peaks at ")
    assert "is it in mm/s?" in logged[0].getMessage()


def test_a_plant_width_that_is_not_identifiable_is_a_warning(monkeypatch: pytest.MonkeyPatch) -> None:
    """The BRFD's identify answer carries its doubts in the same ``warnings`` list (here: a stubbed fit)."""
    from app.services import plant_identification
    from engine.identification.plant_width import WidthFit

    def flat(plant: Any, records: Any, width: str) -> WidthFit:
        return WidthFit(
            1e-3, math.nan, (0.0, 6e-3), False, ["the 95 % interval reaches zero width"], ["eq"], [{}], {}, []
        )

    monkeypatch.setattr(plant_identification, "fit_width", flat)
    monkeypatch.setattr(plant_identification, "_paper", lambda plant, record: {})
    out = plant_identification.identify_records("brfd", [object()])
    assert out["warnings"] == [
        {
            "code": "not_identifiable",
            "message": "the width is not identifiable: the 95 % interval reaches zero width",
            "channel": None,
        }
    ]
