"""Benchmark of the open-world gap diagnosis (issue 10): operating points anywhere in the plausible box, coloured noise.

Three parts, each optional:

* ``--calibration N``: N clean records with operating points across the plausible box
  (:data:`engine.constants.PLAUSIBLE_RANGE`: K 1-15 mm, J1 0.6-1.2 kg m^2, c 0.5-2.0 pu; the
  8 corners of the box 3 % inside its edges, the rest a scrambled Sobol sample, K on a log
  scale; c1 = 0.2 known), white noise at 30-50 dB, calibrated with the diagnosis's nominal
  settings. Counts the fits to the noise (total chi2/n <= 1.05 and every channel <= 1.2, the
  decision's thresholds) and the fits in the basin (|K error| < 3 %, |J1 error| < 1.5 %),
  with Wilson 95 % intervals, and the time per calibration. ``--linear-K`` searches K on a
  linear scale and ``--v1-box`` searches the v1 box (the v1 code's search);
  ``--channels m_el,omega1`` keeps only those channels (a drive's own sensors) and
  ``--before`` uses the nominal settings before the scan at each horizon extension
  (``FORMER_NOMINAL``), for a comparison on the same records.
* ``--noise N``: the nominal fit statistic's false-alarm rate on N clean records per noise
  colour (white; first- and second-order low-passes at fs/20, fs/8 and fs/3), operating points
  uniform in the v1 operating range, per-channel SNR 30-50 dB with channels differing by up
  to 10 dB; and the same with one real catalogue effect (load_inertia 1.3), which should show
  as a gap (``--effect``). ``--v1-noise`` uses the v1 noise estimate (white, finest level).
* ``--estimate N``: the noise estimate alone on N records per colour (draws as ``--noise``):
  the recognised low-pass order (per record; the order is shared by the channels) and the
  estimated / true noise standard deviation per channel.
* ``--escalation N``: the candidates' escalated global search (``ESCALATED_FITS``, or
  ``--esc-global``/``--esc-starts``) on N records with one strong catalogue effect each,
  operating points across the plausible box, white noise 30-50 dB, that the nominal
  calibration does not fit: how often the fit of the true effect reaches chi2/n <= 1.1
  (``--esc-effect NAME``: that effect only).
* ``--verdicts N``: full diagnoses (the whole catalogue as candidates) of N clean records per
  noise colour (white; first order at fs/20; second order at fs/20 and fs/8), same draws as
  ``--noise``: the false-alarm rate of the verdict (anything but ``no_gap``) and how often the
  best candidate lowers the BIC by 10 or more (false evidence from correlated residuals).
  ``--v1-noise`` as above; ``--without NAMES`` leaves effects out of the library,
  ``--colours "LABEL;LABEL"`` picks the colours (labels of ``COLOURS``).
* ``--timing N``: wall time of N single-effect diagnoses (one random catalogue effect each, the
  full catalogue as candidates) with operating points across the plausible box, white noise
  30-50 dB; median, 90th percentile and maximum (budget: 90th percentile <= 10 s on 2 cores),
  with the process CPU time and the machine's load average (other jobs inflate wall times).

Examples::

    python bench/bench_open_world.py --calibration 48 --seed 1
    python bench/bench_open_world.py --noise 30 --seed 2
    python bench/bench_open_world.py --timing 20 --seed 3

Progress goes to the log (stderr); the results are printed as JSON (stdout); ``--out DIR``
also writes the per-record rows there.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import qmc

logger = logging.getLogger("bench_open_world")

#: Unit-box coordinate of the corners' draws (3 % inside the edges).
CORNER_INSET = 0.03
#: Noise colours of ``--noise``: (label, order, cut-off as a fraction of fs); order 0 is white.
COLOURS: tuple[tuple[str, int, float], ...] = (
    ("white", 0, 0.0),
    ("order 1, fs/20", 1, 1 / 20),
    ("order 1, fs/8", 1, 1 / 8),
    ("order 1, fs/3", 1, 1 / 3),
    ("order 2, fs/20", 2, 1 / 20),
    ("order 2, fs/8", 2, 1 / 8),
    ("order 2, fs/3", 2, 1 / 3),
)


def _rate(k: int, n: int) -> dict[str, Any]:
    from engine.validation.stats import wilson_interval

    lo, hi = wilson_interval(k, n)
    return {"k": k, "n": n, "rate": k / n, "wilson95": [lo, hi]}


def box_points(n: int, seed: int) -> list[dict[str, float]]:
    """N operating points across the plausible box: its 8 corners (3 % inside), then Sobol points (log K)."""
    from engine.constants import PLAUSIBLE_RANGE

    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float)
    corners = CORNER_INSET + (1 - 2 * CORNER_INSET) * corners
    sob = qmc.Sobol(3, scramble=True, seed=seed).random(max(n - len(corners), 0))
    U = np.vstack([corners, sob])[:n]
    (K_lo, K_hi, _), (J_lo, J_hi, _), (c_lo, c_hi, _) = (PLAUSIBLE_RANGE[k] for k in ("K", "J1", "c"))
    return [
        {"K": K_lo * (K_hi / K_lo) ** u[0], "J1": J_lo + (J_hi - J_lo) * u[1], "c": c_lo + (c_hi - c_lo) * u[2]}
        for u in U
    ]


def v1_range_records(
    n: int, rng: np.random.Generator, effect: dict[str, float] | None = None
) -> tuple[list[dict[str, float]], Any, list[str]]:
    """N noiseless records at operating points uniform in the v1 operating range (``OPERATING_RANGE``).

    Returns the points (K [m], J1 [kg m^2], c [pu]), the batch simulation (with ``effect`` on every
    record) and the channel names.
    """
    from _plants import uniform_plants

    from engine.constants import OPERATING_RANGE
    from engine.simulation import Case, simulate_batch

    plants = uniform_plants(OPERATING_RANGE, n, rng)
    points = [{"K": p.K, "J1": p.J1, "c": p.c} for p in plants]
    sims = simulate_batch([Case(p) for p in plants], effects=effect)
    return points, sims, list(sims.record(0).channels)


def fits_noise(cal: Any) -> bool:
    """The decision's "fit to the noise": total chi2/n <= 1.05 and every channel <= 1.2."""
    from engine.diagnosis.diagnose import DiagnosisSettings, fit_statistic

    s = DiagnosisSettings()
    total, worst = fit_statistic(cal)
    return bool(total <= s.max_reduced_chi2 and worst <= s.max_channel_chi2)


