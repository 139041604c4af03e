"""``backlash diagnose``: the sim-to-real gap of a record file (like ``POST /v1/diagnose``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from app import output
from app.cli.common import (
    EXIT_OK,
    CommandError,
    add_drive_option,
    add_record_options,
    effects_help,
    examples,
    plant_name,
    read_drive,
    read_record,
)
from app.records_io import stated_provenance
from engine.atomic import write_json_atomic
from engine.plants import DEFAULT_PLANT


def cmd_diagnose(args: argparse.Namespace) -> int:
    """Diagnose the record, write the result as JSON and, with ``--plots``, its figures."""
    from app.services import diagnosis
    from app.services.identification import drive_for_record
    from app.services.simulation import check_units
    from engine.diagnosis.space import check_bounds
    from engine.simulation import CATALOGUE
    from engine.simulation.drive import REFERENCE_DRIVE

    if args.plant != DEFAULT_PLANT:
        if args.drive is not None:
            raise CommandError(f"--drive describes a backlash drive; it does not apply with --plant {args.plant}")
        return _diagnose_plant(args)
    # --drive, else the drive the record states in full (a simulated record); a record of another drive is refused
    # before it is read
    drive = drive_for_record(read_drive(args), stated_provenance(args.record))
    if args.drive is None and drive is not None:
        output.info(f"diagnosing on the drive the record states: {drive.name} ({drive.fingerprint[:12]})")
    record = read_record(args, drive)  # without a sample interval or t: read at the drive's protocol interval
    check_units(record.units, drive)  # omega1 in pu would be read with MODEL.md's base speed: refused
    for name in args.effects or ():
        CATALOGUE[name]  # UnknownEffectError names the known effects before any work is done
    bounds = dict(args.bound or ())
    check_bounds(bounds, drive or REFERENCE_DRIVE)  # BoundsError says what to fix before any work is done
    output.info(
        "diagnosing (calibration, then one fit per candidate effect, sets of effects when none fits; "
        "typically 5-60 s on 2 cores)"
    )
    result = diagnosis.run(record, args.effects, bounds or None, drive=drive)
    plots = [str(p) for p in diagnosis.write_plots(record, result, args.plots)] if args.plots else []
    answer = result.to_dict()
    if drive is not None:  # the drive it was diagnosed on, kept with the answer
        answer["drive"] = drive.provenance()
    return _answer(args, answer, plots)


def _diagnose_plant(args: argparse.Namespace) -> int:
    """``--plant NAME``: the record file as that plant reads it, diagnosed through the plant interface."""
    from app.services import plant_diagnosis

    if args.effects or args.bound:
        raise CommandError(
            "--effects and --bound apply to the backlash drive only; with --plant the whole catalogue is fitted"
        )
    records = plant_diagnosis.read(args.plant, args.record, args.calibrate_on)  # RecordError says what to fix
    output.info(
        f"diagnosing {args.record.name} on plant {args.plant} (calibration, then every catalogue effect and sets; "
        "about a minute on 2 cores)"
    )
    result = plant_diagnosis.run(records, args.hold_calibration)
    plots = [str(p) for p in plant_diagnosis.write_plots(result, args.plots)] if args.plots else []
    return _answer(args, result.to_dict(), plots)


def _answer(args: argparse.Namespace, answer: dict[str, Any], plots: list[str]) -> int:
    """The answer: a summary for a person, the full JSON where asked for.

    ``--out FILE``: the JSON to FILE, the summary on stdout. ``--json``, or stdout not a terminal
    (a pipe, a file: scripts keep getting JSON): the JSON on stdout, the summary on stderr. Else the
    summary alone, and how to get the rest.
    """
    if args.out is not None:
        write_json_atomic(args.out, answer, indent=2)
        output.summary(answer, plots, to_stdout=True)
        output.info(f"wrote the full answer to {args.out}")
    elif args.json or not sys.stdout.isatty():
        output.write_json(answer)
        output.summary(answer, plots)
    else:
        output.summary(answer, plots, to_stdout=True)
        output.info("the full answer (candidates, residual cells, records): add --out FILE or --json")
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
    p = sub.add_parser(
        "diagnose",
        help="diagnose the sim-to-real gap of a record (like POST /v1/diagnose)",
        description="Where the model parts company with the record, which unmodelled effect explains it, how far "
        "the gap shrinks once it is added, and the backlash width of the model the answer ends with. On a terminal "
        "it prints a summary; the full answer goes to --out FILE or, with --json, to stdout.",
        **examples(
            "backlash simulate --K 0.0068 --effect load_inertia=1.3 --snr-db 40 --out rec.csv",
            "backlash diagnose rec.csv --out answer.json --plots plots/",
            "backlash diagnose rec.csv --effects motor_coulomb_friction load_inertia --bound K=0.004:0.010",
            "backlash diagnose emps.mat --plant emps --json > answer.json",
        ),
    )
    add_record_options(p)
    add_drive_option(p)
    p.add_argument(
        "--effects",
        nargs="+",
        metavar="NAME",
        help="candidate effects (default the whole catalogue): " + effects_help(),
    )
    p.add_argument(
        "--bound",
        action="append",
        type=_bound,
        metavar="NAME=LOW:HIGH",
        help="search box of one calibrated parameter in its unit (K [m], J1 [kg m^2], c [pu], c1 [pu]); repeatable; "
        "default K=0.001:0.015 J1=0.6:1.2 c=0.5:2.0",
    )
    p.add_argument("--plots", type=Path, metavar="DIR", help="also write PNG plots (residual map, overlays) to DIR")
    out = p.add_mutually_exclusive_group()
    out.add_argument(
        "--out", type=Path, metavar="FILE", help="write the full answer (JSON) to FILE and print the summary"
    )
    out.add_argument(
        "--json",
        action="store_true",
        help="print the full answer (JSON) on stdout, the summary on stderr (the default when stdout is not a terminal)",
    )
    p.add_argument(
        "--plant",
        type=plant_name,
        metavar="PLANT",
        default=DEFAULT_PLANT,
        help=f"the plant the record is of (default {DEFAULT_PLANT}): brfd, emps (the benchmark's .mat file as "
        "distributed, or its CSV form), or the path of a plant description (plant.toml: your own simulator as an "
        "FMU, its record a CSV file; docs/fmu-plant.md)",
    )
    p.add_argument(
        "--calibrate-on",
        type=Path,
        metavar="FILE",
        help="with --plant: calibrate on this record of the same plant instead of the diagnosed one (cross-record check)",
    )
    p.add_argument(
        "--hold-calibration",
        action="store_true",
        help="with --plant: hold the calibrated parameters while fitting effects (default: refit them with each effect)",
    )
    p.set_defaults(func=cmd_diagnose)
