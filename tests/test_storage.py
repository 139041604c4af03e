"""Tests for the pattern store (engine.storage).

Each test demonstrates one guarantee: round trip, queries, validation, integrity
checks, restart, concurrent writers (threads and spawned processes) and a crash
(SIGKILL) in the middle of a write transaction.
"""

from __future__ import annotations

import contextlib
import inspect
import json
import multiprocessing
import os
import re
import signal
import sqlite3
import subprocess
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import engine
from engine.constants import CHANNELS, K_GRID, MODEL_VERSION
from engine.identification.selection import nearest_pattern_set
from engine.storage import (
    SCHEMA_VERSION,
    CorruptPatternSet,
    InvalidPatternSet,
    PatternSet,
    PatternSetExists,
    PatternSetNotFound,
    PatternStore,
    PatternStoreError,
)
from engine.storage import schema as schema_module

REPO_ROOT = Path(engine.__file__).resolve().parent.parent


# --- helpers -----------------------------------------------------------------------
def make_set(seed: int = 0, *, channel: str = "a1", c: float = 1.0, kind: str = "paper", **meta: Any) -> PatternSet:
    """A realistic pattern set whose arrays are determined by ``seed``."""
    rng = np.random.default_rng(seed)
    params = {"learning_rate": 0.05, "delta1": 1e-3, "max_epochs": 500, "effects": ["friction"], "seed": seed}
    params.update(meta.pop("params", {}))
    return PatternSet(
        kind=kind,
        channel=channel,
        c=c,
        j1_values=[0.87, 0.8482, 0.8265],
        wavelet="sym5",
        params=params,
        arrays={
            "patterns": rng.normal(size=(6, 15)),
            "widths": np.asarray(K_GRID),
            "scaler_scale": rng.uniform(0.5, 2.0, size=15).astype(np.float32),
        },
        **meta,
    )


def raw_integrity(path: Path) -> list[str]:
    """``PRAGMA integrity_check`` through a plain sqlite3 connection."""
    conn = sqlite3.connect(path)
    try:
        return [r[0] for r in conn.execute("PRAGMA integrity_check")]
    finally:
        conn.close()


def fingerprint(ps: Any) -> dict[str, Any]:
    """JSON-able exact description of a pattern set (metadata + array bytes)."""
    return {
        "meta": [ps.id, ps.kind, ps.channel, ps.c, list(ps.j1_values), ps.wavelet, ps.params,
                 ps.model_version, ps.created_at],
        "arrays": {name: [a.dtype.str, list(a.shape), a.tobytes().hex()] for name, a in sorted(ps.arrays.items())},
    }  # fmt: skip


def python_env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT), env.get("PYTHONPATH", "")])
    return env


def run_python(code: str, *args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, env=python_env(), timeout=timeout
    )
    assert proc.returncode == 0, proc.stderr
    return proc


@pytest.fixture
def db_path(tmp_path: Path) -> Path:
    return tmp_path / "store" / "patterns.sqlite3"


@pytest.fixture
def store(db_path: Path) -> PatternStore:
    return PatternStore(db_path)


# --- 1. round trip, queries, errors, validation ------------------------------------------
def test_round_trip_is_bit_exact(store: PatternStore) -> None:
    """Arrays come back with identical dtype, shape and bits; metadata is equal."""
    tricky = {
        "patterns": np.random.default_rng(1).normal(size=(6, 15)),
        "widths": np.array([0.0025, -0.0, 5e-324, 1.7976931348623157e308, np.nextafter(1.0, 2.0), 1.0]),
        "float32": np.array([1.1, -2.5, 3e-38], dtype=np.float32),
        "big_endian": np.arange(4, dtype=">f8") / 3.0,
        "fortran": np.asfortranarray(np.arange(12.0).reshape(3, 4) / 7.0),
        "complex": np.array([1 + 2j, -0.0 - 1e-300j]),
        "ints": np.array([[-(2**63), 2**63 - 1]], dtype=np.int64),
        "uint8": np.arange(7, dtype=np.uint8),
        "mask": np.array([True, False, True]),
        "scalar": np.array(0.1),
    }
    original = make_set(3)
    original.arrays = {name: a.copy(order="K") for name, a in tricky.items()}
    saved = store.save(original)
    back = PatternStore(store.path).get(saved.id)

    assert set(back.arrays) == set(tricky)
    for name, a in tricky.items():
        b = back.arrays[name]
        assert b.dtype == a.dtype and b.shape == a.shape, name
        assert b.tobytes() == a.tobytes(), name
    assert back.arrays["fortran"].flags.f_contiguous
    assert back.summary_fields() == saved.summary_fields()
    assert back == saved
    assert (back.kind, back.channel, back.c, back.j1_values, back.wavelet, back.params, back.model_version) == (
        original.kind, original.channel, original.c, original.j1_values, original.wavelet, original.params,
        MODEL_VERSION,
    )  # fmt: skip


