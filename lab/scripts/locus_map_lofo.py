"""The locus's probability map, each spent family left out in turn (development data).

For each committed blind run of a family outside the catalogue, fit the locus's map on the other
runs and state it on that run's located answers; pool the stated probabilities and score them
(reliability table per group of stated probability, Brier score with its bootstrap interval).
Three maps: one probability for every answer (``constant``), one per part the answer names
(``parts``: its accuracy, shrunk by the map's prior, parts of fewer than 20 answers pooled) and the
isotonic map on the locus's misfit (``misfit``, the committed kind, :mod:`engine.diagnosis.confidence`). "Right" is the part the answer names (the locus
with the loci the record cannot tell from it) holding an effect of the record; ``--single`` scores
the single locus instead. Every run here is spent: development figures, not blind ones.

    python lab/scripts/locus_map_lofo.py docs/validation/v2-heldout-seed241 docs/validation/v2-sealed-seed257 \\
        docs/validation/v2-sealed2-seed263 docs/validation/v2-sealed3-seed269 docs/validation/v2-sealed4-seed281
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from engine.diagnosis.confidence import LOCUS_FEATURE, MIN_BLOCK, PRIOR, fit_isotonic, locus_feature
from engine.simulation.parameters import LOCUS_GROUPS, locus_group_name
from engine.validation.reliability import CaseOutcome, read_run, reliability_table

logger = logging.getLogger("locus_map_lofo")


def part_key(locus: str) -> str:
    """The part an answer naming ``locus`` names: its group's name, else the locus."""
    return locus_group_name(locus) or locus


def fit_parts(keys: Sequence[str], right: Sequence[bool]) -> Callable[[str], float]:
    """Per part, how often an answer naming it was right (Beta(PRIOR, PRIOR)-shrunk; parts of fewer than
    MIN_BLOCK answers pooled, and stated for a part never seen)."""
    counts: dict[str, list[int]] = {}
    for key, ok in zip(keys, right, strict=True):
        c = counts.setdefault(key, [0, 0])
        c[0] += 1
        c[1] += int(ok)
    rest = [c for c in counts.values() if c[0] < MIN_BLOCK]
    n_rest, k_rest = sum(c[0] for c in rest), sum(c[1] for c in rest)
    other = (k_rest + PRIOR) / (n_rest + 2 * PRIOR)
    values = {key: (k + PRIOR) / (n + 2 * PRIOR) for key, (n, k) in counts.items() if n >= MIN_BLOCK}
    return lambda key: values.get(key, other)


def _right(o: CaseOutcome, single: bool) -> bool:
    return bool(o.locus in o.true_loci) if single else bool(o.locus_correct)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="+", help="committed blind runs of families outside the catalogue")
    ap.add_argument("--single", action="store_true", help="score the single locus, not the part the answer names")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    runs = {p.name: [o for o in read_run(p).outcomes if o.locus_correct is not None and o.locus] for p in args.runs}
    out = [
        f"# The locus map, each family left out in turn ({'single locus' if args.single else 'the part named'})",
        "",
        "`python lab/scripts/locus_map_lofo.py " + " ".join(sys.argv[1:] if argv is None else argv) + "`",
        "",
        "| run | located | right | " + " | ".join(f"stated ({m})" for m in ("constant", "parts", "misfit")) + " |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    pooled: dict[str, list[tuple[float, bool]]] = {"constant": [], "parts": [], "misfit": []}
    for name, test in runs.items():
        train = [o for other, rows in runs.items() if other != name for o in rows]
        ys = [_right(o, args.single) for o in train]
        const = (sum(ys) + PRIOR) / (len(ys) + 2 * PRIOR)
        parts = fit_parts([part_key(str(o.locus)) for o in train], ys)
        xy = [(locus_feature(o.locus_estimate), y) for o, y in zip(train, ys, strict=True)]
        iso = fit_isotonic([x for x, _ in xy if x is not None], [y for x, y in xy if x is not None], LOCUS_FEATURE)
        stated: dict[str, list[float]] = {"constant": [], "parts": [], "misfit": []}
        for o in test:
            y = _right(o, args.single)
            x = locus_feature(o.locus_estimate)
            for key, p in (
                ("constant", const),
                ("parts", parts(part_key(str(o.locus)))),
                ("misfit", iso(x) if x is not None else const),
            ):
                stated[key].append(p)
                pooled[key].append((p, y))
        k = sum(_right(o, args.single) for o in test)
        means = " | ".join(f"{100 * sum(v) / len(v):.1f} %" for v in stated.values())
        out.append(f"| {name} | {len(test)} | {k} ({100 * k / len(test):.1f} %) | {means} |")
    for name, members in LOCUS_GROUPS.items():
        at = [o for rows in runs.values() for o in rows if set(o.true_loci) & set(members)]
        single = sum(o.locus in o.true_loci for o in at)
        pooled_k = sum(bool(o.locus_correct) for o in at)
        out += [
            "",
            f"Records of {name} ({', '.join(members)}), pooled: {len(at)} located; right as single loci "
            f"{single}, as the group {pooled_k}.",
        ]
    out += ["", "Pooled over the runs, each stated by the map fitted without it:", ""]
    out += [
        "| map | n | mean stated | observed | Brier | groups of >= 20 within 10 points |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for key, rows in pooled.items():
        t = reliability_table([p for p, _ in rows], [y for _, y in rows])
        d = t.to_dict()
        acc = d["accuracy"]
        out.append(
            f"| {key} | {d['n']} | {100 * d['mean_stated']:.1f} % | {acc['k']}/{acc['n']} = {100 * acc['rate']:.1f} % "
            f"[{100 * acc['low']:.1f}, {100 * acc['high']:.1f}] | {t.brier.text()} | {d['target_met']} |"
        )
        for b in d["bins"]:
            if b["n"]:
                o = b["observed"]
                out.append(
                    f"|  stated {b['low']:.1f}-{b['high']:.1f} | {b['n']} | {100 * b['mean_stated']:.1f} % | "
                    f"{o['k']}/{o['n']} = {100 * o['rate']:.1f} % | | |"
                )
    print("\n".join(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
