"""Simulation requests and responses."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, FiniteFloat

from app.schemas.common import RecordPublic

_EFFECTS_DOC = (
    'Unmodelled effects by catalogue name and value, e.g. {"motor_coulomb_friction": 0.02}; see the '
    "effects catalogue (engine.simulation.CATALOGUE) for names, meanings and ranges."
)


class SimulateCreate(BaseModel):
    """One case of the backlash test; omitted values take MODEL.md's defaults."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={"examples": [{"K": 0.005, "J1": 0.87, "c": 1.0, "c1": 0.2, "effects": {}}]},
    )

    K: FiniteFloat = Field(description="Backlash zone width [m] (paper grid 0.0025 .. 0.01).")
    J1: FiniteFloat | None = Field(default=None, description="Motor-side inertia [kg m^2]; default 0.87.")
    c: FiniteFloat | None = Field(default=None, description="Apparent viscosity of the absorber [pu]; default 1.0.")
    c1: FiniteFloat | None = Field(default=None, description="Absorber discontinuity at zero speed [pu]; default 0.2.")
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
