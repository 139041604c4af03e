"""``backlash diagnose``: the sim-to-real gap of a record file (like ``POST /v1/diagnose``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from app import output
from app.cli.common import EXIT_OK, add_record_options, read_record


def cmd_diagnose(args: argparse.Namespace) -> int:
    """Diagnose the record, write the result as JSON and, with ``--plots``, its figures."""
    from app.services import diagnosis
    from engine.simulation import CATALOGUE

    record = read_record(args)
    for name in args.effects or ():
        CATALOGUE[name]  # UnknownEffectError names the known effects before any work is done
    output.info("diagnosing (calibration, then one fit per candidate effect; typically 3-15 s on 2 cores)")
    result = diagnosis.run(record, args.effects)
    output.write_json(result.to_dict())
    if args.plots:
        for path in diagnosis.write_plots(record, result, args.plots):
            output.info(f"wrote {path}")
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``diagnose`` to the subcommands."""
    p = sub.add_parser("diagnose", help="diagnose the sim-to-real gap of a record (like POST /v1/diagnose)")
    add_record_options(p)
    p.add_argument("--effects", nargs="+", metavar="NAME", help="candidate effects (default the whole catalogue)")
    p.add_argument("--plots", type=Path, metavar="DIR", help="also write PNG plots (residual map, overlays) to DIR")
    p.set_defaults(func=cmd_diagnose)
