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
Clean cases (``--clean``) draw the calibrated parameters alone: the answer should be ``no_gap``
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
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.diagnosis.plant_gap import diagnose_plant
from engine.diagnosis.settings import DiagnosisSettings
from engine.plants.base import Plant, free_parameters, relative_errors
from engine.validation.stats import wilson_interval

__all__ = [
    "MIN_EFFECT",
    "PERTURBATION",
    "QUIET",
    "CheckCase",
    "CheckRow",
    "draw_cases",
    "draw_clean",
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
    """

    index: int
    effect: str | None
    value: float
    calibration: dict[str, float]
    strength: float


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
        return not self.clean and self.noise_strength <= DiagnosisSettings().min_strength

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


def draw_cases(plant: Plant, record: Any, n: int, seed: int) -> list[CheckCase]:
    """Draw ``n`` cases, the effects in turn through the catalogue (module docstring)."""
    rng = np.random.default_rng(seed)
    names = list(plant.catalogue)
    order = [names[i % len(names)] for i in rng.permutation(max(n, len(names)))][:n]
    cases = []
    for i, name in enumerate(order):
        effect = plant.catalogue[name].as_parameter()
        for _ in range(MAX_REDRAWS):
            cal = {
                p.name: float(np.clip(p.nominal + PERTURBATION * abs(p.nominal) * rng.uniform(-1, 1), p.lo, p.hi))
                for p in free_parameters(plant, record)
            }
            value = float(effect.value(float(rng.uniform(0.0, 1.0))))
            strength = _strength(plant, record, cal, name, value)
            if strength >= MIN_EFFECT:
                cases.append(CheckCase(i, name, value, cal, strength))
                break
        else:
            logger.warning("effect %s never reached %.1f %% on this record; case %d skipped", name, MIN_EFFECT, i)
    return cases


def draw_clean(plant: Plant, record: Any, n: int, seed: int, first: int = 0) -> list[CheckCase]:
    """Draw ``n`` clean cases: the calibrated parameters at random as :func:`draw_cases` draws them, no effect.

    ``first`` is the first case's index (after the effect cases of the same run).
    """
    rng = np.random.default_rng([seed, 1])  # a stream of its own: the effect cases of a seed stay as they were
    cases = []
    for i in range(n):
        cal = {
            p.name: float(np.clip(p.nominal + PERTURBATION * abs(p.nominal) * rng.uniform(-1, 1), p.lo, p.hi))
            for p in free_parameters(plant, record)
        }
        cases.append(CheckCase(first + i, None, math.nan, cal, 0.0))
    return cases


def _noise_strength(plant: Plant, synthetic: Any, case: CheckCase) -> float:
    """How far the true effect moves the synthetic record: the largest channel RMS of its change [noise RMS]."""
    if case.effect is None:
        return 0.0
    sl = plant.scored(synthetic)
    a = plant.simulate(synthetic, case.calibration)
    b = plant.simulate(synthetic, {**case.calibration, case.effect: case.value})
    levels = plant.noise(synthetic)
    return max(float(np.sqrt(np.mean((b[c][sl] - a[c][sl]) ** 2))) / levels[c].sigma for c in a)


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
        strength = _noise_strength(plant, synthetic, case)
        rows.append(CheckRow(case, named, value, report.status, share, dt, tuple(sorted(report.absorbed)), strength))
        logger.info(
            "case %d %s=%.4g: %s, named %s (%.0f s)", case.index, case.effect, case.value, report.status, named, dt
        )
    return rows


def summary(rows: Sequence[CheckRow]) -> str:
    """Markdown: rates with Wilson 95 % intervals, then one row per case."""
    n = len(rows)
    if n == 0:
        return "no cases\n"
    clean = [r for r in rows if r.clean]
    effects = [r for r in rows if not r.clean]
    open_ = [r for r in effects if not r.truth_absorbed]
    strong = [r for r in open_ if not r.weak]
    min_strength = DiagnosisSettings().min_strength
    out = [
        f"{n} synthetic cases: {len(clean)} clean, {len(effects)} with one effect; in {len(effects) - len(open_)} of "
        "these the diagnosis reported the true effect as absorbed by the calibration (it cannot be named beside a "
        f"refitted calibration). Strong: the true effect moves the record by more than {min_strength:g} noise RMS.\n",
        "| measure | cases | rate | 95 % interval |",
        "| --- | --- | --- | --- |",
    ]
    measures: tuple[tuple[str, list[CheckRow], Callable[[CheckRow], object]], ...] = (
        ("clean: answered `no_gap`", clean, lambda r: r.status == "no_gap"),
        ("clean: false alarm (an effect named, or `unexplained`)", clean, lambda r: r.false_alarm),
        ("strong: first named effect is the true one", strong, lambda r: r.top1),
        (
            "weak: answered `no_gap`/`weak_gap` or the true effect first",
            [r for r in open_ if r.weak],
            lambda r: r.weak_ok,
        ),
        ("first named effect is the true one", open_, lambda r: r.top1),
        ("true effect in the named set", open_, lambda r: r.found),
        ("named set is the true effect alone", open_, lambda r: r.exact),
        ("no effect named", open_, lambda r: not r.named),
        ("answered `unexplained`", open_, lambda r: r.status == "unexplained"),
        ("true effect reported as absorbed by the calibration", effects, lambda r: r.truth_absorbed),
        ("another effect named where the truth was absorbed", [r for r in rows if r.truth_absorbed], lambda r: r.named),
        (
            f"first named effect true, strength <= {STRONG:g} %",
            [r for r in open_ if r.case.strength <= STRONG],
            lambda r: r.top1,
        ),
        (
            f"first named effect true, strength > {STRONG:g} %",
            [r for r in open_ if r.case.strength > STRONG],
            lambda r: r.top1,
        ),
    )
    for label, group, hit in measures:
        if not group:
            continue
        k, m = sum(bool(hit(r)) for r in group), len(group)
        lo, hi = wilson_interval(k, m)
        which = (
            "not absorbed"
            if group is open_
            else "clean"
            if group is clean
            else "with an effect"
            if group is effects
            else "strong, not absorbed"
            if group is strong
            else "subset"
        )
        out.append(f"| {label} | {which} | {k}/{m} = {100 * k / m:.0f} % | [{100 * lo:.1f}, {100 * hi:.1f}] % |")
    times = sorted(r.seconds for r in rows)
    out.append(f"\nseconds per diagnosis: median {times[n // 2]:.0f}, max {times[-1]:.0f}\n")
    out += [
        "| case | true effect | true value | strength [%] | strength [noise RMS] | answer | named | value | share "
        "| absorbed by the calibration |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        v = "" if r.value is None else f"{r.value:.4g}"
        out.append(
            f"| {r.case.index} | {r.case.effect or '(clean)'} | {r.case.value:.4g} | {r.case.strength:.2f} | "
            f"{r.noise_strength:.3g} | {r.status} | {', '.join(r.named) or '-'} | {v} | {r.share:.3f} | "
            f"{', '.join(r.absorbed) or '-'} |"
        )
    return "\n".join(out) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``--plant NAME --cases N --seed S --record NAME --seconds T`` (a shipped record's inputs)."""
    from engine.plants import PLANTS, get_plant

    p = argparse.ArgumentParser(prog="python -m engine.validation.plant_check", description=__doc__.splitlines()[0])
    p.add_argument("--plant", default="emps", choices=sorted(PLANTS))
    p.add_argument("--cases", type=int, default=20)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--clean", type=int, default=0, help="clean cases (no effect) after the effect cases")
    p.add_argument(
        "--seconds",
        type=float,
        default=12.0,
        help="length of the record's head the cases use [s], where the plant's records can be cut",
    )
    p.add_argument("--record", help="the shipped record whose inputs the cases use (default the plant's first)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    logging.getLogger("engine.diagnosis.plant_gap").setLevel(logging.WARNING)
    plant = get_plant(args.plant)
    if args.record is not None and args.record not in plant.examples:
        p.error(f"plant {args.plant} ships the records {', '.join(plant.examples)}, not {args.record!r}")
    record = plant.example(args.record, args.seconds)
    cases = draw_cases(plant, record, args.cases, args.seed)
    cases += draw_clean(plant, record, args.clean, args.seed, first=len(cases))
    sys.stdout.write(summary(run_check(plant, record, cases, args.seed)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
