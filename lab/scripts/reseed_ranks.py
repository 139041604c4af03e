"""Rank of the true effect after the single candidates' seeded fits, without and with pass 1b.

Development data only (a scored run's cases, read): for each single-effect case of a validation
run directory, the nominal calibration, then the candidates' seeded fits (no escalation) once with
``CandidateSettings.reseed_from_starts`` off and once on (pass 1b: refits from the nominal
calibration's global starts, :func:`engine.diagnosis.candidate.refit_from_starts`). Prints one JSON
line per case: the truth, its rank and chi2/n each way, the best candidate each way, the seconds.
docs/diagnosis.md 8b, *Re-seeded fits*::

    python lab/scripts/reseed_ranks.py out/validation-v2-progress-seed137 --seed 137 --cases 80
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from dataclasses import replace

from _runs import add_run_arguments, chosen_entries, run_library


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(ap, "case ids, comma-separated (default: every single)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)

    from engine.diagnosis.calibration import calibrate
    from engine.diagnosis.candidates import fit_candidates
    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.diagnosis.space import default_space

    layout, entries = chosen_entries(ap, args, "single")
    library = run_library(ap, layout)
    settings = DiagnosisSettings()
    for k in entries:
        if k.kind != "single":
            continue
        truth = k.effects[0].name
        record, _ = layout.read_case(k.case_id).test_window()
        space = default_space(record)
        t0 = time.perf_counter()
        nominal = calibrate(record, space, settings.calibration)
        row: dict[str, object] = {"case": k.case_id, "truth": truth}
        for name, on in (("seeded", False), ("reseeded", True)):
            t = time.perf_counter()
            cs = replace(settings.candidates, reseed_from_starts=on)
            cands = fit_candidates(record, nominal, space, library, cs, escalate=False)
            order = [c.effect for c in cands]
            mine = cands[order.index(truth)].calibration
            best = cands[0].calibration
            row[name] = {
                "rank": order.index(truth) + 1,
                "chi2n": None if mine is None else round(mine.reduced_chi2, 3),
                "best": [order[0], None if best is None else round(best.reduced_chi2, 3)],
                "seconds": round(time.perf_counter() - t, 1),
            }
        row["total_seconds"] = round(time.perf_counter() - t0, 1)
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
