"""A synthetic check of the diagnosis of any plant, through the plant interface.

On real data the answer is unknown; this check says how far the diagnosis can be trusted on a
given record's excitation. Each case draws one catalogue effect at a random value and the
calibrated parameters at random within +-:data:`PERTURBATION` of their nominal values, simulates
a record on the real record's inputs and grid (:meth:`~engine.plants.base.Plant.synthesize`,
with the plant's own measurement imperfections), and diagnoses it with
:func:`engine.diagnosis.plant_gap.diagnose_plant`, which sees the synthetic record only. The
truths are kept apart and compared after every diagnosis is done.

A drawn effect counts only when it matters on this excitation: when it changes the simulated
channels by at least :data:`MIN_EFFECT` relative error [%] summed in quadrature over the
channels (an effect the record cannot show is redrawn, up to :data:`MAX_REDRAWS` times).
Held-back cases (``--held-back``) draw an effect of the plant's held-back family
(:attr:`~engine.plants.base.Plant.held_back`: outside the catalogue, one per locus): the answer
should name no catalogue set as the explanation and say where the gap lies (the verdict's locus,
from :mod:`engine.diagnosis.plant_locus`). Clean cases (``--clean``) draw the calibrated parameters alone: the answer should be ``no_gap``
(``weak_gap`` is no false alarm either); a named effect or ``unexplained`` is a false alarm. After
the diagnosis, each effect's strength against the plant's noise (:meth:`~engine.plants.base.Plant.noise`)
says whether the record shows it beyond the noise: a weak effect (at most ``min_strength`` noise
RMS, the backlash drive's rule) may be answered ``no_gap``/``weak_gap``.

What it does not test: the real record's model error beyond the catalogue (a synthetic record is
the model plus one effect), and noise other than the plant's own (:meth:`synthesize`). It
measures whether the catalogue's effects can be told apart on this excitation, which is what a
verdict on the real record rests on.

    .venv/bin/python -m engine.validation.plant_check --plant emps --cases 40 --seed 2 --seconds 12
    .venv/bin/python -m engine.validation.plant_check --plant brfd --cases 40 --clean 40 --seed 2
    .venv/bin/python -m engine.validation.plant_check --plant backlash_drive --cases 40 --seed 2
    .venv/bin/python -m engine.validation.plant_check --plant engine/plants/fmu/examples/quarter_car/plant.toml \
        --cases 40 --clean 20 --seed 43
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.atomic import write_json_atomic
from engine.diagnosis.plant_gap import change_over_noise, diagnose_plant
from engine.diagnosis.settings import DiagnosisSettings
from engine.plants.base import CandidateEffect, Plant, free_parameters, relative_errors
from engine.plants.noise import NoiseLevel
from engine.validation.provenance import code_version
from engine.validation.stats import wilson_interval

__all__ = [
    "MIN_EFFECT",
    "PERTURBATION",
    "QUIET",
    "CheckCase",
    "CheckRow",
    "Measure",
    "draw_cases",
    "draw_clean",
    "draw_held_back",
    "measures",
    "report",
    "run_check",
    "summary",
]

logger = logging.getLogger(__name__)

#: Relative half-width of the calibrated parameters' random draw around their nominal values.
PERTURBATION: float = 0.1
#: Smallest change an effect must make to the channels, relative error [%] in quadrature.
MIN_EFFECT: float = 1.0
#: Strength [%] above which a case is reported apart: the effect changes the record by more than
#: the record itself (e.g. a delay that sets the loop oscillating), a different machine more than a gap.
STRONG: float = 100.0
#: Draws of an effect's value before the case gives up on that effect and draws another.
MAX_REDRAWS: int = 20
#: The strength [noise RMS] at or below which an effect is weak: the diagnosis's own ``min_strength``.
MIN_STRENGTH: float = DiagnosisSettings().min_strength
#: The answers that say the record shows no gap to attribute.
QUIET: tuple[str, ...] = ("no_gap", "weak_gap")


@dataclass(frozen=True)
class CheckCase:
    """One synthetic case: the truth (kept from the diagnosis).

    Attributes
    ----------
    index : int
    effect : str or None
        The true effect (None: a clean case, the calibrated model alone).
    value : float
        Its value, in its unit (nan for a clean case).
    calibration : dict of str to float
        The true calibrated parameters.
    strength : float
        What the effect changes, relative error [%] in quadrature over the channels.
    held_back : bool
        The effect is of the plant's held-back family (outside the catalogue).
    locus : str or None
        The effect's locus.
    """

    index: int
    effect: str | None
    value: float
    calibration: dict[str, float]
    strength: float
    held_back: bool = False
    locus: str | None = None


@dataclass(frozen=True)
class CheckRow:
    """One diagnosed case beside its truth."""

    case: CheckCase
    named: tuple[str, ...]
    value: float | None
    status: str
    share: float
    seconds: float
    absorbed: tuple[str, ...] = ()
    noise_strength: float = 0.0
    locus: str | None = None
    locus_confidence: float | None = None
    warnings: tuple[str, ...] = ()  # the answer's warnings, as "code:channel"

    @property
    def catalogue(self) -> bool:
        """A case with one of the catalogue's effects."""
        return self.case.effect is not None and not self.case.held_back

    @property
    def locus_right(self) -> bool:
        """The answer's locus (the first named effect's, or the locus estimate's) is the true effect's."""
        return self.locus is not None and self.locus == self.case.locus

    @property
    def clean(self) -> bool:
        """A case with no effect."""
        return self.case.effect is None

    @property
    def false_alarm(self) -> bool:
        """A clean case answered with a gap (an effect named, or ``unexplained``)."""
        return self.clean and self.status not in QUIET

    @property
    def weak(self) -> bool:
        """An effect case whose effect moves the record by at most ``min_strength`` noise RMS."""
        return not self.clean and self.noise_strength <= MIN_STRENGTH

    @property
    def weak_ok(self) -> bool:
        """A weak case answered as weak (``no_gap``, ``weak_gap``) or with the true effect first."""
        return self.status in QUIET or self.top1

    @property
    def truth_absorbed(self) -> bool:
        """The diagnosis reported the true effect as absorbed by the calibration (it cannot be named)."""
        return self.case.effect is not None and self.case.effect in self.absorbed

    @property
    def top1(self) -> bool:
        """The named set's first effect is the true one."""
        return bool(self.named) and self.named[0] == self.case.effect

    @property
    def exact(self) -> bool:
        """The named set is the true effect alone."""
        return self.named == (self.case.effect,)

    @property
    def found(self) -> bool:
        """The true effect is in the named set."""
        return self.case.effect in self.named


