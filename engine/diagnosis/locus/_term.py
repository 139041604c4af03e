"""What the missing term looks like (steps 5 and 7 of the method).

The best locus's input on the record's grid [the locus's unit], its shape (constant, time, angle,
speed, with its amplitude and frequency [Hz]) and one sentence (:func:`locus_term`); the sensor
library's fit as a term (:func:`sensor_term`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from engine.constants import CHANNEL_UNITS, CHANNELS, W_SMOOTH, Z95
from engine.diagnosis.calibration import CalibrationResult
from engine.diagnosis.locus._refine import Estimate
from engine.diagnosis.locus._report import LocusSettings, Term
from engine.diagnosis.locus._responses import Responses
from engine.diagnosis.locus._starts import SCAN_SCALE
from engine.simulation.parameters import COULOMB_FIELDS, DISTURBANCE_MEANING, PART_FIELDS

#: How the unknown input is called in a sentence, per locus.
#: (The place is said once, by ``_WHERE``: "a periodic torque of about 0.03 pu at 37 Hz on the load".)
_WHAT: dict[str, str] = {
    "supply": "supply-voltage deviation",
    "motor_electrical": "additive electromagnetic torque",
    "motor_shaft": "torque",
    "clutch": "angle offset of the backlash zone",
    "drive_train": "torque",
    "load": "torque",
    "clutch_torque": "torque",
}
_WHERE: dict[str, str] = {
    "supply": "at the motor's terminals",
    "motor_electrical": "in the motor",
    "motor_shaft": "on the motor shaft",
    "clutch": "in the clutch",
    "drive_train": "on the drive wheel",
    "load": "on the load",
    "clutch_torque": "across the clutch (its halves on each other)",
}


def _centred_r2(X: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Weighted R^2 about the weighted mean of y on [1, X], and the coefficients (weighted normal equations)."""
    Xc = np.column_stack([np.ones_like(y), X])
    G = (Xc * w[:, None]).T @ Xc
    try:
        coef = np.linalg.solve(G, (Xc * w[:, None]).T @ y)
    except np.linalg.LinAlgError:
        coef = np.linalg.lstsq(G, (Xc * w[:, None]).T @ y, rcond=None)[0]
    res = y - Xc @ coef
    mean = float(np.sum(w * y) / np.sum(w))
    tss = float(np.sum(w * (y - mean) ** 2))
    return (1.0 - float(np.sum(w * res**2)) / tss if tss > 0 else 0.0), coef


def _spike_weights(series: np.ndarray) -> np.ndarray:
    """Weights that damp isolated spikes of an estimated input (Huber-like beyond 3 robust sigmas).

    Spikes appear where a clutch impact of the record and of the calibrated model fall at
    slightly different instants: the input explains the shift, which says little about its shape.
    """
    med = float(np.median(series))
    scale = 1.4826 * float(np.median(np.abs(series - med)))
    if scale <= 0:
        return np.ones_like(series)
    z = np.abs(series - med) / (3.0 * scale)
    return np.minimum(1.0, 1.0 / np.maximum(z, 1e-12) ** 2)


def _best_of(
    designs: list[tuple[Any, np.ndarray]], series: np.ndarray, weights: list[np.ndarray]
) -> tuple[float, Any, np.ndarray]:
    """The best (R^2, label, coefficients) of several designs, each under several weightings."""
    best: tuple[float, Any, np.ndarray] = (-np.inf, None, np.zeros(0))
    for w in weights:
        for label, X in designs:
            q, coef = _centred_r2(X, series, w)
            if q > best[0]:
                best = (q, label, coef)
    return best


