"""The image built and run by a Docker engine: its health check, the API over HTTP, and the volume across a restart.

The module builds the image from this working tree (``docker build --build-arg BASE_IMAGE=...``), runs it on a
free loopback port with a fresh named volume at /data, waits for the image's HEALTHCHECK (polled every second here
instead of the Dockerfile's 30 s), talks to it over HTTP, restarts it, and checks that the pattern set, the jobs
and the diagnosis are still there with the same content. The container, the volume and the image's tag are
removed afterwards; the base image and the layer of the dependencies (tag ``backlash-test-cache:dependencies``,
replaced when they change) are kept for the next run.

The base image: ``$BACKLASH_BASE_IMAGE`` if set, else ``python:3.11-slim`` if the engine has it, else the
stand-in built from Debian's packages by ``../shared/tools/local-python-base.sh`` (beside this checkout or
the repository it was cloned from, or ``$BACKLASH_BASE_SCRIPT``; for a machine without a
container registry; it needs root and debootstrap). Without a Docker engine (``make system-deps`` installs and
starts one as root on Debian) the module skips with the reason.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import hashlib
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from servicekit import SMALL_TRAINING, free_port, wait_for_job

from engine.records import Record
from engine.simulation import PlantParameters, add_white_noise, simulate

# serial: the image build takes both cores, and its health checks have deadlines
pytestmark = [pytest.mark.container, pytest.mark.serial]

REPO = Path(__file__).resolve().parents[2]
SCRIPT_IN_SHARED = Path("shared") / "tools" / "local-python-base.sh"


def _base_script() -> Path:
    """``../shared/tools/local-python-base.sh`` beside this checkout, or beside the repository it was cloned from
    (a CI clone of a local checkout lives elsewhere), or ``$BACKLASH_BASE_SCRIPT``."""
    candidates = [Path(os.environ["BACKLASH_BASE_SCRIPT"])] if os.environ.get("BACKLASH_BASE_SCRIPT") else []
    candidates.append(REPO.parent / SCRIPT_IN_SHARED)
    origin = subprocess.run(
        ["git", "-C", str(REPO), "remote", "get-url", "origin"], capture_output=True, text=True, check=False
    ).stdout.strip()
    if origin and "://" not in origin and ":" not in origin.split("/")[0]:  # a local path, not a URL
        candidates.append(Path(origin).expanduser().resolve().parent / SCRIPT_IN_SHARED)
    return next((c for c in candidates if c.is_file()), candidates[0] if candidates else REPO.parent / SCRIPT_IN_SHARED)


BASE_SCRIPT = _base_script()
DEFAULT_BASE = "python:3.11-slim"
#: The Dockerfile's health check, polled often enough for a test (its own interval, 30 s, stays the image's).
HEALTH_OPTIONS = ["--health-interval=1s", "--health-timeout=5s", "--health-start-period=120s", "--health-retries=3"]
#: Longest wait for the container to report healthy (a bound against hanging, not a timing assumption).
HEALTH_TIMEOUT = 180.0
#: ``docker restart`` sends SIGTERM, then SIGKILL after this many seconds.
STOP_TIMEOUT = 30
#: The container's API key (the image refuses to serve its 0.0.0.0 without one).
API_KEY = "container-test-key"
#: Access-log lines of successful polls (health checks, job states), left out of the logs shown on failures.
POLL = re.compile(r'"GET /(healthz|v1/jobs/\w+) HTTP/1\.1" 200')
#: The Dockerfile's step that installs the dependencies, and the tag that keeps its layer between runs.
DEPENDENCY_STEP, DEPENDENCY_CACHE = "pip install -c constraints.txt -r", "backlash-test-cache:dependencies"
#: The diagnosed record's asset and measurement time (the issue 12 contract).
ASSET, MEASURED_AT = "container-test", "2026-11-20T08:00:00Z"


def docker(*args: str, timeout: float = 120.0, check: bool = True) -> subprocess.CompletedProcess[str]:
    """Run ``docker args``; raise with its stderr if it fails and ``check``."""
    done = subprocess.run(["docker", *args], capture_output=True, text=True, timeout=timeout)
    if check and done.returncode != 0:
        raise RuntimeError(f"docker {' '.join(args)} failed with {done.returncode}:\n{done.stderr[-3000:]}")
    return done


def engine_problem() -> str | None:
    """Why no Docker engine can be used, or None when one answers."""
    if shutil.which("docker") is None:
        return "no docker command (as root on Debian, `make system-deps` installs docker.io and starts dockerd)"
    try:
        done = docker("info", "--format", "{{.ServerVersion}}", timeout=30, check=False)
    except subprocess.TimeoutExpired:
        return "`docker info` did not answer within 30 s"
    if done.returncode != 0 or not done.stdout.strip():
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        return f"no Docker engine answers ({last}); as root on Debian, `make system-deps` starts one"
    return None


def base_image() -> str:
    """The base image to build on (see the module's docstring); skips the module when none can be had."""
    if chosen := os.environ.get("BACKLASH_BASE_IMAGE"):
        return chosen
    if docker("image", "inspect", DEFAULT_BASE, check=False).returncode == 0:
        return DEFAULT_BASE
    if not BASE_SCRIPT.is_file():
        pytest.skip(
            f"{DEFAULT_BASE} is not in the Docker engine and {BASE_SCRIPT} (which builds a stand-in) is missing; "
            "set BACKLASH_BASE_IMAGE to a base image the engine has"
        )
    made = subprocess.run(["sh", str(BASE_SCRIPT)], capture_output=True, text=True, timeout=1800)
    if made.returncode == 0 and made.stdout.strip():
        return made.stdout.strip().splitlines()[-1]
    pulled = docker("pull", DEFAULT_BASE, timeout=600, check=False)  # a machine with a registry but no root
    if pulled.returncode == 0:
        return DEFAULT_BASE
    pytest.skip(
        f"no base image: {BASE_SCRIPT.name} failed ({made.stderr.strip()[-500:]}) and `docker pull {DEFAULT_BASE}` "
        f"failed ({pulled.stderr.strip()[-300:]}); set BACKLASH_BASE_IMAGE to a base image the engine has"
    )


def rfc3339(text: str) -> dt.datetime:
    """An RFC 3339 timestamp (Docker gives up to nanoseconds) as an aware datetime, to the microsecond."""
    m = re.fullmatch(r"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d)(?:\.(\d+))?(Z|[+-]\d\d:\d\d)", text)
    assert m, f"not a Docker timestamp: {text!r}"
    zone = "+00:00" if m[3] == "Z" else m[3]
    return dt.datetime.fromisoformat(f"{m[1]}.{(m[2] or '0')[:6].ljust(6, '0')}{zone}")


def keep_dependency_layer(image: str) -> None:
    """Tag the layer of the image's dependencies as :data:`DEPENDENCY_CACHE`, so that the next build of the same
    pyproject.toml and constraints.txt starts after it (the code's layers are removed with the image); remove the
    layer it replaces. Nothing to keep when the builder left no intermediate images (BuildKit has its own cache)."""
    history = docker("history", "--no-trunc", "--format", "{{.ID}}\t{{.CreatedBy}}", image, check=False).stdout
    layer = next(
        (i for i, _, step in (line.partition("\t") for line in history.splitlines()) if DEPENDENCY_STEP in step),
        "<missing>",
    )
    if not layer.startswith("sha256:"):
        return
    old = docker("image", "inspect", "--format", "{{.Id}}", DEPENDENCY_CACHE, check=False).stdout.strip()
    docker("tag", layer, DEPENDENCY_CACHE)
    if old and old != layer:
        docker("rmi", old, check=False)


@dataclass
class Container:
    """The running container of the module, its image's tag and volume, and what the tests stored in it."""

    name: str
    image: str
    volume: str
    port: int
    build_seconds: float
    base: str

    @property
    def base_url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def client(self) -> httpx.Client:
        return httpx.Client(base_url=self.base_url, timeout=120, headers={"X-API-Key": API_KEY})

    def state(self) -> dict[str, Any]:
        return json.loads(docker("inspect", "--format", "{{json .State}}", self.name).stdout)

    def logs(self, lines: int = 300) -> str:
        """The container's output (stdout and stderr in their order), without the successful polls."""
        done = subprocess.run(
            ["docker", "logs", self.name], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=60
        )
        kept = [line for line in done.stdout.splitlines() if not POLL.search(line)]
        return f"--- docker logs {self.name}: the last {lines} lines but successful polls ---\n" + "\n".join(
            kept[-lines:]
        )

    def wait_healthy(self, timeout: float = HEALTH_TIMEOUT) -> None:
        """Wait until the HEALTHCHECK passed since the container's (re)start."""
        deadline = time.monotonic() + timeout
        state = self.state()
        while time.monotonic() < deadline:
            state = self.state()
            if not state["Running"]:
                raise AssertionError(f"the container stopped (exit code {state['ExitCode']}):\n{self.logs()}")
            health = state.get("Health") or {}
            passed = [e for e in health.get("Log") or [] if e["ExitCode"] == 0]
            if (
                health.get("Status") == "healthy"
                and passed
                and rfc3339(passed[-1]["Start"]) >= rfc3339(state["StartedAt"])
            ):
                return
            time.sleep(0.5)
        raise AssertionError(f"not healthy within {timeout} s: {state.get('Health')}\n{self.logs()}")

    @contextlib.contextmanager
    def logs_on_failure(self) -> Iterator[None]:
        """Add the container's logs to the message of a failure inside the block."""
        try:
            yield
        except Exception as exc:
            raise AssertionError(f"{type(exc).__name__}: {exc}\n{self.logs()}") from exc


@dataclass
class ImageBuild:
    """One ``docker build`` of this tree."""

    image: str
    log: Path
    base: str | None = None
    seconds: float = 0.0
    returncode: int | None = None
    skip: str | None = None

    def run(self) -> None:
        if problem := engine_problem():
            self.skip = problem
            return
        try:
            self.base = base_image()
        except pytest.skip.Exception as exc:
            self.skip = str(exc)
            return
        started = time.monotonic()
        command = ["docker", "build", "--network", "host", "--build-arg", f"BASE_IMAGE={self.base}"]
        with open(self.log, "w") as log:
            built = subprocess.run(
                [*command, "-t", self.image, str(REPO)],
                stdout=log,
                stderr=subprocess.STDOUT,
                timeout=1800,
            )
        self.returncode, self.seconds = built.returncode, time.monotonic() - started

    def result(self) -> ImageBuild:
        """Skip or fail the module as the build went."""
        if self.skip is not None:
            pytest.skip(self.skip)
        if self.returncode != 0:
            pytest.fail(f"docker build on {self.base} failed:\n{self.log.read_text(errors='replace')[-5000:]}")
        return self


def _new_build() -> ImageBuild:
    return ImageBuild(
        f"backlash-test:{uuid.uuid4().hex[:12]}", Path(tempfile.mkdtemp(prefix="backlash-build-")) / "log"
    )


@pytest.fixture(scope="module")
def container() -> Iterator[Container]:
    """The image built from this tree and run with a fresh volume, healthy; everything but the base removed after."""
    build = _new_build()  # built now, after the session's latency tests (see the conftest)
    build.run()
    build.result()
    assert build.base is not None
    image = build.image
    name = image.replace(":", "-")
    try:
        box = Container(name, image, name, free_port(), build.seconds, build.base)
        docker("volume", "create", box.volume)
        docker(
            "run",
            "--detach",
            "--name",
            name,
            "--publish",
            f"127.0.0.1:{box.port}:8000",
            "--volume",
            f"{box.volume}:/data",
            "--env",  # the image listens on 0.0.0.0: it serves only with an API key (or BACKLASH_ALLOW_NO_KEY=1)
            f"BACKLASH_API_KEY={API_KEY}",
            *HEALTH_OPTIONS,
            image,
        )
        box.wait_healthy()
        yield box
    finally:
        docker("rm", "--force", "--volumes", name, check=False)
        docker("volume", "rm", "--force", name, check=False)
        keep_dependency_layer(image)
        docker("rmi", image, check=False)


@pytest.fixture(scope="module")
def paths(container: Container) -> set[str]:
    """The paths of the container's OpenAPI document."""
    with container.client() as c:
        r = c.get("/openapi.json")
    assert r.status_code == 200, r.text
    return set(r.json()["paths"])


@pytest.fixture(scope="module")
def sim_record(container: Container) -> dict[str, Any]:
    """A record simulated by the container (K = 0.005 m, nominal J1 and c), in the JSON record format."""
    with container.client() as c, container.logs_on_failure():
        r = c.post("/v1/simulate", json={"K": 0.005})
        assert r.status_code == 200, r.text
        return r.json()


@pytest.fixture(scope="module")
def trained(container: Container, sim_record: dict[str, Any]) -> dict[str, Any]:
    """A small pattern set trained by the container: the accepted answer, the finished job, the stored set and
    the identification of ``sim_record`` with it."""
    with container.client() as c, container.logs_on_failure():
        r = c.post("/v1/pattern-sets", json=SMALL_TRAINING)
        assert r.status_code == 202, r.text
        accepted = r.json()
        job = wait_for_job(c, accepted["job_id"])
        assert job["state"] == "done", job
        pattern_set = c.get(f"/v1/pattern-sets/{accepted['pattern_set_id']}")
        assert pattern_set.status_code == 200, pattern_set.text
        identified = identify(c, sim_record, accepted["pattern_set_id"])
    return {**accepted, "job": job, "pattern_set": pattern_set.json(), "identified": identified}


def identify(client: httpx.Client, record: dict[str, Any], set_id: str) -> dict[str, Any]:
    r = client.post("/v1/identify", json={"record": record, "channel": "v2", "pattern_set": set_id})
    assert r.status_code == 200, r.text
    return r.json()


@pytest.fixture(scope="module")
def diagnosed(container: Container, paths: set[str]) -> dict[str, Any]:
    """A diagnosis job of a record with a hidden effect (load inertia x 1.4), finished: the accepted answer, the
    job, the stored diagnosis and its figures. An image without /v1/diagnoses fails the tests that use it."""
    assert "/v1/diagnoses" in paths, f"the image serves no /v1/diagnoses (issue 12); its paths: {sorted(paths)}"
    rng = np.random.default_rng(11)
    truth = simulate(PlantParameters(K=0.006, J1=0.82, c=1.2), effects={"load_inertia": 1.4})
    record = Record({k: add_white_noise(v, 40.0, rng) for k, v in truth.channels.items()}, conditions={"c1": 0.2})
    # one candidate keeps the job short (a few seconds); the full catalogue is the default
    body = {"record": {**record.to_dict(), "asset": ASSET, "measured_at": MEASURED_AT}, "effects": ["load_inertia"]}
    with container.client() as c, container.logs_on_failure():
        r = c.post("/v1/diagnoses", json=body)
        assert r.status_code == 202, r.text
        accepted = {**r.json(), "location": r.headers.get("location")}
        job = wait_for_job(c, accepted["job_id"], timeout=300)
        diagnosis = c.get(f"/v1/diagnoses/{accepted['diagnosis_id']}")
        assert diagnosis.status_code == 200, diagnosis.text
    return {**accepted, "job": job, "diagnosis": diagnosis.json(), "figures": figures(container, diagnosis.json())}


def figures(container: Container, diagnosis: dict[str, Any]) -> dict[str, httpx.Response]:
    """The diagnosis's figures, by name."""
    with container.client() as c:
        return {name: c.get(f"/v1/diagnoses/{diagnosis['id']}/figures/{name}") for name in diagnosis["figures"]}


@pytest.fixture(scope="module")
def restarted(container: Container, trained: dict[str, Any], request: pytest.FixtureRequest) -> Container:
    """The container after ``docker restart``, once the pattern set (and the diagnosis, if it can) were stored."""
    # a failed diagnosis is reported by its own tests; the pattern set and the jobs are checked after the restart anyway
    with contextlib.suppress(Exception, pytest.fail.Exception):
        request.getfixturevalue("diagnosed")
    with container.logs_on_failure():
        before = container.state()["StartedAt"]
        started = time.monotonic()
        docker("restart", "--time", str(STOP_TIMEOUT), container.name, timeout=STOP_TIMEOUT + 60)
        took = time.monotonic() - started
        assert took < STOP_TIMEOUT - 5, f"the service took {took:.0f} s to stop: it ignored SIGTERM and was killed"
        assert rfc3339(container.state()["StartedAt"]) > rfc3339(before)
        container.wait_healthy()
    return container


def test_the_container_is_healthy_runs_as_app_and_keeps_its_database_on_the_volume(container: Container) -> None:
    print(f"image built on {container.base} in {container.build_seconds:.0f} s")  # shown by pytest -rP
    with container.logs_on_failure():
        # the image keeps the production interval; only this container polls faster
        check = json.loads(
            docker("image", "inspect", "--format", "{{json .Config.Healthcheck}}", container.image).stdout
        )
        assert check["Interval"] == 30 * 10**9 and "/healthz" in " ".join(check["Test"])
        assert docker("exec", container.name, "id", "-u").stdout.strip() not in ("", "0")  # not root
        assert docker("exec", container.name, "test", "-s", "/data/patterns.sqlite3", check=False).returncode == 0
        mounts = json.loads(docker("inspect", "--format", "{{json .Mounts}}", container.name).stdout)
        assert [(m["Type"], m["Name"], m["Destination"]) for m in mounts] == [("volume", container.volume, "/data")]
        with container.client() as c:
            r = c.get("/healthz")
        assert r.status_code == 200 and r.json()["status"] == "ok", r.text
        assert "Permission denied" not in container.logs()  # every directory the service writes is its own


def test_openapi_and_docs_are_served(container: Container, paths: set[str]) -> None:
    with container.logs_on_failure():
        expected = {"/healthz", "/v1/simulate", "/v1/pattern-sets", "/v1/identify"}
        expected |= {"/v1/jobs", "/v1/jobs/{job_id}", "/v1/diagnoses", "/v1/diagnoses/{diagnosis_id}"}
        assert expected <= paths, sorted(expected - paths)
        with container.client() as c:
            assert c.get("/docs").status_code == 200


def test_simulate_gives_what_the_engine_gives_here(container: Container, sim_record: dict[str, Any]) -> None:
    """The container's numba kernel, compiled at build time, agrees with this process's."""
    here = simulate(PlantParameters(K=0.005))
    with container.logs_on_failure():
        assert set(sim_record["channels"]) == set(here.channels)
        for name, values in here.channels.items():
            span = float(np.ptp(values)) or 1.0
            np.testing.assert_allclose(sim_record["channels"][name], values, rtol=0, atol=1e-9 * span, err_msg=name)


def test_training_job_stores_a_pattern_set_that_identifies(trained: dict[str, Any]) -> None:
    assert trained["job"]["kind"] == "train_pattern_set"
    assert trained["job"]["pattern_set_id"] == trained["pattern_set_id"]
    stored = trained["pattern_set"]
    assert (stored["id"], stored["kind"], stored["channel"], stored["c"], stored["J1_values"]) == (
        trained["pattern_set_id"],
        "paper",
        "v2",
        1.0,
        SMALL_TRAINING["J1_values"],
    )
    assert trained["identified"]["width"] == 0.005  # the simulated width


def test_diagnosis_job_names_the_hidden_effect(container: Container, diagnosed: dict[str, Any]) -> None:
    done = diagnosed
    with container.logs_on_failure():
        assert done["location"] == f"/v1/diagnoses/{done['diagnosis_id']}"
        job = done["job"]
        assert (job["state"], job["kind"], job["diagnosis_id"]) == ("done", "diagnose", done["diagnosis_id"]), job
        diagnosis = done["diagnosis"]
        assert (diagnosis["id"], diagnosis["job_id"], diagnosis["record_id"], diagnosis["state"]) == (
            done["diagnosis_id"],
            done["job_id"],
            done["record_id"],
            "done",
        )
        assert diagnosis["asset"] == ASSET and rfc3339(diagnosis["measured_at"]) == rfc3339(MEASURED_AT)
        verdict = diagnosis["result"]["verdict"]
        assert (verdict["status"], verdict["effect"]) == ("explained", "load_inertia"), verdict
        assert abs(verdict["value"] - 1.4) < 0.05
        assert done["figures"], "the diagnosis lists no figures"
        for name, figure in done["figures"].items():
            assert figure.status_code == 200 and figure.headers["content-type"] == "image/png", (
                name,
                figure.text[:300],
            )
            assert figure.content.startswith(b"\x89PNG"), name


def test_the_pattern_set_survives_a_restart(
    restarted: Container, trained: dict[str, Any], sim_record: dict[str, Any]
) -> None:
    set_id = trained["pattern_set_id"]
    with restarted.client() as c, restarted.logs_on_failure():
        r = c.get(f"/v1/pattern-sets/{set_id}")
        assert r.status_code == 200, r.text
        assert r.json() == trained["pattern_set"]
        assert set_id in {s["id"] for s in c.get("/v1/pattern-sets").json()["data"]}
        # the stored arrays, not only the metadata: the same identification as before the restart
        again = identify(c, sim_record, set_id)
        assert again["width"] == trained["identified"]["width"]
        np.testing.assert_allclose(again["D"], trained["identified"]["D"], rtol=1e-12)


def test_the_training_job_survives_a_restart(restarted: Container, trained: dict[str, Any], paths: set[str]) -> None:
    assert "/v1/jobs" in paths, f"the image lists no jobs (GET /v1/jobs, issue 12); its paths: {sorted(paths)}"
    job_id = trained["job_id"]
    with restarted.client() as c, restarted.logs_on_failure():
        r = c.get(f"/v1/jobs/{job_id}")
        assert r.status_code == 200, r.text
        assert r.json() == trained["job"]
        listed = c.get("/v1/jobs", params={"kind": "train_pattern_set"})
        assert listed.status_code == 200, listed.text
        assert job_id in {j["id"] for j in listed.json()["items"]}


def test_the_diagnosis_survives_a_restart(restarted: Container, diagnosed: dict[str, Any]) -> None:
    done = diagnosed
    with restarted.client() as c, restarted.logs_on_failure():
        r = c.get(f"/v1/diagnoses/{done['diagnosis_id']}")
        assert r.status_code == 200, r.text
        assert r.json() == done["diagnosis"]
        r = c.get(f"/v1/jobs/{done['job_id']}")
        assert r.status_code == 200 and r.json() == done["job"], r.text
        listed = c.get("/v1/diagnoses", params={"asset": ASSET})
        assert listed.status_code == 200, listed.text
        assert [d["id"] for d in listed.json()["items"]] == [done["diagnosis_id"]]
        record = c.get(f"/v1/records/{done['record_id']}")
        assert record.status_code == 200, record.text

    def digests(figs: dict[str, httpx.Response]) -> dict[str, str]:
        return {name: hashlib.sha256(f.content).hexdigest() for name, f in figs.items()}

    assert digests(figures(restarted, done["diagnosis"])) == digests(done["figures"])
