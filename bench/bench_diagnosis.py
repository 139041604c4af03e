"""Benchmark of the sim-to-real gap diagnosis (issue 4).

Three parts, each optional:

* ``--calibration N``: calibrate N simulated records (K uniform in [0.0025, 0.01] m,
  J1 in [0.75, 0.93] kg m^2, c in [0.8, 1.5], c1 = 0.2 known, white noise at
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
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np


def bench_calibration(n: int, snr_db: float, seed: int) -> dict:
    from engine.diagnosis import calibrate
    from engine.records import Record
    from engine.simulation import Case, PlantParameters, simulate_batch
    from engine.simulation.noise import noise_std

    rng = np.random.default_rng(seed)
    plants = [
        PlantParameters(K=rng.uniform(0.0025, 0.01), J1=rng.uniform(0.75, 0.93), c=rng.uniform(0.8, 1.5))
        for _ in range(n)
    ]
    sims = simulate_batch([Case(p) for p in plants])
    rows = []
    for i, p in enumerate(plants):
        x = sims.channels[i]
        noisy = x + rng.standard_normal(x.shape) * noise_std(x, snr_db, axis=1)
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
        print(
            f"  {i + 1:3d}/{n}: K {p.K:.5f} J1 {p.J1:.4f} c {p.c:.3f} -> K err {100 * eK:+.4f} %, "
            f"J1 err {100 * eJ:+.4f} %, c err {100 * ec:+.3f} %, chi2/n {cal.reduced_chi2:.3f}, "
            f"{cal.n_simulations} sims, {dt:.1f} s",
            file=sys.stderr,
        )
    eK = np.array([r["eK"] for r in rows])
    eJ = np.array([r["eJ1"] for r in rows])
    inb = (np.abs(eK) < 0.03) & (np.abs(eJ) < 0.015)
    pulls = np.array([r["pull_K"] for r in rows])[inb]
    return {
        "n": n,
        "snr_db": snr_db,
        "in_basin": int(inb.sum()),
        "median_abs_K_error_pct": float(100 * np.median(np.abs(eK))),
        "max_abs_K_error_pct_in_basin": float(100 * np.max(np.abs(eK[inb]))) if inb.any() else None,
        "median_abs_J1_error_pct": float(100 * np.median(np.abs(eJ))),
        "median_abs_pull_K": float(np.median(np.abs(pulls))) if pulls.size else None,
        "median_chi2_n": float(np.median([r["chi2_n"] for r in rows])),
        "mean_simulations": float(np.mean([r["n_sim"] for r in rows])),
        "median_seconds": float(np.median([r["seconds"] for r in rows])),
        "rows": rows,
    }


def bench_timing(n: int, seed: int, n_jobs: int | None = None) -> dict:
    """Wall time of full diagnoses of ``n`` blind-validation-style cases, one after the other.

    The cases come from :func:`engine.diagnosis.validation.generate_cases`
    with more left-out effects than the validation's mix (40 % effect, 40 %
    left out, 20 % clean): a record no candidate explains is the slowest kind
    (every candidate gets the global search). Each diagnosis uses every core
    numba may use (candidate fits on ``n_jobs`` threads, default: numba's count).
    """
    import numba

    from engine.diagnosis import diagnose
    from engine.diagnosis.candidates import CandidateSettings
    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.diagnosis.validation import generate_cases
    from engine.simulation import CATALOGUE, EffectLibrary

    cases, key = generate_cases(n, seed, fractions={"effect": 0.4, "left_out": 0.4, "clean": 0.2})
    settings = DiagnosisSettings(candidates=CandidateSettings(n_jobs=n_jobs))
    diagnose(cases[0].record, EffectLibrary([CATALOGUE[x] for x in cases[0].library]), settings)  # JIT warm-up
    rows = []
    for case, truth in zip(cases, key):
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
        print(
            f"  {case.case_id} {truth.kind:8s} {truth.effect!s:24s} -> {res.verdict.status:11s} "
            f"{dt:5.1f} s, {res.n_simulations} simulations",
            file=sys.stderr,
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
    for name in ("engine.diagnosis.calibration", "engine.diagnosis.candidates", "engine.diagnosis.diagnose"):
        logging.getLogger(name).setLevel(logging.WARNING)
    if not (args.calibration or args.timing or args.validation):
        args.calibration, args.timing = 20, 20
    if args.calibration:
        res = bench_calibration(args.calibration, args.snr, args.seed)
        print(json.dumps({k: v for k, v in res.items() if k != "rows"}, indent=1))
    if args.timing:
        res = bench_timing(args.timing, args.seed, args.jobs)
        print(json.dumps(res, indent=1))
        if args.baseline:
            base = bench_timing(args.timing, args.seed, 1)
            print(
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
        print(rep.table())
        print()
        print(rep.confusion_table())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