#: The v1 search box (the operating range plus a margin), for ``--v1-box``: K [m], J1 [kg m^2], c [pu].
V1_BOX: dict[str, tuple[float, float]] = {"K": (0.0022, 0.0105), "J1": (0.72, 0.96), "c": (0.75, 1.6)}


#: The nominal calibration's settings before the scan at each horizon extension (for ``--before``), with the
#: optimiser's difference step of that time.
FORMER_NOMINAL: dict[str, Any] = {"n_global": 256, "n_starts": 2, "fd_step": 2e-3}


def bench_calibration(
    n: int,
    seed: int,
    linear_K: bool = False,
    v1_box: bool = False,
    free_c1: bool = False,
    channels: tuple[str, ...] = (),
    before: bool = False,
) -> dict[str, Any]:
    from engine.diagnosis import CalibrationSettings, calibrate, default_space
    from engine.diagnosis.diagnose import NOMINAL_CALIBRATION, fit_statistic
    from engine.records import Record
    from engine.simulation import Case, PlantParameters, simulate_batch
    from engine.simulation.noise import add_noise

    rng = np.random.default_rng(seed)
    points = box_points(n, seed)
    sims = simulate_batch([Case(PlantParameters(K=p["K"], J1=p["J1"], c=p["c"])) for p in points])
    rows: list[dict[str, Any]] = []
    for i, p in enumerate(points):
        snr = float(rng.uniform(30.0, 50.0))
        x = add_noise(sims.channels[i], snr, rng)
        rec = Record(
            {c: x[j] for j, c in enumerate(sims.record(i).channels) if not channels or c in channels},
            conditions={} if free_c1 else {"c1": 0.2},
        )
        space = default_space(rec, V1_BOX if v1_box else None)
        if linear_K:
            space = replace(space, params=tuple(replace(q, log=False) for q in space.params))
        t0 = time.perf_counter()
        cal = calibrate(rec, space, CalibrationSettings(**FORMER_NOMINAL) if before else NOMINAL_CALIBRATION)
        dt = time.perf_counter() - t0
        total, worst = fit_statistic(cal)
        eK, eJ = cal.values["K"] / p["K"] - 1, cal.values["J1"] / p["J1"] - 1
        row = {
            **p,
            "snr_db": snr,
            "corner": i < 8,
            "eK": eK,
            "eJ1": eJ,
            "ec": cal.values["c"] / p["c"] - 1,
            "chi2_n": total,
            "worst_channel": worst,
            "fits_noise": fits_noise(cal),
            "in_basin": bool(abs(eK) < 0.03 and abs(eJ) < 0.015),
            "n_sim": cal.n_simulations,
            "seconds": dt,
        }
        rows.append(row)
        logger.info(
            "  %2d/%d K %.5f J1 %.3f c %.2f %4.1f dB -> K err %+.3f %% J1 err %+.3f %% chi2/n %.3f worst %.3f %s, %.1f s",
            i + 1,
            n,
            p["K"],
            p["J1"],
            p["c"],
            snr,
            100 * eK,
            100 * eJ,
            total,
            worst,
            "fit" if row["fits_noise"] else "MISS",
            dt,
        )
    t = np.array([r["seconds"] for r in rows])
    corners = [r for r in rows if r["corner"]]
    return {
        "n": n,
        "seed": seed,
        "K_scale": "linear" if linear_K else "log",
        "box": "v1" if v1_box else "plausible",
        "c1": "fitted" if free_c1 else "known",
        "channels": list(channels) or "all",
        "settings": f"former nominal {FORMER_NOMINAL}" if before else "NOMINAL_CALIBRATION",
        "fits_noise": _rate(sum(r["fits_noise"] for r in rows), n),
        "in_basin": _rate(sum(r["in_basin"] for r in rows), n),
        "corners_fit_noise": _rate(sum(r["fits_noise"] for r in corners), len(corners)) if corners else None,
        "seconds_median": float(np.median(t)),
        "seconds_p90": float(np.quantile(t, 0.9)),
        "seconds_max": float(t.max()),
        "simulations_mean": float(np.mean([r["n_sim"] for r in rows])),
        "rows": rows,
    }


