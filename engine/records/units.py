"""Units a record's channels may come in, and the one place where they are converted.

Inside the engine every channel is in MODEL.md section 3's unit
(:data:`engine.constants.CHANNEL_UNITS`: a1 and a2 in m/s^2, m_el in pu, omega1
in rad/s, v2 in m/s). A record may arrive in other units; it is converted once,
when it is read (:func:`to_model_units`), and results that are records
(simulations before and after a fix) go back in the record's own units
(:func:`from_model_units`).

Factors (value in the model unit = value in the unit x factor):

========  ==========  ===============================================
channel   unit        factor
========  ==========  ===============================================
a1, a2    ``m/s^2``   1
a1, a2    ``g``       9.80665 (standard gravity, ISO 80000-3)
omega1    ``rad/s``   1
omega1    ``rpm``     2 pi / 60
omega1    ``pu``      Omega_b = w_b / p = 157.08 rad/s (MODEL.md: 50 Hz, 2 pole pairs)
v2        ``m/s``     1
v2        ``mm/s``    1e-3
m_el      ``pu``      1
m_el      ``N*m``     1 / base_torque, with ``conditions.base_torque`` [N*m]
========  ==========  ===============================================
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Final

import numpy as np

from engine.constants import CHANNEL_UNITS, CHANNELS, OMEGA_B

__all__ = [
    "BASE_TORQUE",
    "STANDARD_GRAVITY",
    "UNITS",
    "UnitError",
    "factor",
    "from_model_units",
    "to_model_units",
]

#: Standard gravity g_n [m/s^2] (ISO 80000-3).
STANDARD_GRAVITY: Final[float] = 9.80665
#: Name of the record condition that gives the torque base [N*m] of an m_el in N*m.
BASE_TORQUE: Final[str] = "base_torque"

#: Accepted units per channel: unit -> factor to the model unit, or None where the factor comes
#: from the record's conditions (m_el in N*m: 1 / base_torque).
UNITS: Final[dict[str, dict[str, float | None]]] = {
    "a1": {"m/s^2": 1.0, "g": STANDARD_GRAVITY},
    "m_el": {"pu": 1.0, "N*m": None},
    "omega1": {"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0, "pu": OMEGA_B},
    "a2": {"m/s^2": 1.0, "g": STANDARD_GRAVITY},
    "v2": {"m/s": 1.0, "mm/s": 1e-3},
}
assert all(UNITS[c][CHANNEL_UNITS[c]] == 1.0 for c in CHANNELS)  # the model unit is always factor 1


class UnitError(ValueError):
    """Raised for a unit a channel cannot be given in, or a conversion that lacks its base."""


def factor(channel: str, unit: str, conditions: Mapping[str, float] | None = None) -> float:
    """Factor from ``unit`` to the model unit of ``channel`` (model value = value x factor).

    Raises
    ------
    UnitError
        Unknown unit for the channel (the message names the accepted ones), or m_el in
        N*m without a positive ``conditions.base_torque``.
    """
    accepted = UNITS.get(channel)
    if accepted is None:
        raise UnitError(f"unknown channel {channel!r}; known channels: {', '.join(CHANNELS)}")
    if unit not in accepted:
        raise UnitError(f"unknown unit {unit!r} for channel {channel!r}; accepted units: {', '.join(accepted)}")
    f = accepted[unit]
    if f is not None:
        return f
    base = (conditions or {}).get(BASE_TORQUE)
    if base is None or not (math.isfinite(float(base)) and float(base) > 0):
        raise UnitError(
            f"channel {channel!r} in {unit} needs conditions.{BASE_TORQUE}: the motor's base torque in N*m "
            f"(a positive number), to convert to per unit"
        )
    return 1.0 / float(base)


def _check_units(units: Mapping[str, str], channels: Mapping[str, np.ndarray]) -> None:
    extra = [c for c in units if c not in channels]
    if extra:
        raise UnitError(
            f"units are given for channel {extra[0]!r}, which the record does not hold; it holds: {', '.join(channels)}"
        )


def to_model_units(
    channels: Mapping[str, np.ndarray], units: Mapping[str, str], conditions: Mapping[str, float] | None = None
) -> dict[str, np.ndarray]:
    """Channels in the units ``units`` (missing channel = model unit) converted to the model units.

    A channel already in its model unit (factor 1) is returned as it came, as a float array, not copied.
    """
    _check_units(units, channels)
    out = {}
    for c, x in channels.items():
        f = factor(c, units.get(c, CHANNEL_UNITS[c]), conditions)
        out[c] = np.asarray(x, dtype=float) if f == 1.0 else np.asarray(x, dtype=float) * f
    return out


def from_model_units(
    channels: Mapping[str, np.ndarray], units: Mapping[str, str], conditions: Mapping[str, float] | None = None
) -> dict[str, np.ndarray]:
    """Inverse of :func:`to_model_units`: channels in model units expressed in ``units``."""
    return {
        c: np.asarray(x, dtype=float) / factor(c, units.get(c, CHANNEL_UNITS[c]), conditions)
        for c, x in channels.items()
    }
