"""Effects every plant has, without a line of model code: the measurement chain and the actuators.

Around any FMU (:class:`~engine.plants.fmu.plant.FmuPlant`), per measured channel ``c`` (locus
``sensors``):

==========================  ===========  =============  ===============================================
effect                      neutral      bounds         what the record then reads
==========================  ===========  =============  ===============================================
``<c>_gain``                1            0.8 to 1.25    g y
``<c>_offset``              0            +-5 % of FS    y + o   (FS: the channel's ``full_scale``)
``<c>_delay``               0            0 to max_delay y(t - tau)
``<c>_lag``                 0            0 to max_lag   y low-passed, first order of time constant tau
``<c>_quantisation``        0            0 to 1 % of FS q round(y / q)
==========================  ===========  =============  ===============================================

and per driven input ``u`` (locus ``actuators``): ``<u>_actuator_gain`` (1; 0.8 to 1.25: the FMU
receives g u), ``<u>_actuator_delay`` (0; 0 to max_delay: u(t - tau)) and ``<u>_saturation`` (0;
0 to 0.5: u clipped to its record's mid-range +- (1 - s) half-range). The delays shift a series by
linear interpolation on the record's instants (the first sample held before it); the lag is the
exact discretisation of a first-order low-pass at the record's median sample interval.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from engine.plants.base import CandidateEffect
from engine.plants.fmu.description import ACTUATOR_LOCUS, SENSOR_LOCUS, PlantDescription

__all__ = ["GAIN_BOUNDS", "GenericEffect", "apply_actuators", "apply_sensors", "generic_effects"]

#: Search bounds of a gain [-].
GAIN_BOUNDS: tuple[float, float] = (0.8, 1.25)
#: A sensor's offset is searched within this share of its full scale, either sign.
OFFSET_SHARE: float = 0.05
#: A sensor's quantisation step is searched up to this share of its full scale.
QUANTUM_SHARE: float = 0.01
#: An actuator's saturation: the largest share of the input's half-range it may cut.
SATURATION_BOUNDS: tuple[float, float] = (0.0, 0.5)


@dataclass(frozen=True)
class GenericEffect:
    """One generic effect: what it does (``kind``), to which channel or input column (``target``)."""

    kind: str
    target: str
    effect: CandidateEffect


def generic_effects(description: PlantDescription) -> dict[str, GenericEffect]:
    """Every generic effect of the description's channels and driven inputs, by name (module docstring)."""
    g = description.generic
    out: dict[str, GenericEffect] = {}

    def add(
        kind: str, target: str, name: str, desc: str, bounds: tuple[float, float], neutral: float, unit: str, locus: str
    ) -> None:
        out[name] = GenericEffect(kind, target, CandidateEffect(name, desc, bounds, neutral, unit, locus))

    if g.sensors:
        for c in description.channels:
            fs = c.full_scale
            add(
                "gain",
                c.name,
                f"{c.name}_gain",
                f"gain of the {c.name} sensor: it reads g times the value",
                GAIN_BOUNDS,
                1.0,
                "x",
                SENSOR_LOCUS,
            )
            add(
                "offset",
                c.name,
                f"{c.name}_offset",
                f"offset of the {c.name} sensor [{c.unit}]",
                (-OFFSET_SHARE * fs, OFFSET_SHARE * fs),
                0.0,
                c.unit,
                SENSOR_LOCUS,
            )
            add(
                "delay",
                c.name,
                f"{c.name}_delay",
                f"delay of the {c.name} channel [s]",
                (0.0, g.max_delay),
                0.0,
                "s",
                SENSOR_LOCUS,
            )
            add(
                "lag",
                c.name,
                f"{c.name}_lag",
                f"first-order lag (time constant) of the {c.name} sensor [s]",
                (0.0, g.max_lag),
                0.0,
                "s",
                SENSOR_LOCUS,
            )
            add(
                "quantisation",
                c.name,
                f"{c.name}_quantisation",
                f"quantisation step of the {c.name} channel [{c.unit}]",
                (0.0, QUANTUM_SHARE * fs),
                0.0,
                c.unit,
                SENSOR_LOCUS,
            )
    if g.actuators:
        for i in description.driven:
            col = str(i.column)
            add(
                "actuator_gain",
                col,
                f"{col}_actuator_gain",
                f"gain of the actuator of {col}: the machine receives g times the record's value",
                GAIN_BOUNDS,
                1.0,
                "x",
                ACTUATOR_LOCUS,
            )
            add(
                "actuator_delay",
                col,
                f"{col}_actuator_delay",
                f"delay of the actuator of {col} [s]",
                (0.0, g.max_delay),
                0.0,
                "s",
                ACTUATOR_LOCUS,
            )
            add(
                "saturation",
                col,
                f"{col}_saturation",
                f"saturation of the actuator of {col}: clipped to (1 - s) of its half-range about its mid-range",
                SATURATION_BOUNDS,
                0.0,
                "x",
                ACTUATOR_LOCUS,
            )
    return out


def _delayed(t: np.ndarray, x: np.ndarray, tau: float) -> np.ndarray:
    return x if tau == 0.0 else np.interp(t - tau, t, x)


def _lagged(t: np.ndarray, x: np.ndarray, tau: float) -> np.ndarray:
    if tau <= 0.0:
        return x
    from scipy.signal import lfilter

    a = math.exp(-float(np.median(np.diff(t))) / tau)
    y, _ = lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])
    return np.asarray(y)


def apply_actuators(
    effects: Mapping[str, GenericEffect], values: Mapping[str, float], t: np.ndarray, u: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """The driven inputs ``u`` (record column -> samples) as the actuators deliver them at ``values``."""
    out = dict(u)
    for name, ge in effects.items():
        v = values.get(name)
        if v is None or v == ge.effect.neutral or ge.target not in out:
            continue
        x = out[ge.target]
        if ge.kind == "actuator_gain":
            x = v * x
        elif ge.kind == "actuator_delay":
            x = _delayed(t, x, v)
        elif ge.kind == "saturation":
            lo, hi = float(np.min(x)), float(np.max(x))
            mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
            x = np.clip(x, mid - (1.0 - v) * half, mid + (1.0 - v) * half)
        else:
            continue
        out[ge.target] = x
    return out


#: Order in which a channel's chain acts: the sensor's dynamics, then its static error, then the converter.
_SENSOR_ORDER: tuple[str, ...] = ("lag", "delay", "gain", "offset", "quantisation")


def apply_sensors(
    effects: Mapping[str, GenericEffect], values: Mapping[str, float], t: np.ndarray, y: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """The channels ``y`` (name -> samples) as the measurement chain reads them at ``values``."""
    active = [(ge, float(values[n])) for n, ge in effects.items() if n in values and values[n] != ge.effect.neutral]
    if not active:
        return y
    out = dict(y)
    for kind in _SENSOR_ORDER:
        for ge, v in active:
            if ge.kind != kind or ge.target not in out:
                continue
            x = out[ge.target]
            if kind == "lag":
                x = _lagged(t, x, v)
            elif kind == "delay":
                x = _delayed(t, x, v)
            elif kind == "gain":
                x = v * x
            elif kind == "offset":
                x = x + v
            elif kind == "quantisation" and v > 0.0:
                x = v * np.round(x / v)
            out[ge.target] = x
    return out
