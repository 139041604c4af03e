"""Benchmark: the numba kernel of this tree against the kernel of an earlier git revision.

A change to :mod:`engine.simulation._kernel` that is meant to be a pure speed-up (the same
floating-point operations, reordered or inlined) must leave every record bit for bit as it was.
This script loads ``engine/simulation/_kernel.py`` as it was at ``--baseline`` (``git show``)
into a module of its own, compiles both kernels (a temporary numba cache for the baseline), and
runs both on the same parameter vectors in the same process:

* **Identity.** Every record, event time and status of both kernels must be equal bit for bit,
  else the script stops with an error. The vectors cover every effect of the catalogue and of
  the held-back, held-out and sealed families and of the second, third and fourth sealed families
  (at 30 % and 90 % of its range; simulated only, nothing is diagnosed), an unknown input at every locus of the
  plant (12 knots, with a step at the switch-off: the clutch's makes the zone depend on time),
  and plain plants uniform in the plausible box; on three sample grids (MODEL.md's, a coarser
  shorter one and a finer longer one), at the search and the final integrator step, through the
  serial and the parallel entry point.
  A change that is not bit for bit by design (``--agreement``) is compared instead: the statuses
  must still be equal, and the largest difference of a record (in % of the baseline channel's
  peak-to-peak) and of an event time are reported and must stay within MODEL.md section 4's
  accuracy (0.5 %, 1 us).
* **Speed.** Plain plants of the plausible box on MODEL.md's grid at the search step
  (:data:`engine.diagnosis.calibration.CalibrationSettings.search_step`), serial kernel, the two
  kernels alternating for ``--rounds`` rounds; the median time per simulation and the ratio
  baseline / current.

The baseline must have the same kernel interface (``simulate_serial`` and ``simulate_many``
taking the same parameter vector layout). Run from the repository root::

    python bench/bench_kernel_revision.py --baseline 383599e

Prints one JSON object; the last line of the log is ``speedup: <ratio>x``.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

logger = logging.getLogger("bench_kernel_revision")

KERNEL_PATH = "engine/simulation/_kernel.py"


def load_baseline(rev: str, cache_dir: Path) -> ModuleType:
    """The kernel module of git revision ``rev``, imported under its own name.

    Its numba cache goes to ``cache_dir`` (the environment variable is read when numba is first
    imported, so this must run before any numba import; the current kernel then caches there
    too, which only costs a compilation).
    """
    source = subprocess.run(["git", "show", f"{rev}:{KERNEL_PATH}"], check=True, capture_output=True, text=True).stdout
    path = cache_dir / "baseline_kernel.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("baseline_kernel", path)
    if spec is None or spec.loader is None:
        raise RuntimeError(f"cannot load the kernel of {rev}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def identity_vectors(rng: np.random.Generator) -> list[Any]:
    """The cases of the identity check (see the module docstring)."""
    from _plants import uniform_plants

    from engine.constants import PLAUSIBLE_RANGE
    from engine.simulation import CATALOGUE, Case
    from engine.simulation.effects import apply_effects
    from engine.simulation.held_back import HELD_BACK
    from engine.simulation.held_out import HELD_OUT
    from engine.simulation.parameters import Disturbance
    from engine.simulation.sealed import SEALED
    from engine.simulation.sealed2 import SEALED2
    from engine.simulation.sealed3 import SEALED3
    from engine.simulation.sealed4 import SEALED4

    plants = uniform_plants(PLAUSIBLE_RANGE, 6, rng)
    cases: list[Any] = []
    for lib in (CATALOGUE, HELD_BACK, HELD_OUT, SEALED, SEALED2, SEALED3, SEALED4):  # simulated only
        for name in lib:
            lo, hi = lib[name].bounds
            for frac in (0.3, 0.9):
                cases.append(apply_effects(Case(plants[len(cases) % len(plants)]), {name: lo + frac * (hi - lo)}, lib))
    for locus in ("supply", "motor_electrical", "motor_shaft", "clutch", "drive_train", "load"):
        scale = {"supply": 0.02, "clutch": 0.002}.get(locus, 0.05)
        d = Disturbance(locus=locus, t0=0.02, dt=0.003, values=tuple(scale * rng.standard_normal(12)), step=0.5 * scale)
        cases.append(Case(dataclasses.replace(plants[0], disturbance=d)))
    return cases + [Case(p) for p in plants]


def run(kernel: ModuleType, entry: str, P: np.ndarray, n_samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Records, event times and statuses of ``kernel.<entry>`` for the parameter vectors ``P``."""
    n = P.shape[0]
    out = np.zeros((n, 5, n_samples))
    t_e = np.zeros(n)
    status = np.zeros(n, dtype=np.int64)
    getattr(kernel, entry)(P, out, t_e, status)
    return out, t_e, status


#: MODEL.md section 4: a record within 0.5 % of each channel's peak-to-peak, t_e within 1 us.
AGREEMENT_LIMITS = (0.5, 1e-6)


