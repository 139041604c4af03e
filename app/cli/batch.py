"""``backlash diagnose-batch``: diagnose every record of a directory or glob on Dask, one answer file each."""

from __future__ import annotations

import argparse
from pathlib import Path

from app import output
from app.cli.common import EXIT_OK, CommandError, add_dask_options, add_drive_option, examples, read_drive
from engine.plants import DEFAULT_PLANT, PLANTS


def cmd_diagnose_batch(args: argparse.Namespace) -> int:
    """Diagnose the records; write ``OUT/<record>.json`` per record and ``OUT/summary.{csv,md}``."""
    from app.services.batch import find_records, run_batch

    if args.drive is not None and args.plant != DEFAULT_PLANT:
        raise CommandError(f"--drive describes a backlash drive; it does not apply with --plant {args.plant}")
    drive = read_drive(args)  # ParameterError says what to fix before any record is read
    try:
        files = find_records(args.source)
    except FileNotFoundError as exc:
        raise CommandError(str(exc)) from None
    output.info(f"diagnosing {len(files)} record(s) of plant {args.plant} into {args.out}")
    try:
        rows = run_batch(files, args.out, args.plant, args.workers, args.scheduler, drive)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    output.write((args.out / "summary.md").read_text())
    refused = sum(r["status"] == "refused" for r in rows)
    if refused:
        output.info(f"{refused} record(s) refused: see the detail column of {args.out / 'summary.csv'}")
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``diagnose-batch`` to the subcommands."""
    p = sub.add_parser(
        "diagnose-batch",
        help="diagnose every record file of a directory or glob (on Dask); one answer file each and a summary",
        **examples(
            "backlash diagnose-batch records/ --out answers/",
            "backlash diagnose-batch 'site-a/*.csv' --out answers/ --workers 2",
            "backlash diagnose-batch records/ --out answers/ --scheduler tcp://10.0.0.7:8786",
        ),
    )
    p.add_argument("source", help="a directory of record files, or a glob such as 'bench/*.csv' (quote it)")
    p.add_argument("--out", type=Path, required=True, help="directory of the answers and summary (resumable)")
    p.add_argument(
        "--plant", choices=sorted({DEFAULT_PLANT, *PLANTS}), default=DEFAULT_PLANT, help="the plant the records are of"
    )
    add_drive_option(p)
    add_dask_options(p)
    p.set_defaults(func=cmd_diagnose_batch)
