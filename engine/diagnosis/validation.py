"""Blind validation of the gap diagnosis on simulated records whose cause is withheld.

Protocol (issue 4)
------------------
1. :func:`generate_cases` draws cases of three kinds:

   * ``effect``: one effect of the catalogue, drawn at random, at a random
     value in its range (uniform; log-uniform for the multiplicative effects
     spanning two decades or more: contact stiffness, contact damping, and the
     sensor low-pass cut-off);
   * ``left_out``: the same, but the effect is removed from the library handed
     to the diagnosis (leave-one-effect-out), and with it every effect that is the
     same physics on a record (:data:`SAME_PHYSICS`: a measurement delay and a trigger
     offset are one shift of every channel; revision of 2026-11-26, below);
   * ``clean``: no effect.

   Every case has a random operating point (K uniform in [0.0025, 0.01] m, J1
   in [0.75, 0.93] kg m^2, c in [0.8, 1.5]), c1 = 0.2 as the record's only
   condition (K, J1 and c are unknown to the diagnosis), and white Gaussian
   noise of SNR uniform in [30, 50] dB on every channel (the project's
   convention, :func:`engine.simulation.noise.noise_std`: noise standard
   deviation = channel standard deviation * 10^(-SNR/20)).

2. **Strength rule**: an effect counts only where it moves the record clearly
   beyond the noise: the RMS of (record with the effect - record without it,
   same operating point, noiseless) exceeds 3 times the noise standard
   deviation on at least one channel. Weaker draws are scored as clean cases
   (expected answer ``no_gap``).

3. :func:`write_cases` writes the records (and the names of the effects the
   diagnosis may use) to ``<out>/cases/`` and the answer key to
   ``<out>/key/answer_key.json``. :func:`diagnose_cases` reads only
   ``cases/`` and writes ``results/``; :func:`score` reads the key only after
   every diagnosis is done. The run is resumable (since 2026-11-27): ``<out>/run.json``
   (:data:`engine.run_manifest.MANIFEST`) says what drew the cases, and every case, key and result file is written
   atomically, so :func:`run_validation` called again with the same settings keeps what an
   interrupted run wrote and diagnoses the rest.

Expected answers: ``explained`` with the right effect, or one that is the same
physics (:data:`SAME_PHYSICS`) (counting ``effect`` cases), ``unexplained`` (counting ``left_out`` cases), ``no_gap`` (clean and
weak cases; for a weak draw ``weak_gap``, a real gap too weak to attribute, is
right too).

Revision of 2026-11-26 (the same-physics groups of protocol 2)
---------------------------------------------------------------
Until then a left-out measurement delay left the trigger offset in the library, and a delay
answered as a trigger offset was a top-1 miss. For a positive value the two are the same record
(docs/diagnosis.md section 8), so neither figure measured the diagnosis: the blind run of seed 193
(code 14aae4f) had 7 of its 16 abstention misses and 1 of its 3 top-1 misses there. Protocol 2
(:mod:`engine.validation`) treated them as one physics from the start; protocol 1 now does the
same, in its leave-out and in its top-1/top-2 scoring. A seed draws the same records as before;
only the library of a left-out time shift and the scoring of a twin answer differ.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from engine.atomic import write_json_atomic, write_text_atomic
from engine.constants import OPERATING_RANGE
from engine.diagnosis.diagnose import DiagnosisSettings, diagnose
from engine.diagnosis.space import LOG_SCALED_EFFECTS
from engine.records import Record
from engine.run_manifest import MANIFEST, fingerprint, must_draw_cases, read_manifest
from engine.simulation import CATALOGUE, Case, EffectLibrary, PlantParameters, simulate_batch
from engine.simulation.noise import noise_std

logger = logging.getLogger(__name__)

__all__ = [
    "SAME_PHYSICS",
    "AnswerEntry",
    "BlindCase",
    "ValidationReport",
    "diagnose_cases",
    "generate_cases",
    "prepare_run",
    "run_validation",
    "same_physics_names",
    "score",
    "write_cases",
]

#: Operating-point ranges of the blind cases: K [m], J1 [kg m^2], c [pu] (the plausible
#: operating range, :data:`engine.constants.OPERATING_RANGE`).
K_RANGE: tuple[float, float] = OPERATING_RANGE["K"][:2]
J1_RANGE: tuple[float, float] = OPERATING_RANGE["J1"][:2]
C_RANGE: tuple[float, float] = OPERATING_RANGE["c"][:2]
SNR_RANGE_DB = (30.0, 50.0)
#: An effect counts when it moves some channel by more than this many noise standard deviations (RMS).
STRENGTH_THRESHOLD = 3.0
#: Groups of catalogue effects that are the same physics on a record (pure time shifts of every
#: channel): a left-out case leaves the whole group out, and naming one for another is right.
#: Protocol 2 (:data:`engine.validation.protocol.SAME_PHYSICS`) uses the same groups.
SAME_PHYSICS: tuple[frozenset[str], ...] = (frozenset({"measurement_delay", "trigger_offset"}),)
#: Default mix of case kinds.
DEFAULT_FRACTIONS = {"effect": 0.6, "left_out": 0.2, "clean": 0.2}


@dataclass(frozen=True)
class BlindCase:
    """What the diagnosis is given: a record and the names of the candidate effects."""

    case_id: str
    record: Record
    library: tuple[str, ...]

    def to_dict(self) -> dict:
        return {"case_id": self.case_id, "record": self.record.to_dict(), "library": list(self.library)}

    @classmethod
    def from_dict(cls, d: dict) -> BlindCase:
        return cls(d["case_id"], Record.from_dict(d["record"]), tuple(d["library"]))


@dataclass(frozen=True)
class AnswerEntry:
    """The truth about one blind case (the scorer's answer key).

    Attributes
    ----------
    case_id : str
    kind : {"effect", "left_out", "clean"}
    effect : str or None
        The effect in the record.
    value : float or None
        Its value, in the effect's unit.
    K, J1, c : float
        Operating point [m], [kg m^2], [pu].
    snr_db : float
        Noise level [dB].
    strength : float
        Largest channel RMS change caused by the effect, in noise standard deviations.
    counts : bool
        ``strength > STRENGTH_THRESHOLD``.
    expected_status : str
        ``explained``, ``unexplained`` or ``no_gap``.
    expected_effect : str or None
        The effect the diagnosis should name.
    """

    case_id: str
    kind: str
    effect: str | None
    value: float | None
    K: float
    J1: float
    c: float
    snr_db: float
    strength: float
    counts: bool
    expected_status: str
    expected_effect: str | None


def same_physics_names(a: str, b: str) -> bool:
    """Whether two effect names are one effect or one :data:`SAME_PHYSICS` group."""
    return a == b or any(a in g and b in g for g in SAME_PHYSICS)


def _draw_value(name: str, library: EffectLibrary, rng: np.random.Generator) -> float:
    lo, hi = library[name].bounds
    if name in LOG_SCALED_EFFECTS and lo > 0:
        return float(lo * (hi / lo) ** rng.uniform())
    return float(rng.uniform(lo, hi))


def generate_cases(
    n_cases: int,
    seed: int = 0,
    library: EffectLibrary = CATALOGUE,
    fractions: dict[str, float] | None = None,
) -> tuple[list[BlindCase], list[AnswerEntry]]:
    """Draw blind cases and their answer key (see the module notes).

    Parameters
    ----------
    n_cases : int
        Number of cases.
    seed : int
        Seed of the random generator.
    library : EffectLibrary
        The full catalogue.
    fractions : dict, optional
        Share of each kind (``effect``, ``left_out``, ``clean``); default 60/20/20 %.

    Returns
    -------
    cases : list of BlindCase
    key : list of AnswerEntry
    """
    fractions = dict(DEFAULT_FRACTIONS if fractions is None else fractions)
    rng = np.random.default_rng(seed)
    counts = {k: round(v * n_cases) for k, v in fractions.items()}
    counts["effect"] += n_cases - sum(counts.values())
    kinds = [k for k, n in counts.items() for _ in range(n)]
    rng.shuffle(kinds)
    names = list(library)
    pool: list[str] = []

    def next_effect() -> str:
        # random order, every effect once per round: balanced but unpredictable
        if not pool:
            pool.extend(rng.permutation(names).tolist())
        return pool.pop()

    draws = []
    for i, kind in enumerate(kinds):
        K, J1, c = rng.uniform(*K_RANGE), rng.uniform(*J1_RANGE), rng.uniform(*C_RANGE)
        snr = rng.uniform(*SNR_RANGE_DB)
        effect = next_effect() if kind != "clean" else None
        value = _draw_value(effect, library, rng) if effect else None
        draws.append((f"case{i:04d}", kind, effect, value, K, J1, c, snr))

    plants = [Case(PlantParameters(K=d[4], J1=d[5], c=d[6])) for d in draws]
    clean = simulate_batch(plants)
    with_eff = simulate_batch(
        plants, effects=[{d[2]: d[3]} if d[2] is not None and d[3] is not None else {} for d in draws]
    )
    cases, key = [], []
    for i, (cid, kind, effect, value, K, J1, c, snr) in enumerate(draws):
        x = with_eff.channels[i]
        sd = noise_std(x, snr, axis=1)[:, 0]
        noisy = x + rng.normal(size=x.shape) * sd[:, None]
        strength = float(np.max(np.sqrt(np.mean((x - clean.channels[i]) ** 2, axis=1)) / sd)) if effect else 0.0
        counted = bool(effect) and strength > STRENGTH_THRESHOLD
        rec = with_eff.record(i)
        record = Record(
            {n: noisy[j] for j, n in enumerate(rec.channels)},
            rec.sample_interval,
            rec.event_index,
            conditions={"c1": PlantParameters().c1},
        )
        lib = tuple(
            n for n in names if not (kind == "left_out" and effect is not None and same_physics_names(n, effect))
        )
        cases.append(BlindCase(cid, record, lib))
        if not counted:
            exp_status, exp_effect = "no_gap", None
        elif kind == "effect":
            exp_status, exp_effect = "explained", effect
        else:
            exp_status, exp_effect = "unexplained", None
        key.append(AnswerEntry(cid, kind, effect, value, K, J1, c, snr, strength, counted, exp_status, exp_effect))
    return cases, key


def write_cases(cases: Sequence[BlindCase], key: Sequence[AnswerEntry], out_dir: str | Path) -> Path:
    """Write the blind cases to ``out_dir/cases`` and the key, apart, to ``out_dir/key/answer_key.json``.

    Returns the path of the key.
    """
    out = Path(out_dir)
    (out / "cases").mkdir(parents=True, exist_ok=True)
    (out / "key").mkdir(parents=True, exist_ok=True)
    for c in cases:
        write_json_atomic(out / "cases" / f"{c.case_id}.json", c.to_dict())
    key_path = out / "key" / "answer_key.json"
    write_json_atomic(key_path, [asdict(k) for k in key], indent=1)
    return key_path


def _diagnose_case(case: BlindCase, settings: DiagnosisSettings) -> dict[str, Any]:
    """One blind case's result as its file stores it (a failure is recorded as status ``error``)."""
    library = EffectLibrary([CATALOGUE[n] for n in case.library])
    t0 = time.perf_counter()
    try:
        res = diagnose(case.record, library, settings)
        out = res.to_dict(include_records=False)
        out["ranking"] = [c.effect for c in res.candidates]
    except Exception as exc:
        logger.exception("diagnosis of %s failed", case.case_id)
        out = {
            "verdict": {"status": "error", "effect": None, "value": None, "confidence": 0.0, "reason": repr(exc)},
            "candidates": [],
            "ranking": [],
        }
    out["case_id"] = case.case_id
    out["wall_seconds"] = time.perf_counter() - t0
    return out


def diagnose_cases(
    out_dir: str | Path,
    workers: int | None = 0,
    settings: DiagnosisSettings | None = None,
    scheduler: str | None = None,
    diagnose_fn: Callable[[BlindCase, DiagnosisSettings], dict[str, Any]] | None = None,
) -> Path:
    """Diagnose every case in ``out_dir/cases`` that has no result yet (never reading the key).

    The cases are read and the results written by this process, each result atomically (a
    temporary file renamed over it), so a result file is a whole diagnosis and marks its case
    done: an interrupted call is resumed by calling it again. The diagnoses run on Dask
    (:mod:`engine.distributed`).

    Parameters
    ----------
    out_dir : path
        Directory written by :func:`write_cases`.
    workers : int or None
        Single-threaded worker processes of a local Dask cluster (None: one per core); 0 (the
        default) runs in this process. Ignored when a scheduler is given.
    settings : DiagnosisSettings, optional
        Diagnosis settings (default ``DiagnosisSettings()``).
    scheduler : str, optional
        Address of an existing Dask scheduler (default ``$BACKLASH_DASK_SCHEDULER``, else a local cluster).
    diagnose_fn : callable, optional
        One case's result from the case and the settings (default: the diagnosis; tests pass a
        cheap stand-in, module-level so that the workers can import it).

    Returns
    -------
    Path
        ``out_dir/results``.
    """
    from engine.distributed import dask_client, map_cases

    settings = DiagnosisSettings() if settings is None else settings
    fn = _diagnose_case if diagnose_fn is None else diagnose_fn
    out = Path(out_dir)
    results = out / "results"
    results.mkdir(parents=True, exist_ok=True)
    paths = sorted((out / "cases").glob("*.json"))
    done = {p.stem for p in results.glob("*.json")}
    cases = {p.stem: BlindCase.from_dict(json.loads(p.read_text())) for p in paths if p.stem not in done}
    n_done = len(paths) - len(cases)
    if n_done:
        logger.info("resuming: %d of %d cases already diagnosed, %d to go", n_done, len(paths), len(cases))
    if not cases:
        return results
    with dask_client(scheduler, workers) as client:
        inputs = {k: (c, settings) for k, c in cases.items()}
        for key, result in map_cases(client, fn, inputs, "case", n_done, len(paths)):
            write_json_atomic(results / f"{key}.json", result)
    return results


@dataclass
class ValidationReport:
    """Scores of a blind validation.

    Attributes
    ----------
    n_cases : int
        Cases scored.
    n_by_expected : dict
        Cases per expected answer (``explained``, ``unexplained``, ``no_gap``).
    top1 : float or None
        Counting effect cases whose verdict names the right effect (``explained``), or its
        same-physics twin (:data:`SAME_PHYSICS`).
    top2 : float or None
        Counting effect cases whose effect (or twin) is among the two best-ranked candidates.
    rank1 : float or None
        Counting effect cases whose effect (or twin) is ranked first (whatever the verdict).
    abstention : float or None
        Counting left-out cases answered ``unexplained``.
    false_alarm : float or None
        Clean and weak cases not answered ``no_gap``.
    value_error : dict
        Over counting effect cases whose effect is ranked first: median and 90th
        percentile of the absolute error relative to the effect's range width,
        and the median |error| / reported uncertainty.
    shrinkage : dict
        Gap shrinkage ratio (excess energy before / after) of the true effect's
        fit on counting effect cases: median, 10th percentile, share >= 5x.
    confusion : dict
        ``confusion[true_label][predicted_label]`` counts.
    per_case : list of dict
        One row per case (truth, verdict, rank of the true effect, value, shrinkage, time).
    seconds : dict
        Median and max diagnosis wall time [s].
    identification : dict or None
        Identification accuracy before/after (not wired yet).
    reliability : dict or None
        How often the verdicts stated at each confidence were right
        (:func:`engine.validation.reliability.reliability_section`).
    """

    n_cases: int
    n_by_expected: dict[str, int]
    top1: float | None
    top2: float | None
    rank1: float | None
    abstention: float | None
    false_alarm: float | None
    value_error: dict
    shrinkage: dict
    confusion: dict
    per_case: list[dict] = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    identification: dict | None = None
    reliability: dict | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    def table(self) -> str:
        """Markdown summary table."""

        def pct(x: float | None) -> str:
            return "n/a" if x is None else f"{100 * x:.1f} %"

        n = self.n_by_expected
        rows = [
            (
                "cases (explained / unexplained / no_gap expected)",
                f"{self.n_cases} ({n.get('explained', 0)} / {n.get('unexplained', 0)} / {n.get('no_gap', 0)})",
            ),
            ("top-1 (verdict names the effect or its same-physics twin)", pct(self.top1)),
            ("top-2 (effect among two best-ranked)", pct(self.top2)),
            ("ranked first (any verdict)", pct(self.rank1)),
            ("median gap shrinkage (true effect)", _fmt(self.shrinkage.get("median"), "x")),
            ("share of shrinkage >= 5x", pct(self.shrinkage.get("share_ge_5"))),
            ("median value error / range width", pct(self.value_error.get("median_rel_range"))),
            ("abstention on left-out effects (and their same-physics twins)", pct(self.abstention)),
            ("false alarms on clean cases", pct(self.false_alarm)),
            (
                "diagnosis time median / max",
                f"{self.seconds.get('median', float('nan')):.1f} s / {self.seconds.get('max', float('nan')):.1f} s",
            ),
        ]
        lines = ["| metric | value |", "| --- | --- |"] + [f"| {a} | {b} |" for a, b in rows]
        return "\n".join(lines)

    def confusion_table(self) -> str:
        """Confusion matrix as Markdown (rows: truth, columns: verdict)."""
        cols = sorted({p for row in self.confusion.values() for p in row})
        lines = ["| truth \\ verdict | " + " | ".join(cols) + " |", "| --- |" + " --- |" * len(cols)]
        for t in sorted(self.confusion):
            lines.append(f"| {t} | " + " | ".join(str(self.confusion[t].get(c, "")) for c in cols) + " |")
        return "\n".join(lines)


def _fmt(x: float | None, unit: str) -> str:
    return "n/a" if x is None else f"{x:.3g}{unit}"


def _frac(xs: list[bool]) -> float | None:
    return float(np.mean(xs)) if xs else None


def score(out_dir: str | Path, library: EffectLibrary = CATALOGUE) -> ValidationReport:
    """Score the results in ``out_dir/results`` against ``out_dir/key/answer_key.json``.

    Call only after every diagnosis is done (this is the only reader of the key).
    """
    out = Path(out_dir)
    key = [AnswerEntry(**k) for k in json.loads((out / "key" / "answer_key.json").read_text())]
    confusion: dict[str, Counter] = defaultdict(Counter)
    top1, top2, rank1, abst, fa, rel_err, pulls, shrink, secs, rows = [], [], [], [], [], [], [], [], [], []
    stated: dict[str, dict[str, Any]] = {}  # what each verdict stated, for the reliability table
    for k in key:
        path = out / "results" / f"{k.case_id}.json"
        if not path.exists():
            raise FileNotFoundError(f"no result for {k.case_id}: run diagnose_cases first")
        res = json.loads(path.read_text())
        stated[k.case_id] = {"verdict": res.get("verdict"), "locus": res.get("locus")}
        v = res["verdict"]
        pred = v["effect"] if v["status"] == "explained" else v["status"]
        ranking = res.get("ranking", [])
        truth = (
            str(k.expected_effect)
            if k.expected_status == "explained"
            else f"left-out {k.effect}"
            if k.expected_status == "unexplained"
            else "no_gap"
        )
        confusion[truth][pred] += 1
        row = {
            "case_id": k.case_id,
            "kind": k.kind,
            "effect": k.effect,
            "value": k.value,
            "strength": k.strength,
            "snr_db": k.snr_db,
            "expected": k.expected_status,
            "status": v["status"],
            "named": v["effect"],
            "confidence": v.get("confidence"),
            "seconds": res.get("wall_seconds"),
        }
        secs.append(res.get("wall_seconds", math.nan))
        if k.expected_status == "explained":
            # the first of the ranking that is the true effect or its same-physics twin
            r = next((i + 1 for i, n in enumerate(ranking) if same_physics_names(n, str(k.effect))), None)
            top1.append(
                v["status"] == "explained"
                and v["effect"] is not None
                and same_physics_names(v["effect"], str(k.effect))
            )
            top2.append(r is not None and r <= 2)
            rank1.append(r == 1)
            cand = next((c for c in res["candidates"] if c["effect"] == k.effect), None)
            row["rank"] = r
            if cand is not None and cand["value"] is not None:
                row["fitted"] = cand["value"]
                row["shrinkage"] = cand["shrinkage"]
                shrink.append(cand["shrinkage"])
                if r == 1 and k.effect is not None:
                    lo, hi = library[k.effect].bounds
                    rel_err.append(abs(cand["value"] - k.value) / (hi - lo))
                    if cand.get("uncertainty"):
                        pulls.append(abs(cand["value"] - k.value) / cand["uncertainty"])
        elif k.expected_status == "unexplained":
            abst.append(v["status"] == "unexplained")
        else:
            # a weak draw is a real gap too weak to count: "weak_gap" is as right as "no_gap" there
            fa.append(v["status"] != "no_gap" and not (k.kind != "clean" and v["status"] == "weak_gap"))
        rows.append(row)
    sh = np.array(shrink, dtype=float)
    # here, not at the top: engine.validation imports this module
    from engine.validation.reliability import reliability_section, run_outcomes

    outcomes, _ = run_outcomes(out.name, {"per_case": rows}, stated)
    return ValidationReport(
        n_cases=len(key),
        n_by_expected=dict(Counter(k.expected_status for k in key)),
        top1=_frac(top1),
        top2=_frac(top2),
        rank1=_frac(rank1),
        abstention=_frac(abst),
        false_alarm=_frac(fa),
        value_error={
            "median_rel_range": float(np.median(rel_err)) if rel_err else None,
            "p90_rel_range": float(np.percentile(rel_err, 90)) if rel_err else None,
            "median_pull": float(np.median(pulls)) if pulls else None,
        },
        shrinkage={
            "median": float(np.median(sh)) if sh.size else None,
            "p10": float(np.percentile(sh, 10)) if sh.size else None,
            "share_ge_5": float(np.mean(sh >= 5)) if sh.size else None,
        },
        confusion={t: dict(c) for t, c in confusion.items()},
        per_case=rows,
        seconds={"median": float(np.nanmedian(secs)), "max": float(np.nanmax(secs))} if secs else {},
        reliability=reliability_section(outcomes),
    )


def _manifest(n_cases: int, seed: int, fractions: dict[str, float] | None) -> dict[str, Any]:
    """The manifest of a run: what draws its cases, and their fingerprint (the catalogue included)."""
    mix = dict(DEFAULT_FRACTIONS if fractions is None else fractions)
    spec = {"protocol": 1, "n_cases": n_cases, "seed": seed, "fractions": mix, "library": list(CATALOGUE)}
    return {"protocol": 1, "seed": seed, "n_cases": n_cases, "fractions": mix, "fingerprint": fingerprint(spec)}


def prepare_run(out_dir: str | Path, n_cases: int, seed: int, fractions: dict[str, float] | None = None) -> bool:
    """Whether the cases of a protocol-1 run must be drawn now in ``out_dir``, else that it holds this run.

    Parameters
    ----------
    out_dir : path
        The run's directory.
    n_cases, seed, fractions
        As :func:`run_validation`.

    Returns
    -------
    bool
        True when the directory holds no run yet (the manifest is written, ``complete`` false, and
        the caller draws the cases), or this run's cases were not all written (drawn again: the same
        seed draws the same cases); False when it holds this run's cases, kept.

    Raises
    ------
    FileExistsError
        The directory holds another run: other settings, protocol 2, or cases or results without
        a manifest (a protocol-1 run of before 2026-11-27, or foreign files).
    """
    out = Path(out_dir)
    mine = _manifest(n_cases, seed, fractions)
    has_files = any((out / "cases").glob("*.json")) or any((out / "results").glob("*.json"))
    if not must_draw_cases(out, read_manifest(out), mine["fingerprint"], has_files):
        return False
    out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out / MANIFEST, {**mine, "complete": False}, indent=1)
    return True


