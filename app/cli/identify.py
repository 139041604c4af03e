"""``backlash identify``: the backlash width of a record file, from a stored pattern set (like ``POST /v1/identify``)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from app import output
from app.cli.common import (
    EXIT_OK,
    CommandError,
    add_db_option,
    add_drive_option,
    add_record_options,
    examples,
    read_drive,
    read_record,
    settings,
)
from app.records_io import stated_provenance
from engine.constants import CHANNELS
from engine.identification.training import IDENTIFIERS
from engine.plants import DEFAULT_PLANT, PLANTS

logger = logging.getLogger(__name__)


def cmd_identify(args: argparse.Namespace) -> int:
    """Identify the record's backlash width and write the outcome as JSON."""
    from app.services.identification import drive_for_record, identify_from_store
    from engine.storage import PatternStore

    if args.plant != DEFAULT_PLANT:
        if args.drive is not None:
            raise CommandError(f"--drive describes a backlash drive; it does not apply with --plant {args.plant}")
        return _identify_plant(args)
    if args.joint:
        raise CommandError("--joint applies with --plant (a plant whose records share one width), not to the drive")
    if args.channel is None:
        raise CommandError("give --channel (one of " + ", ".join(CHANNELS) + ")")
    stated = stated_provenance(args.record)
    drive = drive_for_record(read_drive(args), stated)  # --drive, else the drive the record states in full
    if args.drive is None and drive is not None:
        output.info(f"identifying on the drive the record states: {drive.name} ({drive.fingerprint[:12]})")
    record = read_record(args, drive)  # without a sample interval or t: read at the drive's protocol interval
    path = settings(args).db_path
    if not path.exists():  # no empty store left behind, and the CLI's way to fill one
        raise CommandError(
            f"no pattern store at {path}: train a pattern set first (backlash train --channel {args.channel} "
            "--c 1.0; `make run` trains all of them), or point --db or $BACKLASH_DB_PATH at a store"
        )
    answer = identify_from_store(
        PatternStore(path),
        record,
        args.channel,
        args.pattern_set,
        args.kind,
        continuous=args.continuous,
        any_set=args.any_set,
        drive=drive,
        record_drive=None if stated is None else str(stated["fingerprint"]),
    )
    output.write_json(answer)
    for w in answer.get("warnings") or ():  # on stderr, where a person sees them beside the JSON
        logger.warning("%s%s", f"{w['channel']}: " if w.get("channel") else "", w["message"])
    return EXIT_OK


def _identify_plant(args: argparse.Namespace) -> int:
    """``--plant NAME``: the width as a continuous fitted parameter, with its interval and identifiability."""
    from app.services.plant_identification import identify_width

    if not args.continuous:
        raise CommandError("with --plant the width is fitted as a continuous parameter: add --continuous")
    n = 1 + len(args.joint or ())
    output.info(
        f"fitting the backlash width of {n} record(s) of plant {args.plant} (a profile over the width; ~10 s a record)"
    )
    output.write_json(identify_width(args.plant, args.record, args.joint))
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``identify`` to the subcommands."""
    p = sub.add_parser(
        "identify",
        help="identify the backlash width of a record (like POST /v1/identify)",
        description="The backlash width of a record from a stored pattern set (train one first: backlash train), "
        "and with --continuous the calibrated width with its interval.",
        **examples(
            "backlash train --channel a1 --c 1.0",
            "backlash identify rec.csv --channel a1 --continuous",
            "backlash identify sine1.json --plant brfd --joint sine2.json --continuous",
        ),
    )
    add_record_options(p)
    p.add_argument("--channel", choices=CHANNELS, help="the backlash drive's channel (required without --plant)")
    p.add_argument(
        "--plant",
        choices=sorted({DEFAULT_PLANT, *PLANTS}),
        default=DEFAULT_PLANT,
        help=f"the plant the record is of (default {DEFAULT_PLANT}); brfd reads the data set's JSON file as distributed "
        "or its CSV form and fits the width continuously (--continuous)",
    )
    p.add_argument(
        "--joint",
        action="append",
        type=Path,
        metavar="FILE",
        help="with --plant: another record of the same device, fitted jointly (one width shared); repeatable",
    )
    p.add_argument("--pattern-set", help="pattern-set id (default: the stored set with the nearest c)")
    p.add_argument("--kind", choices=sorted(IDENTIFIERS), help="only choose pattern sets of this kind")
    p.add_argument(
        "--any-set",
        action="store_true",
        help="also choose sets trained with effects or on another J1 grid (default: only sets trained as the paper)",
    )
    p.add_argument(
        "--continuous",
        action="store_true",
        help="also the calibrated K as a continuous width with its uncertainty (a few seconds)",
    )
    add_drive_option(p)
    add_db_option(p)
    p.set_defaults(func=cmd_identify)
