"""Cost of each diagnosis in simulation-equivalents, on the records of committed blind runs (issue 54, *Measured*).

Every diagnosis's wall time is reported in seconds and in **simulation-equivalents** (sims): its
seconds divided by the time of one simulation measured in the same process, so that figures taken
on different machines compare. **One simulation** is one call of
``engine.simulation.simulate_batch([PlantParameters()])``: the nominal plant of MODEL.md, no
effect, no noise, on the protocol grid (2048 samples of 0.1 ms, the event at sample 48) with the
default solver (RK4 steps of at most a third of a sample, 33 us); a batch of one case runs the
serial kernel, on one core. Its time is the median of
:data:`SIM_CALLS` timed calls once the kernels are compiled (warm-up: three calls of one case and
one of two, which compiles the parallel kernel too), taken in each process after every process has
warmed up; it is timed again at the end (a check of the machine's load), and :data:`SIM_CALLS_EACH`
calls before every diagnosis are kept in the rows (``sim_s_before``).

The records are those of two committed blind runs, drawn again from their seeds into ``--work``
(nothing is read from ``out/`` or from another checkout):

* protocol 2, seed 229 (``docs/validation/v2-seed229``, 300 records, every case given the whole
  catalogue): ``single``, ``compound`` (a pair or a triple), ``held_back`` (an effect outside the
  catalogue) and ``clean``;
* protocol 1, seed 227 (``docs/validation/v1-seed227``, 200 records): ``left_out``, the records
  whose effect (with its same-physics twin) was taken out of the case's library and counts (it
  moves some channel by more than 3 noise standard deviations; expected answer ``unexplained``).

``left_out`` and ``held_back`` are the out-of-catalogue records. The cases of a kind are the first
``--per-kind`` of it in case-id order (for ``compound``, of the pairs and triples together): no
choice by outcome. Drawing takes about 8 min for protocol 2 (its absorption rule fits every
effect draw) and seconds for protocol 1, once: a ``--work`` directory that holds a run's cases
keeps them. The drawn answer keys are checked against the committed reports (kind, true effects
and their values, operating point); a mismatch is logged and stated in the output.

A verdict is right by :func:`engine.validation.score.correct` for protocol 2 (the named effect,
the exact set, ``unexplained``, ``no_gap``), and for a protocol-1 left-out record when it is
``unexplained`` (protocol 1's abstention). The committed run's own answer to each record is kept
in the rows (``blind``) for reference.

The diagnoses run one at a time, in worker processes of the same Python (this venv) with
``PYTHONPATH`` set to the code's tree alone: the working tree of this repository (uncommitted
changes included), or with ``--current REF`` a git worktree of that commit. ``--baseline REF``
diagnoses the same records with a worktree of REF too (``git worktree add --detach`` in a
temporary directory, removed at the end), in a second worker that measures its own simulation
time; the two alternate case by case (current first on even cases, the baseline first on odd
ones) so that they share the machine's load. Then the ratios current / baseline of the 50th and
90th percentiles, in seconds and in sims, and the median of the per-case ratios are printed, and
every case whose verdict (status, named effects, locus) differs, with both verdicts and whether
each is right. Each code's sims are in its own simulation: when the two simulators differ in
speed (a kernel change), a ratio in sims is the change of the diagnosis's cost relative to its own
simulator and the ratio in seconds its change on this machine (the output says so beyond
:data:`UNIT_TOLERANCE`); the simulations each diagnosis reports running (``n_simulations``) are
printed beside them. ``--threads N`` sets ``NUMBA_NUM_THREADS`` in the workers (default: unset, every
core, as the service runs one diagnosis at a time); the diagnosis's candidate fits use as many
threads.

Per kind and code: n, right, the 50th and 90th percentiles of the seconds and of the sims with
their order-statistic 95 % intervals (:func:`engine.validation.stats.quantile_interval`; for the
90th percentile n >= 36 is needed, fewer say so) and how many exceed the issue's target
(:data:`TARGET_P90_S` s at the 90th percentile; measured here, not enforced).

Examples (one record of each default kind against the commit three back, about 10 min on a busy
2-core machine; the issue's sample, every left-out record and 75 of the others, about 2.3 h on 2
idle cores with a baseline from before the kernel of 7eb96ea)::

    python bench/bench_diagnosis_cost.py --per-kind 1 --baseline HEAD~3 --json out/cost.json
    python bench/bench_diagnosis_cost.py --per-kind 75 --baseline REF --json out/cost-all.json

The result lines go to stdout, progress to the log (stderr); ``--json FILE`` holds every row and
the summary, rewritten after every case (an interrupted run keeps its rows).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

logger = logging.getLogger("bench_diagnosis_cost")

#: The repository holding this script.
REPO: Path = Path(__file__).resolve().parents[1]
#: Timed calls of one simulation for a process's unit (after warm-up).
SIM_CALLS: int = 51
#: Timed calls of one simulation before each diagnosis (a load check kept in the rows).
SIM_CALLS_EACH: int = 7
#: Relative difference of the two codes' simulation times beyond which the output says they differ.
UNIT_TOLERANCE: float = 0.10
#: The issue's target for the 90th percentile of every kind [s] (measured, not enforced).
TARGET_P90_S: float = 10.0
#: What one simulation is, as the output states it.
SIMULATION: str = (
    "one call of engine.simulation.simulate_batch([PlantParameters()]): the nominal plant, no effect, "
    "no noise, protocol grid (2048 samples of 0.1 ms), default solver (RK4 steps <= 33 us), serial kernel on one core"
)


@dataclass(frozen=True)
class Run:
    """A committed blind run whose records are drawn again from its seed.

    Attributes
    ----------
    name : str
        Its folder under ``docs/validation/`` and under ``--work``.
    protocol : int
        1 or 2.
    seed : int
        Seed of its case generator.
    n_cases : int
        Its number of cases.
    """

    name: str
    protocol: int
    seed: int
    n_cases: int

    @property
    def report(self) -> Path:
        """The committed report (its per-case rows are checked against the drawn key)."""
        return REPO / "docs" / "validation" / self.name / "report.json"


V2_SEED229 = Run("v2-seed229", 2, 229, 300)
V1_SEED227 = Run("v1-seed227", 1, 227, 200)

#: The kinds of this bench: the run whose records they are and the run's own kinds they take
#: (protocol 1's ``left_out`` only where it counts: expected ``unexplained``).
KINDS: dict[str, tuple[Run, tuple[str, ...]]] = {
    "single": (V2_SEED229, ("single",)),
    "compound": (V2_SEED229, ("pair", "triple")),
    "left_out": (V1_SEED227, ("left_out",)),
    "held_back": (V2_SEED229, ("held_back",)),
    "clean": (V2_SEED229, ("clean",)),
}
DEFAULT_KINDS = ("single", "compound", "left_out")


@dataclass(frozen=True)
class BenchCase:
    """One record to diagnose and what scores its answer.

    Attributes
    ----------
    uid : str
        ``<run>/<case_id>``.
    group : str
        Its kind in this bench (a key of :data:`KINDS`).
    kind : str
        Its kind in its run (``pair``, ``triple``, ``left_out``, ...).
    run : Run
        The run it belongs to.
    path : Path
        Its case file.
    record_key : str or None
        Key of the record in the case file (protocol 1: ``record``); None: the file is the record.
    library : tuple of str
        Names of the catalogue effects given to the diagnosis.
    truth : tuple of str
        The effects in the record.
    key : object
        Protocol 2: its :class:`engine.validation.key.KeyEntry`; protocol 1: None.
    blind : dict
        The committed run's answer (``status``, ``effects``, ``correct``), empty when the report has none.
    """

    uid: str
    group: str
    kind: str
    run: Run
    path: Path
    record_key: str | None
    library: tuple[str, ...]
    truth: tuple[str, ...]
    key: Any = None
    blind: dict[str, Any] = field(default_factory=dict)


# -- drawing and choosing the records (this process, the working tree's code) ----------------------


def draw_run(run: Run, work: Path) -> Path:
    """Draw ``run``'s cases and key into ``work/<run.name>`` unless they are there already; returns that folder."""
    out = work / run.name
    t0 = time.perf_counter()
    if run.protocol == 2:
        from engine.validation.layout import RunLayout
        from engine.validation.run import prepare_cases

        if not (out / "run.json").is_file():
            logger.info("drawing protocol 2 seed %d (%d cases; about 8 min) into %s", run.seed, run.n_cases, out)
        drawn = prepare_cases(RunLayout(out), run.n_cases, run.seed)
    else:
        from engine.atomic import write_json_atomic
        from engine.diagnosis.validation import generate_cases, prepare_run, write_cases
        from engine.run_manifest import MANIFEST, read_manifest

        drawn = prepare_run(out, run.n_cases, run.seed)
        if drawn:
            logger.info("drawing protocol 1 seed %d (%d cases) into %s", run.seed, run.n_cases, out)
            cases, key = generate_cases(run.n_cases, run.seed)
            write_cases(cases, key, out)
            manifest = read_manifest(out)
            assert manifest is not None  # prepare_run wrote it
            write_json_atomic(out / MANIFEST, {**manifest, "complete": True}, indent=1)
    logger.info("%s: %s (%.0f s)", run.name, "drawn" if drawn else "cases kept", time.perf_counter() - t0)
    return out