def _strength(plant: Plant, record: Any, base: dict[str, float], effect: str, value: float) -> float:
    sl = plant.scored(record)
    a = plant.simulate(record, base)
    b = plant.simulate(record, {**base, effect: value})
    return math.sqrt(sum(e**2 for e in relative_errors(a, b, sl).values()))


def _perturbed(plant: Plant, record: Any, rng: np.random.Generator) -> dict[str, float]:
    """The calibrated parameters the record leaves free, each within +-:data:`PERTURBATION` of nominal."""
    return {
        p.name: float(np.clip(p.nominal + PERTURBATION * abs(p.nominal) * rng.uniform(-1, 1), p.lo, p.hi))
        for p in free_parameters(plant, record)
    }


def _draw_effects(
    plant: Plant,
    record: Any,
    effects: Mapping[str, CandidateEffect],
    n: int,
    rng: np.random.Generator,
    first: int,
    held_back: bool,
) -> list[CheckCase]:
    """``n`` cases, ``effects`` in turn in a random order, each value redrawn until the record shows it."""
    names = list(effects)
    order = [names[i % len(names)] for i in rng.permutation(max(n, len(names)))][:n]
    cases = []
    for i, name in enumerate(order):
        effect = effects[name].as_parameter()
        for _ in range(MAX_REDRAWS):
            cal = _perturbed(plant, record, rng)
            value = float(effect.value(float(rng.uniform(0.0, 1.0))))
            strength = _strength(plant, record, cal, name, value)
            if strength >= MIN_EFFECT:
                cases.append(CheckCase(first + i, name, value, cal, strength, held_back, effects[name].locus))
                break
        else:
            logger.warning("effect %s never reached %.1f %% on this record; case %d skipped", name, MIN_EFFECT, i)
    return cases


def draw_cases(plant: Plant, record: Any, n: int, seed: int) -> list[CheckCase]:
    """Draw ``n`` cases, the effects in turn through the catalogue (module docstring)."""
    return _draw_effects(plant, record, plant.catalogue, n, np.random.default_rng(seed), 0, False)


