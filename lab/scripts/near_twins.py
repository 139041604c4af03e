"""Replay the near-twin rule on the stored results of finished validation runs (no simulation).

The rule (:mod:`engine.diagnosis.ambiguity`) compares the model a verdict names with the other
models the search fitted. A result file keeps every single candidate and the ``n_report`` best
sets with their BIC, fit statistics and strengths, which is all the rule reads, so it can be
replayed on runs diagnosed before the rule existed: how often an ``explained`` answer would
declare near twins, and how often a true effect the answer missed is among them. A run's
records are development data once scored; this reads its results and key only.

Example (the four progress runs with results on this machine)::

    python lab/scripts/near_twins.py out/validation-v2-progress-seed119 out/validation-v2-progress-seed123 \\
        out/validation-v2-progress-seed127 out/validation-v2-progress-seed131

Prints one JSON line per answer that declares near twins, then a summary line.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", type=Path, help="directories of scored validation runs (results/ and key/)")
    args = ap.parse_args(argv)

    from engine.diagnosis.ambiguity import near_twins
    from engine.diagnosis.calibration import CalibrationResult
    from engine.diagnosis.candidate import SEEDED_FITS, Candidate
    from engine.diagnosis.candidate_set import CandidateSet
    from engine.diagnosis.decision import explains_as_well
    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.simulation import CATALOGUE
    from engine.validation.layout import RunLayout

    settings = DiagnosisSettings()

    def calibration(c: dict[str, Any], refined: bool) -> CalibrationResult:
        cal = c["calibration"]
        return CalibrationResult(
            values=dict(cal["values"]),
            uncertainties={},
            fixed={},
            chi2=cal["reduced_chi2"] * cal["n_data"],
            chi2_per_channel=dict(cal["chi2_per_channel"]),
            n_data=cal["n_data"],
            noise={},
            sigma={},
            effect=None,
            n_simulations=0,
            seconds=0.0,
            # results written before the summary held its step: a model with strengths was refined
            # (they are computed after the refinement)
            step=cal.get("step") or (SEEDED_FITS.final_step if refined else SEEDED_FITS.search_step),
        )

    def model(c: dict[str, Any]) -> Candidate | CandidateSet | None:
        if not c.get("calibration") or c.get("bic") is None:
            return None
        if c["kind"] == "single":
            refined = c.get("strength") is not None
            return Candidate(
                c["effect"], c["value"], c.get("uncertainty"), c["unit"], calibration(c, refined), c["bic"],
                strength=c.get("strength"), locus=c.get("locus", ""),
            )  # fmt: skip
        rows = c["effects"]
        refined = all(r.get("strength") is not None for r in rows)
        return CandidateSet(
            effects=tuple(r["effect"] for r in rows),
            calibration=calibration(c, refined),
            units={r["effect"]: r["unit"] for r in rows},
            loci={r["effect"]: r["locus"] for r in rows},
            bic=c["bic"],
            strengths={r["effect"]: r["strength"] for r in rows if r.get("strength") is not None},
        )

    n_explained = n_declared = n_rescued = n_wrong_declared = 0
    for run in args.runs:
        layout = RunLayout(run)
        _, key = layout.read_key()
        done = layout.done()
        for k in key:
            if k.case_id not in done:
                continue
            res = layout.read_result(k.case_id)
            v = res.get("verdict") or {}
            if v.get("status") != "explained":
                continue
            n_explained += 1
            named = {e["effect"] for e in v.get("effects") or []}
            models = [m for m in (model(c) for c in res.get("candidates") or []) if m is not None]
            chosen = next(
                (m for m in models if {*(m.effects if isinstance(m, CandidateSet) else (m.effect,))} == named), None
            )
            if chosen is None:
                continue
            twins = near_twins(
                chosen, models, lambda m: explains_as_well(m, settings), settings.min_delta_bic, CATALOGUE
            )
            if not twins:
                continue
            n_declared += 1
            truth = set(k.effect_names)
            missed = truth - named
            offered = {t.effect for ts in twins.values() for t in ts}
            rescued = bool(missed) and missed <= offered
            n_rescued += rescued
            n_wrong_declared += not missed
            row = {
                "run": run.name,
                "case": k.case_id,
                "kind": k.kind,
                "truth": sorted(truth),
                "named": sorted(named),
                "near_twins": {n: [(t.effect, round(t.delta_bic, 1)) for t in ts] for n, ts in twins.items()},
                "missed_true_offered": rescued,
            }
            sys.stdout.write(json.dumps(row) + "\n")
    summary = {
        "explained_answers": n_explained,
        "with_near_twins": n_declared,
        "of_which_right_without_them": n_wrong_declared,
        "of_which_every_missed_true_effect_offered": n_rescued,
    }
    sys.stdout.write(json.dumps(summary) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