def _close(a: float | None, b: float | None, rel: float = 1e-3) -> bool:
    """Whether two numbers agree to ``rel`` (the committed reports round to 4 significant digits)."""
    if a is None or b is None:
        return a is None and b is None
    return abs(a - b) <= rel * max(abs(a), abs(b)) + 1e-15


def committed_answers(run: Run, folder: Path) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """The committed run's answer to each case, and the cases whose drawn truth differs from its report.

    Returns
    -------
    answers : dict
        By case id: ``status``, ``effects`` (names) and ``correct`` as the committed report has them.
    mismatches : list of str
        Case ids whose kind, true effects, their values or (protocol 2) operating point K differ
        between the drawn key and the committed report (and cases missing from either).
    """
    doc = json.loads(run.report.read_text())
    answers: dict[str, dict[str, Any]] = {}
    mismatches: list[str] = []
    if run.protocol == 2:
        from engine.validation.layout import RunLayout

        cols = doc["cases"]["columns"]
        rows = {r["case"]: r for r in (dict(zip(cols, x, strict=True)) for x in doc["cases"]["rows"])}
        for k in RunLayout(folder).read_key()[1]:
            r = rows.get(k.case_id)
            same = (
                r is not None
                and r["kind"] == k.kind
                and [t[0] for t in r["truth"]] == list(k.effect_names)
                and all(_close(t[1], e.value) for t, e in zip(r["truth"], k.effects, strict=True))
                and _close(r["K_mm"], 1e3 * k.K)
            )
            if not same:
                mismatches.append(k.case_id)
            if r is not None:
                answers[k.case_id] = {
                    "status": r["status"],
                    "effects": [e[0] for e in r["effects"]],
                    "correct": r["correct"],
                }
    else:
        rows = {r["case_id"]: r for r in doc["per_case"]}
        for k in json.loads((folder / "key" / "answer_key.json").read_text()):
            r = rows.get(k["case_id"])
            same = (
                r is not None
                and (r["kind"], r["effect"], r["expected"]) == (k["kind"], k["effect"], k["expected_status"])
                and _close(r["value"], k["value"], 1e-9)
            )
            if not same:
                mismatches.append(k["case_id"])
            if r is not None:
                answers[k["case_id"]] = {
                    "status": r["status"],
                    "effects": [r["named"]] if r["named"] else [],
                    "correct": r["status"] == r["expected"],
                }
    return answers, mismatches