def draw_held_back(
    plant: Plant, record: Any, n: int, seed: int, first: int = 0, family: str = "held_back"
) -> list[CheckCase]:
    """Draw ``n`` cases of one of the plant's families outside the catalogue (``held_back`` or
    ``sealed``), in turn, as :func:`draw_cases` draws the catalogue's; ``first`` is the first case's index."""
    effects: Mapping[str, CandidateEffect] = getattr(plant, family)
    if n and not effects:
        raise ValueError(f"plant {plant.name!r} declares no {family} family")
    rng = np.random.default_rng([seed, 2])  # a stream of its own: the other cases of a seed stay as they were
    return _draw_effects(plant, record, effects, n, rng, first, True)


def draw_clean(plant: Plant, record: Any, n: int, seed: int, first: int = 0) -> list[CheckCase]:
    """Draw ``n`` clean cases: the calibrated parameters at random as :func:`draw_cases` draws them, no effect.

    ``first`` is the first case's index (after the effect cases of the same run).
    """
    rng = np.random.default_rng([seed, 1])  # a stream of its own: the effect cases of a seed stay as they were
    return [CheckCase(first + i, None, math.nan, _perturbed(plant, record, rng), 0.0) for i in range(n)]


def _noise_strength(plant: Plant, synthetic: Any, case: CheckCase, levels: Mapping[str, NoiseLevel]) -> float:
    """How far the true effect moves the synthetic record: the largest channel RMS of its change [noise RMS],
    against the noise ``levels`` the diagnosis read on that record."""
    if case.effect is None:
        return 0.0
    sl = plant.scored(synthetic)
    a = plant.simulate(synthetic, case.calibration)
    b = plant.simulate(synthetic, {**case.calibration, case.effect: case.value})
    return change_over_noise({c: v[sl] for c, v in a.items()}, {c: v[sl] for c, v in b.items()}, levels)


def run_check(plant: Plant, record: Any, cases: Sequence[CheckCase], seed: int) -> list[CheckRow]:
    """Diagnose a synthetic record per case (the diagnosis sees the record only; the truth's strength
    against the plant's noise is computed after it)."""
    rng = np.random.default_rng(seed + 1)
    rows = []
    for case in cases:
        truth = {**case.calibration, **({case.effect: case.value} if case.effect is not None else {})}
        synthetic = plant.synthesize(record, truth, rng)
        t0 = time.perf_counter()
        report = diagnose_plant(plant, synthetic)
        dt = time.perf_counter() - t0
        named = report.named.effects if report.named else ()
        value = report.named.fit.values.get(case.effect) if report.named and case.effect else None
        share = report.named.share if report.named else 0.0
        levels = report.gate.levels if report.gate is not None else plant.noise(synthetic)
        strength = _noise_strength(plant, synthetic, case, levels)
        answer = report.to_dict(plant)
        verdict = answer["verdict"]
        rows.append(
            CheckRow(
                case,
                named,
                value,
                report.status,
                share,
                dt,
                tuple(sorted(report.absorbed)),
                strength,
                verdict["locus"],
                verdict["locus_confidence"],
                tuple(f"{w['code']}:{w['channel']}" for w in answer["warnings"]),
            )
        )
        logger.info(
            "case %d %s=%.4g: %s, named %s, locus %s (%.0f s)",
            case.index,
            case.effect,
            case.value,
            report.status,
            named,
            verdict["locus"],
            dt,
        )
    return rows


@dataclass(frozen=True)
class Measure:
    """One rate of the check: ``k`` of ``n`` cases of group ``group`` are hits."""

    key: str
    label: str
    group: str
    k: int
    n: int

    def to_dict(self) -> dict[str, Any]:
        lo, hi = wilson_interval(self.k, self.n)
        return {
            "key": self.key,
            "label": self.label,
            "group": self.group,
            "k": self.k,
            "n": self.n,
            "low": lo,
            "high": hi,
        }


