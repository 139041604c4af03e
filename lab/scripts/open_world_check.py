"""Development check of the open-world part of the confidence map (engine/diagnosis/open_world.py).

    PYTHONPATH=. .venv/bin/python lab/scripts/open_world_check.py

Reads committed runs only (nothing is diagnosed again). Two checks, both on records whose figures are
spent (development data, not validation):

1. Leave one family out: the open-world part is fitted on the development runs' in-catalogue
   records and two of the three spent families kept for scoring, and applied to the third's
   ``explained`` answers (all of them catalogue stand-ins): what they stated as run, what they state
   now, observed.
2. A mixed run as the field would give it: the held-out in-family run seed 229 with its held-back
   records (the family the diagnosis was developed on) replaced by a spent family's (the one left
   out of the fit): the explained answers per band of the nominal chi2/n, stated (verdict map x one
   minus the stand-in probability) against observed, with Wilson intervals.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

from engine.diagnosis.confidence import calibrated_confidence, load_map
from engine.diagnosis.open_world import fit_open_world
from engine.validation.reliability import IN_CATALOGUE_KINDS, CaseOutcome, explained_by_gap, read_run
from engine.validation.stats import wilson_interval

logger = logging.getLogger("open_world_check")

RUNS = Path("docs/validation")
DEVELOPMENT = [f"v2-seed{s}" for s in (97, 151, 163, 173, 191, 223)] + [f"v1-seed{s}" for s in (193, 199, 211)]
SPENT = ["v2-heldout-seed241", "v2-sealed-seed257", "v2-sealed2-seed263"]


def _pct(k: int, n: int) -> str:
    lo, hi = wilson_interval(k, n) if n else (float("nan"), float("nan"))
    return f"{k}/{n} = {100 * k / n:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}]" if n else "0/0"


def main() -> None:
    logging.basicConfig(level=logging.WARNING)
    dev = [o for name in DEVELOPMENT for o in read_run(RUNS / name).outcomes]
    inside = explained_by_gap(dev, IN_CATALOGUE_KINDS)
    spent = {name: read_run(RUNS / name).outcomes for name in SPENT}
    held = read_run(RUNS / "v2-seed229").outcomes
    committed = load_map()
    print("| left out | stand-in probability (weak, strong) | explained | stated as run | stated now | observed |")
    print("| --- | --- | --- | --- | --- | --- |")
    mixed: list[tuple[str, CaseOutcome, float]] = []
    for left in SPENT:
        world = fit_open_world(inside, explained_by_gap(o for n in SPENT if n != left for o in spent[n]))
        cmap = replace(committed, open_world=world)
        expl = [o for o in spent[left] if o.status == "explained"]
        now = [calibrated_confidence(o.status, o.score or 0.0, cmap, o.nominal_chi2) for o in expl]
        as_run = [o.confidence or 0.0 for o in expl]
        print(
            f"| {left} | {world.stand_in(0.0):.3f}, {world.stand_in(1e9):.3f} | {len(expl)} | "
            f"{100 * sum(as_run) / len(expl):.1f} % | {100 * sum(now) / len(expl):.1f} % | "
            f"{sum(o.correct for o in expl)}/{len(expl)} |"
        )
        for o in [*(o for o in held if o.kind != "held_back"), *spent[left]]:
            if o.status == "explained" and o.score is not None:
                mixed.append((left, o, calibrated_confidence(o.status, o.score, cmap, o.nominal_chi2)))
    print()
    print("Seed 229's in-catalogue and clean records with the left-out family as the records outside the catalogue:")
    print()
    print("| left out | band | explained | mean stated | observed (Wilson 95 %) |")
    print("| --- | --- | --- | --- | --- |")
    for left in SPENT:
        for band, sel in (("chi2/n < 10", lambda x: x < 10), ("chi2/n >= 10", lambda x: x >= 10)):
            rows = [(o, p) for lf, o, p in mixed if lf == left and o.nominal_chi2 is not None and sel(o.nominal_chi2)]
            k = sum(o.correct for o, _ in rows)
            stated = sum(p for _, p in rows) / len(rows) if rows else float("nan")
            print(f"| {left} | {band} | {len(rows)} | {100 * stated:.1f} % | {_pct(k, len(rows))} |")


if __name__ == "__main__":
    main()