def select_cases(kinds: Sequence[str], per_kind: int, folders: Mapping[str, Path]) -> list[BenchCase]:
    """The first ``per_kind`` cases of each kind in case-id order (kinds in the order given).

    Parameters
    ----------
    kinds : sequence of str
        Keys of :data:`KINDS`.
    per_kind : int
        Cases of each kind (fewer when the run holds fewer).
    folders : mapping of str to Path
        Each run's drawn folder by run name (:func:`draw_run`).
    """
    chosen: list[BenchCase] = []
    for group in kinds:
        run, run_kinds = KINDS[group]
        folder = folders[run.name]
        answers, _ = committed_answers(run, folder)
        picked: list[BenchCase] = []
        if run.protocol == 2:
            from engine.validation.layout import RunLayout

            layout = RunLayout(folder)
            manifest = layout.read_manifest() or {}
            for k in sorted(layout.read_key()[1], key=lambda k: k.case_id):
                if k.kind in run_kinds and len(picked) < per_kind:
                    picked.append(
                        BenchCase(
                            f"{run.name}/{k.case_id}",
                            group,
                            k.kind,
                            run,
                            layout.case_path(k.case_id),
                            None,
                            tuple(manifest["library"]),
                            k.effect_names,
                            k,
                            answers.get(k.case_id, {}),
                        )
                    )
        else:
            key = sorted(json.loads((folder / "key" / "answer_key.json").read_text()), key=lambda k: k["case_id"])
            for k in key:
                if k["kind"] in run_kinds and k["expected_status"] == "unexplained" and len(picked) < per_kind:
                    path = folder / "cases" / f"{k['case_id']}.json"
                    library = tuple(json.loads(path.read_text())["library"])
                    picked.append(
                        BenchCase(
                            f"{run.name}/{k['case_id']}",
                            group,
                            k["kind"],
                            run,
                            path,
                            "record",
                            library,
                            (k["effect"],),
                            None,
                            answers.get(k["case_id"], {}),
                        )
                    )
        if len(picked) < per_kind:
            logger.warning("%s: only %d cases of this kind in %s", group, len(picked), run.name)
        chosen.extend(picked)
    return chosen


# -- the worker: diagnoses with one code tree, in its own process ---------------------------------


def simulation_time(calls: int) -> dict[str, Any]:
    """Median wall time of ``calls`` simulations as :data:`SIMULATION` says [s], and the quartiles."""
    from engine.simulation import PlantParameters, simulate_batch

    plant = PlantParameters()
    times = []
    for _ in range(calls):
        t0 = time.perf_counter()
        simulate_batch([plant])
        times.append(time.perf_counter() - t0)
    q = statistics.quantiles(times, n=4) if len(times) > 1 else [times[0]] * 3
    return {"median_s": statistics.median(times), "q1_s": q[0], "q3_s": q[2], "calls": calls}