def run_validation(
    n_cases: int,
    seed: int,
    out_dir: str | Path,
    workers: int | None = 0,
    settings: DiagnosisSettings | None = None,
    fractions: dict[str, float] | None = None,
    scheduler: str | None = None,
    diagnose_fn: Callable[[BlindCase, DiagnosisSettings], dict[str, Any]] | None = None,
) -> ValidationReport:
    """Generate, diagnose blind, then score; writes ``report.json`` and ``report.md`` in ``out_dir``.

    Resumable: called again with the same ``n_cases``, ``seed`` and ``fractions`` on the directory
    of an interrupted run, it keeps the cases and the diagnoses already written and diagnoses the
    rest (:func:`prepare_run`).

    Parameters
    ----------
    n_cases : int
        Number of blind cases.
    seed : int
        Seed of the case generator.
    out_dir : path
        Working directory (``cases/``, ``key/``, ``results/``, reports).
    workers : int or None
        Single-threaded workers of a local Dask cluster (None: one per core; 0, the default: in this
        process).
    settings : DiagnosisSettings, optional
        Diagnosis settings (default ``DiagnosisSettings()``).
    fractions : dict, optional
        Mix of case kinds (see :func:`generate_cases`).
    scheduler : str, optional
        An existing Dask scheduler (default ``$BACKLASH_DASK_SCHEDULER``, else a local cluster).
    diagnose_fn : callable, optional
        As :func:`diagnose_cases` (tests only).

    Raises
    ------
    FileExistsError
        When ``out_dir`` holds another run (other settings, protocol 2, or files without a
        protocol-1 manifest); nothing is overwritten.
    """
    out = Path(out_dir)
    if prepare_run(out, n_cases, seed, fractions):
        cases, key = generate_cases(n_cases, seed, fractions=fractions)
        write_cases(cases, key, out)
        del key  # the diagnosis never sees it
        write_json_atomic(out / MANIFEST, {**_manifest(n_cases, seed, fractions), "complete": True}, indent=1)
    diagnose_cases(out, workers, settings, scheduler, diagnose_fn)
    report = score(out)
    # json.dumps as before: a figure over no case may be NaN, which write_json_atomic refuses
    write_text_atomic(out / "report.json", json.dumps(report.to_dict(), indent=1))
    from engine.validation.reliability import reliability_markdown  # engine.validation imports this module

    reliability = "\n".join(["", *reliability_markdown(report.reliability)]) if report.reliability else ""
    write_text_atomic(
        out / "report.md",
        f"# Blind validation: {n_cases} cases, seed {seed}\n\n{report.table()}\n\n## Confusion matrix\n\n"
        f"{report.confusion_table()}\n{reliability}",
    )
    return report
