"""What every ``backlash`` command shares: exit codes, argument types, options, settings and record reading."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from engine.constants import SAMPLE_INTERVAL

if TYPE_CHECKING:
    from app.core.config import Settings
    from engine.records import Record
    from engine.simulation.drive import DriveDescription
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


def unit(text: str) -> tuple[str, str]:
    """``CHANNEL=UNIT`` of a record channel's unit (argparse type); whether the unit is accepted is the engine's to say."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip() or not value.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: write a unit as CHANNEL=UNIT, e.g. omega1=rpm or a1=g")
    return name.strip(), value.strip()


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


#: Accepted units, for help texts (the engine's table is :data:`engine.records.UNITS`; not imported here to keep
#: the command's start fast: an unknown unit's error names the accepted ones from that table).
UNITS_HELP = "a1, a2: m/s^2 | g; omega1: rad/s | rpm | pu; v2: m/s | mm/s; m_el: pu | N*m (with --base-torque)"


def plant_name(text: str) -> str:
    """``--plant``: a registered plant's name, or the path of a plant description (``*.toml``, an FMU plant)."""
    from engine.plants import DEFAULT_PLANT, PLANTS, is_description

    if is_description(text):
        if not Path(text).is_file():
            raise argparse.ArgumentTypeError(f"no plant description file {text!r}")
        return text
    if text not in {DEFAULT_PLANT, *PLANTS}:
        known = ", ".join(sorted({DEFAULT_PLANT, *PLANTS}))
        raise argparse.ArgumentTypeError(f"unknown plant {text!r}: one of {known}, or a plant description file (.toml)")
    return text


def add_unit_options(p: argparse.ArgumentParser, what: str) -> None:
    """``--unit CHANNEL=UNIT`` (repeatable) and ``--base-torque``; ``what`` completes the help (whose units)."""
    p.add_argument(
        "--unit",
        type=unit,
        action="append",
        metavar="CHANNEL=UNIT",
        help=f"unit of a channel {what} (repeatable; default the model units); accepted: {UNITS_HELP}",
    )
    p.add_argument("--base-torque", type=finite, help="the motor's base torque [N*m] (for m_el in N*m)")


def add_record_options(p: argparse.ArgumentParser) -> None:
    """The record file and what completes it (Ts, event index, units, known conditions)."""
    p.add_argument(
        "record",
        type=Path,
        help="record file: .json (record format) or .csv (header of channel names, optionally t [s]; one row per "
        "sample); the options complete a CSV file and override a JSON file's values",
    )
    p.add_argument(
        "--sample-interval",
        type=finite,
        help=f"Ts [s], 10 us to 1 ms (default: the step of the record's t column, else the --drive's protocol "
        f"interval, else {SAMPLE_INTERVAL:g})",
    )
    p.add_argument(
        "--event-index",
        type=int,
        help="index of the sample at the event (default: the record's, else located from m_el or a1)",
    )
    add_unit_options(p, "in the record")
    for name, unit_name in (("J1", "kg m^2"), ("c", "pu"), ("c1", "pu"), ("K", "m")):
        p.add_argument(f"--{name}", type=finite, help=f"known condition {name} [{unit_name}]")


def add_dask_options(p: argparse.ArgumentParser) -> None:
    """``--workers`` and ``--scheduler``: where many-case work runs (engine.distributed)."""
    from engine.distributed import SCHEDULER_ENV

    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="single-threaded Dask worker processes of the local cluster (default: this machine's cores; "
        "0 runs in this process)",
    )
    p.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help=f"an existing Dask scheduler to send the work to (default ${SCHEDULER_ENV}, else a local cluster)",
    )


def add_drive_option(p: argparse.ArgumentParser) -> None:
    """``--drive FILE``: the user's drive description (TOML or JSON; docs/drive-description.md)."""
    p.add_argument(
        "--drive",
        type=Path,
        metavar="FILE",
        help="drive description, .toml or .json (docs/drive-description.md): the drive's own parameters, base "
        "values and test protocol; keys left out keep MODEL.md's values (default: MODEL.md's reference plant)",
    )


