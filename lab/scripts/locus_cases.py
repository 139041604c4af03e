"""The locus of held-back cases of a finished validation run, from the nominal calibration alone.

Development data only (a scored run's cases, read). The diagnosis answers a held-back effect
``unexplained`` after every candidate and set has failed, and then places the gap with
:func:`engine.diagnosis.locus.estimate_locus` on the *nominal* calibration. That last step does
not depend on the candidates, so it can be measured apart, in about 16 s a record on 2 cores
instead of the 2-5 min of a whole diagnosis: this runs the nominal calibration and the locus
estimate of each held-back case (or of the given ids) and prints one JSON line per case: the true
effect and locus, the answered locus and its confidence, the share of the residual each locus's
input explains, and the seconds. The locus is estimated whatever the nominal fit leaves (the
diagnosis does it only for ``unexplained`` and ``weak_gap`` verdicts). The run directory can be
made again from its seed (``--seed S --cases N`` draws the cases if absent; no diagnosis).
docs/diagnosis.md, *Locus of a gap outside the catalogue*::

    python lab/scripts/locus_cases.py out/validation-v2-seed97 --seed 97 --cases 300 > locus.jsonl
    python lab/scripts/locus_cases.py out/validation-v2-seed97 --locus '{"refine_loci": 3}' > variant.jsonl

``--locus`` updates the default :class:`~engine.diagnosis.locus.LocusSettings`. The last line on
stdout is a summary: right locus k/n with its Wilson 95 % interval, per held-back effect.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from collections import Counter
from dataclasses import replace

from _runs import add_run_arguments, chosen_entries


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(ap, "case ids, comma-separated (default: every held-back case)")
    ap.add_argument("--locus", default="{}", help="LocusSettings fields as JSON, e.g. '{\"refine_loci\": 3}'")
    ap.add_argument("--log-level", default="WARNING", help="log level (default WARNING)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)

    from engine.diagnosis.calibration import calibrate
    from engine.diagnosis.confidence import locus_feature
    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.diagnosis.locus import LocusSettings, estimate_locus
    from engine.diagnosis.space import default_space
    from engine.validation.stats import wilson_interval

    try:
        locus_settings = replace(LocusSettings(), **json.loads(args.locus))
    except (TypeError, ValueError) as e:
        ap.error(f"--locus: {e}")
    layout, entries = chosen_entries(ap, args, "held_back")
    settings = DiagnosisSettings()
    right: Counter[str] = Counter()
    seen: Counter[str] = Counter()
    for k in entries:
        record, _ = layout.read_case(k.case_id).test_window()
        t0 = time.perf_counter()
        nominal = calibrate(record, default_space(record), settings.calibration)
        report = estimate_locus(record, nominal, locus_settings)
        truth = k.effects[0] if k.effects else None
        true_locus = None if truth is None else truth.locus
        ok = report.locus == true_locus
        name = "none" if truth is None else truth.name
        seen[name] += 1
        right[name] += ok
        out = report.to_dict()
        row = {
            "case": k.case_id,
            "truth": None if truth is None else [truth.name, truth.value],
            "true_locus": true_locus,
            "locus": report.locus,
            "right": ok,
            "confidence": round(report.confidence, 3),
            "explained": {n: round(s["explained"], 3) for n, s in out.get("scores", {}).items()},
            "delta_bic": {n: round(s["delta_bic"], 1) for n, s in out.get("scores", {}).items()},
            "dispersion": round(report.dispersion, 3),
            "chi2n_left": round(min(s["rss"] for s in out.get("scores", {}).values()) / report.n_data, 3)
            if out.get("scores")
            else None,
            "description": report.description,
            # the part term's value and its interval (a friction [pu] or a drift's factor), if any
            "part_term": {
                k: v
                for k, v in (report.term.details.items() if report.term is not None else ())
                if k.startswith(("drift_", "coulomb_"))
            },
            "nominal_chi2n": round(nominal.reduced_chi2, 2),
            # what the committed confidence map reads (engine.diagnosis.confidence.locus_feature)
            "locus_feature": locus_feature(out),
            "seconds": round(time.perf_counter() - t0, 1),
            "locus_simulations": report.n_simulations,
        }
        print(json.dumps(row), flush=True)
    n, k_right = sum(seen.values()), sum(right.values())
    summary = {
        "summary": f"right locus {k_right}/{n}",
        "wilson_95": [round(100 * x, 1) for x in wilson_interval(k_right, n)] if n else None,
        "per_effect": {e: f"{right[e]}/{seen[e]}" for e in sorted(seen)},
        "locus_settings": json.loads(args.locus),
    }
    print(json.dumps(summary), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
