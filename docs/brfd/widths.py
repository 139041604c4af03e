"""The backlash width of every BRFD record in a directory, each alone and per series jointly.

    .venv/bin/python docs/brfd/widths.py DIR [--out docs/brfd/widths.md]

DIR holds the data set's JSON files (e.g. the full copy in ``../shared/data/brfd``; the package
ships three of them). Prints a Markdown table: per record the width fitted alone with its 95 %
profile interval, identifiable or why not, the correlation with sigma0 and the force error without
and with the play; then per series (dataset-1, dataset-2 sinusoidal, dataset-2 earthquakes) the
joint fit (one width shared), the spread of the per-record widths and their Birge ratio
(``sqrt(Q / (n - 1))`` of their inverse-variance pool: about 1 when they scatter as their sigmas say).
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np

from engine.identification.plant_width import fit_width
from engine.plants import get_plant
from engine.validation.stats import pooled_estimate


def _series(name: str) -> str:
    if name.startswith("dataset-1"):
        return "dataset-1 (sinusoidal, July 2022)"
    if "DBE" in name or "MCE" in name:
        return "dataset-2 (earthquake histories)"
    return "dataset-2 (sinusoidal, April 2023)"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("directory", type=Path)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    plant = get_plant("brfd")
    files = sorted(args.directory.glob("*.json"))
    per_series: dict[str, list[str]] = {}
    fits = {}
    for f in files:
        rec = plant.read(f)
        t0 = time.perf_counter()
        w = fit_width(plant, [rec])
        fits[rec.name] = (rec, w, time.perf_counter() - t0)
        per_series.setdefault(_series(rec.name), []).append(rec.name)
        sys.stderr.write(f"{rec.name}: {w.K * 1e3:.2f} mm\n")
    joint = {}
    summary = [
        "| series | records identifiable | their widths: mean, spread (sd) [mm] | Birge ratio of their widths | "
        "joint fit [mm] | joint interval [mm] |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for series, names in per_series.items():
        ok = [n for n in names if fits[n][1].identifiable]
        ks = np.array([fits[n][1].K for n in ok]) * 1e3
        # the identifiable records jointly; where none is, all of them jointly (does pooling help?)
        j = fit_width(plant, [fits[n][0] for n in (ok or names)])
        joint[series] = j if ok else None
        spread = f"{ks.mean():.2f}, {ks.std(ddof=1):.2f}" if ks.size > 1 else (f"{ks[0]:.2f}, -" if ks.size else "-")
        jtxt = f"{j.K * 1e3:.2f} +- {j.sigma_K * 1e3:.2f}" + (
            ""
            if ok
            else " (all records; "
            + ("identifiable)" if j.identifiable else "not identifiable: " + "; ".join(j.reasons) + ")")
        )
        jint = f"[{j.interval[0] * 1e3:.2f}, {j.interval[1] * 1e3:.2f}]"
        # do the per-record widths scatter as their stated sigmas say? (issue 50: Birge ratio <= 2)
        birge = (
            f"{pooled_estimate([fits[n][1].K for n in ok], [fits[n][1].sigma_K for n in ok]).birge_ratio:.2f}"
            if len(ok) > 1
            else "-"
        )
        summary.append(f"| {series} | {len(ok)}/{len(names)} | {spread} | {birge} | {jtxt} | {jint} |")
    lines = [
        "| record | tension [lb] | width [mm] | 95 % interval [mm] | identifiable | holds its series' joint width | "
        "corr(K, sigma0) | force error without -> with play [%] | s |",
        "| --- | ---: | ---: | --- | --- | --- | ---: | --- | ---: |",
    ]
    for name, (rec, w, dt) in fits.items():
        j = joint[_series(name)]
        holds = (
            "-" if j is None or not w.identifiable else ("yes" if w.interval[0] <= j.K <= w.interval[1] else "**no**")
        )
        e = w.relative_error[0]
        lines.append(
            f"| {name} | {rec.tension if rec.tension is not None else '-'} | {w.K * 1e3:.2f} +- {w.sigma_K * 1e3:.2f} | "
            f"[{w.interval[0] * 1e3:.2f}, {w.interval[1] * 1e3:.2f}] | "
            f"{'yes' if w.identifiable else 'no: ' + '; '.join(w.reasons)} | {holds} | {w.correlation['sigma0']:+.2f} | "
            f"{e['without']['force']:.1f} -> {e['with_width']['force']:.1f} | {dt:.0f} |"
        )
    lines += ["", *summary]
    text = "\n".join(lines) + "\n"
    if args.out:
        args.out.write_text(text)
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
