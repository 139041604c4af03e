"""What every ``backlash`` command shares: exit codes, argument types, options, settings and record reading."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from engine.constants import EVENT_INDEX, SAMPLE_INTERVAL

if TYPE_CHECKING:
    from app.core.config import Settings
    from engine.records import Record
    from engine.storage import PatternStore

EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2
#: Exit status after Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130


class CommandError(Exception):
    """A user-facing failure of a command (exit status 2)."""


# -- argument types -----------------------------------------------------------------


def finite(text: str) -> float:
    """A finite float (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def effect(text: str) -> tuple[str, float]:
    """``NAME=VALUE`` of an unmodelled effect (argparse type)."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: write an effect as NAME=VALUE, e.g. motor_coulomb_friction=0.02")
    return name.strip(), finite(value)


def param(text: str) -> tuple[str, Any]:
    """``NAME=VALUE`` of an identifier hyper-parameter, VALUE read as JSON if it is JSON (argparse type)."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: write a parameter as NAME=VALUE, e.g. window=600")
    try:
        return name.strip(), json.loads(value)
    except ValueError:
        return name.strip(), value


# -- shared options -----------------------------------------------------------------


def add_record_options(p: argparse.ArgumentParser) -> None:
    """The record file and what completes it (Ts, event index, known conditions)."""
    p.add_argument("record", type=Path, help="record file: .json (record format) or .csv (header of channel names)")
    p.add_argument("--sample-interval", type=finite, help=f"Ts [s] of a CSV record (default {SAMPLE_INTERVAL:g})")
    p.add_argument(
        "--event-index", type=int, help=f"index of the sample at the event, CSV record (default {EVENT_INDEX})"
    )
    for name, unit in (("J1", "kg m^2"), ("c", "pu"), ("c1", "pu"), ("K", "m")):
        p.add_argument(f"--{name}", type=finite, help=f"known condition {name} [{unit}]")


def add_db_option(p: argparse.ArgumentParser) -> None:
    """``--db``: the pattern-store file."""
    from engine.storage import DEFAULT_STORE_PATH, STORE_PATH_ENV

    p.add_argument("--db", type=Path, help=f"pattern-store file (default ${STORE_PATH_ENV} or ./{DEFAULT_STORE_PATH})")


# -- what commands read -------------------------------------------------------------


def settings(args: argparse.Namespace, **overrides: Any) -> Settings:
    """The service settings from the environment, with command-line overrides (``None`` values are not given).

    Raises
    ------
    CommandError
        The settings do not validate; the message names each offending setting.
    """
    from pydantic import ValidationError

    from app.core.config import Settings

    given = {k: v for k, v in overrides.items() if v is not None}
    if getattr(args, "db", None) is not None:
        given["db_path"] = args.db
    if getattr(args, "log_level", None) is not None:
        given["log_level"] = args.log_level
    try:
        return Settings(**given)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(map(str, e['loc'])) or 'settings'}: {e['msg']}" for e in exc.errors())
        raise CommandError(f"invalid settings (BACKLASH_* environment variables or options): {problems}") from None


def open_store(args: argparse.Namespace) -> PatternStore:
    """The pattern store of the settings (``--db`` or ``$BACKLASH_DB_PATH``)."""
    from engine.storage import PatternStore

    return PatternStore(settings(args).db_path)


def read_record(args: argparse.Namespace) -> Record:
    """The record file of :func:`add_record_options`, completed by its options."""
    from app.records_io import read_record as read_file

    conditions = {k: getattr(args, k) for k in ("J1", "c", "c1", "K") if getattr(args, k, None) is not None}
    return read_file(args.record, args.sample_interval, args.event_index, conditions)


def user_errors() -> tuple[type[BaseException], ...]:
    """Exceptions whose message tells the user what to fix: printed, exit status 2."""
    from app.records_io import RecordFormatError
    from app.services.errors import ServiceError
    from engine.records import RecordError
    from engine.simulation import ParameterError, SimulationError
    from engine.storage import InvalidPatternSet, PatternStoreError

    return (
        CommandError,
        RecordFormatError,
        RecordError,
        ParameterError,
        SimulationError,
        InvalidPatternSet,
        PatternStoreError,
        ServiceError,
    )