def _trimmed(result: Mapping[str, Any]) -> dict[str, Any]:
    """What the scorer reads of a diagnosis's result (:func:`engine.validation.score.answer_of`) and its cost."""
    gap = result.get("gap") or {}
    return {
        "verdict": result.get("verdict"),
        "gap": {side: {"rms_over_noise": (gap.get(side) or {}).get("rms_over_noise")} for side in ("before", "after")},
        "stages": result.get("stages", []),
        "n_simulations": result.get("n_simulations"),
        "seconds": result.get("seconds"),
    }


def serve(root: Path) -> int:
    """The worker's loop: diagnose the records asked for on stdin with the code of ``root``.

    Protocol: one JSON object per line each way. The worker first answers ``{"event": "ready",
    ...}`` (or ``{"fatal": ...}``) once the kernels are compiled; then per request ``{"op":
    "simulation", "calls": N}`` the simulation time (:func:`simulation_time`), ``{"op": "diagnose",
    "case", "path", "record_key", "library"}`` the diagnosis's wall time [s] and trimmed result, and
    ``{"op": "quit"}`` ends it. Anything else the code prints goes to stderr (file descriptor 1 is
    pointed at 2; the protocol keeps a copy of the original).
    """
    channel: IO[str] = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)

    def send(doc: Mapping[str, Any]) -> None:
        channel.write(json.dumps(doc) + "\n")

    import engine

    where = Path(engine.__file__).resolve()
    if not where.is_relative_to(root.resolve()):
        send({"fatal": f"engine imported from {where}, not from {root} (PYTHONPATH?)"})
        return 2
    import numba

    from engine.diagnosis import diagnose
    from engine.records import Record
    from engine.simulation import CATALOGUE, EffectLibrary, PlantParameters, simulate_batch

    t0 = time.perf_counter()
    for _ in range(3):
        simulate_batch([PlantParameters()])
    simulate_batch([PlantParameters(), PlantParameters()])
    send(
        {
            "event": "ready",
            "engine": str(where.parent),
            "numba_threads": int(numba.get_num_threads()),
            "cores": os.cpu_count(),
            "warm_up_s": time.perf_counter() - t0,
        }
    )
    for line in sys.stdin:
        msg = json.loads(line)
        if msg["op"] == "quit":
            break
        if msg["op"] == "simulation":
            send(simulation_time(int(msg.get("calls", SIM_CALLS))))
            continue
        doc = json.loads(Path(msg["path"]).read_text())
        record = Record.from_dict(doc[msg["record_key"]] if msg.get("record_key") else doc)
        library = EffectLibrary([CATALOGUE[n] for n in msg["library"]])
        before = simulation_time(SIM_CALLS_EACH)["median_s"]
        load = os.getloadavg()[0]
        error = None
        t0 = time.perf_counter()
        try:
            result = _trimmed(diagnose(record, library).to_dict(include_records=False))
        except Exception as exc:  # a failed diagnosis is a wrong answer, as in the validation runs
            logging.getLogger("bench_diagnosis_cost").exception("diagnosis of %s failed", msg["case"])
            result, error = {"verdict": {"status": "error", "effect": None, "effects": [], "locus": None}}, repr(exc)
        seconds = time.perf_counter() - t0
        send(
            {"case": msg["case"], "seconds": seconds, "sim_s_before": before, "load_1min": load}
            | {"result": result, "error": error}
        )
    return 0


class Worker:
    """A worker process (:func:`serve`) diagnosing with the code of one tree.

    Parameters
    ----------
    label : str
        ``current`` or ``baseline``.
    root : Path
        The code's tree (its ``engine`` package is imported: ``PYTHONPATH`` is set to it alone).
    threads : int
        ``NUMBA_NUM_THREADS`` in the worker; 0 leaves it unset (every core).
    log_level : str
        Level of the diagnosis's log in the worker (stderr).
    """

    def __init__(self, label: str, root: Path, threads: int, log_level: str) -> None:
        self.label = label
        self.root = root
        env = {**os.environ, "PYTHONPATH": str(root)}
        env.pop("NUMBA_NUM_THREADS", None)
        if threads:
            env["NUMBA_NUM_THREADS"] = str(threads)
        cmd = [sys.executable, str(Path(__file__).resolve()), "--serve", str(root), "--log-level", log_level]
        logger.info("%s: starting a worker on %s (imports, then compiles the kernels when not cached)", label, root)
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=root, env=env)
        self.ready = self._read()

    def _read(self) -> dict[str, Any]:
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the {self.label} worker ended (exit code {self.proc.wait()}); its log is above")
        doc: dict[str, Any] = json.loads(line)
        if "fatal" in doc:
            raise RuntimeError(f"the {self.label} worker: {doc['fatal']}")
        return doc

    def ask(self, msg: Mapping[str, Any]) -> dict[str, Any]:
        """Send one request and return the answer."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps(msg) + "\n")
        self.proc.stdin.flush()
        return self._read()

    def close(self) -> None:
        """Ask the worker to end; kill it when it does not within 30 s."""
        try:
            if self.proc.poll() is None:
                assert self.proc.stdin is not None
                self.proc.stdin.write(json.dumps({"op": "quit"}) + "\n")
                self.proc.stdin.close()
            self.proc.wait(timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait()


def _git(*args: str, cwd: Path = REPO) -> str:
    return subprocess.run(["git", "-C", str(cwd), *args], capture_output=True, text=True, check=True).stdout.strip()


@contextmanager
def worktree(ref: str) -> Iterator[tuple[Path, dict[str, Any]]]:
    """A detached git worktree of ``ref`` in a temporary directory, removed on exit; yields its path and version."""
    commit = _git("rev-parse", "--verify", f"{ref}^{{commit}}")
    tmp = Path(tempfile.mkdtemp(prefix="bench-diagnosis-cost-"))
    path = tmp / commit[:12]
    _git("worktree", "add", "--detach", "--quiet", str(path), commit)
    logger.info("worktree of %s (%s) at %s", ref, commit[:12], path)
    try:
        yield path, {"ref": ref, "commit": commit, "describe": _git("describe", "--always", "--tags", commit)}
    finally:
        try:
            _git("worktree", "remove", "--force", str(path))
        except subprocess.CalledProcessError as exc:
            logger.warning("could not remove the worktree %s: %s", path, exc.stderr.strip())
        shutil.rmtree(tmp, ignore_errors=True)


def working_tree_version() -> dict[str, Any]:
    """The version of this repository's working tree (uncommitted changes to tracked files count as dirty)."""
    dirty = bool(_git("status", "--porcelain", "--untracked-files=no"))
    return {"ref": "working tree", "commit": _git("rev-parse", "HEAD"), "dirty": dirty} | {
        "describe": _git("describe", "--always", "--tags", "--dirty")
    }