def bench_noise(n: int, seed: int, effect: dict[str, float] | None = None, v1_noise: bool = False) -> dict[str, Any]:
    """False alarms of the nominal fit statistic per noise colour (or, with ``effect``, how often it shows)."""
    from engine.constants import SAMPLE_INTERVAL
    from engine.diagnosis import calibrate
    from engine.diagnosis.diagnose import NOMINAL_CALIBRATION, fit_statistic
    from engine.diagnosis.noise import estimate_noise
    from engine.records import Record
    from engine.simulation.noise import add_noise

    rng = np.random.default_rng(seed)
    points, sims, names = v1_range_records(n, rng, effect)
    out: dict[str, Any] = {"n": n, "seed": seed, "effect": effect, "v1_noise": v1_noise, "colours": {}}
    for label, order, frac in COLOURS:
        rows = []
        for i, p in enumerate(points):
            base = rng.uniform(30.0, 40.0)
            snr = base + rng.uniform(0.0, 10.0, len(names))  # channels differ by up to 10 dB
            lp = frac / SAMPLE_INTERVAL if order else None
            x = add_noise(sims.channels[i], snr, rng, lowpass_hz=lp, order=max(order, 1))
            rec = Record({c: x[j] for j, c in enumerate(names)}, conditions={"c1": 0.2})
            t0 = time.perf_counter()
            noise = estimate_noise(rec, coloured=not v1_noise)
            cal = calibrate(rec, settings=NOMINAL_CALIBRATION, noise=noise)
            total, worst = fit_statistic(cal)
            rows.append(
                {
                    **p,
                    "snr_db": snr.tolist(),
                    "chi2_n": total,
                    "worst_channel": worst,
                    "gap": not fits_noise(cal),
                    "eK": cal.values["K"] / p["K"] - 1,
                    "seconds": time.perf_counter() - t0,
                }
            )
            logger.info(
                "  %s %2d/%d: chi2/n %.3f worst %.3f -> %s",
                label,
                i + 1,
                n,
                total,
                worst,
                "gap" if rows[-1]["gap"] else "-",
            )
        out["colours"][label] = {
            "gap": _rate(sum(r["gap"] for r in rows), n),
            "chi2_n_median": float(np.median([r["chi2_n"] for r in rows])),
            "chi2_n_max": float(np.max([r["chi2_n"] for r in rows])),
            "worst_channel_max": float(np.max([r["worst_channel"] for r in rows])),
            "rows": rows,
        }
    return out