def check_identity(
    base: ModuleType, cur: ModuleType, rng: np.random.Generator, exact: bool = True
) -> tuple[int, int, float, float]:
    """Compare both kernels on the identity cases.

    With ``exact``, raise on the first record that differs in any bit; else raise on a different
    status only, and on a difference beyond :data:`AGREEMENT_LIMITS`.

    Returns
    -------
    n : int
        Records compared.
    n_equal : int
        Records equal bit for bit.
    max_rel_pct : float
        Largest difference of a sample [% of the baseline channel's peak-to-peak].
    max_dte : float
        Largest difference of an event time [s].
    """
    from engine.diagnosis.calibration import CalibrationSettings
    from engine.records import PROTOCOL_GRID, SampleGrid
    from engine.simulation import SolverSettings
    from engine.simulation.simulator import parameter_vector

    cases = identity_vectors(rng)
    grids = [PROTOCOL_GRID, SampleGrid(2e-4, 1100, 30), SampleGrid(5e-5, 4400, 200)]
    cal = CalibrationSettings()
    n = n_equal = 0
    max_rel = max_dte = 0.0
    for grid in grids:
        for step in (cal.search_step, cal.final_step):
            P = np.array([parameter_vector(c, SolverSettings(max_step=step), grid) for c in cases])
            for entry in ("simulate_serial", "simulate_many"):
                a, b = run(base, entry, P, grid.n_samples), run(cur, entry, P, grid.n_samples)
                for i in range(len(cases)):
                    where = f"case {i} ({cases[i]}), {grid}, step {step}, {entry}"
                    same = (
                        np.array_equal(a[0][i], b[0][i])
                        and np.array_equal(a[1][i], b[1][i], equal_nan=True)
                        and a[2][i] == b[2][i]
                    )
                    n += 1
                    n_equal += int(same)
                    if same:
                        continue
                    if exact or a[2][i] != b[2][i]:
                        raise SystemExit(f"kernels differ: {where}")
                    if a[2][i] == 0:
                        pp = np.ptp(a[0][i], axis=1)
                        diff = np.max(np.abs(a[0][i] - b[0][i]), axis=1) / np.where(pp > 0, pp, 1.0)
                        max_rel = max(max_rel, 100.0 * float(np.max(diff)))
                        max_dte = max(max_dte, abs(float(a[1][i] - b[1][i])))
                    if max_rel > AGREEMENT_LIMITS[0] or max_dte > AGREEMENT_LIMITS[1]:
                        raise SystemExit(f"kernels disagree beyond MODEL.md's accuracy: {where}")
    return n, n_equal, max_rel, max_dte


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", required=True, help="git revision of the baseline kernel")
    ap.add_argument("--plants", type=int, default=16, help="plants of the speed runs")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--agreement",
        action="store_true",
        help="the change is not bit for bit by design: report the largest differences instead of stopping at the first",
    )
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")

    cache = Path(tempfile.mkdtemp(prefix="bench_kernel_"))
    os.environ["NUMBA_CACHE_DIR"] = str(cache)
    sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/_plants.py
    base = load_baseline(args.baseline, cache)
    from _plants import uniform_plants

    from engine.constants import PLAUSIBLE_RANGE
    from engine.diagnosis.calibration import CalibrationSettings
    from engine.records import PROTOCOL_GRID
    from engine.simulation import Case, SolverSettings
    from engine.simulation import _kernel as cur
    from engine.simulation.simulator import parameter_vector

    t = time.perf_counter()
    n_cmp, n_same, max_rel, max_dte = check_identity(base, cur, np.random.default_rng(args.seed), not args.agreement)
    logger.info(
        "identity: %d of %d records equal bit for bit; largest difference %.2e %% of peak-to-peak, t_e %.2e s"
        " (%.0f s, compilation included)",
        n_same,
        n_cmp,
        max_rel,
        max_dte,
        time.perf_counter() - t,
    )

    plants = uniform_plants(PLAUSIBLE_RANGE, args.plants, np.random.default_rng(args.seed + 1))
    solver = SolverSettings(max_step=CalibrationSettings().search_step)
    P = np.array([parameter_vector(Case(p), solver, PROTOCOL_GRID) for p in plants])
    times: dict[str, list[float]] = {"baseline": [], "current": []}
    for _ in range(args.rounds):
        for name, kernel in (("baseline", base), ("current", cur)):
            t = time.perf_counter()
            run(kernel, "simulate_serial", P, PROTOCOL_GRID.n_samples)
            times[name].append((time.perf_counter() - t) / len(P))
    ms = {k: 1e3 * float(np.median(v)) for k, v in times.items()}
    ratio = ms["baseline"] / ms["current"]
    result = {
        "baseline": args.baseline,
        "compared_records": n_cmp,
        "identical_records": n_same,
        "max_difference_pct_of_peak_to_peak": max_rel,
        "max_event_time_difference_s": max_dte,
        "plants": args.plants,
        "rounds": args.rounds,
        "ms_per_simulation": ms,
        "ratio_per_round": [b / c for b, c in zip(times["baseline"], times["current"], strict=True)],
        "speedup": ratio,
    }
    sys.stdout.write(json.dumps(result, indent=1) + "\n")
    logger.info("speedup: %.2fx", ratio)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