def test_save_assigns_id_and_time_and_leaves_input_alone(store: PatternStore) -> None:
    """The store sets id (uuid4 hex) and created_at (ISO UTC); a given id is kept."""
    original = make_set(0)
    saved = store.save(original)
    assert original.id is None and original.created_at is None
    assert re.fullmatch(r"[0-9a-f]{32}", saved.id), saved.id
    assert store.save(make_set(1)).id != saved.id  # a fresh id per save
    assert saved.created_at.endswith("+00:00")
    assert store.save(make_set(1, id="chosen-id")).id == "chosen-id"
    with pytest.raises(PatternSetExists, match="already exists"):
        store.save(make_set(2, id="chosen-id"))
    assert len(store) == 3
    assert store.get("chosen-id").params["seed"] == 1


def test_list_filters_and_orders_newest_first(store: PatternStore) -> None:
    a = store.save(make_set(0, channel="a1", c=1.0, kind="paper"))
    b = store.save(make_set(1, channel="a1", c=1.25, kind="template"))
    c = store.save(make_set(2, channel="m_el", c=1.0, kind="paper"))
    d = store.save(make_set(3, channel="a1", c=1.0, kind="template", model_version="0.9"))

    def ids(**kw: Any) -> list[str]:
        return [s.id for s in store.list(**kw)]

    assert ids() == [d.id, c.id, b.id, a.id]
    assert ids(channel="a1") == [d.id, b.id, a.id]
    assert ids(c=1.0) == [d.id, c.id, a.id]
    assert ids(kind="template") == [d.id, b.id]
    assert ids(channel="a1", c=1.0, kind="paper") == [a.id]
    assert ids(model_version=MODEL_VERSION) == [c.id, b.id, a.id]
    assert ids(channel="v2") == []
    summary = store.list(channel="m_el")[0]
    assert summary.array_shapes == {"patterns": (6, 15), "widths": (6,), "scaler_scale": (15,)}
    assert summary.array_dtypes["scaler_scale"] == "<f4"
    assert summary.params == c.params and summary.created_at == c.created_at
    assert [s.created_at for s in store.list()] == sorted((s.created_at for s in store.list()), reverse=True)
    with pytest.raises(ValueError, match="unknown channel"):
        store.list(channel="A1")


def test_delete_and_not_found(store: PatternStore) -> None:
    keep = store.save(make_set(0))
    gone = store.save(make_set(1))
    store.delete(gone.id)
    assert len(store) == 1 and gone.id not in store and keep.id in store
    for call in (lambda: store.get(gone.id), lambda: store.delete(gone.id)):
        with pytest.raises(PatternSetNotFound, match=f"no pattern set with id '{gone.id}'") as info:
            call()
        assert isinstance(info.value, KeyError)
    assert store.get(keep.id) == keep


def _mutations() -> dict[str, tuple[dict[str, Any], str]]:
    return {
        "unknown channel": ({"channel": "speed"}, "unknown channel 'speed'; use one of"),
        "nan c": ({"c": float("nan")}, "c must be finite"),
        "inf c": ({"c": float("inf")}, "c must be finite"),
        "text c": ({"c": "1.0"}, "c must be a real number"),
        "no arrays": ({"arrays": {}}, "arrays must be a non-empty dict"),
        "empty array": ({"arrays": {"patterns": np.zeros((6, 0))}}, "array 'patterns' is empty"),
        "nan in array": ({"arrays": {"patterns": np.array([[1.0, np.nan]])}}, r"non-finite value .* at index \(0, 1\)"),
        "inf in array": ({"arrays": {"widths": np.array([np.inf])}}, "non-finite value"),
        "object array": ({"arrays": {"x": np.array([{}, 1], dtype=object)}}, "only bool, integer, float and complex"),
        "bad array name": ({"arrays": {"../x": np.ones(2)}}, "array name '../x' is not allowed"),
        "set in params": ({"params": {"effects": {"friction"}}}, "params must be JSON-serialisable"),
        "numpy int in params": ({"params": {"max_epochs": np.int64(5)}}, r"\.item\(\)"),
        "nan in params": ({"params": {"delta1": float("nan")}}, "finite floats"),
        "empty j1": ({"j1_values": []}, "j1_values is empty"),
        "negative j1": ({"j1_values": [-0.87]}, "finite positive inertias"),
        "empty kind": ({"kind": ""}, "kind must be a non-empty string"),
        "bad id": ({"id": "a/b"}, "id 'a/b' is not allowed"),
    }


