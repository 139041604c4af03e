"""The sample-interval check of every plant on synthetic records (issue 50 item 3, through the plant interface).

:func:`engine.diagnosis.plant_plausibility.interval_evidence` is the statistic behind the
``sample_interval`` warning of a generic plant's diagnosis: how many times better (chi2) the record fits
the plant read at another sample interval than as declared; the warning needs
:data:`~engine.diagnosis.plausibility.EVIDENCE`. This script measures, per plant, on records drawn as
:mod:`engine.validation.plant_check` draws them (the plant's shipped record's inputs, the calibrated
parameters +-10 % around nominal, one catalogue or held-back effect, or none; the plant's own noise):

* **false warnings**: records read at their true interval whose evidence reaches ``EVIDENCE``
  (clean, catalogue and held-back records counted apart);
* **detection**: the same records declared with a wrong interval (``a`` x the true one, for every
  factor ``a`` of :data:`~engine.diagnosis.plausibility.TIME_FACTORS`: the plant's own reading,
  :meth:`~engine.plants.base.Plant.retimed`) whose evidence reaches ``EVIDENCE`` *and* names the
  reading that undoes the mistake (factor ``1/a``).

The models compared at each reading are the record's true calibrated parameters without the effect
and the nominal model: what a diagnosis's answer is when the effect is not named (the check runs in a
diagnosis only after a misfit; here it runs on every record, which can only add false warnings). No
diagnosis runs, so the figures are of the statistic and the threshold, not of whole answers; the
tests diagnose one record of each kind.

EMPS has nothing to measure: its reader refuses any grid but the controller's 1 kHz.

    .venv/bin/python bench/interval_check.py --plant brfd --cases 40 --held-back 20 --clean 20 --seed 51 \
        --json docs/validation/plausibility/interval-brfd-seed51.json
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from engine.atomic import write_json_atomic
from engine.diagnosis.plant_plausibility import interval_evidence
from engine.diagnosis.plausibility import EVIDENCE, TIME_FACTORS
from engine.plants import get_plant
from engine.validation.plant_check import CheckCase, draw_cases, draw_clean, draw_held_back
from engine.validation.provenance import code_version
from engine.validation.stats import wilson_interval

logger = logging.getLogger("interval_check")


def kind(case: CheckCase) -> str:
    """``clean``, ``catalogue`` or ``held_back``."""
    return "clean" if case.effect is None else ("held_back" if case.held_back else "catalogue")


def measure(plant: Any, record: Any, cases: list[CheckCase], seed: int) -> list[dict[str, Any]]:
    """Per case: its kind, effect, and the evidence and factor as declared and at every wrong interval."""
    rng = np.random.default_rng([seed, 7])
    rows = []
    for case in cases:
        truth = {**case.calibration, **({case.effect: case.value} if case.effect is not None else {})}
        synthetic = plant.synthesize(record, truth, rng)
        models = [dict(case.calibration), {}]
        t0 = time.perf_counter()
        evidence, factor = interval_evidence(plant, synthetic, models, plant.noise(synthetic))
        wrong = {}
        for a in TIME_FACTORS:
            try:
                declared = plant.retimed(synthetic, a)  # the record declared at a x its true interval
            except ValueError:
                continue
            ev, f = interval_evidence(plant, declared, models, plant.noise(declared))
            wrong[f"{a:g}"] = {"evidence": ev, "factor": f}
        rows.append(
            {
                "case": case.index,
                "kind": kind(case),
                "effect": case.effect,
                "value": None if math.isnan(case.value) else case.value,
                "evidence": evidence,
                "factor": factor,
                "wrong": wrong,
                "seconds": time.perf_counter() - t0,
            }
        )
        logger.info(
            "case %d %s: as declared %.3g (%gx); wrong: %s",
            case.index,
            case.effect,
            evidence,
            factor,
            ", ".join(f"{a}: {w['evidence']:.3g} ({w['factor']:g}x)" for a, w in wrong.items()),
        )
    return rows


def _rate(k: int, n: int) -> dict[str, Any]:
    lo, hi = wilson_interval(k, n)
    return {"k": k, "n": n, "low": lo, "high": hi}


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """False warnings per kind and detection per wrong factor (the right reading named), with Wilson intervals."""
    out: dict[str, Any] = {"false_warning": {}, "detected": {}}
    for k in ("clean", "catalogue", "held_back"):
        group = [r for r in rows if r["kind"] == k]
        if group:
            out["false_warning"][k] = _rate(sum(r["evidence"] >= EVIDENCE for r in group), len(group))
    for a in TIME_FACTORS:
        key = f"{a:g}"
        got = [r["wrong"][key] for r in rows if key in r["wrong"]]
        if got:
            hits = sum(w["evidence"] >= EVIDENCE and math.isclose(w["factor"] * a, 1.0) for w in got)
            out["detected"][key] = _rate(hits, len(got))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--plant", required=True, help="a registered plant or a .toml FMU plant description")
    p.add_argument("--cases", type=int, default=40, help="catalogue cases")
    p.add_argument("--held-back", type=int, default=0, help="held-back cases")
    p.add_argument("--clean", type=int, default=20, help="clean cases")
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--seconds", type=float, default=12.0, help="head of the shipped record the cases use [s]")
    p.add_argument("--json", type=Path)
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    code = code_version()
    plant = get_plant(args.plant)
    record = plant.example(None, args.seconds)
    cases = draw_cases(plant, record, args.cases, args.seed)
    cases += draw_clean(plant, record, args.clean, args.seed, first=len(cases))
    if args.held_back:
        cases += draw_held_back(plant, record, args.held_back, args.seed, first=len(cases))
    rows = measure(plant, record, cases, args.seed)
    summary = summarise(rows)
    for k, r in summary["false_warning"].items():
        sys.stdout.write(f"false warning, {k}: {r['k']}/{r['n']} [{100 * r['low']:.1f}, {100 * r['high']:.1f}] %\n")
    for a, r in summary["detected"].items():
        sys.stdout.write(f"declared {a}x: detected {r['k']}/{r['n']} [{100 * r['low']:.1f}, {100 * r['high']:.1f}] %\n")
    if args.json is not None:
        run = {
            "plant": args.plant,
            "record": getattr(record, "name", ""),
            "seconds_of_record": args.seconds,
            "seed": args.seed,
            "evidence_threshold": EVIDENCE,
            "code": code,
            "command": "python bench/interval_check.py " + " ".join(sys.argv[1:] if argv is None else argv),
        }
        write_json_atomic(args.json, {"run": run, "summary": summary, "rows": rows}, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