def read_drive(args: argparse.Namespace) -> DriveDescription | None:
    """The ``--drive`` file's description, or None without the option.

    Raises
    ------
    engine.simulation.ParameterError
        An unreadable file or an impossible description (the message names the file and what to fix).
    """
    if getattr(args, "drive", None) is None:
        return None
    from engine.simulation.drive import load_drive

    return load_drive(args.drive)


def add_db_option(p: argparse.ArgumentParser) -> None:
    """``--db``: the pattern-store file."""
    from engine.storage import DEFAULT_STORE_PATH, STORE_PATH_ENV

    p.add_argument("--db", type=Path, help=f"pattern-store file (default ${STORE_PATH_ENV} or {DEFAULT_STORE_PATH})")


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


def read_record(args: argparse.Namespace, drive: DriveDescription | None = None) -> Record:
    """The record file of :func:`add_record_options`, completed by its options.

    ``drive``: the drive the record is read for (``--drive``, or the one the record states); a record with neither
    ``--sample-interval`` nor a ``t`` is read at its protocol interval (without a drive, MODEL.md's 0.1 ms).
    """
    from app.records_io import read_record as read_file
    from app.services.simulation import record_interval

    conditions = {k: getattr(args, k) for k in ("J1", "c", "c1", "K") if getattr(args, k, None) is not None}
    if getattr(args, "base_torque", None) is not None:
        conditions["base_torque"] = args.base_torque
    return read_file(
        args.record,
        args.sample_interval,
        args.event_index,
        conditions,
        units_of(args),
        default_interval=record_interval(drive),
    )


def units_of(args: argparse.Namespace) -> dict[str, str]:
    """The ``--unit`` options as channel -> unit.

    Raises
    ------
    CommandError
        A channel given two different units.
    """
    units: dict[str, str] = {}
    for channel, name in getattr(args, "unit", None) or ():
        if units.get(channel, name) != name:
            raise CommandError(f"--unit gives channel {channel!r} two units: {units[channel]!r} and {name!r}")
        units[channel] = name
    return units


def user_errors() -> tuple[type[BaseException], ...]:
    """Exceptions whose message tells the user what to fix: printed, exit status 2."""
    from app.core.instance import ServiceLockError
    from app.core.server import ExposureError
    from app.records_io import RecordFormatError
    from app.services.errors import ServiceError
    from engine.diagnosis.space import BoundsError
    from engine.distributed import SchedulerUnreachable
    from engine.plants.fmu.build import FmuBuildError
    from engine.plants.fmu.description import DescriptionError
    from engine.plants.fmu.runner import FmuSimulationError
    from engine.records import RecordError
    from engine.simulation import ParameterError, SimulationError
    from engine.storage import InvalidPatternSet, PatternStoreError

    return (
        CommandError,
        SchedulerUnreachable,
        RecordFormatError,
        RecordError,
        BoundsError,
        ParameterError,
        SimulationError,
        InvalidPatternSet,
        PatternStoreError,
        ServiceError,
        ServiceLockError,
        ExposureError,
        DescriptionError,
        FmuBuildError,
        FmuSimulationError,
    )


def effects_help(simulated: bool = False) -> str:
    """The catalogue's effect names with their ranges and units, for help texts.

    ``simulated``: also the held-back effects of model 1.1, which the simulator (not the diagnosis) accepts.
    """
    from engine.simulation import CATALOGUE, HELD_BACK

    libs = (CATALOGUE, HELD_BACK) if simulated else (CATALOGUE,)
    return "; ".join(f"{e.name} [{e.bounds[0]:g}, {e.bounds[1]:g}] {e.unit}" for lib in libs for e in lib.values())


def examples(*lines: str) -> dict[str, Any]:
    """``add_parser`` keywords for an epilog of examples, shown as written."""
    return {
        "epilog": "examples:\n" + "\n".join(f"  {line}" for line in lines),
        "formatter_class": argparse.RawDescriptionHelpFormatter,
    }
