"""Benchmark of the sim-to-real gap diagnosis (issue 4).

Three parts, each optional:

* ``--calibration N``: calibrate N simulated records (K, J1, c uniform in the
  operating range, ``engine.constants.OPERATING_RANGE``: K in [0.0025, 0.01] m,
  J1 in [0.75, 0.93] kg m^2, c in [0.8, 1.5]; c1 = 0.2 known, white noise at
  ``--snr`` dB) and report how often the fit lands in the basin (|K error| < 3 %
  and |J1 error| < 1.5 %), the K error, the spread of (error / reported
  uncertainty), simulations and time per calibration.
* ``--timing [N]``: wall time of N (default 20) full diagnoses of blind cases
  drawn like the validation's but with more left-out effects (the slowest
  kind), with all the cores numba uses; median, 90th percentile, maximum and
  the count over the 30 s budget.
* ``--validation N``: the blind validation (``engine.diagnosis.validation``)
  with N cases, written to ``--out``.

Examples::

    python bench/bench_diagnosis.py --calibration 20 --timing 20 --seed 11
    python bench/bench_diagnosis.py --validation 200 --workers 2 --out out/diagnosis-validation

Progress goes to the log (stderr); the results are printed as JSON (stdout).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

logger = logging.getLogger("bench_diagnosis")


def bench_calibration(n: int, snr_db: float, seed: int) -> dict[str, Any]:
    from _plants import uniform_plants

    from engine.constants import OPERATING_RANGE
    from engine.diagnosis import calibrate
    from engine.records import Record
    from engine.simulation import Case, simulate_batch
    from engine.simulation.noise import add_white_noise

    rng = np.random.default_rng(seed)
    plants = uniform_plants(OPERATING_RANGE, n, rng)
    sims = simulate_batch([Case(p) for p in plants])
    rows: list[dict[str, float]] = []
    for i, p in enumerate(plants):
        noisy = add_white_noise(sims.channels[i], snr_db, rng, axis=1)
        rec = Record({c: noisy[j] for j, c in enumerate(sims.record(i).channels)}, conditions={"c1": 0.2})
        t0 = time.perf_counter()
        cal = calibrate(rec)
        dt = time.perf_counter() - t0
        eK = cal.values["K"] / p.K - 1
        eJ = cal.values["J1"] / p.J1 - 1
        ec = cal.values["c"] / p.c - 1
        rows.append(
            {
                "K": p.K,
                "J1": p.J1,
                "c": p.c,
                "eK": eK,
                "eJ1": eJ,
                "ec": ec,
                "pull_K": (cal.values["K"] - p.K) / cal.uncertainties["K"],
                "chi2_n": cal.reduced_chi2,
                "n_sim": cal.n_simulations,
                "seconds": dt,
            }
        )
        logger.info(
            "  %3d/%d: K %.5f J1 %.4f c %.3f -> K err %+.4f %%, J1 err %+.4f %%, c err %+.3f %%, chi2/n %.3f, "
            "%d sims, %.1f s",
            i + 1,
            n,
            p.K,
            p.J1,
            p.c,
            100 * eK,
            100 * eJ,
            100 * ec,
            cal.reduced_chi2,
            cal.n_simulations,
            dt,
        )
    err_K = np.array([r["eK"] for r in rows])
    err_J = np.array([r["eJ1"] for r in rows])
    inb = (np.abs(err_K) < 0.03) & (np.abs(err_J) < 0.015)
    pulls = np.array([r["pull_K"] for r in rows])[inb]
    return {
        "n": n,
        "snr_db": snr_db,
        "in_basin": int(inb.sum()),
        "median_abs_K_error_pct": float(100 * np.median(np.abs(err_K))),
        "max_abs_K_error_pct_in_basin": float(100 * np.max(np.abs(err_K[inb]))) if inb.any() else None,
        "median_abs_J1_error_pct": float(100 * np.median(np.abs(err_J))),
        "median_abs_pull_K": float(np.median(np.abs(pulls))) if pulls.size else None,
        "median_chi2_n": float(np.median([r["chi2_n"] for r in rows])),
        "mean_simulations": float(np.mean([r["n_sim"] for r in rows])),
        "median_seconds": float(np.median([r["seconds"] for r in rows])),
        "rows": rows,
    }


def bench_timing(n: int, seed: int, n_jobs: int | None = None) -> dict[str, Any]:
    """Wall time of full diagnoses of ``n`` blind-validation-style cases, one after the other.

    The cases come from :func:`engine.diagnosis.validation.generate_cases`
    with more left-out effects than the validation's mix (40 % effect, 40 %
    left out, 20 % clean): a record no candidate explains is the slowest kind
    (every candidate gets the global search). Each diagnosis uses every core
    numba may use (candidate fits on ``n_jobs`` threads, default: numba's count).
    """
    import numba

    from engine.diagnosis import CandidateSettings, DiagnosisSettings, diagnose
    from engine.diagnosis.validation import generate_cases
    from engine.simulation import CATALOGUE, EffectLibrary

    cases, key = generate_cases(n, seed, fractions={"effect": 0.4, "left_out": 0.4, "clean": 0.2})
    settings = DiagnosisSettings(candidates=CandidateSettings(n_jobs=n_jobs))
    diagnose(cases[0].record, EffectLibrary([CATALOGUE[x] for x in cases[0].library]), settings)  # JIT warm-up
    rows: list[dict[str, Any]] = []
    for case, truth in zip(cases, key, strict=True):
        lib = EffectLibrary([CATALOGUE[x] for x in case.library])
        t0 = time.perf_counter()
        res = diagnose(case.record, lib, settings)
        dt = time.perf_counter() - t0
        rows.append(
            {
                "case": case.case_id,
                "kind": truth.kind,
                "effect": truth.effect,
                "status": res.verdict.status,
                "seconds": dt,
                "n_simulations": res.n_simulations,
            }
        )
        logger.info(
            "  %s %-8s %-24s -> %-11s %5.1f s, %d simulations",
            case.case_id,
            truth.kind,
            truth.effect,
            res.verdict.status,
            dt,
            res.n_simulations,
        )
    t = np.array([r["seconds"] for r in rows])
    by_status = {}
    for st in sorted({r["status"] for r in rows}):
        ts = np.array([r["seconds"] for r in rows if r["status"] == st])
        by_status[st] = {"n": int(ts.size), "median_s": float(np.median(ts)), "max_s": float(ts.max())}
    return {
        "n": n,
        "seed": seed,
        "numba_threads": numba.get_num_threads(),
        "n_jobs": CandidateSettings(n_jobs=n_jobs).jobs(),
        "median_s": float(np.median(t)),
        "p90_s": float(np.quantile(t, 0.9)),
        "max_s": float(t.max()),
        "over_30_s": int(np.sum(t > 30.0)),
        "by_verdict": by_status,
    }


def _emit(text: str) -> None:
    """Write one result to stdout (the log goes to stderr)."""
    sys.stdout.write(text.rstrip("\n") + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--calibration", type=int, default=0, help="records of the calibration benchmark")
    ap.add_argument("--snr", type=float, default=40.0, help="SNR of the calibration benchmark [dB]")
    ap.add_argument(
        "--timing",
        type=int,
        nargs="?",
        const=20,
        default=0,
        metavar="N",
        help="time N full diagnoses (default 20 when given without N)",
    )
    ap.add_argument(
        "--jobs", type=int, default=None, help="candidate fits at once in --timing (default: numba threads)"
    )
    ap.add_argument(
        "--baseline",
        action="store_true",
        help="with --timing, also time the same cases with one candidate fit at a time and print the ratio",
    )
    ap.add_argument("--validation", type=int, default=0, help="blind validation cases")
    ap.add_argument("--workers", type=int, default=2, help="parallel diagnosis processes of the validation")
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--out", type=Path, default=Path("out/diagnosis-validation"))
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)
    for name in (
        "engine.diagnosis.calibration",
        "engine.diagnosis.candidates",
        "engine.diagnosis.diagnose",
        "engine.diagnosis.staged",
    ):
        logging.getLogger(name).setLevel(logging.WARNING)
    if not (args.calibration or args.timing or args.validation):
        args.calibration, args.timing = 20, 20
    if args.calibration:
        res = bench_calibration(args.calibration, args.snr, args.seed)
        _emit(json.dumps({k: v for k, v in res.items() if k != "rows"}, indent=1))
    if args.timing:
        res = bench_timing(args.timing, args.seed, args.jobs)
        _emit(json.dumps(res, indent=1))
        if args.baseline:
            base = bench_timing(args.timing, args.seed, 1)
            _emit(
                json.dumps(
                    {
                        "baseline_n_jobs_1": base,
                        "speedup_median": base["median_s"] / res["median_s"],
                        "speedup_max": base["max_s"] / res["max_s"],
                    },
                    indent=1,
                )
            )
    if args.validation:
        from engine.diagnosis.validation import run_validation

        rep = run_validation(args.validation, args.seed, args.out, workers=args.workers)
        _emit(rep.table() + "\n")
        _emit(rep.confusion_table())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
