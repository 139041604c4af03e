"""Coverage of the locus's part-term intervals on rows of ``locus_cases.py``: does the stated 95 %
interval of a drift's factor or a Coulomb friction hold the true value?

Development data only. For each row whose true effect is a term of the locus library (the
development family's supply frequency, resilient damping and load mass drifts, the held-back
wheel Coulomb friction), the row's ``part_term`` must name the true field; its 95 % interval either
holds the truth or not (a row that names another field counts as not covered). Prints one line
per row (the truth, the estimate, its standard deviation, z) and the coverage with its Wilson 95 %
interval::

    python lab/scripts/part_term_coverage.py lab/validation/dev-locus-seed307/part-term-intervals.jsonl
"""

from __future__ import annotations

import json
import statistics
import sys

#: The field each library term of the development family sets.
FIELD = {
    "supply_frequency_drift": "f",
    "resilient_damping_drift": "d2",
    "load_mass_drift": "T3",
    "wheel_coulomb_friction": "tau_C2",
}


def main(argv: list[str] | None = None) -> int:
    from engine.validation.stats import wilson_interval

    path = (argv or sys.argv[1:])[0]
    hit = n = 0
    secs: list[float] = []
    with open(path) as fh:
        rows = [json.loads(line) for line in fh]
    for r in rows:
        if "case" not in r:
            continue
        name, value = r["truth"]
        if name not in FIELD:
            continue
        secs.append(r["seconds"])
        n += 1
        pt = r.get("part_term") or {}
        field = pt.get("drift_field") or pt.get("coulomb_field")
        interval = pt.get("drift_factor_interval_95") or pt.get("coulomb_friction_interval_95")
        if field != FIELD[name] or interval is None:
            print(r["case"], name, "names", field, "at", r["locus"], "- not covered")
            continue
        est = pt.get("drift_factor", pt.get("coulomb_friction"))
        sd = pt.get("drift_factor_sigma", pt.get("coulomb_friction_sigma"))
        ok = interval[0] <= value <= interval[1]
        hit += ok
        print(r["case"], name, f"truth {value:.6g} estimate {est:.6g} sd {sd:.2g} z {(est - value) / sd:+.2f}", ok)
    lo, hi = wilson_interval(hit, n) if n else (float("nan"), float("nan"))
    print(
        f"covered {hit}/{n} [{100 * lo:.1f}, {100 * hi:.1f}] %; median seconds a record {statistics.median(secs) if secs else float('nan')}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
