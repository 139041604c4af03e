"""Benchmark: the peak memory of reading and diagnosing a record, against the record's length (issue 54).

    .venv/bin/python bench/bench_memory.py [--lengths 1e4,1e5,1e6,1e7] [--diagnose-up-to 1e7] [--data DIR]

A long capture as a bench writes it: one backlash test (K = 6.8 mm, J1 = 0.85 kg m^2, a load 30 % heavier
than the model's, ``load_inertia`` = 1.3), rendered by the simulator from before the motor is switched on to
0.5 s after the event, inside a record of ``L`` samples of 0.1 ms: a quarter of the rest before it (the
drive at rest: zeros) and three quarters after it (the drive coasting: the last sample held), all of it
with white noise at 40 dB of each channel over the test window; a CSV with a time column ``t`` [s] (12
significant digits) and the five channels (9 significant digits), no event index (the reader locates it).
The files are written once into ``--data`` (a temporary directory by default; 1e7 samples is about 1 GB).

Each length is measured in fresh processes (``--child``), so that nothing one leaves behind counts for the
next:

* ``read``: the CLI's reading of the file (:func:`app.records_io.read_record`, what ``backlash diagnose
  rec.csv`` does), then ``diagnose``: the CLI's diagnosis of it (:func:`app.services.diagnosis.run` with the
  one effect ``load_inertia``: calibration, the candidate, identification before and after; the cheapest
  full diagnosis), up to ``--diagnose-up-to`` samples;
* ``api``: the service's reading of the same CSV as a request body (:func:`app.services.diagnosis_requests.parse`,
  what ``POST /v1/diagnose`` and a diagnosis job do with ``text/csv``), the body already in memory;
* ``arrays``: the engine's boundary (:func:`engine.records.record_from_data`) on channels already parsed into
  lists of floats (what a JSON body becomes; the JSON parse itself is not counted), up to the engine's cap
  :data:`engine.records.limits.MAX_SAMPLES`.

Two figures per step, each the peak above what the process held when the step began (after the imports
and a warm-up simulation that loads the compiled kernels; for the diagnosis, with the read record held):
the peak of the Python and numpy allocations (``tracemalloc``), and the peak resident set (Linux: the peak
reset through ``/proc/self/clear_refs`` before the step, ``VmHWM`` - ``VmRSS``; elsewhere the growth of
``ru_maxrss``), in a second process without ``tracemalloc``, whose own bookkeeping would count. The
resident set also counts what ``tracemalloc`` does not see (numba's arrays, the allocator's fragmentation).
``record held`` is what the read record keeps once read. Each figure is also printed as a ratio
against the shortest record (``--lengths``' first, measured in the same run). Progress goes to the log
(stderr); the table to stdout. Memory is measured here, never in tests with timings.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

logger = logging.getLogger("bench_memory")

#: The sample interval of every record [s].
SAMPLE_INTERVAL = 1e-4
#: The effect of the test's plant and the one candidate the diagnosis fits.
EFFECT = "load_inertia"
#: Rows written per block when a record file is made.
BLOCK = 100_000
MB = 1e6


def make_record(path: Path, n: int, seed: int = 1) -> int:
    """Write a CSV record of ``n`` samples (see the module notes); return the event's sample index."""
    from engine.records import SampleGrid
    from engine.simulation import PlantParameters, simulate
    from engine.simulation.noise import noise_std

    grid = SampleGrid.around_event(SAMPLE_INTERVAL, 0.05, 0.5)
    if n < grid.n_samples:
        raise ValueError(f"a record needs at least {grid.n_samples} samples here, got {n}")
    sim = simulate(PlantParameters(K=0.0068, J1=0.85), {EFFECT: 1.3}, grid=grid)
    names = list(sim.channels)
    core = np.stack([sim.channels[c] for c in names], axis=1)
    std = np.array([noise_std(sim.channels[c][grid.window()], 40.0)[0] for c in names])
    before = (n - grid.n_samples) // 4
    after = n - grid.n_samples - before
    rng = np.random.default_rng(seed)
    row = 0
    with path.open("w", encoding="utf-8") as f:
        f.write(",".join(["t", *names]) + "\n")

        def emit(block: np.ndarray) -> None:
            nonlocal row
            noisy = block + rng.standard_normal(block.shape) * std
            t = (row + np.arange(block.shape[0])) * SAMPLE_INTERVAL
            np.savetxt(f, np.column_stack([t, noisy]), fmt=["%.12g"] + ["%.9g"] * len(names), delimiter=",")
            row += block.shape[0]

        for k in range(0, before, BLOCK):
            emit(np.zeros((min(BLOCK, before - k), len(names))))
        emit(core)
        for k in range(0, after, BLOCK):
            emit(np.tile(core[-1], (min(BLOCK, after - k), 1)))
    return before + grid.event_index