def bench_estimate(n: int, seed: int) -> dict[str, Any]:
    """The noise estimate alone (no calibration): recognised order and estimated / true standard deviation."""
    from engine.constants import SAMPLE_INTERVAL
    from engine.diagnosis.noise import estimate_noise
    from engine.records import Record
    from engine.simulation.noise import add_noise

    rng = np.random.default_rng(seed)
    _, sims, names = v1_range_records(n, rng, None)
    out: dict[str, Any] = {"n": n, "seed": seed, "colours": {}}
    for label, order, frac in COLOURS:
        ratios, orders = [], []
        for i in range(n):
            x0 = sims.channels[i]
            snr = rng.uniform(30.0, 40.0) + rng.uniform(0.0, 10.0, len(names))
            lp = frac / SAMPLE_INTERVAL if order else None
            x = add_noise(x0, snr, rng, lowpass_hz=lp, order=max(order, 1))
            est = estimate_noise(Record({c: x[j] for j, c in enumerate(names)}))
            sd = np.sqrt(np.var(x0, axis=1) / 10 ** (snr / 10))
            ratios += [est[c] / sd[j] for j, c in enumerate(names)]
            orders.append(est.channel(names[0]).order)
        r = np.array(ratios)
        out["colours"][label] = {
            "order_counts": np.bincount(orders, minlength=3).tolist(),
            "sigma_ratio_median": float(np.median(r)),
            "sigma_ratio_min": float(r.min()),
            "sigma_ratio_max": float(r.max()),
        }
        logger.info("  %s: %s", label, out["colours"][label])
    return out


