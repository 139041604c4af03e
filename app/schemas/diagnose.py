"""Diagnosis request (the response is defined by the diagnosis issue)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictBool

from app.schemas.assets import AssetName, MeasuredAt
from app.schemas.common import Number, NumberSeries, RecordIn, Sample, Samples
from app.schemas.drive import DriveIn
from engine.diagnosis.space import DEFAULT_BOUNDS
from engine.plants.brfd import BrfdRecord
from engine.plants.brfd.record import from_json_object
from engine.plants.emps import EmpsRecord
from engine.plants.emps.record import record_from_arrays
from engine.records.limits import MAX_SAMPLES
from engine.simulation import CATALOGUE


class DiagnoseCreate(BaseModel):
    """Diagnose the gap between a measured record and the model."""

    model_config = ConfigDict(extra="forbid")

    plant: Literal["backlash_drive"] = Field(
        default="backlash_drive",
        description="The plant the record is of; `emps` and `brfd` take their own records instead.",
    )
    record: RecordIn
    effects: list[Annotated[str, Field(json_schema_extra={"enum": list(CATALOGUE)})]] | None = Field(
        default=None, description="Candidate effects (catalogue names) to consider; default the whole catalogue."
    )
    bounds: (
        Annotated[
            dict[str, tuple[Sample, Sample]], Field(json_schema_extra={"propertyNames": {"enum": list(DEFAULT_BOUNDS)}})
        ]
        | None
    ) = Field(
        default=None,
        description=(
            "Search box of the calibration per parameter, name -> [low, high] in its unit: K [m], J1 [kg m^2], "
            "c [pu], c1 [pu]. Parameters not given keep the default box (K 0.001-0.015 m, J1 0.6-1.2 kg m^2, "
            "c 0.5-2.0 pu, c1 0-0.6 pu); a record's conditions fix a parameter outright."
        ),
        examples=[{"K": [0.002, 0.008], "J1": [0.7, 0.9]}],
    )
    drive: DriveIn | None = Field(
        default=None,
        description="The description of the drive the record is of (docs/drive-description.md; default MODEL.md's "
        "reference plant): the diagnosis calibrates on its nominal plant and search box, checks the record "
        "against its envelopes, and keeps it with the diagnosis (``drive`` in the answer).",
    )


class EmpsRecordIn(BaseModel):
    """One EMPS record as the benchmark's .mat file holds it (1 kHz, one value per sample and signal)."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(default="record", max_length=200, description="Name of the record (echoed in the answer).")
    asset: AssetName | None = None
    measured_at: MeasuredAt | None = None
    t: NumberSeries = Field(description="Sample instants [s], uniform at 1 ms.")
    qm: NumberSeries = Field(description="Measured motor position, load side [m].")
    qg: NumberSeries = Field(description="Reference position [m].")
    vir: NumberSeries = Field(description="Controller output as measured [V].")
    pulses_N: NumberSeries | None = Field(default=None, description="Pulse signal added to the command [V].")
    kp: Number = Field(description="Position gain [1/s].")
    kv: Number = Field(description="Velocity gain [V/(m/s)].")
    gtau: Number = Field(description="Drive gain [N/V].")

    def to_record(self) -> EmpsRecord:
        """The engine's record, checked (RecordError, 422, says what to fix)."""
        import numpy as np

        arrays = {
            k: np.asarray(v, dtype=float)
            for k in ("t", "qm", "qg", "vir", "pulses_N")
            if (v := getattr(self, k)) is not None
        }
        return record_from_arrays(arrays, {"kp": self.kp, "kv": self.kv, "gtau": self.gtau}, self.name)


class BrfdRecordIn(BaseModel):
    """One BRFD record as the data set's JSON file holds it (inches and kips, converted once by the engine)."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    name: str = Field(default="record", max_length=200, description="Name of the record (echoed in the answer).")
    asset: AssetName | None = None
    measured_at: MeasuredAt | None = None
    data: Annotated[list[list[Number]], Field(max_length=MAX_SAMPLES)] = Field(
        description="One row per sample: time [s], displacement, friction force (then velocity and the actuator "
        "forces, which are not used)."
    )
    dt: Number | None = Field(default=None, description="Sample interval [s] (checked against the time column).")
    sampling_freq: Number | None = Field(default=None, alias="sampling freq", description="[Hz], informative.")
    time_units: str = Field(default="s", alias="time units")
    displacement_units: str = Field(alias="displacement units", description="in, mm or m (the data set: in).")
    friction_force_units: str = Field(alias="friction force units", description="kip, lb, kN or N (the data set: kip).")
    actuator_force_units: str | None = Field(default=None, alias="actuator force units", description="Not used.")

    def to_record(self) -> BrfdRecord:
        """The engine's record, in SI units and checked (RecordError, 422, says what to fix)."""
        obj = self.model_dump(by_alias=True, exclude_none=True, exclude={"name", "asset", "measured_at"})
        return from_json_object(obj, self.name)


class BrfdDiagnoseCreate(BaseModel):
    """Diagnose a record of the BRFD friction damper (``"plant": "brfd"``)."""

    model_config = ConfigDict(extra="forbid")

    plant: Literal["brfd"] = Field(description="The plant the record is of.")
    record: BrfdRecordIn
    calibrate_on: BrfdRecordIn | None = Field(
        default=None, description="Calibrate on this record of the same plant instead (the cross-record check)."
    )
    hold_calibration: StrictBool = Field(
        default=False, description="Hold the calibrated parameters while fitting effects (default: refit them)."
    )