def _shape(
    series: np.ndarray,
    weight: np.ndarray,
    t: np.ndarray,
    base: np.ndarray,
    radius: float,
    omega_b: float,
    settings: LocusSettings,
    f_max: float,
) -> tuple[str, float, float, dict[str, float], dict[str, Any]]:
    """(follows, amplitude, dominant frequency [Hz], R^2 per shape, details) of a term on the grid.

    ``base`` is the calibrated simulation (all five channels) on the grid ``t`` [s from the
    event], ``radius`` the wheel radius [m] and ``omega_b`` the base speed Omega_b [rad/s] of the plant (v2 = r
    Omega_b w_3), ``weight`` the resolution of
    the term at each instant. Every shape is fitted under that weighting and under it times
    :func:`_spike_weights`; each shape keeps its better R^2.
    """
    w = weight / max(float(weight.max(initial=0.0)), 1e-300)
    if float(np.sum(w)) <= 0 or not np.any(series):
        return "unclear", 0.0, math.nan, {}, {}
    weights = [w, w * _spike_weights(series)]
    mean = float(np.sum(w * series) / np.sum(w))
    energy = float(np.sum(w * series**2) / np.sum(w))
    const_share = mean**2 / energy if energy > 0 else 0.0
    r2: dict[str, float] = {"constant": const_share}
    details: dict[str, Any] = {"mean": mean}
    span = float(t[-1] - t[0])
    # time: a sinusoid of fixed frequency
    freqs = np.arange(max(1.5 / span, 2.0), f_max, 0.25)
    q_t, f_t, c_t = _best_of(
        [(float(f), np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])) for f in freqs],
        series,
        weights,
    )
    r2["time"] = q_t
    # time: a transient from the event, exp(-t / tau) for t >= 0
    after = (t >= 0).astype(float)
    q_x, tau_x, c_x = _best_of(
        [(float(tau), (after * np.exp(-np.clip(t, 0.0, None) / tau))[:, None]) for tau in np.geomspace(2e-4, 0.1, 40)],
        series,
        weights,
    )
    r2["transient"] = q_x
    # angle: periodic in the motor angle theta_1 = integral of omega1
    omega1 = base[CHANNELS.index("omega1")]
    dt_s = float(t[1] - t[0])
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (omega1[1:] + omega1[:-1]) * dt_s)])
    w_max = max(float(np.max(np.abs(omega1))), 1e-9)
    swept = float(np.ptp(theta))
    q_a, order_a, c_a = -np.inf, math.nan, np.zeros(3)
    if swept > 0:
        orders = np.arange(max(0.5, 2 * np.pi / swept), 2 * np.pi * f_max / w_max, max(0.05, 0.25 * np.pi / swept))
        q_a, order_a, c_a = _best_of(
            [(float(o), np.column_stack([np.sin(o * theta), np.cos(o * theta)])) for o in orders[:4000]],
            series,
            weights,
        )
    r2["angle"] = q_a
    # speed: a + b tanh(w / W_SMOOTH) + c w of the motor or the load speed (pu)
    speeds = {"w_1": omega1 / omega_b, "w_3": base[CHANNELS.index("v2")] / (omega_b * radius)}
    q_s, speed_s, c_s = _best_of(
        [(name, np.column_stack([np.tanh(sp / W_SMOOTH), sp])) for name, sp in speeds.items()], series, weights
    )
    r2["speed"] = q_s
    if const_share >= settings.const_share:
        details["constant_share"] = const_share
        return "constant", mean, math.nan, r2, details
    shapes = {k: v for k, v in r2.items() if k != "constant"}
    ranked = sorted(shapes, key=lambda k: shapes[k], reverse=True)
    kind = ranked[0]
    second = max(shapes[ranked[1]], 0.0)
    if shapes[kind] < settings.min_shape_r2 or shapes[kind] < settings.shape_margin * second:
        return "unclear", math.sqrt(energy), math.nan, r2, details
    if kind == "time":
        details["frequency_hz"] = f_t
        return "time", float(np.hypot(c_t[1], c_t[2])), f_t, r2, details
    if kind == "transient":
        details["time_constant_s"] = tau_x
        details["transient"] = True
        return "time", float(c_x[1]), math.nan, r2, details
    if kind == "angle":
        mean_speed = float(np.sum(w * np.abs(omega1)) / np.sum(w))
        details["order_per_revolution"] = order_a
        details["mean_speed_rad_s"] = mean_speed
        return "angle", float(np.hypot(c_a[1], c_a[2])), order_a * mean_speed / (2 * np.pi), r2, details
    details["speed"] = speed_s
    details["sign_part"] = float(c_s[1])
    details["proportional_part"] = float(c_s[2])
    return "speed", abs(float(c_s[1])), math.nan, r2, details


#: The part whose motion a Coulomb friction at a locus opposes, and the speed it follows.
_FRICTION_PART: dict[str, tuple[str, str]] = {
    "motor_shaft": ("motor shaft", "w_1"),
    "drive_train": ("drive wheel", "w_2"),
    "load": ("load", "w_3"),
}
#: A schedule smaller than the Coulomb friction beside it is described too when its weighted RMS exceeds
#: this share of the friction (a larger one is the term's shape, the friction described beside it).
_FRICTION_ALONE: float = 0.25
#: A schedule beside a drifted part parameter is described too when its weighted RMS exceeds this
#: share of the locus's scan scale (:data:`~engine.diagnosis.locus.SCAN_SCALE`).
_DRIFT_ALONE: float = 0.1