# -- scoring and summary (this process) --------------------------------------------------------------


def scored_row(case: BenchCase, code: str, order: int, unit_s: float, reply: Mapping[str, Any]) -> dict[str, Any]:
    """One diagnosis's row: the case, the code, its cost in seconds and sims, the answer and whether it is right."""
    from engine.validation.score import answer_of, correct

    result = dict(reply["result"])
    answer = answer_of(result)
    right = correct(case.key, answer) if case.run.protocol == 2 else answer.status == "unexplained"
    return {
        "case": case.uid,
        "group": case.group,
        "kind": case.kind,
        "protocol": case.run.protocol,
        "truth": list(case.truth),
        "code": code,
        "order": order,
        "seconds": reply["seconds"],
        "sims": reply["seconds"] / unit_s,
        "sim_s": unit_s,
        "sim_s_before": reply["sim_s_before"],
        "load_1min": reply["load_1min"],
        "status": answer.status,
        "effects": list(answer.names),
        "locus": answer.locus,
        "correct": bool(right),
        "n_simulations": result.get("n_simulations"),
        "stages": [[s["stage"], s["seconds"]] for s in result.get("stages") or []],
        "error": reply.get("error"),
        "blind": case.blind,
    }


def _estimates(values: Sequence[float]) -> dict[str, Any]:
    from engine.validation.stats import quantile_interval

    return {"p50": quantile_interval(values, 0.5).to_dict(), "p90": quantile_interval(values, 0.9).to_dict()}


def _median(values: Sequence[Any]) -> float | None:
    """Median of the numbers among ``values`` (None when there are none)."""
    xs = [float(v) for v in values if isinstance(v, (int, float))]
    return statistics.median(xs) if xs else None


def summarise(rows: Sequence[Mapping[str, Any]], groups: Sequence[str], codes: Sequence[str]) -> dict[str, Any]:
    """Per group and code: n, right, the 50th and 90th percentiles of the seconds and the sims; ratios of the codes.

    Parameters
    ----------
    rows : sequence of mapping
        Rows of :func:`scored_row` (``case``, ``group``, ``code``, ``seconds``, ``sims``, ``correct``).
    groups : sequence of str
        The groups to summarise, in order (those without rows are left out).
    codes : sequence of str
        The codes, the first the one under test (``current``), the second (if any) its baseline.

    Returns
    -------
    dict
        ``summary[group][code]``: ``n``, ``right``, ``seconds`` and ``sims`` (each ``p50`` and
        ``p90`` as :meth:`engine.validation.stats.QuantileEstimate.to_dict`), ``over_target``
        (seconds over :data:`TARGET_P90_S`), ``n_simulations_p50`` (median of the simulations the
        diagnoses report running, ``n_simulations``; None without); with two codes ``summary[group]["ratio"]``:
        first / second of ``p50_s``, ``p90_s``, ``p50_sims``, ``p90_sims``, and the medians of the
        per-case ratios (``per_case_median_s``, ``per_case_median_sims``) over the cases both diagnosed.
    """
    out: dict[str, Any] = {}
    for group in groups:
        mine = [r for r in rows if r["group"] == group]
        if not mine:
            continue
        out[group] = {}
        for code in codes:
            theirs = [r for r in mine if r["code"] == code]
            if not theirs:
                continue
            seconds = [float(r["seconds"]) for r in theirs]
            out[group][code] = {
                "n": len(theirs),
                "right": sum(bool(r["correct"]) for r in theirs),
                "seconds": _estimates(seconds),
                "sims": _estimates([float(r["sims"]) for r in theirs]),
                "over_target": sum(s > TARGET_P90_S for s in seconds),
                "n_simulations_p50": _median([r.get("n_simulations") for r in theirs]),
            }
        if len(codes) == 2 and all(c in out[group] for c in codes):
            a, b = (out[group][c] for c in codes)
            ratio: dict[str, float | None] = {}
            for unit, short in (("seconds", "s"), ("sims", "sims")):
                for q in ("p50", "p90"):
                    x, y = a[unit][q]["value"], b[unit][q]["value"]
                    ratio[f"{q}_{short}"] = x / y if x is not None and y else None
                by_case = {c: {r["case"]: float(r[unit]) for r in mine if r["code"] == c} for c in codes}
                both = [
                    by_case[codes[0]][k] / by_case[codes[1]][k] for k in by_case[codes[0]] if by_case[codes[1]].get(k)
                ]
                ratio[f"per_case_median_{short}"] = statistics.median(both) if both else None
            out[group]["ratio"] = ratio
    return out