class PlantDiagnoseCreate(BaseModel):
    """Diagnose a record of the EMPS benchmark (``"plant": "emps"``)."""

    model_config = ConfigDict(extra="forbid")

    plant: Literal["emps"] = Field(description="The plant the record is of.")
    record: EmpsRecordIn
    calibrate_on: EmpsRecordIn | None = Field(
        default=None, description="Calibrate on this record of the same plant instead (the cross-record check)."
    )
    hold_calibration: StrictBool = Field(
        default=False, description="Hold the calibrated parameters while fitting effects (default: refit them)."
    )


#: Most columns of an FMU plant's record in JSON (a description's time, driven inputs and channels).
MAX_FMU_COLUMNS = 256


class FmuRecordIn(BaseModel):
    """One record of a stored FMU plant: its columns as the plant's description names them, in its units."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(default="record", max_length=200, description="Name of the record (echoed in the answer).")
    asset: AssetName | None = None
    measured_at: MeasuredAt | None = None
    columns: Annotated[dict[Annotated[str, Field(max_length=200)], Samples], Field(max_length=MAX_FMU_COLUMNS)] = Field(
        description="Column name -> samples: the description's time column [s], every driven input's column and "
        "every channel, in the description's units (other columns are ignored).",
        examples=[{"t": [0.0, 0.001, 0.002], "z_road": [0.0, 0.0, 0.001], "a_body": [0.0, 0.01, 0.02]}],
    )
    units: dict[Annotated[str, Field(max_length=200)], Annotated[str, Field(max_length=40)]] | None = Field(
        default=None,
        description="Column name -> unit, for checking: a unit other than the description's is refused (the "
        "record is not converted).",
    )

    def to_record(self, description: Any) -> Any:
        """The engine's record of the plant ``description`` (:class:`engine.plants.fmu.PlantDescription`), checked
        (RecordError, 422, says what to fix)."""
        from engine.plants.fmu.record import record_from_table

        return record_from_table(description, self.columns, self.units, self.name)


class FmuDiagnoseCreate(BaseModel):
    """Diagnose a record of a stored FMU plant (``"plant": "fmu-..."``, the id POST /v1/plants answered)."""

    model_config = ConfigDict(extra="forbid")

    plant: Annotated[str, Field(pattern=r"^fmu-[0-9a-f]{16}$")] = Field(
        description="The stored plant's id (POST /v1/plants; GET /v1/plants lists them)."
    )
    record: FmuRecordIn
    calibrate_on: FmuRecordIn | None = Field(
        default=None, description="Calibrate on this record of the same plant instead (the cross-record check)."
    )
    hold_calibration: StrictBool = Field(
        default=False, description="Hold the calibrated parameters while fitting effects (default: refit them)."
    )


class DiagnosisAnswer(BaseModel):
    """A diagnosis: the shape of issues 4 and 10 (backlash drive) or of the plant interface (``emps``, ``brfd``).

    Only the fields every diagnosis has are declared; the others are described in docs/gap-diagnosis.md and
    docs/diagnosis.md and kept as they come (``extra="allow"``).
    """

    model_config = ConfigDict(extra="allow")

    verdict: dict[str, Any] = Field(
        description="status (backlash drive; the plants give it at the top level), effect, value, effects "
        "[{effect, value, uncertainty, share, alternatives, near_twins}] (alternatives: effects that give the "
        "very same record; near_twins: effects this record cannot tell from the named one), locus."
    )
    calibration: dict[str, Any] = Field(description="The calibrated parameters with their uncertainties.")
    record: dict[str, Any] | str | None = Field(default=None, description="How the record was read.")
    status: str | None = Field(default=None, description="The plants' verdict status.")
    width: dict[str, Any] | None = Field(
        default=None,
        description="The backlash width of the model the answer ends with: K [m], sigma_K [m], interval_95 "
        "[m, m], from (nominal, the named effect or set, or the best fit when unexplained), identifiable and "
        "the reason when not.",
    )
    warnings: list[dict[str, Any]] = Field(
        default_factory=list,
        description="What makes the record doubtful for the plant ({code, message, channel}): check these "
        "before acting on the answer.",
    )
    locus: dict[str, Any] | None = Field(
        default=None,
        description="Where a gap the catalogue does not close lies and what the missing term looks like: locus "
        "(the part of the machine, or null), confidence, ties, scores per locus, term (entry or kind, unit, size, "
        "the signal it follows, description), note. Null when not estimated (no gap, a fit to the noise).",
    )


class DiagnosisAccepted(BaseModel):
    """A queued diagnosis job (202)."""

    job_id: str
    diagnosis_id: str
    record_id: str = Field(description="The stored record (GET /v1/records/{id}).")
    job_url: str
    diagnosis_url: str


class DiagnosisPublic(BaseModel):
    """A stored diagnosis: its job's state and, once done, the result (the answer of POST /v1/diagnose)."""

    id: str
    job_id: str
    record_id: str
    plant: str
    asset: str | None = None
    measured_at: datetime | None = None
    created_at: datetime
    state: Literal["queued", "running", "done", "failed", "interrupted", "cancelled"]
    status: str | None = Field(default=None, description="The verdict's status, once done.")
    effect: str | None = Field(default=None, description="The verdict's effect, once done.")
    K: float | None = Field(default=None, description="The backlash width the diagnosis found [m], where it has one.")
    K_sigma: float | None = Field(default=None, description="Its 1-sigma uncertainty [m].")
    figures: list[str] = Field(default_factory=list, description="GET /v1/diagnoses/{id}/figures/{name} (PNG).")
    result: DiagnosisAnswer | None = Field(default=None, description="The diagnosis, once done.")


class DiagnosesPublic(BaseModel):
    items: list[DiagnosisPublic] = Field(description="Newest first, without their results.")
