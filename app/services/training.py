"""Training one pattern set for the service: validate everything first, then let the engine train, then store.

The orchestration (the paper's grid at one c -> simulate -> fit -> ``PatternSet``)
is the engine's :func:`engine.identification.training.train_pattern_set`; this
module validates the request before a job is queued (so that a job can only fail
in the simulation or the fit), simulates the validated cases and saves the set
under the id announced to the client. A training job saves its set in the transaction
that marks the job ``done`` (:class:`app.jobs.JobResult`), and a retry of a job whose set is
already stored does not train again (:func:`stored_result`).
"""

from __future__ import annotations

import functools
import sqlite3
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.jobs import JobKind, JobResult, ProgressFn
from app.services import simulation
from app.services.errors import InvalidInputError
from app.services.patterns import check_identifier
from engine.constants import J1_GRID, K_GRID
from engine.identification import training as engine_training
from engine.identification.training import DEFAULT_KIND
from engine.simulation import Case
from engine.simulation.drive import DriveDescription
from engine.simulation.simulator import DEFAULT_SOLVER
from engine.storage import PatternSet, PatternStore


def _no_progress(fraction: float, stage: str) -> None:
    """Default progress callback: ignore."""


@dataclass(frozen=True)
class TrainingSpec:
    """What to train: one pattern set of ``kind`` on ``channel`` for the group ``c``.

    ``params`` are the identifier's hyper-parameters by name (e.g. the paper kind's
    ``learning_rate``, ``delta1``, ``max_epochs``); missing ones take the identifier's
    defaults. ``effects`` (catalogue name -> value) are applied to every training case. ``drive``: the
    drive description the set is trained for (default MODEL.md's reference plant); it is stored with the set,
    which then identifies only records of that drive.
    """

    channel: str
    c: float
    J1_values: tuple[float, ...] = J1_GRID
    kind: str = DEFAULT_KIND
    params: Mapping[str, Any] = field(default_factory=dict)
    effects: Mapping[str, float] = field(default_factory=dict)
    drive: DriveDescription | None = None

    def cases(self) -> list[Case]:
        """The training cases with the effects applied, validated (6 widths x J1 values, width-major).

        Raises ``ParameterError`` / ``UnknownEffectError`` without simulating anything.
        """
        if not self.J1_values:
            raise InvalidInputError("J1_values is empty; give at least one inertia J1 [kg m^2]")
        if len(set(self.J1_values)) != len(self.J1_values):
            raise InvalidInputError(f"J1_values {list(self.J1_values)} repeat a value; give distinct inertias")
        grid = engine_training.training_cases(self.c, tuple(self.J1_values), self.drive)
        return simulation.prepare(grid, [self.effects] * len(grid))


def default_j1_values(drive: DriveDescription | None) -> tuple[float, ...]:
    """The training inertias when a request gives none [kg m^2]: the paper's grid, scaled to the drive's nominal J1."""
    return J1_GRID if drive is None else drive.j1_grid()


def check(spec: TrainingSpec) -> None:
    """Validate everything a training job needs before it is queued (cheap: nothing is simulated)."""
    spec.cases()
    check_identifier(spec.kind, spec.channel, dict(spec.params))


def compute_pattern_set(spec: TrainingSpec, progress: ProgressFn = _no_progress) -> PatternSet:
    """Simulate the training cases and let the engine fit and package the identifier (not stored)."""
    cases = spec.cases()
    progress(
        0.02,
        f"simulating {len(cases)} cases ({len(K_GRID)} widths x {len(spec.J1_values)} J1 values) at c = {spec.c:g}",
    )
    grid = simulation.run(cases, solver=DEFAULT_SOLVER if spec.drive is None else spec.drive.solver())
    return engine_training.train_pattern_set(
        spec.channel,
        spec.c,
        kind=spec.kind,
        J1_values=tuple(spec.J1_values),
        params=dict(spec.params),
        effects=dict(spec.effects),
        grid=grid,
        progress=progress,
        drive=spec.drive,
    )


