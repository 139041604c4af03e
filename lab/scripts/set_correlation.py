"""Correlation of the members' values of a diagnosis's best fit, at the stored fit (development, not blind).

Why: docs/validation/v1-seed193/README.md and README (*The open world*) say that the sets that
stood in for a left-out electrical effect on the protocol-1 run of seed 193 are well-determined
fits, not ones whose members trade off along a flat valley. This recomputes what that rests on:
for each chosen case, the Gauss-Newton covariance of the best candidate's parameters
(:func:`engine.diagnosis.calibration.unit_covariance`, the one the reported uncertainties come
from) at its stored values, with the stored noise model, and the correlations between the
members' values. A correlation near +-1 would flag a set whose members the record cannot tell
apart; the seven electrical stand-ins of seed 193 give 0.68, 0.63, -0.98, -0.84, 0.02, -0.89 and 0.90.

The records are drawn again from the run's seed (protocol 1, :func:`engine.diagnosis.validation.generate_cases`;
a seed draws the same records under the revision of 2026-11-26). Example, from a clone::

    mkdir -p /tmp/v193 && tar -xJf docs/validation/v1-seed193/results.tar.xz -C /tmp/v193
    python lab/scripts/set_correlation.py /tmp/v193/results --seed 193 --cases 200 \\
        case0004,case0034,case0057,case0069,case0091,case0161,case0176

A case whose drawn record does not reproduce the stored fit's chi2/n (wrong seed, case count or
results) or whose fit used a coloured noise model is refused with a message. One JSON line per
case on stdout: the members, chi2/n of the stored fit recomputed, the
correlations between members, and each member's largest correlation with any parameter (K, J1,
c included). Seconds per case (one Jacobian, central differences).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

#: Largest relative difference between the stored fit's chi2/n and the one recomputed on the drawn
#: record (the same simulation at the same step: they agree to rounding when the record is the same).
CHI2N_REL_TOL = 1e-3


def cal_model(candidate: dict) -> dict[str, dict]:
    """The stored fit's noise model per channel (``{"colour": ...}``; empty when not stored)."""
    return dict(candidate["calibration"].get("noise_model") or {})


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", type=Path, help="directory of the run's diagnoses (<case_id>.json)")
    ap.add_argument("ids", help="case ids, comma-separated")
    ap.add_argument("--seed", type=int, required=True, help="seed of the protocol-1 run")
    ap.add_argument("--cases", type=int, required=True, help="number of cases of the run")
    ap.add_argument("--rel-step", type=float, default=1e-4, help="finite-difference step in the unit box")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)

    import numpy as np

    from engine.diagnosis.calibration import correlation, unit_covariance
    from engine.diagnosis.noise import NoiseModel, noise_weights
    from engine.diagnosis.objective import Objective
    from engine.diagnosis.space import default_space
    from engine.diagnosis.validation import generate_cases
    from engine.simulation import CATALOGUE, SolverSettings

    ids = [i for i in args.ids.split(",") if i]
    cases = {c.case_id: c for c in generate_cases(args.cases, args.seed)[0]}
    missing = [i for i in ids if i not in cases or not (args.results / f"{i}.json").exists()]
    if missing:
        ap.error(f"no case or no diagnosis for {', '.join(missing)}")
    for cid in ids:
        res = json.loads((args.results / f"{cid}.json").read_text())
        best = res["candidates"][0]
        if best.get("calibration") is None:
            print(json.dumps({"case": cid, "skipped": "the best candidate has no fit"}), flush=True)
            continue
        coloured = sorted(n for n, m in cal_model(best).items() if m.get("colour", "white") != "white")
        if coloured:  # protocol 1's noise is white; a coloured model would be read as white here
            ap.error(f"{cid}: the stored fit has a coloured noise model on {', '.join(coloured)}; only white is read")
        members = [e["effect"] for e in best["effects"]] if best.get("effects") else [best["effect"]]
        record, _ = cases[cid].record.test_window()
        space = default_space(record).with_effects([CATALOGUE[m] for m in members])
        cal = best["calibration"]
        obj = Objective(record, space, noise_weights(record, NoiseModel.of(cal["noise"])))
        u = space.unit(cal["values"])
        solver = SolverSettings(max_step=cal["step"])
        r0 = obj.residuals(u[None], record.n_samples, solver)[0]
        J = obj.jacobian(u, record.n_samples, solver, args.rel_step, r0, central=True)
        chi2n, stored = float(r0 @ r0) / r0.size, best["calibration"]["reduced_chi2"]
        if abs(chi2n - stored) > CHI2N_REL_TOL * stored:  # the drawn record is not the one diagnosed
            ap.error(
                f"{cid}: the record drawn from --seed {args.seed} --cases {args.cases} gives chi2/n {chi2n:.4g} "
                f"at the stored fit, not the stored {stored:.4g}: wrong seed, case count or results directory?"
            )
        C = correlation(unit_covariance(J))
        idx = [space.names.index(m) for m in members]
        row = {
            "case": cid,
            "members": members,
            "chi2n": round(chi2n, 3),
            "corr": {
                f"{space.names[i]}~{space.names[j]}": round(float(C[i, j]), 3)
                for a, i in enumerate(idx)
                for j in idx[a + 1 :]
            },
            "max_abs_corr_with_any": {
                space.names[i]: round(float(np.nanmax(np.abs(np.delete(C[i], i)))), 3) for i in idx
            },
        }
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
