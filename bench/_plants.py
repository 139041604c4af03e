"""Shared by the benchmarks that draw plants: operating points uniform in a range table.

:func:`uniform_plants` draws K, J1 and c of each plant in that order from a table shaped like
:data:`engine.constants.OPERATING_RANGE` or :data:`engine.constants.PLAUSIBLE_RANGE` (``name:
(low, high, unit)``), so that a seed gives the same plants in every script.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from engine.simulation import PlantParameters


def uniform_plants(
    ranges: Mapping[str, tuple[float, float, str]], n: int, rng: np.random.Generator
) -> list[PlantParameters]:
    """``n`` plants with K [m], J1 [kg m^2] and c [pu] uniform in ``ranges``, the rest nominal."""
    (K_lo, K_hi, _), (J1_lo, J1_hi, _), (c_lo, c_hi, _) = (ranges[k] for k in ("K", "J1", "c"))
    return [
        PlantParameters(K=rng.uniform(K_lo, K_hi), J1=rng.uniform(J1_lo, J1_hi), c=rng.uniform(c_lo, c_hi))
        for _ in range(n)
    ]