# -- what a child process measures ------------------------------------------------------------------------------


def _warm_up() -> None:
    """Load the compiled kernels (numba's cache) before anything is measured."""
    from engine.simulation import PlantParameters, simulate

    simulate(PlantParameters())


def _resident() -> tuple[int, int] | None:
    """The process's resident set and its peak since the last :func:`_reset_peak` [bytes] (Linux), else None."""
    try:
        fields = dict(line.split(":", 1) for line in Path("/proc/self/status").read_text().splitlines() if ":" in line)
        return int(fields["VmRSS"].split()[0]) * 1024, int(fields["VmHWM"].split()[0]) * 1024
    except (OSError, KeyError, ValueError):
        return None


def _reset_peak() -> bool:
    """Reset the peak resident set (Linux >= 4.0: ``/proc/self/clear_refs``); whether it could."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return False
    return True


def _step(name: str, fn: Callable[[], Any], traced: bool, out: dict[str, Any]) -> Any:
    """Run ``fn``; put in ``out`` its peak above what was held before it [MB]: the traced allocations' or the
    resident set's (the peak resident set reset first where Linux allows, else the growth of ``ru_maxrss``)."""
    held = tracemalloc.get_traced_memory()[0] if traced else 0
    if traced:
        tracemalloc.reset_peak()
    reset = not traced and _reset_peak()
    rss0 = _resident() if reset else None
    maxrss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t0 = time.perf_counter()
    try:
        value = fn()
    except ValueError as exc:  # a refused record (RecordError is a ValueError): what the refusal cost
        value = None
        out[f"{name}_refused"] = str(exc)[:300]
    out[f"{name}_seconds"] = time.perf_counter() - t0
    if traced:
        out[f"{name}_peak_mb"] = (tracemalloc.get_traced_memory()[1] - held) / MB
        out[f"{name}_held_mb"] = (tracemalloc.get_traced_memory()[0] - held) / MB
    else:
        rss1 = _resident() if rss0 is not None else None
        if rss0 is not None and rss1 is not None:
            out[f"{name}_rss_mb"] = (rss1[1] - rss0[0]) / MB
        else:
            out[f"{name}_rss_mb"] = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - maxrss0) / MB
    return value


def child(mode: str, path: Path, traced: bool, diagnose: bool) -> dict[str, Any]:
    """Measure one mode on one record file in this (fresh) process."""
    _warm_up()
    out: dict[str, Any] = {}
    if mode == "read":
        from app.records_io import read_record
        from app.services import diagnosis

        if traced:
            tracemalloc.start()
        record = _step("read", lambda: read_record(path), traced, out)
        if record is not None:
            out["event_index"] = record.origin.first + record.event_index  # in the file (the record may be an excerpt)
            if diagnose:
                result = _step("diagnose", lambda: diagnosis.run(record, [EFFECT]), traced, out)
                out["verdict"] = f"{result.verdict.status} {result.verdict.effect}"
                out["K_mm"] = round(result.width.K * 1e3, 4) if result.width is not None else None
    elif mode == "api":
        from app.services.diagnosis_requests import DiagnosisRequest, parse

        body = path.read_bytes()
        if traced:
            tracemalloc.start()
        _step("api", lambda: parse(DiagnosisRequest("csv", body, {})), traced, out)
    elif mode == "arrays":
        from engine.records import record_from_data

        table = np.loadtxt(path, delimiter=",", skiprows=1)
        header = path.open(encoding="utf-8").readline().strip().split(",")
        channels = {name: table[:, j].tolist() for j, name in enumerate(header) if name != "t"}
        time_column = table[:, 0].tolist()
        del table
        if traced:
            tracemalloc.start()
        _step("arrays", lambda: record_from_data(channels, time=time_column), traced, out)
    else:
        raise ValueError(f"unknown mode {mode!r}")
    return out


def _run_child(mode: str, path: Path, traced: bool, diagnose: bool) -> dict[str, Any]:
    cmd = [sys.executable, __file__, "--child", mode, "--path", str(path)]
    cmd += ["--traced"] if traced else []
    cmd += ["--with-diagnosis"] if diagnose else []
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


