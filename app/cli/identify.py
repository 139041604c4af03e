"""``backlash identify``: the backlash width of a record file, from a stored pattern set (like ``POST /v1/identify``)."""

from __future__ import annotations

import argparse

from app import output
from app.cli.common import EXIT_OK, add_db_option, add_record_options, open_store, read_record
from engine.constants import CHANNELS


def cmd_identify(args: argparse.Namespace) -> int:
    """Identify the record's backlash width and write the outcome as JSON."""
    from app.services.identification import identify_from_store

    record = read_record(args)
    output.write_json(
        identify_from_store(
            open_store(args), record, args.channel, args.pattern_set, args.kind, continuous=args.continuous
        )
    )
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``identify`` to the subcommands."""
    p = sub.add_parser("identify", help="identify the backlash width of a record (like POST /v1/identify)")
    add_record_options(p)
    p.add_argument("--channel", required=True, choices=CHANNELS)
    p.add_argument("--pattern-set", help="pattern-set id (default: the stored set with the nearest c)")
    p.add_argument("--kind", help="only choose pattern sets of this kind")
    p.add_argument(
        "--continuous",
        action="store_true",
        help="also the calibrated K as a continuous width with its uncertainty (a few seconds)",
    )
    add_db_option(p)
    p.set_defaults(func=cmd_identify)
