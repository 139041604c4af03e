"""``backlash store``: the retention run (``prune``: delete what is older than the retention, then compact) and
``compact`` alone, on the database file, with a report of what went and the file's size before and after."""

from __future__ import annotations

import argparse

from app import output
from app.cli.common import EXIT_OK, add_db_option, examples, open_store, settings


def positive_days(text: str) -> float:
    """A number of days > 0 (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of days") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r}: give a finite number of days > 0")
    return value


def cmd_store(args: argparse.Namespace) -> int:
    """Run the retention (``prune``) or the compaction alone (``compact``); write the report as JSON."""
    from app.services import retention

    store = open_store(args)
    if args.action == "compact":
        report = retention.run(store, None)
    else:
        days = args.older_than_days if args.older_than_days is not None else settings(args).retention_days
        if days is None:
            output.info(
                "no retention set (BACKLASH_RETENTION_DAYS or --older-than-days): nothing is deleted, the file is "
                "only compacted"
            )
        report = retention.run(store, days, compact=not args.no_compact)
    output.write_json(report.to_dict())
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``store`` to the subcommands."""
    p = sub.add_parser(
        "store",
        help="retention of the database file: delete old jobs, diagnoses, identifications and records; compact it",
        description="prune: delete the finished jobs, diagnoses (with their figures), identifications and the "
        "records nothing refers to any more that were stored more than --older-than-days (default "
        "$BACKLASH_RETENTION_DAYS) ago, never a pattern set nor a queued or running job's rows; then compact. "
        "compact: give the pages freed by deletions back to the file system (the file shrinks). Both print what "
        "they did and the file's size before and after [bytes]. Safe beside a running service: SQLite serialises "
        "the writes (the service's wait while the compaction runs).",
        **examples(
            "backlash store prune --older-than-days 90",
            "BACKLASH_RETENTION_DAYS=30 backlash store prune",
            "backlash store compact --db /srv/backlash/patterns.sqlite3",
        ),
    )
    p.add_argument("action", choices=["prune", "compact"])
    p.add_argument(
        "--older-than-days",
        type=positive_days,
        metavar="DAYS",
        help="prune: delete what was stored more than DAYS days ago (default $BACKLASH_RETENTION_DAYS; "
        "unset: nothing is deleted)",
    )
    p.add_argument("--no-compact", action="store_true", help="prune: delete only, leave the file's size alone")
    add_db_option(p)
    p.set_defaults(func=cmd_store)