@pytest.mark.parametrize("case", list(_mutations()))
def test_invalid_input_is_rejected_and_nothing_is_written(store: PatternStore, case: str) -> None:
    before = store.save(make_set(0))
    changes, message = _mutations()[case]
    bad = make_set(1)
    for key, value in changes.items():
        setattr(bad, key, value)
    with pytest.raises(InvalidPatternSet, match=message) as info:
        store.save(bad)
    assert isinstance(info.value, ValueError)
    assert [s.id for s in store.list()] == [before.id]
    assert store.get(before.id) == before
    assert store.check() == []


# --- integrity checks, schema ----------------------------------------------------------
def test_corrupt_blob_is_detected(store: PatternStore) -> None:
    good = store.save(make_set(0))
    bad = store.save(make_set(1, channel="m_el"))
    conn = sqlite3.connect(store.path)
    blob = bytearray(conn.execute("SELECT arrays_blob FROM pattern_sets WHERE id = ?", (bad.id,)).fetchone()[0])
    blob[len(blob) // 2] ^= 0x01  # one flipped bit inside the array data
    with conn:
        conn.execute("UPDATE pattern_sets SET arrays_blob = ? WHERE id = ?", (bytes(blob), bad.id))
    conn.close()

    with pytest.raises(CorruptPatternSet, match=f"pattern set '{bad.id}' .* is corrupt"):
        store.get(bad.id)
    with pytest.raises(CorruptPatternSet):
        nearest_pattern_set(store, "m_el", 1.0)
    assert store.get(good.id) == good
    assert len(store.list()) == 2  # metadata stays listable, so the set can be found and deleted
    assert store.check() == [f"pattern set '{bad.id}': arrays fail their SHA-256 check"]
    store.delete(bad.id)
    assert store.check() == []


def test_schema_version_pragmas_and_migration_hook(
    db_path: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    store = PatternStore(db_path)
    kept = store.save(make_set(0))
    conn = sqlite3.connect(db_path)
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 3
    conn.close()

    def add_note_column(c: sqlite3.Connection) -> None:
        c.execute("ALTER TABLE pattern_sets ADD COLUMN note TEXT DEFAULT 'migrated'")

    monkeypatch.setattr(schema_module, "MIGRATIONS", [*schema_module.MIGRATIONS, add_note_column])
    migrated = PatternStore(db_path)
    conn = sqlite3.connect(db_path)
    assert conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION + 1
    assert conn.execute("SELECT note FROM pattern_sets").fetchall() == [("migrated",)]
    conn.close()
    assert migrated.get(kept.id) == kept
    monkeypatch.undo()

    with pytest.raises(PatternStoreError, match=f"schema version {SCHEMA_VERSION + 1}, newer than this code supports"):
        PatternStore(db_path)
    other = tmp_path / "other.sqlite3"
    conn = sqlite3.connect(other)
    conn.execute("CREATE TABLE t (x)")
    conn.close()
    with pytest.raises(PatternStoreError, match="not a pattern store"):
        PatternStore(other)
    junk = tmp_path / "junk.sqlite3"
    junk.write_bytes(b"this is not a database" * 100)
    with pytest.raises(PatternStoreError, match=str(junk)):
        PatternStore(junk)


def test_a_version_1_store_gains_the_service_tables_and_keeps_its_sets(db_path: Path) -> None:
    """A store written before the service's tables existed (schema 1) opens, migrates to the current schema and
    keeps its sets."""
    kept = PatternStore(db_path).save(make_set(0))
    conn = sqlite3.connect(db_path, isolation_level=None)
    for table in ("jobs", "records", "diagnoses", "figures", "identifications", "plants", "fmus"):  # schema 1
        conn.execute(f"DROP TABLE {table}")
    conn.execute("PRAGMA user_version = 1")
    conn.close()
    reopened = PatternStore(db_path)
    conn = sqlite3.connect(db_path)
    tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    version = conn.execute("PRAGMA user_version").fetchone()[0]
    conn.close()
    assert version == SCHEMA_VERSION
    assert {"pattern_sets", "jobs", "records", "diagnoses", "figures", "identifications", "plants", "fmus"} <= tables
    assert reopened.get(kept.id) == kept


def test_default_path_comes_from_the_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "env" / "patterns.sqlite3"
    monkeypatch.setenv("BACKLASH_DB_PATH", str(target))
    saved = PatternStore().save(make_set(0))
    assert PatternStore(target).get(saved.id) == saved
    with pytest.raises(ValueError, match="database file path"):
        PatternStore(":memory:")


# --- 2. restart ----------------------------------------------------------------------------
_READER = """
import json, sys
from engine.storage import PatternStore
store = PatternStore(sys.argv[1])
print(json.dumps({s.id: fingerprint(store.get(s.id)) for s in store.list()}))
"""

_WRITER_THEN_KILLED = """
import os, signal, sys
import numpy as np
from engine.storage import PatternSet, PatternStore
store = PatternStore(sys.argv[1])
saved = store.save(PatternSet(kind="template", channel="v2", c=0.8, j1_values=[0.87], wavelet="sym5",
                              params={"from": "child"}, arrays={"patterns": np.arange(90.0).reshape(6, 15)}))
print(saved.id, flush=True)
os.kill(os.getpid(), signal.SIGKILL)  # die right after save() returns: no clean shutdown
"""


def test_survives_restart_and_other_processes_see_the_data(db_path: Path) -> None:
    store = PatternStore(db_path)
    saved = [store.save(make_set(i, channel=CHANNELS[i % len(CHANNELS)], c=0.8 + 0.1 * i)) for i in range(4)]
    expected = {s.id: fingerprint(s) for s in saved}
    del store

    reopened = PatternStore(db_path)
    assert {s.id: fingerprint(reopened.get(s.id)) for s in reopened.list()} == expected

    child = run_python("from typing import Any\n" + inspect.getsource(fingerprint) + _READER, str(db_path))
    assert json.loads(child.stdout) == json.loads(json.dumps(expected))

    killed = subprocess.run(
        [sys.executable, "-c", _WRITER_THEN_KILLED, str(db_path)], capture_output=True, text=True, env=python_env()
    )
    assert killed.returncode == -signal.SIGKILL, killed.stderr
    child_id = killed.stdout.strip()
    back = PatternStore(db_path).get(child_id)
    assert back.params == {"from": "child"}
    assert back.arrays["patterns"].tobytes() == np.arange(90.0).reshape(6, 15).tobytes()
    assert len(PatternStore(db_path)) == 5
    assert raw_integrity(db_path) == ["ok"]


# --- 3. concurrent writers -------------------------------------------------------------------
N_PROCS, N_THREADS, N_PER_THREAD = 4, 3, 20


def keyed_set(worker: int, thread: int, i: int) -> PatternSet:
    """The set saved by (worker, thread, i); its content is reproducible from the key."""
    seed = worker * 10_000 + thread * 100 + i
    ps = make_set(seed, channel=CHANNELS[seed % len(CHANNELS)], c=0.8 + 0.05 * (seed % 13))
    ps.params.update(worker=worker, thread=thread, i=i)
    return ps


def is_deleted(i: int) -> bool:
    return i % 5 == 4


def _concurrent_worker(path: str, worker: int, barrier: Any, results: Any) -> None:
    """Process body: N_THREADS threads share one store and save/get/delete concurrently."""
    try:
        barrier.wait(timeout=60)
        store = PatternStore(path, busy_timeout=60.0)  # all processes create/open the new file at once
        errors: list[str] = []

        def run(thread: int) -> None:
            try:
                for i in range(N_PER_THREAD):
                    saved = store.save(keyed_set(worker, thread, i))
                    if store.get(saved.id) != saved:
                        errors.append(f"read-back mismatch for {saved.id}")
                    if is_deleted(i):
                        store.delete(saved.id)
            except Exception:
                errors.append(traceback.format_exc())

        threads = [threading.Thread(target=run, args=(t,)) for t in range(N_THREADS)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        results.put((worker, errors))
    except Exception:
        results.put((worker, [traceback.format_exc()]))


def test_concurrent_writers_never_corrupt(db_path: Path) -> None:
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(N_PROCS + 1)
    results = ctx.Queue()
    procs = [ctx.Process(target=_concurrent_worker, args=(str(db_path), w, barrier, results)) for w in range(N_PROCS)]
    for p in procs:
        p.start()

    reader_errors: list[str] = []
    done = threading.Event()

    def read_while_writing() -> None:  # readers are not blocked by, and do not break, writers
        try:
            while not done.is_set():
                for summary in parent_store.list()[:3]:
                    with contextlib.suppress(PatternSetNotFound):  # deleted meanwhile
                        parent_store.get(summary.id)
                nearest_pattern_set(parent_store, "a1", 1.0)
                len(parent_store)
        except Exception:
            reader_errors.append(traceback.format_exc())

    barrier.wait(timeout=60)
    parent_store = PatternStore(db_path)
    reader = threading.Thread(target=read_while_writing)
    reader.start()
    outcomes = dict(results.get(timeout=60) for _ in procs)
    done.set()
    reader.join()
    for p in procs:
        p.join(timeout=30)
        assert p.exitcode == 0

    assert outcomes == {w: [] for w in range(N_PROCS)}
    assert reader_errors == []
    assert raw_integrity(db_path) == ["ok"]
    assert parent_store.check() == []
    expected_keys = {
        (w, t, i) for w in range(N_PROCS) for t in range(N_THREADS) for i in range(N_PER_THREAD) if not is_deleted(i)
    }
    assert len(parent_store) == len(expected_keys) == N_PROCS * N_THREADS * N_PER_THREAD * 4 // 5
    seen = set()
    for summary in parent_store.list():
        back = parent_store.get(summary.id)
        key = (back.params["worker"], back.params["thread"], back.params["i"])
        expected = keyed_set(*key)
        expected.id, expected.created_at = back.id, back.created_at
        assert back == expected, key
        seen.add(key)
    assert seen == expected_keys


# --- 4. crash in the middle of a write -------------------------------------------------------
_KILLED_MID_TRANSACTION = """
import pathlib, sys, time
import numpy as np
from engine.storage import PatternSet, PatternStore

path, marker, operation, target = sys.argv[1:5]

class StallingStore(PatternStore):
    def _in_transaction_hook(self, op, set_id):
        pathlib.Path(marker).write_text(op + " " + set_id)  # tell the parent we are inside BEGIN ... COMMIT
        time.sleep(120)

store = StallingStore(path)
if operation == "save":
    # 16 MB of arrays: more than SQLite's page cache, so uncommitted pages spill into the WAL file
    store.save(PatternSet(id="half-written", kind="paper", channel="a1", c=1.0, j1_values=[0.87],
                          wavelet="sym5", arrays={"patterns": np.ones((2_000_000,))}))
else:
    store.delete(target)
raise SystemExit("the transaction was not interrupted")
"""


@pytest.mark.parametrize("operation", ["save", "delete"])
def test_crash_mid_transaction_keeps_previous_state(db_path: Path, tmp_path: Path, operation: str) -> None:
    store = PatternStore(db_path)
    before = [store.save(make_set(i, c=0.8 + 0.1 * i)) for i in range(5)]
    marker = tmp_path / "inside-transaction"
    child = subprocess.Popen(
        [sys.executable, "-c", _KILLED_MID_TRANSACTION, str(db_path), str(marker), operation, before[2].id],
        env=python_env(),
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 30
        while not marker.exists():
            assert child.poll() is None, child.communicate()[1]
            assert time.monotonic() < deadline, "the child never reached the transaction"
            time.sleep(0.01)
        assert len(store) == 5  # readers still see the committed state while the writer holds the lock
        if operation == "save":  # the uncommitted pages did reach the disk: recovery must discard them
            assert Path(f"{db_path}-wal").stat().st_size > 8_000_000
        os.kill(child.pid, signal.SIGKILL)
    finally:
        if child.poll() is None:
            child.kill()
        child.communicate()
    assert child.returncode == -signal.SIGKILL

    assert raw_integrity(db_path) == ["ok"]
    reopened = PatternStore(db_path)
    assert [s.id for s in reopened.list()] == [s.id for s in reversed(before)]
    for s in before:
        assert reopened.get(s.id) == s
    assert "half-written" not in reopened
    assert reopened.check() == []
    # the dead writer's lock is gone: the store is writable again at once
    after = PatternStore(db_path, busy_timeout=2.0).save(make_set(99))
    assert len(reopened) == 6 and reopened.get(after.id) == after