def verdict_text(row: Mapping[str, Any]) -> str:
    """E.g. ``explained load_inertia``, ``explained a+b``, ``unexplained at motor_shaft``, ``no_gap``."""
    if row["effects"]:
        return f"{row['status']} {'+'.join(row['effects'])}"
    return f"{row['status']} at {row['locus']}" if row["status"] == "unexplained" else str(row["status"])


def _verdict(row: Mapping[str, Any]) -> tuple[str, tuple[str, ...], str | None]:
    return str(row["status"]), tuple(row["effects"]), row["locus"]


def verdict_changes(rows: Sequence[Mapping[str, Any]], codes: Sequence[str]) -> list[dict[str, Any]]:
    """Every case whose verdict (status, named effects in order, locus) differs between the two codes.

    Returns
    -------
    list of dict
        ``case``, ``group``, ``kind``, ``truth``, then per code its verdict (:func:`verdict_text`)
        and whether it is right, and ``change``: ``better`` (wrong to right), ``worse`` (right to
        wrong) or ``same score`` (both right or both wrong), reading from the second code to the first.
    """
    if len(codes) != 2:
        return []
    by = {(r["case"], r["code"]): r for r in rows}
    changes = []
    for case in dict.fromkeys(r["case"] for r in rows):
        new, old = by.get((case, codes[0])), by.get((case, codes[1]))
        if new is None or old is None or _verdict(new) == _verdict(old):
            continue
        change = "same score" if new["correct"] == old["correct"] else "better" if new["correct"] else "worse"
        changes.append(
            {"case": case, "group": new["group"], "kind": new["kind"], "truth": new["truth"], "change": change}
            | {f"{c}_verdict": verdict_text(r) for c, r in zip(codes, (new, old), strict=True)}
            | {f"{c}_correct": r["correct"] for c, r in zip(codes, (new, old), strict=True)}
        )
    return changes


def _q(est: Mapping[str, Any], fmt: str, unit: str) -> str:
    """``value unit [low, high]``; the value alone when the sample is too small for an interval."""
    if est["value"] is None:
        return "n/a"
    if est["low"] is None:
        return f"{est['value']:{fmt}} {unit}"
    return f"{est['value']:{fmt}} {unit} [{est['low']:{fmt}}, {est['high']:{fmt}}]"


def _ratio(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.2f}x"


def summary_lines(summary: Mapping[str, Any], codes: Sequence[str]) -> list[str]:
    """The summary in words: per group one line per code, and one of the ratios of the codes."""
    lines = []
    for group, by_code in summary.items():
        for code in codes:
            s = by_code.get(code)
            if s is None:
                continue
            sec, sims = s["seconds"], s["sims"]
            missing = [q for q in ("p50", "p90") if sec[q]["low"] is None]
            p90 = sec["p90"]["value"]
            lines.append(
                f"{group:<9} {code:<8} n={s['n']:<3} right {s['right']}/{s['n']}  "
                f"p50 {_q(sec['p50'], '.1f', 's')} = {_q(sims['p50'], '.0f', 'sims')}  "
                f"p90 {_q(sec['p90'], '.1f', 's')} = {_q(sims['p90'], '.0f', 'sims')}  "
                f"p90 <= {TARGET_P90_S:g} s: {'yes' if p90 <= TARGET_P90_S else 'no'} (point; {s['over_target']} over)"
                + (f"  median simulations run {s['n_simulations_p50']:.0f}" if s.get("n_simulations_p50") else "")
                + (f"  (n too small for a 95 % interval of {' and '.join(missing)})" if missing else "")
            )
        r = by_code.get("ratio")
        if r:
            lines.append(
                f"{group:<9} {codes[0]}/{codes[1]}: seconds p50 {_ratio(r['p50_s'])} p90 {_ratio(r['p90_s'])} "
                f"(median per case {_ratio(r['per_case_median_s'])}); sims p50 {_ratio(r['p50_sims'])} "
                f"p90 {_ratio(r['p90_sims'])} (median per case {_ratio(r['per_case_median_sims'])})"
            )
    return lines