def _describe(locus: str, unit: str, follows: str, amplitude: float, freq: float, details: Mapping[str, Any]) -> str:
    what, where = _WHAT[locus], _WHERE[locus]
    a = "an" if what[0] in "aeiou" else "a"
    amp = f"{abs(amplitude):.2g} {unit}"
    if follows == "constant":
        if locus == "clutch":
            return (
                f"a constant angle offset of about {amplitude:+.2g} rad in the clutch (the backlash zone is off-centre)"
            )
        return f"a constant {what} of about {amplitude:+.2g} {unit} {where}"
    if follows == "time" and details.get("transient"):
        tau = details["time_constant_s"]
        return (
            f"{a} {what} of about {amp} at the event {where}, decaying with a time constant of about {tau * 1e3:.2g} ms"
        )
    if follows == "time":
        return f"a periodic {what} of about {amp} at {freq:.3g} Hz (fixed frequency) {where}"
    if follows == "angle":
        order = details["order_per_revolution"]
        return (
            f"{a} {what} of about {amp} periodic in the motor angle ({order:.3g} periods per revolution, "
            f"about {freq:.3g} Hz at the test's mean speed) {where}"
        )
    if follows == "speed":
        sp = "the motor speed" if details["speed"] == "w_1" else "the load speed"
        return f"{a} {what} of about {amp} that follows {sp} (like a friction) {where}"
    return f"{a} {what} of RMS about {amp} {where}, of no clear shape"


def _interval(value: float, sigma: float, lo: float, hi: float) -> tuple[float, float] | None:
    """The 95 % interval ``value +- 1.96 sigma`` within ``[lo, hi]``, or None without a finite sigma."""
    if not math.isfinite(sigma):
        return None
    return max(lo, value - Z95 * sigma), min(hi, value + Z95 * sigma)


def _decimals(sigma: float, default: int) -> int:
    """Decimals that show a value to about a tenth of its standard deviation (``default`` without one)."""
    if not (math.isfinite(sigma) and sigma > 0.0):
        return default
    return max(0, 1 - math.floor(math.log10(sigma)))


def _stated(value: float, interval: tuple[float, float] | None, sigma: float, default: int) -> str:
    """``value`` to about a tenth of ``sigma``, and its 95 % interval when there is one."""
    d = _decimals(sigma, default)
    if interval is None:
        return f"{value:.{d}f}"
    return f"{value:.{d}f} (95 % interval {interval[0]:.{d}f} to {interval[1]:.{d}f})"


def locus_term(
    locus: str,
    est: Estimate,
    resp: Responses,
    cal: CalibrationResult,
    t_rel: np.ndarray,
    settings: LocusSettings,
    part_sigma: float = math.nan,
) -> Term:
    """The estimated input of ``locus`` on the record's grid, and its shape.

    ``part_sigma`` is the standard deviation of the estimate's part term (its friction [pu], or its
    drift's factor; :func:`~engine.diagnosis.locus._uncertainty.part_term_sigma`): the term's
    details and description then carry it and its 95 % interval.
    """
    assert cal.case is not None and cal.event_time is not None
    t_abs = cal.event_time + t_rel
    series = np.interp(t_abs, resp.knots, resp.values(est.x, est.e)) + np.where(t_rel >= 0, est.e[1], 0.0)
    # how well the record determines the input at each instant (the constant is determined throughout)
    resolution = np.ones(resp.knots.size)
    resolution[resp.first_free :] = est.fit.resolution
    weight = np.interp(t_abs, resp.knots, resolution)
    unit = DISTURBANCE_MEANING[locus][1]
    f_max = min(settings.max_frequency_hz, 0.4 / float(resp.knots[1] - resp.knots[0]))
    follows, amp, freq, r2, details = _shape(
        series, weight, t_rel, resp.base, cal.case.plant.r, cal.case.plant.omega_b, settings, f_max
    )
    description = _describe(locus, unit, follows, amp, freq, details)
    if est.field and est.field not in COULOMB_FIELDS.values() and est.f != 0.0:  # a part parameter drifted
        meaning = PART_FIELDS[locus][est.field][0]
        rms = float(np.sqrt(np.average(series**2, weights=weight))) if np.any(weight > 0) else 0.0
        lo, hi = PART_FIELDS[locus][est.field][1]
        ci = _interval(1.0 + est.f, part_sigma, lo, hi)
        drift = f"the {meaning} at about {_stated(1.0 + est.f, ci, part_sigma, 2)} times its calibrated value"
        if rms > _DRIFT_ALONE * SCAN_SCALE[locus]:
            drift += "; besides it, " + description
        description = drift
        details = {
            **details,
            "drift_field": est.field,
            "drift_factor": 1.0 + est.f,
            "drift_factor_sigma": part_sigma if math.isfinite(part_sigma) else None,
            "drift_factor_interval_95": None if ci is None else list(ci),
        }
    elif est.f > 0.0:  # a Coulomb friction at the locus: it follows the part's speed, beside the schedule
        part, speed = _FRICTION_PART[locus]
        rms = float(np.sqrt(np.average(series**2, weights=weight))) if np.any(weight > 0) else 0.0
        ci = _interval(est.f, part_sigma, 0.0, math.inf)
        friction = (
            f"a Coulomb friction of about {_stated(est.f, ci, part_sigma, 3)} pu against the motion of the {part} "
            f"(it follows the sign of {speed})"
        )
        details = {
            **details,
            "coulomb_friction": est.f,
            "coulomb_field": COULOMB_FIELDS[locus],
            "coulomb_friction_sigma": part_sigma if math.isfinite(part_sigma) else None,
            "coulomb_friction_interval_95": None if ci is None else list(ci),
        }
        if rms <= est.f:  # the friction is the larger part: it is the term's shape
            if rms > _FRICTION_ALONE * est.f:
                friction += "; besides it, " + description
            description = friction
            details["speed"] = speed
            follows, amp, freq = "speed", est.f, math.nan
        else:
            description += "; besides it, " + friction
    return Term(
        kind=_WHAT[locus],
        unit=unit,
        t=t_rel,
        series=series,
        rms=float(np.sqrt(np.mean(series**2))),
        peak=float(np.max(np.abs(series))),
        amplitude=float(amp),
        dominant_frequency_hz=float(freq),
        follows=follows,
        shape_r2=r2,
        details=details,
        description=description,
    )