def bench_escalation(
    n: int, seed: int, n_global: int | None = None, n_starts: int | None = None, effect: str | None = None
) -> dict[str, Any]:
    """The candidates' escalated global search on strong effects across the plausible box.

    Draws operating points across the box (:func:`box_points`) and one catalogue effect each
    (value uniform in its range, log-uniform for the log-scaled ones), white noise 30-50 dB,
    keeps the records the nominal calibration does not fit (chi2/n > 1.1: those the
    escalation exists for) up to ``n`` of them, and fits the true effect with the global
    search (:func:`engine.diagnosis.candidate.fit_candidate`, ``global_search=True``, no
    polish). Success: the escalation's own criterion, search-step chi2/n <= 1.1.
    """
    from dataclasses import replace as dc_replace

    from engine.diagnosis import calibrate, default_space
    from engine.diagnosis.candidate import CandidateSettings, fit_candidate
    from engine.diagnosis.diagnose import NOMINAL_CALIBRATION
    from engine.diagnosis.space import LOG_SCALED_EFFECTS
    from engine.records import Record
    from engine.simulation import CATALOGUE, Case, PlantParameters, simulate_batch
    from engine.simulation.noise import add_noise

    settings = CandidateSettings()
    esc = settings.escalated
    esc = dc_replace(
        esc,
        n_global=esc.n_global if n_global is None else n_global,
        n_starts=esc.n_starts if n_starts is None else n_starts,
    )
    settings = dc_replace(settings, escalated=esc)
    rng = np.random.default_rng(seed)
    names = [e for e in sorted(CATALOGUE) if e != "speed_quantization"]  # fitted by scans, not escalated
    if effect is not None:
        names = [CATALOGUE[effect].name]
    rows: list[dict[str, Any]] = []
    batch = 0
    while len(rows) < n and batch < 20:
        points = box_points(4 * n, seed + 1000 * batch)[8:] if batch else box_points(4 * n, seed)
        batch += 1
        effects = [str(rng.choice(names)) for _ in points]
        values = []
        for e in effects:
            lo, hi = CATALOGUE[e].bounds
            log = e in LOG_SCALED_EFFECTS and lo > 0
            values.append(float(lo * (hi / lo) ** rng.uniform()) if log else float(rng.uniform(lo, hi)))
        cases = [Case(PlantParameters(K=p["K"], J1=p["J1"], c=p["c"])) for p in points]
        sims = simulate_batch(cases, effects=[{e: v} for e, v in zip(effects, values, strict=True)])
        for i, p in enumerate(points):
            if len(rows) >= n:
                break
            x = add_noise(sims.channels[i], float(rng.uniform(30.0, 50.0)), rng)
            rec = Record({c: x[j] for j, c in enumerate(sims.record(i).channels)}, conditions={"c1": 0.2})
            space = default_space(rec)
            nominal = calibrate(rec, space, NOMINAL_CALIBRATION)
            if nominal.reduced_chi2 <= settings.escalate_above:
                continue
            t0 = time.perf_counter()
            cand = fit_candidate(rec, nominal, space, CATALOGUE[effects[i]], settings, polish=False, global_search=True)
            cal = cand.calibration
            ok = cal is not None and cal.reduced_chi2 <= settings.escalate_above
            rows.append(
                {
                    **p,
                    "effect": effects[i],
                    "value": values[i],
                    "nominal_chi2_n": nominal.reduced_chi2,
                    "chi2_n": cal.reduced_chi2 if cal is not None else None,
                    "found": bool(ok),
                    "n_sim": cal.n_simulations if cal is not None else 0,
                    "seconds": time.perf_counter() - t0,
                }
            )
            logger.info(
                "  %2d/%d %s %.4g at K %.4f J1 %.3f c %.2f: nominal %.4g -> %.4g %s (%d sims, %.1f s)",
                len(rows),
                n,
                effects[i],
                values[i],
                p["K"],
                p["J1"],
                p["c"],
                nominal.reduced_chi2,
                rows[-1]["chi2_n"] or np.nan,
                "found" if ok else "MISSED",
                rows[-1]["n_sim"],
                rows[-1]["seconds"],
            )
    t = np.array([r["seconds"] for r in rows])
    return {
        "n": len(rows),
        "seed": seed,
        "n_global": esc.n_global,
        "n_starts": esc.n_starts,
        "found": _rate(sum(r["found"] for r in rows), len(rows)),
        "simulations_mean": float(np.mean([r["n_sim"] for r in rows])),
        "seconds_median": float(np.median(t)),
        "seconds_p90": float(np.quantile(t, 0.9)),
        "rows": rows,
    }


#: Noise colours of ``--verdicts`` (a subset of :data:`COLOURS`: full diagnoses are slow).
VERDICT_COLOURS: tuple[str, ...] = ("white", "order 1, fs/20", "order 2, fs/20", "order 2, fs/8")


