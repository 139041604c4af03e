"""How often the width a diagnosis shows covers the truth: the coverage of its 95 % interval on a blind run.

For every case of a protocol-2 run (:mod:`engine.validation.layout`) with a result, the true K
(the answer key) is compared with two intervals:

- ``answer``: the answer's own ``width.interval_95`` (:mod:`engine.diagnosis.width`), the width the
  service shows since issue 50; a width reported as not identifiable is counted apart (it makes no
  claim to cover anything) and a result written before issue 50 has none;
- ``nominal``: the nominal calibration's K +- 1.96 sigma, the width the service showed before
  issue 50 (for comparison on the same records);
- ``rule``: for a result written before issue 50, the answer's width rebuilt from the stored fits
  by :func:`engine.diagnosis.width.width_sigma` with ``tau = 1`` (the residuals are not stored;
  ``tau >= 1``, so the rule as run is at least as wide): how the rule's constants were chosen on
  the development runs and scored on held-out ones; for a result with a width, the answer's own with
  today's structure factor and, when it was written before term 5 (a named effect that may be a
  stand-in, :mod:`engine.diagnosis.width`), that term added.

Coverage is the fraction of intervals that hold the truth, with a Wilson 95 % interval, in total and
by verdict status and by the case's kind. A committed run without its answer key (the key is not
committed) can be read through its report's rows instead, whose ``K_mm`` is rounded to 1 um: an
interval then counts as covering when it meets the rounding interval of the printed truth (said in
the output).
"""

from __future__ import annotations

import io
import json
import math
import tarfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from engine.constants import Z95
from engine.diagnosis.confidence import load_map
from engine.diagnosis.open_world import stand_in_doubt
from engine.diagnosis.settings import DiagnosisSettings
from engine.diagnosis.space import DEFAULT_BOUNDS
from engine.diagnosis.width import MAX_RELATIVE_HALF_WIDTH, MISSING_PHYSICS, STRUCTURE_FACTOR, width_sigma
from engine.validation.layout import RunLayout
from engine.validation.stats import wilson_interval

__all__ = [
    "CoverageRow",
    "Truth",
    "coverage",
    "coverage_markdown",
    "stand_in_reach",
    "stored_rule",
    "today_rule",
    "truths_from_committed",
    "truths_from_layout",
]

#: Half the rounding step of a report's ``K_mm`` (printed to 1 um) [m].
REPORT_ROUNDING: float = 0.5e-6


@dataclass(frozen=True)
class Truth:
    """The true width of one case and what the diagnosis answered.

    Attributes
    ----------
    case_id, kind : str
        The case and its kind (clean, single, pair, triple, held_back).
    K : float
        True width [m].
    tolerance : float
        Half-width of the truth's own rounding [m] (0 with the answer key).
    status : str
        The verdict's status.
    width : dict or None
        The answer's ``width`` (None before issue 50).
    nominal : tuple of float or None
        The nominal calibration's (K, sigma_K) [m], when K was fitted.
    rule : tuple of float or None
        The answer's (K, sigma_K) [m] by today's width rule: rebuilt from the fits (results before
        issue 50, tau = 1), or the answer's own width with today's structure factor
        (:func:`recomposed_rule`).
    """

    case_id: str
    kind: str
    K: float
    tolerance: float
    status: str
    width: Mapping[str, Any] | None
    nominal: tuple[float, float] | None
    rule: tuple[float, float] | None = None


@dataclass(frozen=True)
class CoverageRow:
    """Coverage of one interval rule over one group of cases."""

    rule: str
    group: str
    n: int
    covered: int
    not_identifiable: int
    median_half_width_um: float

    @property
    def fraction(self) -> float:
        return self.covered / self.n if self.n else math.nan

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.covered, self.n) if self.n else (math.nan, math.nan)


def _nominal(result: Mapping[str, Any]) -> tuple[float, float] | None:
    cal = result.get("calibration") or {}
    K = (cal.get("values") or {}).get("K")
    sd = (cal.get("uncertainties") or {}).get("K")
    if K is None or sd is None or not math.isfinite(sd):
        return None
    return float(K), float(sd)


#: The K range of the default search box [m], for the identifiability of a rebuilt width.
_K_RANGE: float = DEFAULT_BOUNDS["K"][1] - DEFAULT_BOUNDS["K"][0]


