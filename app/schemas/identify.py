"""Identification requests and responses."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictBool

from app.schemas.common import ChannelName, RecordIn
from app.schemas.diagnose import BrfdRecordIn
from app.schemas.drive import DriveIn
from engine.constants import C_NOMINAL, K_GRID


class IdentifyCreate(BaseModel):
    """Identify the backlash width of a record with a stored pattern set."""

    model_config = ConfigDict(extra="forbid")

    record: RecordIn
    channel: ChannelName = Field(description="Channel of the record to identify from; the pattern set's channel.")
    pattern_set: str | None = Field(
        default=None,
        description="Id of the pattern set; default: the stored set of this channel whose c is nearest the "
        f"record's conditions.c (nominal c = {C_NOMINAL:g} when the record does not give c).",
    )
    kind: str | None = Field(default=None, description="Only choose pattern sets of this identifier kind.")
    any_set: StrictBool = Field(
        default=False,
        description="Also choose among sets trained with effects or on another J1 grid than the paper's (by default "
        "only sets trained as the paper trains are chosen; a set named by pattern_set is always used).",
    )
    continuous: StrictBool = Field(
        default=False,
        description="Also estimate K as a continuous width by fitting the simulator to the channel (a few "
        "seconds): K, its standard deviation and the fit.",
    )
    drive: DriveIn | None = Field(
        default=None,
        description="The description of the drive the record is of (docs/drive-description.md); default MODEL.md's "
        "reference plant. Only a pattern set trained for this drive identifies the record; its nominal c is the "
        "c used when the record gives none. The continuous width is not yet calibrated on a described drive.",
    )


class ContinuousWidthPublic(BaseModel):
    K: float = Field(description="Calibrated backlash zone width [m] (continuous, beyond the six classes).")
    sigma_K: float = Field(
        description="One standard deviation of K [m] (Gauss-Newton, measurement noise only; "
        "too small on a1 under noise: the true K lies within 2 sd in about half the cases)."
    )
    nearest_width: float = Field(description="The paper's width nearest to K [m].")
    fitted: dict[str, float] = Field(description="Every fitted parameter (K [m], J1 [kg m^2], c [pu], c1 [pu]).")
    fixed: dict[str, float] = Field(description="Parameters fixed by the record's conditions.")
    reduced_chi2: float = Field(description="chi2 / n of the fit (about 1 when the model fits to the noise).")
    seconds: float = Field(description="Time of the fit [s].")
    interval_95: list[float] | None = Field(
        default=None, description="95 % interval of K [m, m] (when the width estimate gives one)."
    )


class WarningOut(BaseModel):
    """A suspicion that the record is not what the plant can produce, and what to check."""

    code: str = Field(
        description="Short stable id: constant_channel, channel_scale, sample_interval, misfit "
        "(engine.diagnosis.plausibility); stand_in (an explained answer at a weak gap that may stand in for "
        "physics outside the catalogue, engine.diagnosis.open_world)."
    )
    message: str = Field(description="The suspicion, with the numbers behind it, and what to check.")
    channel: str | None = Field(default=None, description="The channel it concerns (null: the whole record).")


class RecordReadPublic(BaseModel):
    """How the record was read: its grid, where its event is, which samples were used."""

    sample_interval: float = Field(description="The record's Ts [s].")
    n_samples: int = Field(description="Samples per channel in the record.")
    event_index: int = Field(description="Sample at the event (given, or located from the data).")
    event_location: dict[str, Any] | None = Field(
        default=None,
        description="When the record gave no event_index: the located index, the interval (-Ts, 0] [s] in which "
        "the event lies relative to it, its standard uncertainty sigma [s], the channel and the method.",
    )
    window: dict[str, int | float] = Field(
        description="The samples used (the test window, 4.8 ms before to 200 ms after the event) and how many "
        "were ignored before and after them."
    )
    patterns_read: str = Field(
        description="What the pattern set compared: the window as recorded (0.1 ms records) or resampled to "
        "0.1 ms (scipy.signal.resample_poly)."
    )


class IdentificationPublic(BaseModel):
    D: list[float] = Field(description="D(i) = sum_j |Wt(j) - Ww(i,j)| for the six widths [-].")
    index: int = Field(ge=1, le=len(K_GRID), description="1-based index of the smallest D (the paper's nr5).")
    width: float = Field(description="Identified backlash zone width K [m].")
    widths: list[float] = Field(description="The six widths K [m] that D refers to, in order.")
    epochs: int = Field(description="Epochs the record's own network needed.")
    rms: float = Field(description="RMS output error of the record's network [-].")
    converged: bool = Field(description="Whether that network reached RMS < delta1 before the epoch cap.")
    channel: str
    pattern_set: str = Field(description="Id of the pattern set used.")
    kind: str = Field(description="Identifier kind of the pattern set.")
    pattern_set_c: float = Field(description="c of the pattern set used [pu].")
    drive: str | None = Field(
        default=None,
        description="Fingerprint of the drive description the pattern set was trained for, the record's drive.",
    )
    selection: Literal["requested", "exact", "nearest"] = Field(
        description="requested: named in the request; exact: its c equals c_used; "
        "nearest: the stored set with the nearest c."
    )
    c_used: float | None = Field(description="c [pu] used to choose the set (null when the set was requested).")
    c_source: Literal["record", "nominal"] | None = Field(
        description=f"Where c_used came from: the record's conditions, or the nominal c = {C_NOMINAL:g}."
    )
    c_distance: float | None = Field(
        default=None,
        description="|c of the set - c_used| [pu] (null when the set was requested); a set farther than "
        "max_c_distance is never chosen (422).",
    )
    max_c_distance: float = Field(description="The farthest c a chosen set may have from the record's [pu].")
    identification_id: str | None = Field(
        default=None, description="Where the identification of a named asset is stored (its history)."
    )
    asset: str | None = Field(default=None, description="The record's asset, when it names one.")
    measured_at: datetime | None = Field(default=None, description="When the record was taken (or received).")
    continuous: ContinuousWidthPublic | None = Field(
        default=None, description="The calibrated K as a continuous width (only when requested)."
    )
    warnings: list[WarningOut] = Field(
        default_factory=list,
        description="What makes the record doubtful for the plant (a channel in a wrong unit, a wrong sample "
        "interval, a fit far above the noise; with the continuous width also what its calibration reveals): "
        "check these before acting on the width. Empty when nothing is.",
    )
    record: RecordReadPublic = Field(description="How the record was read.")


class PlantIdentifyCreate(BaseModel):
    """The backlash width of records of a plant with a play in its catalogue (``"plant": "brfd"``)."""

    model_config = ConfigDict(extra="forbid")

    plant: Literal["brfd"] = Field(description="The plant the records are of.")
    record: BrfdRecordIn
    joint: list[BrfdRecordIn] = Field(
        default_factory=list,
        max_length=20,
        description="Other records of the same device, fitted jointly with ``record`` (one width shared).",
    )
    continuous: Literal[True] = Field(
        default=True, description="The width is fitted as a continuous parameter (the only way for this plant)."
    )


class PlantWidthPublic(BaseModel):
    """The width of a plant's records: continuous with its interval and identifiability; the seed's method beside it."""

    plant: str
    records: list[str]
    unit: str = Field(description="Unit of the width (m).")
    continuous: dict[str, Any] = Field(
        description="K, sigma_K (null when not identifiable), interval_95, identifiable, reasons, fitted, "
        "correlation_with_K, relative_error, profile."
    )
    paper: list[dict[str, Any]] | None = Field(
        default=None, description="Per record, the seed's W3/D/argmin width on a grid of six widths."
    )
    warnings: list[WarningOut] = Field(
        default_factory=list, description="What to check before acting on the width (e.g. why it is not identifiable)."
    )
    identification_id: str | None = Field(
        default=None, description="Where the identification of a named asset is stored (its history)."
    )
    asset: str | None = Field(default=None, description="The record's asset, when it names one.")
    measured_at: datetime | None = Field(default=None, description="When the record was taken (or received).")
