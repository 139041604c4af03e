"""The users' own simulators: FMU archives (``/v1/fmus``) and the plants described on them (``/v1/plants``)."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from pydantic import BaseModel, ConfigDict, Field


class FmuPublic(BaseModel):
    """A stored FMU archive: its hash (how a plant description names it) and what it is."""

    sha256: str = Field(description='SHA-256 of the archive (hex); a description\'s fmu is "sha256:<this>".')
    size: int = Field(description="The archive's size [bytes].")
    model_name: str
    fmi_version: str
    platforms: list[str] = Field(description="The platforms it has binaries for.")
    interfaces: list[str] = Field(
        description='The FMI 2.0 interfaces it offers ("co-simulation", "model-exchange"); a description\'s '
        "interface names the one to run."
    )
    inputs: list[str] = Field(description="Its real inputs (a description's inputs name these).")
    outputs: list[str] = Field(description="Its real outputs (a description's channels name these).")
    parameters: list[str] = Field(description="Its real parameters (calibrated parameters and effects name these).")
    created_at: datetime


class PlantCreate(BaseModel):
    """A plant description (docs/fmu-plant.md) whose FMU is a stored archive; TOML may be sent as it is instead."""

    model_config = ConfigDict(extra="forbid")

    description: dict[str, Any] = Field(
        description="The plant description as a JSON object: the keys of its TOML file, with fmu = "
        '"sha256:<hex>" of an archive POST /v1/fmus stored, and no examples.',
        examples=[
            {
                "name": "quarter_car",
                "fmu": "sha256:" + "0" * 64,
                "loci": ["body", "suspension", "wheel", "rig"],
                "inputs": [{"variable": "z_r", "column": "z_road", "unit": "m", "locus": "rig"}],
                "channels": [{"name": "a_body", "variable": "a_body", "unit": "m/s2", "full_scale": 20.0}],
            }
        ],
    )


class EffectPublic(BaseModel):
    """One candidate effect of a plant's catalogue."""

    name: str
    locus: str
    unit: str
    bounds: tuple[float, float]
    description: str = ""


class PlantPublic(BaseModel):
    """A stored plant: its id (what a diagnosis request names), its FMU and what the diagnosis reads of it."""

    id: str = Field(description='Name the plant so in a diagnosis: {"plant": id, ...} or ?plant=id with CSV.')
    name: str
    fmu_sha256: str
    created_at: datetime
    loci: list[str] = Field(description="The parts of the machine its effects and inputs belong to.")
    channels: list[str] = Field(description="The record's measured columns.")
    columns: list[str] = Field(description="Every column a record of it needs: time, driven inputs, channels.")
    calibrated: list[str] = Field(description="The parameters refitted on every record.")
    effects: list[EffectPublic] = Field(description="The catalogue: the description's effects and the generic ones.")
    description: dict[str, Any] = Field(description="The description as stored (every default filled in).")


class PlantsPublic(BaseModel):
    items: list[PlantPublic] = Field(description="Newest first.")
