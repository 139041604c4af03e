"""Simulation requests and responses."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, FiniteFloat

from app.schemas.common import RecordPublic
from engine.constants import C1_NOMINAL, C_NOMINAL, J1_NOMINAL, K_GRID, K_NOMINAL

_EFFECTS_DOC = (
    'Unmodelled effects by catalogue name and value, e.g. {"motor_coulomb_friction": 0.02}; see the '
    "effects catalogue (engine.simulation.CATALOGUE) for names, meanings and ranges."
)


class SimulateCreate(BaseModel):
    """One case of the backlash test; omitted values take MODEL.md's defaults."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [{"K": K_NOMINAL, "J1": J1_NOMINAL, "c": C_NOMINAL, "c1": C1_NOMINAL, "effects": {}}]
        },
    )

    K: FiniteFloat = Field(description=f"Backlash zone width [m] (paper grid {K_GRID[0]:g} .. {K_GRID[-1]:g}).")
    J1: FiniteFloat | None = Field(default=None, description=f"Motor-side inertia [kg m^2]; default {J1_NOMINAL:g}.")
    c: FiniteFloat | None = Field(
        default=None, description=f"Apparent viscosity of the absorber [pu]; default {C_NOMINAL:g}."
    )
    c1: FiniteFloat | None = Field(
        default=None, description=f"Absorber discontinuity at zero speed [pu]; default {C1_NOMINAL:g}."
    )
    effects: dict[str, FiniteFloat] = Field(default_factory=dict, description=_EFFECTS_DOC)


class SimulateBatchCreate(BaseModel):
    """Several cases simulated in one call (at most BACKLASH_MAX_BATCH_CASES)."""

    model_config = ConfigDict(extra="forbid")

    cases: list[SimulateCreate] = Field(min_length=1, description="The cases, simulated in this order.")


class SimulationPublic(RecordPublic):
    """The simulated record; ``conditions`` carry its J1, c, c1 and K, ``event_time`` is t_e."""

    event_time: float = Field(description="t_e [s] since the motor was switched on.")


class SimulationsPublic(BaseModel):
    data: list[SimulationPublic]
    count: int