# -- the bench -----------------------------------------------------------------------------------------


def _write(path: Path | None, doc: Mapping[str, Any]) -> None:
    if path is not None:
        from engine.atomic import write_text_atomic

        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(path, json.dumps(doc, indent=1) + "\n")


def _emit(line: str) -> None:
    """One result line on stdout."""
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def bench(args: argparse.Namespace, kinds: list[str]) -> int:
    """Draw, choose, diagnose with each code one at a time, summarise (see the module notes)."""
    runs = {KINDS[k][0] for k in kinds}
    folders = {run.name: draw_run(run, args.work) for run in sorted(runs, key=lambda r: r.name)}
    checks = {}
    for run in runs:
        _, mismatches = committed_answers(run, folders[run.name])
        checks[run.name] = mismatches
        if mismatches:
            logger.warning(
                "%s: %d drawn cases differ from the committed report (e.g. %s): not the committed run's records",
                run.name,
                len(mismatches),
                mismatches[0],
            )
    cases = select_cases(kinds, args.per_kind, folders)
    codes = ["current"] + (["baseline"] if args.baseline else [])
    meta: dict[str, Any] = {
        "kinds": kinds,
        "per_kind": args.per_kind,
        "choice": "the first per_kind cases of each kind in case-id order",
        "cases": {k: [c.uid for c in cases if c.group == k] for k in kinds},
        "runs": {
            r.name: {
                "protocol": r.protocol,
                "seed": r.seed,
                "n_cases": r.n_cases,
                "matches_committed_report": not checks[r.name],
            }
            for r in runs
        },
        "simulation": SIMULATION,
        "threads_asked": args.threads or None,
        "load_average_start": os.getloadavg(),
        "target_p90_s": TARGET_P90_S,
    }
    _emit(
        f"diagnosis cost (issue 54): {len(cases)} records, one diagnosis at a time, "
        f"numba threads: {args.threads if args.threads else 'NUMBA_NUM_THREADS unset (every core)'}, "
        f"{os.cpu_count()} cores, load average at start {os.getloadavg()[0]:.2f}"
    )
    for k in kinds:
        run, run_kinds = KINDS[k]
        ids = ", ".join(c.uid.split("/")[1] for c in cases if c.group == k)
        which = "/".join(run_kinds) + (" counted (expected unexplained)" if run.protocol == 1 else "")
        _emit(f"  {k}: the first {args.per_kind} {which} of protocol {run.protocol} seed {run.seed} in id order: {ids}")
    for name, mismatches in checks.items():
        _emit(
            f"  {name}: drawn again from its seed; "
            + (
                "kinds, true effects, values and operating points as in the committed report"
                if not mismatches
                else f"{len(mismatches)} cases DIFFER from the committed report ({', '.join(mismatches[:5])})"
            )
        )
    _emit(f"  one simulation = {SIMULATION}; median of {SIM_CALLS} calls after warm-up, in each worker")

    rows: list[dict[str, Any]] = []
    doc: dict[str, Any] = {"meta": meta, "rows": rows}
    with ExitStack() as stack:
        roots: dict[str, Path] = {}
        versions: dict[str, dict[str, Any]] = {}
        if args.current:
            roots["current"], versions["current"] = stack.enter_context(worktree(args.current))
        else:
            roots["current"], versions["current"] = REPO, working_tree_version()
        if args.baseline:
            roots["baseline"], versions["baseline"] = stack.enter_context(worktree(args.baseline))
        workers: dict[str, Worker] = {}
        for code in codes:
            workers[code] = Worker(code, roots[code], args.threads, args.log_level)
            stack.callback(workers[code].close)
        units = {code: workers[code].ask({"op": "simulation", "calls": SIM_CALLS}) for code in codes}
        meta["codes"] = {
            code: versions[code] | {"worker": workers[code].ready, "simulation_start": units[code]} for code in codes
        }
        for code in codes:
            v, w, u = versions[code], workers[code].ready, units[code]
            _emit(
                f"  {code}: {v['describe']} ({v['ref']}), engine from {w['engine']}, "
                f"numba threads {w['numba_threads']}, "
                f"one simulation {1e3 * u['median_s']:.3f} ms [quartiles {1e3 * u['q1_s']:.3f}, {1e3 * u['q3_s']:.3f}]"
            )
        if len(codes) == 2:
            unit_ratio = units[codes[0]]["median_s"] / units[codes[1]]["median_s"]
            if abs(unit_ratio - 1.0) > UNIT_TOLERANCE:
                _emit(
                    f"  the two codes' simulations differ ({codes[0]}/{codes[1]} {unit_ratio:.2f}x): each code's sims "
                    "are in its own simulation, so a ratio in sims is the change of the diagnosis's cost relative "
                    "to its simulator, and the ratio in seconds the change of its time on this machine"
                )
        t_start = time.perf_counter()
        for i, case in enumerate(cases):
            order = codes if i % 2 == 0 else codes[::-1]
            now = []
            for position, code in enumerate(order, start=1):
                msg = {"op": "diagnose", "case": case.uid, "path": str(case.path), "record_key": case.record_key}
                reply = workers[code].ask(msg | {"library": list(case.library)})
                row = scored_row(case, code, position, units[code]["median_s"], reply)
                rows.append(row)
                now.append(row)
                logger.info(
                    "%d/%d %s %s: %.1f s = %.0f sims, %s (%s); %.0f s so far",
                    i + 1,
                    len(cases),
                    case.uid,
                    code,
                    row["seconds"],
                    row["sims"],
                    verdict_text(row),
                    "right" if row["correct"] else "wrong",
                    time.perf_counter() - t_start,
                )
            _emit(
                f"{case.uid} {case.group} ({case.kind}: {'+'.join(case.truth) or 'none'}): "
                + " | ".join(
                    f"{r['code']} {r['seconds']:.1f} s = {r['sims']:.0f} sims ({r['n_simulations']} run), "
                    f"{'right' if r['correct'] else 'WRONG'}, {verdict_text(r)}"
                    for r in sorted(now, key=lambda r: codes.index(r["code"]))
                )
            )
            _write(args.json, doc)
        for code in codes:
            end = workers[code].ask({"op": "simulation", "calls": SIM_CALLS})
            meta["codes"][code]["simulation_end"] = end
            _emit(
                f"  {code}: one simulation at the end {1e3 * end['median_s']:.3f} ms "
                f"({end['median_s'] / units[code]['median_s']:.2f} x the start's, the unit used)"
            )
    meta["load_average_end"] = os.getloadavg()
    summary = summarise(rows, kinds, codes)
    changes = verdict_changes(rows, codes)
    doc |= {"summary": summary, "verdict_changes": changes}
    for line in summary_lines(summary, codes):
        _emit(line)
    if args.baseline:
        _emit(f"verdicts that differ between current and baseline: {len(changes) or 'none'}")
        for c in changes:
            _emit(
                f"  {c['case']} {c['group']} ({c['kind']}: {'+'.join(c['truth']) or 'none'}): {c['change']}: "
                f"current {c['current_verdict']} ({'right' if c['current_correct'] else 'wrong'}), "
                f"baseline {c['baseline_verdict']} ({'right' if c['baseline_correct'] else 'wrong'})"
            )
    same_as_blind = [r for r in rows if r["code"] == "current" and r["blind"]]
    agree = sum(r["status"] == r["blind"]["status"] and r["effects"] == r["blind"]["effects"] for r in same_as_blind)
    _emit(
        "current's verdicts equal to the committed blind run's (status and named effects): "
        f"{agree}/{len(same_as_blind)}"
    )
    _write(args.json, doc)
    if args.json:
        _emit(f"rows and summary: {args.json}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--kinds",
        default=",".join(DEFAULT_KINDS),
        help=f"kinds, comma-separated, of {', '.join(KINDS)} (default {','.join(DEFAULT_KINDS)})",
    )
    ap.add_argument(
        "--per-kind", type=int, default=5, help="records of each kind, the first in case-id order (default 5)"
    )
    ap.add_argument(
        "--baseline", metavar="REF", help="also diagnose with this commit's code (a git worktree), alternating"
    )
    ap.add_argument("--current", metavar="REF", help="the code under test from this commit (default: the working tree)")
    ap.add_argument(
        "--threads", type=int, default=0, help="NUMBA_NUM_THREADS of the workers (default: unset, every core)"
    )
    ap.add_argument(
        "--work",
        type=Path,
        default=REPO / "out" / "bench-diagnosis-cost",
        help="where the runs' records are drawn (kept for the next call; default out/bench-diagnosis-cost)",
    )
    ap.add_argument("--json", type=Path, help="write every row and the summary here")
    ap.add_argument(
        "--log-level", default="WARNING", help="level of the diagnosis's log in the workers (default WARNING)"
    )
    ap.add_argument("--serve", type=Path, help=argparse.SUPPRESS)  # the worker (serve())
    args = ap.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)
    if args.serve is not None:
        return serve(args.serve)
    logger.setLevel(logging.INFO)
    kinds = [k for k in args.kinds.split(",") if k]
    unknown = [k for k in kinds if k not in KINDS]
    if unknown or not kinds:
        ap.error(f"--kinds: unknown {', '.join(unknown)} (known: {', '.join(KINDS)})")
    if args.per_kind < 1:
        ap.error("--per-kind must be at least 1")
    try:
        return bench(args, kinds)
    except FileExistsError as exc:  # --work holds another run under a run's name
        ap.error(f"--work {args.work}: {exc}")


if __name__ == "__main__":
    raise SystemExit(main())