def _calibrations(result: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    """Every stored fit of a result with a fitted K: the nominal one first, then the candidates'."""
    fits = [result.get("calibration") or {}]
    fits += [c["calibration"] for c in result.get("candidates") or () if c.get("calibration")]
    return [f for f in fits if "K" in (f.get("values") or {}) and f.get("bic") is not None]


def _answer_fit(result: Mapping[str, Any]) -> Mapping[str, Any] | None:
    """The stored fit of the model the answer ended with (as :func:`engine.diagnosis.width.answer_calibration`)."""
    verdict = result["verdict"]
    fits = _calibrations(result)
    if verdict["status"] == "explained":
        named = sorted(e["effect"] for e in verdict.get("effects") or ())
        for c in result.get("candidates") or ():
            own = sorted(e["effect"] for e in c.get("effects") or ()) if c.get("kind") == "set" else [c.get("effect")]
            if own == named and c.get("calibration") and "K" in c["calibration"].get("values", {}):
                fit: Mapping[str, Any] = c["calibration"]
                return fit
        return None
    if verdict["status"] == "unexplained":
        return min(fits, key=lambda f: f["bic"]) if fits else None
    return fits[0] if fits and fits[0] is (result.get("calibration") or {}) else None


def stored_rule(
    result: Mapping[str, Any], min_delta_bic: float = DiagnosisSettings().min_delta_bic
) -> tuple[float, float] | None:
    """The answer's (K, sigma_K) [m] rebuilt from a stored result by the width rule with ``tau = 1``, or None
    when the answer's model has no fitted K or its interval would be reported as not identifiable."""
    fit = _answer_fit(result)
    if fit is None:
        return None
    K = float(fit["values"]["K"])
    sd = float((fit.get("uncertainties") or {}).get("K", math.nan))
    others = [(float(f["values"]["K"]), float(f["bic"])) for f in _calibrations(result) if f is not fit]
    sigma, _, _ = width_sigma(
        K,
        sd,
        1.0,
        float(fit["bic"]),
        others,
        min_delta_bic,
        result["verdict"]["status"] in MISSING_PHYSICS,
        stand_in_reach(result, K),
    )
    if not math.isfinite(sigma) or Z95 * sigma > MAX_RELATIVE_HALF_WIDTH * _K_RANGE:
        return None
    return K, sigma


#: The structure factor of answers that do not store theirs (code before commit 1e92135).
ANSWERED_STRUCTURE_FACTOR: float = 3.0


def stand_in_reach(result: Mapping[str, Any], K: float) -> float:
    """Term 5 of the width rule for a stored result: ``|K_nominal - K|`` [m] when its verdict is ``explained``
    in doubt by :func:`~engine.diagnosis.open_world.stand_in_doubt` (the committed map), else 0."""
    chi2 = (result.get("calibration") or {}).get("reduced_chi2")
    status = str((result.get("verdict") or {}).get("status"))
    doubt = stand_in_doubt(status, float(chi2) if isinstance(chi2, (int, float)) else None, load_map().open_world)
    nominal = _nominal(result)
    return 0.0 if doubt is None or nominal is None else abs(nominal[0] - K)


def recomposed_rule(width: Mapping[str, Any] | None, reach: float = 0.0) -> tuple[float, float] | None:
    """A stored answer's (K, sigma_K) [m] with its missing-physics term at today's :data:`STRUCTURE_FACTOR`.

    The stored ``structure_spread`` is the factor of its time times the K spread of the best
    models (``structure_factor`` in the answer; :data:`ANSWERED_STRUCTURE_FACTOR` for answers that
    store none); every other term is kept. An answer written before term 5 (no ``stand_in_reach``)
    gets ``reach`` [m] (:func:`stand_in_reach`) as that term. None when the answer was not
    identifiable or, at today's factor, its interval would be reported as not identifiable.
    """
    if width is None or not width.get("identifiable") or width.get("sigma_K") is None:
        return None
    K, sd = float(width["K"]), float(width["sigma_K"])
    s = float(width.get("structure_spread") or 0.0)
    then = float(width.get("structure_factor", ANSWERED_STRUCTURE_FACTOR))
    added = 0.0 if "stand_in_reach" in width else (reach / Z95) ** 2
    sigma = math.sqrt(max(sd**2 - s**2, 0.0) + (s * STRUCTURE_FACTOR / then) ** 2 + added)
    if Z95 * sigma > MAX_RELATIVE_HALF_WIDTH * _K_RANGE:
        return None
    return K, sigma


def today_rule(result: Mapping[str, Any]) -> tuple[float, float] | None:
    """A stored result's (K, sigma_K) [m] by today's width rule: :func:`stored_rule` for a result written
    before issue 50, else :func:`recomposed_rule` with :func:`stand_in_reach`."""
    w = result.get("width")
    if w is None:
        return stored_rule(result)
    return recomposed_rule(w, stand_in_reach(result, float(w["K"])) if w.get("K") is not None else 0.0)


def truths_from_layout(root: Path) -> list[Truth]:
    """The cases of a run directory with a result, their truth from its answer key."""
    layout = RunLayout(root)
    _, entries = layout.read_key()
    done = layout.done()
    out = []
    for e in entries:
        if e.case_id not in done:
            continue
        res = layout.read_result(e.case_id)
        w = res.get("width")
        rule = today_rule(res)
        out.append(Truth(e.case_id, e.kind, e.K, 0.0, res["verdict"]["status"], w, _nominal(res), rule))
    return out


def truths_from_committed(root: Path) -> list[Truth]:
    """The cases of a committed run (``report.json`` and ``results.tar.xz``), the truth from the report's rows."""
    report = json.loads((root / "report.json").read_text())
    cols = report["cases"]["columns"]
    rows = {r[cols.index("case")]: dict(zip(cols, r, strict=True)) for r in report["cases"]["rows"]}
    out = []
    with tarfile.open(root / "results.tar.xz") as tar:
        for member in tar.getmembers():
            if not member.isfile() or not member.name.endswith(".json"):
                continue
            f = tar.extractfile(member)
            if f is None:
                continue
            res = json.load(io.TextIOWrapper(f, encoding="utf-8"))
            row = rows.get(Path(member.name).stem)
            if row is None:
                continue
            out.append(
                Truth(
                    row["case"],
                    row["kind"],
                    float(row["K_mm"]) * 1e-3,
                    REPORT_ROUNDING,
                    res["verdict"]["status"],
                    res.get("width"),
                    _nominal(res),
                    today_rule(res),
                )
            )
    return sorted(out, key=lambda t: t.case_id)


def _covers(lo: float, hi: float, t: Truth) -> bool:
    return lo - t.tolerance <= t.K <= hi + t.tolerance


def _answer(t: Truth) -> tuple[str, float | None]:
    """``("covered" | "missed" | "not_identifiable" | "absent", half-width)`` of the answer's interval."""
    w = t.width
    if w is None:
        return "absent", None
    if not w.get("identifiable") or not w.get("interval_95"):
        return "not_identifiable", None
    lo, hi = (float(x) for x in w["interval_95"])
    return ("covered" if _covers(lo, hi, t) else "missed"), (hi - lo) / 2


def _nominal_check(t: Truth) -> tuple[str, float | None]:
    if t.nominal is None:
        return "not_identifiable", None
    K, sd = t.nominal
    return ("covered" if _covers(K - Z95 * sd, K + Z95 * sd, t) else "missed"), Z95 * sd


def _rule_check(t: Truth) -> tuple[str, float | None]:
    if t.rule is None:
        return "not_identifiable", None
    K, sd = t.rule
    return ("covered" if _covers(K - Z95 * sd, K + Z95 * sd, t) else "missed"), Z95 * sd


def _row(rule: str, group: str, checks: Iterable[tuple[str, float | None]]) -> CoverageRow:
    checks = list(checks)
    scored = [(c, h) for c, h in checks if c in ("covered", "missed")]
    halves = sorted(h for _, h in scored if h is not None)
    median = halves[len(halves) // 2] * 1e6 if halves else math.nan
    return CoverageRow(
        rule,
        group,
        len(scored),
        sum(c == "covered" for c, _ in scored),
        sum(c == "not_identifiable" for c, _ in checks),
        median,
    )


def coverage(truths: list[Truth]) -> list[CoverageRow]:
    """Coverage rows: per rule (``answer`` over the results with a width, ``rule`` (today's) over every
    diagnosed result, ``nominal`` over all), in total, by verdict status and by kind. A diagnosis that failed (status
    ``error``) has no width: it counts under ``nominal`` only, and the report says how many there were."""
    rows = []
    members_of = {
        "answer": [t for t in truths if t.width is not None],
        "rule": [t for t in truths if t.status != "error"],
        "nominal": truths,
    }
    for rule, check in (("answer", _answer), ("rule", _rule_check), ("nominal", _nominal_check)):
        scored = members_of[rule]
        if not scored:
            continue
        groups: dict[str, list[Truth]] = {"all": scored}
        for t in scored:
            groups.setdefault(f"status {t.status}", []).append(t)
        for t in scored:
            groups.setdefault(f"kind {t.kind}", []).append(t)
        for name, members in groups.items():
            rows.append(_row(rule, name, (check(t) for t in members)))
    return rows


def coverage_markdown(rows: list[CoverageRow], source: str) -> str:
    """The rows as a markdown table, with what they were evaluated on."""
    head = (
        f"Truth inside the stated 95 % interval, {source}. `answer`: the answer's `width` (issue 50); "
        f"`rule`: today's rule (structure factor {STRUCTURE_FACTOR:g}): the width rebuilt from the fits of a result "
        "written before issue 50 (tau = 1), or the answer's width with its missing-physics term at that factor, "
        "each with the stand-in term of a weak-gap `explained` answer (engine/diagnosis/width.py, term 5); "
        "`nominal`: the nominal calibration's K +- 1.96 sigma (what was shown before).\n\n"
        "| rule | group | n | covered | coverage [Wilson 95 %] | not identifiable | median half-width [um] |\n"
        "|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for r in rows:
        lo, hi = r.interval
        frac = f"{100 * r.fraction:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}]" if r.n else "–"
        lines.append(
            f"| {r.rule} | {r.group} | {r.n} | {r.covered} | {frac} | {r.not_identifiable} | "
            f"{r.median_half_width_um:.3g} |"
        )
    return head + "\n".join(lines) + "\n"
