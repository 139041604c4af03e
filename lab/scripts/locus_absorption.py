"""How much of a held-back effect the nominal calibration takes up: the true effect on the true and on the calibrated point.

Development data only (reads a scored run's answer key). The locus of a gap outside the catalogue
is estimated around the *nominal* calibration (:func:`engine.diagnosis.locus.estimate_locus`); when
that calibration has moved K, J1 or c to make up for part of the missing effect, an unknown input
estimated around it has to stand for the effect and for the parameters' error at once, and a
neighbouring part of the plant can do that about as well (docs/diagnosis.md section 10, the load
torque ripples placed on the drive train).

For each held-back case (or the given ids) this runs the nominal calibration as the diagnosis does
(on the record's test window, the default search box) and simulates the record with the true
held-back effect at its true value

- ``true point``: at the key's K, J1, c (the record's own c1; the noise-free truth of the case),
- ``calibrated point``: at the calibration's case (its K, J1, c and everything else it holds),

and prints one JSON line per case with chi2/n of the nominal fit and of both simulations against
the record (the calibration's noise model: each channel's noise, whitened where coloured; the
plain channel chi2, without the calibration's own treatment of a rounded channel), and the
calibrated point's relative errors. ``true point`` near 1 says the held-back effect is all that is
missing; ``calibrated point`` much larger says the calibration took up part of it. The last line
is a summary per held-back effect: the median of each chi2/n. A case costs a nominal calibration (about
5 s); the 60 held-back records of seed 151 took 37 min at `nice` 10 beside a blind run::

    python lab/scripts/locus_absorption.py out/validation-v2-seed151 > absorption.jsonl
    python lab/scripts/locus_absorption.py out/validation-v2-seed151 case0033,case0051,case0155
"""

from __future__ import annotations

import argparse
import json
import logging
import statistics
import sys
from collections import defaultdict

from _runs import add_run_arguments, chosen_entries


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(ap, "case ids, comma-separated (default: every held-back case)")
    ap.add_argument("--log-level", default="WARNING", help="log level (default WARNING)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)

    import numpy as np

    from engine.constants import CHANNELS
    from engine.diagnosis.calibration import CalibrationResult, calibrate
    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.diagnosis.noise import NoiseModel
    from engine.diagnosis.space import default_space
    from engine.records import Record
    from engine.simulation import HELD_BACK, Case, PlantParameters, SolverSettings, run_cases

    def chi2n(cal: CalibrationResult, record: Record, cases: list[Case]) -> list[float]:
        """chi2/n of each case simulated on the record's grid (one batch), with the calibration's noise model."""
        ch, _, status = run_cases(cases, SolverSettings(max_step=cal.step), record.grid)
        noise = NoiseModel.of(cal.sigma)
        return [
            sum(float(noise.chi2(n, ch[i, CHANNELS.index(n)] - record[n])) for n in record.channels) / cal.n_data
            if status[i] == 0
            else float("nan")
            for i in range(len(cases))
        ]

    layout, entries = chosen_entries(ap, args, "held_back")
    settings = DiagnosisSettings()
    per_effect: dict[str, list[dict[str, float]]] = defaultdict(list)
    for k in entries:
        if k.kind != "held_back" or len(k.effects) != 1:
            ap.error(f"{k.case_id} is a {k.kind} case, not a held-back one")
        truth = k.effects[0]
        record, _ = layout.read_case(k.case_id).test_window()
        cal = calibrate(record, default_space(record), settings.calibration)
        if cal.case is None:
            raise RuntimeError(f"{k.case_id}: the calibration has no case")
        effect = HELD_BACK[truth.name]
        if "c1" not in record.conditions:
            ap.error(f"{k.case_id}: the record does not state c1, so its true point is not known")
        plant = PlantParameters(K=k.K, J1=k.J1, c=k.c, c1=float(record.conditions["c1"]))
        at_truth, at_calibration = chi2n(
            cal, record, [effect.apply(Case(plant), truth.value), effect.apply(cal.case, truth.value)]
        )
        row = {"nominal": cal.reduced_chi2, "true point": at_truth, "calibrated point": at_calibration}
        per_effect[truth.name].append(row)
        errors = {p: (cal.values[p] - getattr(k, p)) / getattr(k, p) for p in ("K", "J1", "c")}
        out = {
            "case": k.case_id,
            "truth": [truth.name, truth.value],
            "locus": truth.locus,
            "chi2n": {name: round(v, 2) for name, v in row.items()},
            "calibrated_relative_error": {p: round(float(v), 4) for p, v in errors.items()},
            "channels": list(record.channels),
            "noise": k.colour,
        }
        print(json.dumps(out), flush=True)
    summary = {
        "summary": "median chi2/n per held-back effect (n cases)",
        "per_effect": {
            name: {
                "n": len(rows),
                **{key: round(float(statistics.median(r[key] for r in rows)), 2) for key in rows[0]},
                "calibrated/true (median of the ratios)": round(
                    float(np.median([r["calibrated point"] / r["true point"] for r in rows])), 1
                ),
            }
            for name, rows in sorted(per_effect.items())
        },
    }
    print(json.dumps(summary), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
