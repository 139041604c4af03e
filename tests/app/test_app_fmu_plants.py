"""The user's own simulator through the service (issue 55): an FMU uploaded once by hash, a description stored
as a plant, records of it diagnosed synchronously and as jobs, refusals that say what to fix.

The FMU is the quarter-car example built from its sources; the diagnosed records are synthesized from it
here (engine.plants.fmu.FmuPlant.synthesize) with a known effect, so the named effect can be wrong.
A reduced description (three effects, no generic effects) keeps each diagnosis to a few seconds.
"""

from __future__ import annotations

import copy
import hashlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fmukit import EXAMPLE, OCTET, as_csv, as_json, local_plant, small_description, synthetic
from servicekit import Server, make_factory, wait_for_job

from engine.plants.fmu import FmuPlant
from engine.plants.fmu.build import build_fmu


@pytest.fixture(scope="module")
def fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_fmu(EXAMPLE, tmp_path_factory.mktemp("qc_fmu"))


@pytest.fixture(scope="module")
def on(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """A service with FMU plants turned on."""
    servers: list[Server] = []
    yield make_factory(tmp_path_factory.mktemp("fmu_on"), servers)(allow_fmu_plants="1")
    for s in servers:
        s.stop()


@pytest.fixture(scope="module")
def local(fmu: Path) -> FmuPlant:
    return local_plant(fmu)


@pytest.fixture(scope="module")
def stored(on: Server, fmu: Path) -> dict[str, Any]:
    """The FMU uploaded and the reduced plant stored: {"fmu": FmuPublic, "plant": PlantPublic}."""
    with on.client() as c:
        up = c.post("/v1/fmus", content=fmu.read_bytes(), headers=OCTET)
        assert up.status_code == 201, up.text
        made = c.post("/v1/plants", json={"description": small_description(up.json()["sha256"])})
        assert made.status_code == 201, made.text
    return {"fmu": up.json(), "plant": made.json()}


def test_fmu_plants_are_off_unless_the_operator_turns_them_on(client: httpx.Client, fmu: Path) -> None:
    """The shared service has the default settings: nothing of an FMU is accepted, and the answer says why."""
    r = client.post("/v1/fmus", content=fmu.read_bytes(), headers=OCTET)
    assert r.status_code == 403, r.text
    assert "BACKLASH_ALLOW_FMU_PLANTS" in r.json()["detail"]
    r = client.post("/v1/plants", json={"description": {"name": "x"}})
    assert r.status_code == 403, r.text
    body = {"plant": "fmu-0123456789abcdef", "record": {"columns": {"t": [0.0, 1.0]}}}
    r = client.post("/v1/diagnose", json=body)
    assert r.status_code == 403 and "BACKLASH_ALLOW_FMU_PLANTS" in r.json()["detail"], r.text
    r = client.post(
        "/v1/diagnose",
        params={"plant": "fmu-0123456789abcdef"},
        content=b"t\n0\n",
        headers={"Content-Type": "text/csv"},
    )
    assert r.status_code == 403, r.text
    assert client.get("/v1/plants").json() == {"items": []}
    assert client.get("/healthz").status_code == 200


def test_an_fmu_is_stored_once_by_its_hash(on: Server, fmu: Path, stored: dict[str, Any]) -> None:
    content = fmu.read_bytes()
    assert stored["fmu"]["sha256"] == hashlib.sha256(content).hexdigest()
    assert set(stored["fmu"]["outputs"]) == {"a_body", "x_susp", "a_wheel"}
    with on.client() as c:
        again = c.post("/v1/fmus", content=content, headers=OCTET)
        assert again.status_code == 200 and again.json() == stored["fmu"], again.text
        assert c.get(f"/v1/fmus/{stored['fmu']['sha256']}").json() == stored["fmu"]
        assert c.get(f"/v1/fmus/{'f' * 64}").status_code == 404
        for bad, status, words in (
            (b"", 422, "empty"),
            (b"not a zip archive at all", 422, "zip archive"),
            (content[: len(content) // 2], 422, "zip"),
        ):
            r = c.post("/v1/fmus", content=bad, headers=OCTET)
            assert r.status_code == status and words in r.json()["detail"], (bad[:20], r.text)
        r = c.post("/v1/fmus", content=content, headers={"Content-Type": "text/plain"})
        assert r.status_code == 415 and "application/octet-stream" in r.json()["detail"], r.text


def test_a_description_is_checked_against_its_fmu_and_stored_as_a_plant(on: Server, stored: dict[str, Any]) -> None:
    plant, sha = stored["plant"], stored["fmu"]["sha256"]
    assert plant["id"].startswith("fmu-") and plant["name"] == "quarter_car_small"
    assert [e["name"] for e in plant["effects"]] == ["damper_friction", "progressive_spring", "tyre_stiffness"]
    assert plant["columns"] == ["t", "z_road", "a_body", "x_susp", "a_wheel"]
    with on.client() as c:
        same = c.post("/v1/plants", json={"description": small_description(sha)})
        assert same.status_code == 200 and same.json()["id"] == plant["id"], same.text
        assert c.get(f"/v1/plants/{plant['id']}").json() == plant
        assert plant["id"] in [p["id"] for p in c.get("/v1/plants").json()["items"]]
        # the example's own TOML file, as it is but for its FMU: another plant, with the generic effects
        text = (EXAMPLE / "plant.toml").read_text().replace('fmu = "."', f'fmu = "sha256:{sha}"')
        text = "\n".join(line for line in text.splitlines() if not line.startswith("examples"))
        full = c.post("/v1/plants", content=text.encode(), headers={"Content-Type": "application/toml"})
        assert full.status_code == 201, full.text
        assert full.json()["id"] != plant["id"] and "a_body_gain" in [e["name"] for e in full.json()["effects"]]

        def refused(description: dict[str, Any], *words: str) -> None:
            r = c.post("/v1/plants", json={"description": description})
            assert r.status_code == 422, r.text
            for w in words:
                assert w in r.json()["detail"], (w, r.text)

        good = small_description(sha)
        refused({**good, "fmu": "quarter_car.fmu"}, "sha256:")
        refused({**good, "fmu": f"sha256:{'0' * 64}"}, "POST /v1/fmus")
        refused({**good, "examples": ["record.csv"]}, "examples")
        refused({**good, "colour": "red"}, "colour")
        wrong = copy.deepcopy(good)
        wrong["channels"][0]["variable"] = "a_bodyy"
        refused(wrong, "a_bodyy", "a_body")
        wrong = copy.deepcopy(good)
        wrong["calibrated"][0]["unit"] = "g"
        refused(wrong, "'g'", "'kg'")
        r = c.post("/v1/plants", content=b"name = [", headers={"Content-Type": "application/toml"})
        assert r.status_code == 422 and "TOML" in r.json()["detail"], r.text
        assert c.get("/v1/plants/fmu-0000000000000000").status_code == 404


def test_records_of_a_stored_plant_are_diagnosed_synchronously_and_as_jobs(
    on: Server, stored: dict[str, Any], local: FmuPlant
) -> None:
    """The named effect is the one the record was made with (JSON, synchronously), a clean record is no_gap (CSV
    form, a job), and the stored record reads again to the same answer."""
    plant_id = stored["plant"]["id"]
    friction = synthetic(local, {"damper_friction": 100.0}, seed=5)
    with on.client() as c:
        r = c.post("/v1/diagnose", json={"plant": plant_id, "record": as_json(friction, local)})
        assert r.status_code == 200, r.text
        answer = r.json()
        assert answer["status"] == "explained" and answer["verdict"]["effect"] == "damper_friction", answer["verdict"]
        named = {row["effect"]: row for row in answer["verdict"]["effects"]}["damper_friction"]
        assert abs(named["value"] - 100.0) < 4 * named["uncertainty"] + 5.0, named

        clean = synthetic(local, {}, seed=6)
        r = c.post(
            "/v1/diagnoses",
            params={"plant": plant_id, "asset": "rig-3"},
            content=as_csv(clean, local),
            headers={"Content-Type": "text/csv"},
        )
        assert r.status_code == 202, r.text
        accepted = r.json()
        assert wait_for_job(c, accepted["job_id"], timeout=300)["state"] == "done"
        done = c.get(f"/v1/diagnoses/{accepted['diagnosis_id']}").json()
        assert done["plant"] == plant_id and done["status"] == "no_gap", done
        assert "overlay_a_body" in done["figures"], done["figures"]  # measured vs simulated, drawn by the job
        png = c.get(f"/v1/diagnoses/{accepted['diagnosis_id']}/figures/overlay_a_body")
        assert png.status_code == 200 and png.content.startswith(b"\x89PNG"), png.status_code
        record = c.get(f"/v1/records/{accepted['record_id']}").json()
        assert record["plant"] == plant_id and record["params"]["plant"] == plant_id

        # a record the plant cannot read is refused, naming what to fix
        r = c.post(
            "/v1/diagnose",
            params={"plant": plant_id},
            content=as_csv(clean, local).replace(b"a_body [m/s2]", b"a_body [g]"),
            headers={"Content-Type": "text/csv"},
        )
        assert r.status_code == 422 and "'g'" in r.json()["detail"] and "convert" in r.json()["detail"], r.text
        columns = as_json(clean, local)
        del columns["columns"]["x_susp"]
        r = c.post("/v1/diagnose", json={"plant": plant_id, "record": columns})
        assert r.status_code == 422 and "x_susp" in r.json()["detail"], r.text
        r = c.post(
            "/v1/diagnose",
            params={"plant": plant_id, "units": "a1:g"},
            content=b"t\n",
            headers={"Content-Type": "text/csv"},
        )
        assert r.status_code == 422 and "backlash drive" in r.json()["detail"], r.text
        r = c.post("/v1/diagnose", json={"plant": "fmu-0000000000000000", "record": columns})
        assert r.status_code == 422 and "GET /v1/plants" in r.json()["detail"], r.text
        r = c.post("/v1/diagnose", json={"plant": "fmu-nothex", "record": columns})
        assert r.status_code == 422, r.text

        # a plant that stored records name stays until they are deleted
        r = c.delete(f"/v1/plants/{plant_id}")
        assert r.status_code == 409 and "DELETE /v1/records" in r.json()["detail"], r.text
        assert c.get("/healthz").status_code == 200


def test_a_plant_no_record_names_is_deleted_with_its_unused_fmu(on: Server, stored: dict[str, Any], fmu: Path) -> None:
    with on.client() as c:
        other = small_description(stored["fmu"]["sha256"])
        other["name"] = "quarter_car_other"
        made = c.post("/v1/plants", json={"description": other})
        assert made.status_code == 201, made.text
        assert c.delete(f"/v1/plants/{made.json()['id']}").status_code == 204
        assert c.get(f"/v1/plants/{made.json()['id']}").status_code == 404
        assert c.get(f"/v1/fmus/{stored['fmu']['sha256']}").status_code == 200  # other plants still use it
        assert c.delete(f"/v1/plants/{made.json()['id']}").status_code == 404