def train_pattern_set(
    spec: TrainingSpec,
    store: PatternStore,
    *,
    set_id: str | None = None,
    progress: ProgressFn = _no_progress,
    cluster: Any = None,
    save: bool = True,
) -> PatternSet:
    """Train the pattern set (here, or on the Dask cluster of ``cluster``), save it; return it as stored.

    On a cluster the job's progress shows its stage (sent, running there, saving); the fraction
    moves only when the result is back (the worker reports no finer progress).

    Parameters
    ----------
    store : PatternStore
        Where to save it.
    save : bool
        False: return it unsaved, with ``id`` = ``set_id`` (a job saves it in the transaction that marks the
        job done: :func:`run_job`).
    """
    if cluster is None:
        pattern_set = compute_pattern_set(spec, progress)
    else:
        from engine.distributed import run_single_threaded

        progress(0.02, f"sent to the Dask cluster at {cluster.scheduler.address}")
        future = cluster.submit(run_single_threaded, compute_pattern_set, spec, key=f"train-{set_id or 'set'}")
        progress(0.05, "training on the Dask cluster")
        pattern_set = future.result()
    pattern_set.id = set_id
    if not save:
        progress(0.99, "storing the pattern set")
        return pattern_set
    saved = store.save(pattern_set)
    progress(1.0, "done")
    return saved


#: The training job's kind.
TRAIN_JOB = "train_pattern_set"


def job_spec(spec: TrainingSpec, set_id: str) -> dict[str, Any]:
    """The job's stored spec (JSON): what to train and the id announced for the set."""
    return {
        "pattern_set_id": set_id,
        "channel": spec.channel,
        "c": spec.c,
        "J1_values": list(spec.J1_values),
        "kind": spec.kind,
        "params": dict(spec.params),
        "effects": dict(spec.effects),
        "drive": None if spec.drive is None else spec.drive.to_dict(),
    }


def _spec_of(stored: dict[str, Any]) -> TrainingSpec:
    drive = stored.get("drive")  # absent from the specs of jobs queued before drive descriptions
    return TrainingSpec(
        channel=stored["channel"],
        c=float(stored["c"]),
        J1_values=tuple(float(v) for v in stored["J1_values"]),
        kind=stored["kind"],
        params=dict(stored["params"]),
        effects={k: float(v) for k, v in stored["effects"].items()},
        drive=None if drive is None else DriveDescription.from_mapping(drive),
    )


def _save(store: PatternStore, pattern_set: PatternSet, conn: sqlite3.Connection) -> None:
    store.save(pattern_set, conn=conn)


def _result(store: PatternStore, pattern_set: PatternSet) -> JobResult:
    """The job's result: the set, saved in the transaction that marks the job done."""
    return JobResult({"pattern_set_id": pattern_set.id}, write=functools.partial(_save, store, pattern_set))


def run_job(db_path: Path, stored: dict[str, Any], progress: ProgressFn) -> JobResult:
    """A training job in a worker process: train the set; it is stored under the announced id with the job's end."""
    store = PatternStore(db_path)
    pattern_set = train_pattern_set(
        _spec_of(stored), store, set_id=stored["pattern_set_id"], progress=progress, save=False
    )
    return _result(store, pattern_set)


def stored_result(conn: sqlite3.Connection, stored: dict[str, Any]) -> dict[str, Any] | None:
    """The job's meta if the set of the job's spec ``stored`` is already stored (its retry then trains nothing)."""
    set_id = stored.get("pattern_set_id")
    if set_id is None or conn.execute("SELECT 1 FROM pattern_sets WHERE id = ?", (set_id,)).fetchone() is None:
        return None
    return {"pattern_set_id": set_id}


def job_kind(store: PatternStore, cluster: Any = None, runs_in: str = "process") -> JobKind:
    """Training as a job kind: in a worker process (``runs_in="process"``, the default), or on a thread of the
    service (``"thread"``; always so with a Dask ``cluster``, where the thread only waits for it)."""
    if cluster is None and runs_in == "process":
        return JobKind(TRAIN_JOB, "process", run_job, pool="training", stored=stored_result)

    def run(stored: dict[str, Any], progress: ProgressFn) -> JobResult:
        pattern_set = train_pattern_set(
            _spec_of(stored), store, set_id=stored["pattern_set_id"], progress=progress, cluster=cluster, save=False
        )
        return _result(store, pattern_set)

    return JobKind(TRAIN_JOB, "thread", run, stored=stored_result)