def measures(rows: Sequence[CheckRow]) -> list[Measure]:
    """The check's rates, each over its group of cases (groups without a case are left out)."""
    clean = [r for r in rows if r.clean]
    effects = [r for r in rows if r.catalogue]
    open_ = [r for r in effects if not r.truth_absorbed]
    strong = [r for r in open_ if not r.weak]
    held = [r for r in rows if r.case.held_back]
    held_strong = [r for r in held if not r.weak]
    specs: tuple[tuple[str, str, str, list[CheckRow], Callable[[CheckRow], object]], ...] = (
        ("clean_no_gap", "clean: answered `no_gap`", "clean", clean, lambda r: r.status == "no_gap"),
        (
            "clean_false_alarm",
            "clean: false alarm (an effect named, or `unexplained`)",
            "clean",
            clean,
            lambda r: r.false_alarm,
        ),
        (
            "clean_warned",
            "clean: a plausibility warning (a record of the model itself)",
            "clean",
            clean,
            lambda r: r.warnings,
        ),
        (
            "scale_warned",
            "a `channel_scale` warning (every record is in its declared units)",
            "every case",
            list(rows),
            lambda r: any(w.startswith("channel_scale:") for w in r.warnings),
        ),
        ("strong_top1", "strong: first named effect is the true one", "strong, not absorbed", strong, lambda r: r.top1),
        (
            "weak_ok",
            "weak: answered `no_gap`/`weak_gap` or the true effect first",
            "weak, not absorbed",
            [r for r in open_ if r.weak],
            lambda r: r.weak_ok,
        ),
        ("top1", "first named effect is the true one", "not absorbed", open_, lambda r: r.top1),
        ("found", "true effect in the named set", "not absorbed", open_, lambda r: r.found),
        ("exact", "named set is the true effect alone", "not absorbed", open_, lambda r: r.exact),
        ("none_named", "no effect named", "not absorbed", open_, lambda r: not r.named),
        ("unexplained", "answered `unexplained`", "not absorbed", open_, lambda r: r.status == "unexplained"),
        (
            "absorbed",
            "true effect reported as absorbed by the calibration",
            "with an effect",
            effects,
            lambda r: r.truth_absorbed,
        ),
        (
            "named_where_absorbed",
            "another effect named where the truth was absorbed",
            "absorbed",
            [r for r in rows if r.truth_absorbed],
            lambda r: r.named,
        ),
        (
            "top1_moderate",
            f"first named effect true, strength <= {STRONG:g} %",
            "not absorbed",
            [r for r in open_ if r.case.strength <= STRONG],
            lambda r: r.top1,
        ),
        (
            "held_back_locus",
            "held-back, strong: the answer's locus is the effect's",
            "held-back, strong",
            held_strong,
            lambda r: r.locus_right,
        ),
        (
            "held_back_abstained",
            "held-back, strong: not answered `explained` (no catalogue set claims it)",
            "held-back, strong",
            held_strong,
            lambda r: r.status != "explained",
        ),
        (
            "held_back_unexplained",
            "held-back, strong: answered `unexplained`",
            "held-back, strong",
            held_strong,
            lambda r: r.status == "unexplained",
        ),
        (
            "held_back_weak_ok",
            "held-back, weak: answered `no_gap`/`weak_gap` or the right locus",
            "held-back, weak",
            [r for r in held if r.weak],
            lambda r: r.status in QUIET or r.locus_right,
        ),
        (
            "top1_large",
            f"first named effect true, strength > {STRONG:g} %",
            "not absorbed",
            [r for r in open_ if r.case.strength > STRONG],
            lambda r: r.top1,
        ),
    )
    return [
        Measure(key, label, group, sum(bool(hit(r)) for r in members), len(members))
        for key, label, group, members, hit in specs
        if members
    ]


