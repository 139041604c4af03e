"""The EMPS kernel against an earlier commit's, in the same process: bit for bit, and how much faster (issue 54).

    NUMBA_NUM_THREADS=1 python bench/bench_emps_kernel.py --baseline REF [--draws 40] [--json FILE]

The baseline is ``engine/plants/emps/_kernel.py`` as it is at ``REF`` (``git show``), loaded as a
module of its own beside the current one. Both simulate the same ``--draws`` parameter vectors on
each of the two shipped EMPS records: the published model's values with M, Fv, Fc and the offset
within +-10 %, and each group of terms (asymmetric and Stribeck friction, the flexible
transmission, position friction, the actuator delay, the held-back and sealed families' terms, gain
and offset changes, an external force schedule) switched on with probability 0.4, so that every
branch of the kernel runs. A draw is **identical** when both outputs are equal to the last bit (or
both raise the divergence error).

Speed: the nominal vector on each record, both kernels compiled, timed alternately
(:data:`ROUNDS` rounds of :data:`CALLS` calls each); printed: each kernel's median time per
simulation and the ratio current / baseline. Never run by the tests.
"""

from __future__ import annotations

import argparse
import importlib.util
import logging
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from engine.atomic import write_json_atomic
from engine.plants.emps import EmpsPlant
from engine.plants.emps import _kernel as current
from engine.validation.provenance import code_version

logger = logging.getLogger("bench_emps_kernel")

REPO: Path = Path(__file__).resolve().parents[1]
#: Timed rounds (the two kernels alternate) and calls per round.
ROUNDS: int = 5
CALLS: int = 10
#: Seed of the parameter draws.
SEED: int = 54


def baseline_kernel(ref: str, folder: Path) -> ModuleType:
    """The kernel module as it is at ``ref``, loaded from a copy in ``folder``."""
    source = subprocess.run(
        ["git", "show", f"{ref}:engine/plants/emps/_kernel.py"], cwd=REPO, check=True, capture_output=True, text=True
    ).stdout
    path = folder / "baseline_emps_kernel.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("baseline_emps_kernel", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def draw(p0: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One parameter vector around ``p0`` (module docstring) and an external force (empty or ``n`` values)."""
    k = current
    p = p0.copy()
    for j in (k.P_M, k.P_FV, k.P_FC, k.P_OFFSET):
        p[j] *= 1.0 + 0.1 * rng.uniform(-1.0, 1.0)
    on = rng.uniform(size=12) < 0.4
    if on[0]:
        p[k.P_DFC], p[k.P_DFV] = rng.uniform(-3, 3), rng.uniform(-30, 30)
    if on[1]:
        p[k.P_FS], p[k.P_VS] = rng.uniform(1, 5), 0.005
    if on[2]:
        p[k.P_F_FLEX], p[k.P_RHO_FLEX], p[k.P_ZETA_FLEX] = rng.uniform(10, 40), 0.3, 0.05
    if on[3]:
        p[k.P_A_POS], p[k.P_PERIOD_POS] = rng.uniform(0.5, 3), 0.05
    if on[4]:
        p[k.P_DELAY] = rng.uniform(0.0, 0.0015)
    if on[5]:
        p[k.P_DEAD_BAND] = rng.uniform(0.0, 0.3)
    if on[6]:
        p[k.P_QUAD_DRAG], p[k.P_RIPPLE], p[k.P_CABLE_K] = rng.uniform(0, 100), rng.uniform(0, 2), rng.uniform(0, 50)
    if on[7]:
        p[k.P_GAIN_ASYM] = rng.uniform(-0.1, 0.1)
    if on[8]:
        p[k.P_CONTAM_F], p[k.P_CONTAM_Q], p[k.P_CONTAM_W] = rng.uniform(0, 10), 0.1, 0.02
    if on[9]:
        p[k.P_SCREW_MU] = rng.uniform(0.0, 0.05)
    if on[10]:
        p[k.P_GAIN_ERR], p[k.P_D_OFFSET] = rng.uniform(-0.1, 0.1), rng.uniform(-1, 1)
    force = rng.normal(0.0, 2.0, n) if on[11] else np.zeros(0)
    return p, force


def _run(kernel: ModuleType, p: np.ndarray, record: Any, force: np.ndarray) -> np.ndarray | None:
    try:
        return np.asarray(kernel.simulate_loop(p, record.qg, record.pulses, force))
    except FloatingPointError:
        return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", required=True, help="commit whose kernel is the baseline")
    ap.add_argument("--draws", type=int, default=40, help="parameter draws per record")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    plant = EmpsPlant()
    rng = np.random.default_rng(SEED)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        old = baseline_kernel(args.baseline, Path(tmp))
        for name in plant.examples:
            record = plant.example(name)
            p0 = plant.parameters({}).vector(record, plant.n_substeps)
            same = 0
            for _ in range(args.draws):
                p, force = draw(p0, record.n, rng)
                a, b = _run(old, p, record, force), _run(current, p, record, force)
                same += (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))
            none = np.zeros(0)
            times: dict[str, list[float]] = {"baseline": [], "current": []}
            for _ in range(ROUNDS):
                for label, kernel in (("baseline", old), ("current", current)):
                    t0 = time.perf_counter()
                    for _ in range(CALLS):
                        kernel.simulate_loop(p0, record.qg, record.pulses, none)
                    times[label].append((time.perf_counter() - t0) / CALLS)
            row = {
                "record": name,
                "samples": int(record.n),
                "draws": args.draws,
                "identical": int(same),
                "baseline_s": statistics.median(times["baseline"]),
                "current_s": statistics.median(times["current"]),
            }
            row["ratio"] = row["current_s"] / row["baseline_s"]
            rows.append(row)
            print(
                f"{name} ({row['samples']} samples): {same}/{args.draws} draws bit for bit; one simulation "
                f"{1e3 * row['baseline_s']:.1f} ms ({args.baseline}) -> {1e3 * row['current_s']:.1f} ms, "
                f"ratio {row['ratio']:.2f}",
                flush=True,
            )
    if args.json:
        write_json_atomic(args.json, {"code": code_version(), "baseline": args.baseline, "rows": rows}, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