def bench_verdicts(
    n: int,
    seed: int,
    v1_noise: bool = False,
    without: tuple[str, ...] = (),
    colours: tuple[str, ...] = VERDICT_COLOURS,
) -> dict[str, Any]:
    """Full diagnoses of clean records per noise colour: how often the verdict is not ``no_gap``."""
    from engine.constants import SAMPLE_INTERVAL
    from engine.diagnosis import diagnose
    from engine.diagnosis.noise import estimate_noise
    from engine.records import Record
    from engine.simulation import CATALOGUE
    from engine.simulation.noise import add_noise

    library = CATALOGUE.without(*without) if without else CATALOGUE
    rng = np.random.default_rng(seed)
    points, sims, names = v1_range_records(n, rng, None)
    out: dict[str, Any] = {"n": n, "seed": seed, "v1_noise": v1_noise, "without": list(without), "colours": {}}
    for label, order, frac in COLOURS:
        if label not in colours:
            continue
        rows: list[dict[str, Any]] = []
        for i, p in enumerate(points):
            snr = rng.uniform(30.0, 40.0) + rng.uniform(0.0, 10.0, len(names))
            lp = frac / SAMPLE_INTERVAL if order else None
            x = add_noise(sims.channels[i], snr, rng, lowpass_hz=lp, order=max(order, 1))
            rec = Record({c: x[j] for j, c in enumerate(names)}, conditions={"c1": 0.2})
            t0 = time.perf_counter()
            res = diagnose(rec, library, noise=estimate_noise(rec, coloured=not v1_noise))
            best = next((c for c in res.candidates if c.calibration is not None), None)
            rows.append(
                {
                    **p,
                    "status": res.verdict.status,
                    "effect": res.verdict.effect,
                    "delta_bic_best": res.calibration.bic - best.bic if best is not None else None,
                    "best": best.effect if best is not None else None,
                    "seconds": time.perf_counter() - t0,
                }
            )
            logger.info(
                "  %s %2d/%d: %s %s (best %s, BIC lower by %.1f), %.1f s",
                label,
                i + 1,
                n,
                res.verdict.status,
                res.verdict.effect or "",
                rows[-1]["best"],
                rows[-1]["delta_bic_best"] or 0.0,
                rows[-1]["seconds"],
            )
        out["colours"][label] = {
            "false_alarm": _rate(sum(r["status"] != "no_gap" for r in rows), n),
            "evidence_dbic_ge_10": _rate(sum((r["delta_bic_best"] or 0.0) >= 10.0 for r in rows), n),
            "seconds_median": float(np.median([r["seconds"] for r in rows])),
            "rows": rows,
        }
    return out


def bench_timing(n: int, seed: int) -> dict[str, Any]:
    """Single-effect diagnoses across the plausible box: time and verdict."""
    from engine.diagnosis import diagnose
    from engine.records import Record
    from engine.simulation import CATALOGUE, Case, PlantParameters, simulate_batch
    from engine.simulation.noise import add_noise

    rng = np.random.default_rng(seed)
    points = box_points(n, seed)
    names = sorted(CATALOGUE)
    effects = [str(rng.choice(names)) for _ in points]
    values = []
    for e in effects:
        lo, hi = CATALOGUE[e].bounds
        values.append(float(rng.uniform(lo, hi)))
    sims = simulate_batch(
        [Case(PlantParameters(K=p["K"], J1=p["J1"], c=p["c"])) for p in points],
        effects=[{e: v} for e, v in zip(effects, values, strict=True)],
    )
    rows = []
    for i, p in enumerate(points):
        snr = float(rng.uniform(30.0, 50.0))
        x = add_noise(sims.channels[i], snr, rng)
        rec = Record({c: x[j] for j, c in enumerate(sims.record(i).channels)}, conditions={"c1": 0.2})
        if i == 0:
            diagnose(rec)  # JIT warm-up
        t0, c0 = time.perf_counter(), time.process_time()
        res = diagnose(rec)
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        rows.append(
            {
                "cpu_seconds": cpu,
                "n_simulations": res.n_simulations,
                "load_average_1min": os.getloadavg()[0],
                **p,
                "effect": effects[i],
                "value": values[i],
                "status": res.verdict.status,
                "named": res.verdict.effect,
                "seconds": dt,
            }
        )
        logger.info(
            "  %2d/%d %s %.4g -> %s %s, %.1f s",
            i + 1,
            n,
            effects[i],
            values[i],
            res.verdict.status,
            res.verdict.effect,
            dt,
        )
    t = np.array([r["seconds"] for r in rows])
    cpu_s = np.array([r["cpu_seconds"] for r in rows])
    return {
        "n": n,
        "seed": seed,
        "load_average_1min_median": float(np.median([r["load_average_1min"] for r in rows])),
        "cpu_s_median": float(np.median(cpu_s)),
        "cpu_s_p90": float(np.quantile(cpu_s, 0.9)),
        "simulations_median": float(np.median([r["n_simulations"] for r in rows])),
        "median_s": float(np.median(t)),
        "p90_s": float(np.quantile(t, 0.9)),
        "max_s": float(t.max()),
        "named_correctly": _rate(sum(r["named"] == r["effect"] for r in rows), n),
        "rows": rows,
    }