def sensor_term(values: Mapping[str, float], names: list[str], settings: LocusSettings) -> Term:
    """The sensor library's fit as a term (no time series).

    ``values`` may hold cross-talk shares ``crosstalk_<i>_from_<j>`` (channel i reads that share of
    channel j in addition; in channel i's unit per channel j's, named where they differ), and a
    periodic interference: ``interference_hz`` [Hz] with ``interference_<i>``, the amplitude channel
    i reads [its unit] (:mod:`engine.diagnosis.locus._interference`). The delay and low-pass columns are responses to the probe delay and the
    probe cut-off, so their coefficients scale those: a delay of about ``coef * delay_probe`` [s], and a first-order lag of
    about ``coef / (2 pi lowpass_probe_hz)`` [s] (valid while the terms are small).
    """
    parts = []
    details: dict[str, Any] = {}
    for name in names:
        off, gain = values[f"offset_{name}"], values[f"gain_{name}"]
        details[f"offset_{name}"] = off
        details[f"gain_error_{name}"] = gain
        parts.append(f"{name}: gain {1 + gain:.3g}, offset {off:+.3g}")
    delay = values["delay"] * settings.delay_probe
    lag = values["lowpass"] / (2 * math.pi * settings.lowpass_probe_hz)
    details["delay_s"] = delay
    details["lag_s"] = lag
    parts.append(f"delay {delay * 1e6:+.3g} us, first-order lag {lag * 1e6:+.3g} us")
    cross = []
    for key, g in values.items():
        if key.startswith("crosstalk_"):
            reader, source = key.removeprefix("crosstalk_").split("_from_")
            details[key] = g
            ui, uj = CHANNEL_UNITS[reader], CHANNEL_UNITS[source]
            unit = "" if ui == uj else f" ({ui} per {uj})"
            cross.append(f"{reader} reads {g:+.3g}{unit} x {source} in addition (cross-talk)")
    if "interference_hz" in values:
        f = values["interference_hz"]
        details["interference_hz"] = f
        reached = [c for c in names if f"interference_{c}" in values]  # in the record's order
        amps = []
        for c in reached:
            details[f"interference_{c}"] = values[f"interference_{c}"]
            amps.append(f"{c} {values[f'interference_{c}']:.3g} {CHANNEL_UNITS[c]}")
        who = reached[0] if len(reached) == 1 else ", ".join(reached[:-1]) + " and " + reached[-1]
        cross.insert(
            0,
            f"{who} read{'s' if len(reached) == 1 else ''} an interference at {f:.4g} Hz "
            f"(amplitude {', '.join(amps)}) besides the signal",
        )
    parts = cross + parts  # what the data asked for first
    return Term(
        kind="sensor error",
        unit="",
        t=np.zeros(0),
        series=np.zeros(0),
        rms=math.nan,
        peak=math.nan,
        amplitude=math.nan,
        dominant_frequency_hz=math.nan,
        follows="constant",
        shape_r2={},
        details=details,
        description="an error of the measurement chain (" + "; ".join(parts) + ")",
    )
