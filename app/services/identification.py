"""Identification for the service: choose a stored pattern set, rebuild its identifier, identify a record."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from app.services.errors import IncompatibleError, InvalidInputError, NotFoundError
from app.services.patterns import identifier_from_pattern_set
from app.services.simulation import check_units
from engine.constants import C_NOMINAL, K_GRID, MODEL_VERSION
from engine.diagnosis import plausibility
from engine.diagnosis.plausibility import PlausibilityWarning
from engine.identification import IdentificationResult
from engine.identification.selection import MAX_C_DISTANCE, drive_fingerprint, is_plain, nearest_pattern_set
from engine.identification.training import DEFAULT_KIND
from engine.identification.width import estimate_width, nearest_grid_width
from engine.records import Record, to_protocol_grid
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.storage import PatternSet, PatternSetNotFound, PatternStore

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Selection:
    """Which pattern set identifies a record, and why.

    Attributes
    ----------
    pattern_set : PatternSet
    how : {"requested", "exact", "nearest"}
        ``requested``: named by the caller; ``exact``: its c equals the c used;
        ``nearest``: the stored set of that channel with the nearest c.
    c_used : float or None
        c [pu] used to choose the set (``None`` when the set was requested).
    c_source : {"record", "nominal"} or None
        Where ``c_used`` came from: the record's conditions or the nominal c
        (:data:`engine.constants.C_NOMINAL`).
    """

    pattern_set: PatternSet
    how: Literal["requested", "exact", "nearest"]
    c_used: float | None
    c_source: Literal["record", "nominal"] | None


def not_found_message(set_id: str) -> str:
    return (
        f"no pattern set with id {set_id!r} is stored; list the stored sets with GET /v1/pattern-sets "
        "(or `backlash pattern-sets list`)"
    )


def get_pattern_set(store: PatternStore, set_id: str) -> PatternSet:
    """The stored set ``set_id``; :class:`NotFoundError` if there is none."""
    try:
        return store.get(set_id)
    except PatternSetNotFound:
        raise NotFoundError(not_found_message(set_id)) from None


def check_record_drive(record_drive: str | None, drive: DriveDescription | None) -> None:
    """A record that states the drive it was made on (``record_drive``, a fingerprint) must be of ``drive``.

    Raises
    ------
    IncompatibleError
        The record was made on another drive than the request's (MODEL.md's reference plant when ``drive`` is None).
    """
    wanted = drive or REFERENCE_DRIVE
    if record_drive is not None and record_drive != wanted.fingerprint:
        label = f"{wanted.fingerprint[:12]} ({wanted.name})"
        raise IncompatibleError(
            f"the record was made on drive {record_drive[:12]}, the request is for drive {label}; give the record's "
            "own drive description (drive)",
            cli=f"the record was made on drive {record_drive[:12]}, the command is for drive {label}; give the "
            "record's own drive description with --drive FILE",
        )


def drive_for_record(requested: DriveDescription | None, stated: Mapping[str, Any] | None) -> DriveDescription | None:
    """The drive a record is identified or diagnosed on: the request's, else the one the record states in full, else
    the reference.

    A simulated record carries the drive it was made on (``backlash simulate --drive``, ``POST /v1/simulate``): its
    fingerprint and its whole description. Without a drive in the request, such a record is read on its own
    drive; with one, the record must be of it (:func:`check_record_drive`). A record that states only a fingerprint (not
    the description) of another drive than the reference is refused, as before.

    Parameters
    ----------
    requested : DriveDescription or None
        The request's drive (``--drive``, ``"drive"``); None when it gives none.
    stated : mapping or None
        The record's ``drive`` (``{"fingerprint": ..., "description": ...}``), if any.

    Returns
    -------
    DriveDescription or None
        None for MODEL.md's reference plant.

    Raises
    ------
    IncompatibleError
        The record states another drive than the request's, or only the fingerprint of a drive other than the
        reference.
    engine.simulation.ParameterError
        The record's description does not give its stated fingerprint (an edited record), or is refused.
    """
    if requested is not None or stated is None or stated.get("description") is None:
        check_record_drive(None if stated is None else str(stated["fingerprint"]), requested)
        return requested
    drive = DriveDescription.from_provenance(stated)
    if drive.is_reference:
        return None
    logger.info("on the drive the record states: %s (%s)", drive.name, drive.fingerprint[:12])
    return drive


def _drive_label(fingerprint: str, drive: DriveDescription | None = None) -> str:
    """A fingerprint's first 12 digits, with the name of ``drive`` (or of the reference plant's fingerprint)."""
    if drive is None and fingerprint == REFERENCE_DRIVE.fingerprint:
        drive = REFERENCE_DRIVE
    return fingerprint[:12] + (f" ({drive.name})" if drive is not None else "")


def select_pattern_set(
    store: PatternStore,
    channel: str,
    record: Record,
    set_id: str | None = None,
    kind: str | None = None,
    any_set: bool = False,
    drive: DriveDescription | None = None,
) -> Selection:
    """The set named by ``set_id``, else the stored set of ``channel`` whose c is nearest the record's c.

    The record's c comes from ``record.conditions["c"]``; without it the nominal c
    (:data:`engine.constants.C_NOMINAL`) is used. Only sets of the current model version
    (and of ``kind``, if given) are chosen, and only sets trained as the paper trains (no
    effects, its J1 grid) unless ``any_set``; among equally near sets the default kind wins,
    then the newest. A set farther than :data:`~engine.identification.selection.MAX_C_DISTANCE`
    from the record's c is refused (:class:`IncompatibleError`).

    Only a set trained for ``drive`` (MODEL.md's reference plant when None) identifies the record: a requested
    set of another drive is refused (:class:`IncompatibleError`), and the automatic choice looks only at the
    drive's sets (:func:`engine.identification.selection.drive_fingerprint`). Without a c in the record's
    conditions, the drive's nominal c is used.
    """
    wanted = (drive or REFERENCE_DRIVE).fingerprint
    if set_id is not None:
        requested = get_pattern_set(store, set_id)
        if requested.channel != channel:
            raise IncompatibleError(
                f"pattern set {set_id!r} was trained on channel {requested.channel!r}, not {channel!r}; "
                f"identify with channel {requested.channel!r} or choose a set of channel {channel!r}"
            )
        if kind is not None and requested.kind != kind:
            raise IncompatibleError(f"pattern set {set_id!r} is of kind {requested.kind!r}, not {kind!r}")
        if requested.model_version != MODEL_VERSION:
            raise IncompatibleError(
                f"pattern set {set_id!r} was trained on model version {requested.model_version}, this engine implements "
                f"{MODEL_VERSION}; train a new set"
            )
        trained_for = drive_fingerprint(requested)
        if trained_for != wanted:
            raise IncompatibleError(
                f"pattern set {set_id!r} was trained for drive {_drive_label(trained_for)}, the record is of drive "
                f"{_drive_label(wanted, drive)}: a set identifies only records of its own drive; train a set for "
                "this drive (POST /v1/pattern-sets with its drive description)",
                cli=f"pattern set {set_id!r} was trained for drive {_drive_label(trained_for)}, the record is of drive "
                f"{_drive_label(wanted, drive)}: a set identifies only records of its own drive; train a set for "
                "this drive (backlash train --drive FILE)",
            )
        return Selection(requested, "requested", None, None)
    c = record.conditions.get("c")
    source: Literal["record", "nominal"] = "record" if c is not None else "nominal"
    c_used = float(c) if c is not None else (C_NOMINAL if drive is None else drive.c)
    ps = nearest_pattern_set(
        store,
        channel,
        c_used,
        kind=kind,
        model_version=MODEL_VERSION,
        prefer_kind=DEFAULT_KIND,
        plain_only=not any_set,
        drive=wanted,
    )
    train = f'POST /v1/pattern-sets {{"channel": "{channel}", "c": {c_used:g}}}'
    if ps is None:
        what = f"channel {channel!r}" + (f" and kind {kind!r}" if kind else "")
        if drive is not None and not drive.is_reference:
            what += f" and drive {_drive_label(wanted, drive)}"
            train = train[:-1] + ', "drive": {...}}'
        stored = store.list(channel, kind=kind, model_version=MODEL_VERSION)
        others = [s for s in stored if not is_plain(s) and drive_fingerprint(s) == wanted]
        skipped = (
            f"; {len(others)} set(s) trained with effects or on another J1 grid are chosen only when named "
            f"(pattern_set: {', '.join(s.id for s in others[:3])})"
            if others
            else ""
        )
        # a record of a described drive read without its description (a CSV, say) looks for the reference's sets
        drives = sorted({fp[:12] for fp in map(drive_fingerprint, stored) if fp != wanted})

        def elsewhere(option: str) -> str:
            if not drives:
                return ""
            return (
                f"; sets of {channel!r} are stored for drive(s) {', '.join(drives[:3])}: if the record is of one of "
                f"them, give its description ({option})"
            )

        head = (
            f"no pattern set for {what} (model version {MODEL_VERSION}) trained as the paper trains (no effects, "
            f"its J1 grid) is stored{skipped}"
        )
        drive_option = "" if drive is None or drive.is_reference else " --drive FILE"
        raise NotFoundError(
            f"{head}{elsewhere('drive')}; train one first, e.g. {train}, or allow any set (any_set)",
            cli=f"{head}{elsewhere('--drive FILE')}; train one first, e.g. backlash train --channel {channel} "
            f"--c {c_used:g}{drive_option}, or allow any set (--any-set)",
        )
    distance = abs(ps.c - c_used)
    if distance > MAX_C_DISTANCE + 1e-12:
        raise IncompatibleError(
            f"the nearest stored set ({ps.id}) has c = {ps.c:g} pu, {distance:.3g} pu from the record's c = {c_used:g} "
            f"({source}); the limit is {MAX_C_DISTANCE:g} pu (patterns of a farther c were trained on another "
            f"deceleration); train a set at that c, e.g. {train}, or name a set with pattern_set"
        )
    how: Literal["exact", "nearest"] = "exact" if math.isclose(ps.c, c_used, rel_tol=1e-9, abs_tol=1e-12) else "nearest"
    return Selection(ps, how, c_used, source)


def check_record(record: Record, channel: str) -> None:
    """The record must hold ``channel``.

    Raises
    ------
    engine.records.RecordError
        The record lacks the channel.
    """
    record[channel]


def identify(record: Record, channel: str, pattern_set: PatternSet) -> IdentificationResult:
    """Identify the backlash width of ``record`` on ``channel`` with a stored pattern set.

    Pattern sets are trained on MODEL.md's grid: the record's test window is resampled onto
    it first when it has another interval (:func:`engine.records.to_protocol_grid`).
    """
    check_record(record, channel)
    return identifier_from_pattern_set(pattern_set).identify(to_protocol_grid(record)[channel])


def _one_channel(record: Record, channel: str) -> Record:
    """``record`` reduced to ``channel``, keeping that channel's declared unit (the warnings quote it)."""
    return record.replace(
        channels={channel: record[channel]}, units={c: u for c, u in record.units.items() if c == channel}
    )


def continuous_width_checked(
    record: Record, channel: str, drive: DriveDescription | None = None
) -> tuple[dict, list[PlausibilityWarning]]:
    """:func:`continuous_width` and the warnings about the fit behind it, on ``drive`` (None: MODEL.md's plant).

    The warnings are the width estimate's own (e.g. its ``misfit``) and what the calibration
    reveals about the record (:func:`engine.diagnosis.plausibility.check_calibration`: a channel
    in a wrong unit, a wrong sample interval, a misfit far above the noise).
    """
    check_record(record, channel)
    single = record.replace(channels={channel: record[channel]}, units={})
    plant = REFERENCE_DRIVE if drive is None else drive
    est = estimate_width(single, drive=plant)
    cal = est.calibration
    out: dict = {
        "K": est.K,
        "sigma_K": est.sigma_K,
        "nearest_width": nearest_grid_width(est.K, plant.k_grid()),
        "fitted": dict(cal.values),
        "fixed": dict(cal.fixed),
        "reduced_chi2": cal.reduced_chi2,
        "seconds": cal.seconds,
    }
    interval = getattr(est, "interval_95", None)
    if interval is not None:
        out["interval_95"] = [float(v) for v in interval]
    warnings = plausibility.merge_warnings(
        getattr(est, "warnings", []), plausibility.check_calibration(_one_channel(record, channel), cal)
    )
    return out, warnings


def continuous_width(record: Record, channel: str) -> dict:
    """The calibrated K of ``record``'s ``channel`` as a continuous width, with its uncertainty (JSON-ready).

    The simulator is fitted to that one channel (K free, J1 and c free unless the
    record's conditions give them, c1 likewise; a K condition is ignored), as in
    docs/identification.md, "The calibrated K as a continuous width". The warnings about the fit
    are :func:`continuous_width_checked`'s.
    """
    return continuous_width_checked(record, channel)[0]


def identify_from_store(
    store: PatternStore,
    record: Record,
    channel: str,
    set_id: str | None = None,
    kind: str | None = None,
    continuous: bool = False,
    any_set: bool = False,
    drive: DriveDescription | None = None,
    record_drive: str | None = None,
) -> dict:
    """Choose the pattern set (:func:`select_pattern_set`), identify, and describe the outcome (JSON-ready).

    ``drive`` is the drive the record is of (MODEL.md's reference plant when None); ``record_drive`` the
    fingerprint the record states of the drive it was made on, if any (a simulated record's), which must be
    ``drive``'s (:func:`check_record_drive`). The continuous width is calibrated on the drive's nominal plant
    and search box.

    With ``continuous``, also the calibrated K as a continuous width (:func:`continuous_width`, a few seconds).
    The answer's ``warnings`` (a list, empty when none) say what makes the record doubtful for the plant:
    the checks of the identified channel that need no fit (:func:`engine.diagnosis.plausibility.check_record`)
    and, with ``continuous``, those of its calibration (:func:`continuous_width_checked`); each is
    ``{"code", "message", "channel"}``; they compare the record with the drive's own plausible box.
    """
    check_record(record, channel)
    check_record_drive(record_drive, drive)
    check_units(record.units, drive)
    sel = select_pattern_set(store, channel, record, set_id=set_id, kind=kind, any_set=any_set, drive=drive)
    identifier = identifier_from_pattern_set(sel.pattern_set)  # rebuilt once: it gives the widths below too
    res = identifier.identify(to_protocol_grid(record)[channel])
    analysed, window = record.test_window()
    if not (np.all(np.isfinite(res.D)) and np.isfinite(res.rms)):
        largest = float(np.max(np.abs(record[channel])))
        raise InvalidInputError(
            f"the identification gave non-finite numbers: channel {channel!r} of the record reaches |x| = {largest:.3g}, "
            "far outside what the pattern set was trained on; check the record's units and values"
        )
    warnings = plausibility.check_record(_one_channel(record, channel), REFERENCE_DRIVE if drive is None else drive)
    width = None
    if continuous:
        width, fit_warnings = continuous_width_checked(record, channel, drive)
        warnings = plausibility.merge_warnings(warnings, fit_warnings)
    return {
        "D": [float(d) for d in res.D],
        "index": int(res.index),
        "width": float(res.width),
        "widths": [float(k) for k in getattr(identifier, "widths_", K_GRID)],
        "epochs": int(res.epochs),
        "rms": float(res.rms),
        "converged": bool(res.converged),
        "channel": channel,
        "pattern_set": sel.pattern_set.id,
        "kind": sel.pattern_set.kind,
        "pattern_set_c": sel.pattern_set.c,
        "drive": drive_fingerprint(sel.pattern_set),
        "selection": sel.how,
        "c_used": sel.c_used,
        "c_source": sel.c_source,
        "c_distance": None if sel.c_used is None else abs(sel.pattern_set.c - sel.c_used),
        "max_c_distance": MAX_C_DISTANCE,
        "continuous": width,
        "warnings": [w.to_dict() for w in warnings],
        "record": {
            "sample_interval": record.sample_interval,
            "n_samples": record.origin.n_samples,  # in the record as read (an excerpt counts its own)
            "event_index": record.origin.first + record.event_index,
            "event_location": record.event_location.to_dict() if record.event_location else None,
            "window": window.to_dict(),
            "patterns_read": (
                "the test window as recorded (MODEL.md's grid)"
                if analysed.grid.is_protocol()
                else f"the test window resampled from {record.sample_interval:g} s to MODEL.md's 0.1 ms "
                "(scipy.signal.resample_poly, anti-aliased)"
            ),
        },
    }