def _emit(text: str) -> None:
    """Write one result to stdout (the log goes to stderr)."""
    sys.stdout.write(text.rstrip("\n") + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--calibration", type=int, default=0, metavar="N", help="clean records across the plausible box")
    ap.add_argument("--linear-K", action="store_true", help="search K on a linear scale (v1)")
    ap.add_argument("--free-c1", action="store_true", help="c1 not given: calibrated too (4 parameters)")
    ap.add_argument("--v1-box", action="store_true", help="search the v1 box (K 2.2-10.5 mm, J1 0.72-0.96, c 0.75-1.6)")
    ap.add_argument("--channels", default="", help="with --calibration: only these channels (comma-separated)")
    ap.add_argument("--before", action="store_true", help="with --calibration: the former nominal settings")
    ap.add_argument("--noise", type=int, default=0, metavar="N", help="clean records per noise colour")
    ap.add_argument("--estimate", type=int, default=0, metavar="N", help="noise estimate alone, N records per colour")
    ap.add_argument("--effect", action="store_true", help="with --noise, add load_inertia 1.3 to every record")
    ap.add_argument("--v1-noise", action="store_true", help="with --noise/--verdicts, the v1 (white) noise estimate")
    ap.add_argument("--escalation", type=int, default=0, metavar="N", help="escalated fits of N strong effects")
    ap.add_argument(
        "--esc-global", type=int, default=None, help="with --escalation: Sobol points (default: ESCALATED_FITS)"
    )
    ap.add_argument("--esc-starts", type=int, default=None, help="with --escalation: starts (default: ESCALATED_FITS)")
    ap.add_argument("--esc-effect", default=None, help="with --escalation: this effect only")
    ap.add_argument("--verdicts", type=int, default=0, metavar="N", help="full diagnoses of N clean records per colour")
    ap.add_argument("--without", default="", help="with --verdicts: effects left out of the library (comma-separated)")
    ap.add_argument(
        "--colours", default=";".join(VERDICT_COLOURS), help="with --verdicts: noise colours (labels, ';'-separated)"
    )
    ap.add_argument("--timing", type=int, default=0, metavar="N", help="single-effect diagnoses")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="directory for the per-record rows (JSON)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)
    for name in (
        "engine.diagnosis.calibration",
        "engine.diagnosis.candidates",
        "engine.diagnosis.diagnose",
        "engine.diagnosis.staged",
    ):
        logging.getLogger(name).setLevel(logging.WARNING)
    results: dict[str, Any] = {}
    from engine.constants import CHANNELS

    channels = tuple(x for x in args.channels.split(",") if x)
    unknown = [c for c in channels if c not in CHANNELS]
    if unknown:
        ap.error(f"--channels: unknown channel(s) {', '.join(unknown)}; the channels are {', '.join(CHANNELS)}")
    if args.calibration:
        results["calibration"] = bench_calibration(
            args.calibration,
            args.seed,
            args.linear_K,
            args.v1_box,
            args.free_c1,
            channels,
            args.before,
        )
    if args.noise:
        results["noise"] = bench_noise(
            args.noise, args.seed, {"load_inertia": 1.3} if args.effect else None, args.v1_noise
        )
    if args.estimate:
        results["estimate"] = bench_estimate(args.estimate, args.seed)
    if args.escalation:
        results["escalation"] = bench_escalation(
            args.escalation, args.seed, args.esc_global, args.esc_starts, args.esc_effect
        )
    if args.verdicts:
        results["verdicts"] = bench_verdicts(
            args.verdicts,
            args.seed,
            args.v1_noise,
            tuple(x for x in args.without.split(",") if x),
            tuple(x.strip() for x in args.colours.split(";") if x.strip()),
        )
    if args.timing:
        results["timing"] = bench_timing(args.timing, args.seed)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        for k, v in results.items():
            (args.out / f"{k}.json").write_text(json.dumps(v, indent=1))

    def strip(d: Any) -> Any:
        if isinstance(d, dict):
            return {k: strip(v) for k, v in d.items() if k != "rows"}
        return d

    _emit(json.dumps(strip(results), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
