"""The Dockerfile, checked without a Docker engine: its structure, and its command and health check run locally."""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
from pathlib import Path

import httpx
import pytest
from servicekit import Server, clean_env, free_port

from engine.warm_up import STEPS

REPO = Path(__file__).resolve().parents[2]
DOCKERFILE = REPO / "Dockerfile"


def instructions(path: Path) -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) pairs; comments dropped, continuation lines joined."""
    out: list[tuple[str, str]] = []
    pending = ""
    for raw in path.read_text().splitlines():
        line = raw.strip()
        if not pending and (not line or line.startswith("#")):
            continue
        if line.startswith("#"):
            continue
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        full = (pending + line).strip()
        pending = ""
        keyword, _, args = full.partition(" ")
        out.append((keyword.upper(), args.strip()))
    return out


@pytest.fixture(scope="module")
def dockerfile() -> list[tuple[str, str]]:
    return instructions(DOCKERFILE)


def _index(steps: list[tuple[str, str]], keyword: str, contains: str = "") -> int:
    return next(i for i, (k, a) in enumerate(steps) if k == keyword and contains in a)


def _exec_form(args: str) -> list[str]:
    assert args.startswith("["), f"use the exec (JSON) form: {args}"
    return json.loads(args)


def test_base_image_and_layer_order(dockerfile: list[tuple[str, str]]) -> None:
    # the base is a build argument (a machine without a registry builds on a local stand-in), by default the official
    assert dockerfile[:2] == [("ARG", "BASE_IMAGE=python:3.11-slim"), ("FROM", "${BASE_IMAGE}")]
    copy_pyproject = _index(dockerfile, "COPY", "pyproject.toml")
    # the dependency list and the pinned versions, nothing else yet
    assert dockerfile[copy_pyproject][1].split()[:-1] == ["pyproject.toml", "constraints.txt"]
    install_deps = _index(dockerfile, "RUN", "pip install -c constraints.txt -r")
    copy_code = min(_index(dockerfile, "COPY", "engine"), _index(dockerfile, "COPY", "app"))
    install_package = _index(dockerfile, "RUN", "pip install --no-deps .")
    assert copy_pyproject < install_deps < copy_code < install_package
    copies = [a for k, a in dockerfile[:install_deps] if k in ("COPY", "ADD")]
    assert copies == [dockerfile[copy_pyproject][1]]  # the dependency layer sees no code


def test_runs_as_a_non_root_user(dockerfile: list[tuple[str, str]]) -> None:
    users = [(i, a) for i, (k, a) in enumerate(dockerfile) if k == "USER"]
    assert users, "no USER instruction: the container would run as root"
    last_index, last_user = users[-1]
    assert last_user.split(":")[0] not in ("root", "0")
    assert last_index < _index(dockerfile, "CMD")


def test_volume_port_healthcheck_and_command(dockerfile: list[tuple[str, str]]) -> None:
    env = " ".join(a for k, a in dockerfile if k == "ENV")
    db_path = next(tok.split("=", 1)[1] for tok in shlex.split(env) if tok.startswith("BACKLASH_DB_PATH="))
    numba_cache = next(tok.split("=", 1)[1] for tok in shlex.split(env) if tok.startswith("NUMBA_CACHE_DIR="))
    assert numba_cache.startswith("/home/app/")
    volumes = _exec_form(next(a for k, a in dockerfile if k == "VOLUME"))
    assert str(Path(db_path).parent) in volumes  # the database lives on the volume
    assert ("EXPOSE", "8000") in dockerfile
    health = next(a for k, a in dockerfile if k == "HEALTHCHECK")
    assert "CMD" in health and "/healthz" in health and "curl" not in health
    assert _exec_form(next(a for k, a in dockerfile if k == "CMD")) == [
        "backlash",
        "serve",
        "--host",
        "0.0.0.0",
        "--port",
        "8000",
    ]


def test_dockerignore_keeps_local_state_out() -> None:
    ignored = set((REPO / ".dockerignore").read_text().split())
    assert {".git", ".venv", "data", "out", "*.sqlite3"} <= ignored
    assert not {"constraints.txt", "pyproject.toml"} & ignored  # the dependency layer needs both


def test_the_images_command_serves_and_passes_its_health_check(
    dockerfile: list[tuple[str, str]], tmp_path: Path
) -> None:
    """Run the CMD (with a free port for 8000) and the HEALTHCHECK command as they are written: without an API key
    the CMD refuses to serve its 0.0.0.0; with one it serves, and the health check (no key) passes."""
    port = free_port()
    cmd = [
        str(Path(sys.executable).with_name(a)) if i == 0 else a
        for i, a in enumerate(_exec_form(next(a for k, a in dockerfile if k == "CMD")))
    ]
    cmd[cmd.index("--port") + 1] = str(port)
    health = next(a for k, a in dockerfile if k == "HEALTHCHECK")
    check = [
        sys.executable if a == "python" else a.replace(":8000/", f":{port}/")
        for a in _exec_form(health[health.index("CMD") + 3 :].strip())
    ]
    db = tmp_path / "data" / "patterns.sqlite3"
    refused = subprocess.run(cmd, env=clean_env(BACKLASH_DB_PATH=str(db)), capture_output=True, text=True, timeout=120)
    assert refused.returncode == 2, refused.stderr  # 0.0.0.0 without an API key: the image needs one (README)
    assert "BACKLASH_API_KEY" in refused.stderr and "BACKLASH_ALLOW_NO_KEY=1" in refused.stderr
    server = Server(
        cmd,
        clean_env(BACKLASH_DB_PATH=str(db), BACKLASH_API_KEY="image-test-key"),
        port,
        tmp_path / "server.log",
        tmp_path,
    )
    server.start()
    try:
        assert subprocess.run(check, capture_output=True, timeout=30).returncode == 0
        r = httpx.get(f"http://127.0.0.1:{port}/healthz")
        assert r.json()["status"] == "ok"
        assert (tmp_path / "data" / "patterns.sqlite3").exists()
    finally:
        assert server.stop() == 0
    assert subprocess.run(check, capture_output=True, timeout=30).returncode != 0  # down -> unhealthy


def test_the_image_compiles_every_kernel_at_build_time(dockerfile: list[tuple[str, str]], tmp_path: Path) -> None:
    """The build runs ``python -m engine.warm_up`` (every numba kernel: the drive's serial and parallel ones, the
    EMPS loop and the BRFD element on the records shipped in the package, the speed quantum's scan, the paper's
    network) after the package is installed, as the image's user, and the module runs as written."""
    steps = [args for instruction, args in dockerfile if instruction == "RUN"]
    (warm,) = [i for i, args in enumerate(steps) if args == "python -m engine.warm_up"]
    assert warm > next(i for i, args in enumerate(steps) if args.startswith("pip install --no-deps ."))
    assert ("USER", "app") in dockerfile[: dockerfile.index(("RUN", steps[warm]))]
    done = subprocess.run(
        [sys.executable, "-m", "engine.warm_up"], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert all(name in done.stderr for name in STEPS), done.stderr
