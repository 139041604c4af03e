"""``backlash diagnose``: the sim-to-real gap of a record file (like ``POST /v1/diagnose``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from app import output
from app.cli.common import EXIT_OK, add_record_options, read_record


def cmd_diagnose(args: argparse.Namespace) -> int:
    """Diagnose the record, write the result as JSON and, with ``--plots``, its figures."""
    from app.services import diagnosis
    from engine.diagnosis.space import check_bounds
    from engine.simulation import CATALOGUE

    record = read_record(args)
    for name in args.effects or ():
        CATALOGUE[name]  # UnknownEffectError names the known effects before any work is done
    bounds = dict(args.bound or ())
    check_bounds(bounds)  # BoundsError says what to fix before any work is done
    output.info(
        "diagnosing (calibration, then one fit per candidate effect, sets of effects when none fits; "
        "typically 5-60 s on 2 cores)"
    )
    result = diagnosis.run(record, args.effects, bounds or None)
    output.write_json(result.to_dict())
    if args.plots:
        for path in diagnosis.write_plots(record, result, args.plots):
            output.info(f"wrote {path}")
    return EXIT_OK


def _bound(text: str) -> tuple[str, tuple[float, float]]:
    """``NAME=LOW:HIGH`` -> (name, (low, high))."""
    name, sep, rng = text.partition("=")
    lo, sep2, hi = rng.partition(":")
    try:
        if not (sep and sep2):
            raise ValueError
        return name.strip(), (float(lo), float(hi))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=LOW:HIGH (e.g. K=0.002:0.008), got {text!r}") from None


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``diagnose`` to the subcommands."""
    p = sub.add_parser("diagnose", help="diagnose the sim-to-real gap of a record (like POST /v1/diagnose)")
    add_record_options(p)
    p.add_argument("--effects", nargs="+", metavar="NAME", help="candidate effects (default the whole catalogue)")
    p.add_argument(
        "--bound",
        action="append",
        type=_bound,
        metavar="NAME=LOW:HIGH",
        help="search box of one calibrated parameter in its unit (K [m], J1 [kg m^2], c [pu], c1 [pu]); repeatable; "
        "default K=0.001:0.015 J1=0.6:1.2 c=0.5:2.0",
    )
    p.add_argument("--plots", type=Path, metavar="DIR", help="also write PNG plots (residual map, overlays) to DIR")
    p.set_defaults(func=cmd_diagnose)