# -- the run --------------------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    p.add_argument("--lengths", default="1e4,1e5,1e6,1e7", help="record lengths [samples], the first the baseline")
    p.add_argument("--diagnose-up-to", type=float, default=1e7, help="diagnose records up to this many samples")
    p.add_argument("--modes", default="read,api,arrays", help="what to measure (read includes the diagnosis)")
    p.add_argument("--data", type=Path, help="directory of the record files (kept; made when missing)")
    p.add_argument("--no-rss", action="store_true", help="skip the processes that measure the resident set")
    p.add_argument("--json", type=Path, help="also write the rows, the command and the code version here")
    p.add_argument("--child", help=argparse.SUPPRESS)
    p.add_argument("--path", type=Path, help=argparse.SUPPRESS)
    p.add_argument("--traced", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--with-diagnosis", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)
    if args.child:
        for name in ("engine", "app"):
            logging.getLogger(name).setLevel(logging.ERROR)
        sys.stdout.write(json.dumps(child(args.child, args.path, args.traced, args.with_diagnosis)) + "\n")
        return 0

    from engine.records.limits import MAX_SAMPLES

    lengths = [int(float(x)) for x in args.lengths.split(",")]
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    tmp = None if args.data else tempfile.TemporaryDirectory(prefix="bench-memory-")
    data = args.data or Path(tmp.name)  # type: ignore[union-attr]
    data.mkdir(parents=True, exist_ok=True)
    rows: dict[int, dict[str, Any]] = {}
    try:
        for n in lengths:
            path = data / f"record_{n}.csv"
            if not path.exists():
                t0 = time.perf_counter()
                event = make_record(path, n)
                logger.info("wrote %s (%d samples, event at %d) in %.0f s", path, n, event, time.perf_counter() - t0)
            row: dict[str, Any] = {"file_mb": path.stat().st_size / MB}
            for mode in modes:
                if mode == "arrays" and n > MAX_SAMPLES:
                    continue
                diagnose = mode == "read" and n <= args.diagnose_up_to
                for traced in (True, False) if not args.no_rss else (True,):
                    logger.info("%s, %d samples, %s", mode, n, "tracemalloc" if traced else "resident set")
                    row.update(_run_child(mode, path, traced, diagnose))
            rows[n] = row
            logger.info("%d samples: %s", n, row)
    finally:
        if tmp is not None:
            tmp.cleanup()
    _report(rows, lengths[0])
    if args.json:
        from engine.atomic import write_json_atomic
        from engine.validation.provenance import code_version

        doc = {
            "command": "python bench/bench_memory.py " + " ".join(sys.argv[1:] if argv is None else argv),
            "code_version": code_version(),
            "cores": os.cpu_count(),
            "baseline_samples": lengths[0],
            "rows": [{"samples": n, **r} for n, r in rows.items()],
        }
        write_json_atomic(args.json, doc, indent=1)
    return 0


def _report(rows: dict[int, dict[str, Any]], base: int) -> None:
    """The table: each figure with its ratio against the baseline length's."""
    keys = [
        ("read_peak_mb", "read (CLI) peak"),
        ("read_held_mb", "record held"),
        ("read_rss_mb", "read (CLI) RSS"),
        ("diagnose_peak_mb", "diagnose (CLI) peak"),
        ("diagnose_rss_mb", "diagnose (CLI) RSS"),
        ("api_peak_mb", "read (API CSV) peak"),
        ("api_rss_mb", "read (API CSV) RSS"),
        ("arrays_peak_mb", "record_from_data peak"),
        ("arrays_rss_mb", "record_from_data RSS"),
    ]
    keys = [(k, label) for k, label in keys if any(k in r for r in rows.values())]
    lines = ["| samples | file [MB] | " + " | ".join(f"{label} [MB] (ratio)" for _, label in keys) + " | answer |"]
    lines.append("|---" * (len(keys) + 3) + "|")
    ref = rows[base]
    for n, r in rows.items():
        cells = []
        for k, _ in keys:
            if k not in r:
                refused = r.get(k.split("_")[0] + "_refused")
                cells.append("refused" if refused else "-")
                continue
            ratio = r[k] / ref[k] if ref.get(k) else float("nan")
            cells.append(f"{r[k]:.1f} ({ratio:.2f}x)")
        answer = r.get("verdict", "-")
        if r.get("K_mm") is not None:
            answer += f", K {r['K_mm']} mm"
        lines.append(f"| {n:.0e} | {r['file_mb']:.0f} | " + " | ".join(cells) + f" | {answer} |")
    refusals = {n: r[k] for n, r in rows.items() for k in r if k.endswith("_refused")}
    lines += [f"refused at {n:.0e}: {why}" for n, why in refusals.items()]
    sys.stdout.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    raise SystemExit(main())