def summary(rows: Sequence[CheckRow]) -> str:
    """Markdown: rates with Wilson 95 % intervals, then one row per case."""
    n = len(rows)
    if n == 0:
        return "no cases\n"
    n_clean = sum(r.clean for r in rows)
    n_absorbed = sum(r.truth_absorbed for r in rows)
    min_strength = MIN_STRENGTH
    out = [
        f"{n} synthetic cases: {n_clean} clean, {n - n_clean} with one effect; in {n_absorbed} of "
        "these the diagnosis reported the true effect as absorbed by the calibration (it cannot be named beside a "
        f"refitted calibration). Strong: the true effect moves the record by more than {min_strength:g} noise RMS.\n",
        "| measure | cases | rate | 95 % interval |",
        "| --- | --- | --- | --- |",
    ]
    for m in measures(rows):
        lo, hi = wilson_interval(m.k, m.n)
        out.append(
            f"| {m.label} | {m.group} | {m.k}/{m.n} = {100 * m.k / m.n:.0f} % | [{100 * lo:.1f}, {100 * hi:.1f}] % |"
        )
    times = sorted(r.seconds for r in rows)
    out.append(f"\nseconds per diagnosis: median {times[n // 2]:.0f}, max {times[-1]:.0f}\n")
    out += [
        "| case | true effect | true value | true locus | strength [%] | strength [noise RMS] | answer | named "
        "| value | share | locus | absorbed by the calibration |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        v = "" if r.value is None else f"{r.value:.4g}"
        held = " (held back)" if r.case.held_back else ""
        out.append(
            f"| {r.case.index} | {r.case.effect or '(clean)'}{held} | {r.case.value:.4g} | {r.case.locus or '-'} | "
            f"{r.case.strength:.2f} | {r.noise_strength:.3g} | {r.status} | {', '.join(r.named) or '-'} | {v} | "
            f"{r.share:.3f} | {r.locus or '-'} | {', '.join(r.absorbed) or '-'} |"
        )
    return "\n".join(out) + "\n"


def report(rows: Sequence[CheckRow], run: dict[str, Any]) -> dict[str, Any]:
    """The JSON report of a run: what ran (``run``), the rates with Wilson 95 % intervals, every case."""
    times = sorted(r.seconds for r in rows)
    return {
        "run": run,
        "n": len(rows),
        "min_strength_noise_rms": MIN_STRENGTH,
        "measures": [m.to_dict() for m in measures(rows)],
        "seconds": {"median": times[len(times) // 2], "max": times[-1]} if times else None,
        "cases": [
            {
                "index": r.case.index,
                "effect": r.case.effect,
                "held_back": r.case.held_back,
                "true_locus": r.case.locus,
                "value": None if r.case.effect is None else r.case.value,
                "calibration": r.case.calibration,
                "strength_percent": r.case.strength,
                "strength_noise_rms": r.noise_strength,
                "status": r.status,
                "named": list(r.named),
                "named_value": r.value,
                "share": r.share,
                "absorbed": list(r.absorbed),
                "locus": r.locus,
                "locus_confidence": r.locus_confidence,
                "warnings": list(r.warnings),
                "seconds": r.seconds,
            }
            for r in rows
        ],
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``--plant NAME --cases N --seed S --record NAME --seconds T`` (a shipped record's inputs)."""
    from engine.plants import PLANTS, get_plant, is_description

    p = argparse.ArgumentParser(prog="python -m engine.validation.plant_check", description=__doc__.splitlines()[0])
    p.add_argument(
        "--plant",
        default="emps",
        help=f"a registered plant ({', '.join(sorted(PLANTS))}) or a plant description file (.toml: an FMU plant)",
    )
    p.add_argument("--cases", type=int, default=20)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--clean", type=int, default=0, help="clean cases (no effect) after the effect cases")
    p.add_argument("--held-back", type=int, default=0, help="cases of a family outside the catalogue (--family), last")
    p.add_argument(
        "--family",
        choices=("held_back", "sealed"),
        default="held_back",
        help="the family --held-back draws from: the held-back one, or the sealed one (scored once, blind)",
    )
    p.add_argument(
        "--seconds",
        type=float,
        default=12.0,
        help="length of the record's head the cases use [s], where the plant's records can be cut",
    )
    p.add_argument("--record", help="the shipped record whose inputs the cases use (default the plant's first)")
    p.add_argument("--json", type=Path, help="also write the JSON report (rates and every case) to this file")
    args = p.parse_args(argv)
    if args.plant not in PLANTS and not is_description(args.plant):
        p.error(
            f"--plant: {args.plant!r} is neither a registered plant ({', '.join(sorted(PLANTS))}) nor a .toml description"
        )
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    logging.getLogger("engine.diagnosis.plant_gap").setLevel(logging.WARNING)
    code = code_version()  # the code this run imports now, not the tree's state when it ends
    plant = get_plant(args.plant)
    if args.record is not None and args.record not in plant.examples:
        p.error(f"plant {args.plant} ships the records {', '.join(plant.examples)}, not {args.record!r}")
    record = plant.example(args.record, args.seconds)
    cases = draw_cases(plant, record, args.cases, args.seed)
    cases += draw_clean(plant, record, args.clean, args.seed, first=len(cases))
    cases += draw_held_back(plant, record, args.held_back, args.seed, first=len(cases), family=args.family)
    rows = run_check(plant, record, cases, args.seed)
    sys.stdout.write(summary(rows))
    if args.json is not None:
        run = {
            "plant": args.plant,
            "record": getattr(record, "name", args.record),
            "seconds_of_record": args.seconds,
            "seed": args.seed,
            "cases": args.cases,
            "clean": args.clean,
            "held_back": args.held_back,
            "family": args.family,
            "code": code,
            "command": "python -m engine.validation.plant_check " + " ".join(sys.argv[1:] if argv is None else argv),
        }
        write_json_atomic(args.json, report(rows, run), indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
