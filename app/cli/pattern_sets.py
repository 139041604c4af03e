"""``backlash train`` and ``backlash pattern-sets``: train, list, show and delete stored pattern sets."""

from __future__ import annotations

import argparse

from app import output
from app.cli.common import (
    EXIT_OK,
    add_db_option,
    add_drive_option,
    effect,
    effects_help,
    examples,
    finite,
    open_store,
    param,
    read_drive,
)
from engine.constants import CHANNELS
from engine.identification.training import DEFAULT_KIND, IDENTIFIERS


def cmd_train(args: argparse.Namespace) -> int:
    """Train one pattern set, store it, and write its description (progress on stderr)."""
    from app.services import training
    from app.services.patterns import describe
    from engine.identification.training import DEFAULT_KIND

    named = {"learning_rate": args.l, "delta1": args.delta1, "max_epochs": args.max_epochs}
    params = {**dict(args.param or []), **{k: v for k, v in named.items() if v is not None}}
    drive = read_drive(args)
    spec = training.TrainingSpec(
        channel=args.channel,
        c=args.c,
        J1_values=tuple(args.J1 or training.default_j1_values(drive)),
        kind=args.kind or DEFAULT_KIND,
        params=params,
        effects=dict(args.effect or []),
        drive=drive,
    )
    training.check(spec)
    store = open_store(args)

    def progress(fraction: float, stage: str) -> None:
        output.info(f"[{fraction:4.0%}] {stage}")

    saved = training.train_pattern_set(spec, store, progress=progress)
    output.write_json(describe(saved))
    return EXIT_OK


def cmd_pattern_sets(args: argparse.Namespace) -> int:
    """``list`` (filtered), ``show`` or ``delete`` stored pattern sets."""
    from app.services.identification import get_pattern_set
    from app.services.patterns import describe

    store = open_store(args)
    if args.action == "list":
        sets = store.list(channel=args.channel, c=args.c, kind=args.kind)
        drive = read_drive(args)
        if drive is not None:  # only the sets trained for that drive
            from engine.identification.selection import drive_fingerprint

            sets = [s for s in sets if drive_fingerprint(s) == drive.fingerprint]
        output.write_json({"data": [describe(s) for s in sets], "count": len(sets)})
    elif args.action == "show":
        output.write_json(describe(get_pattern_set(store, args.id)))
    else:  # delete
        get_pattern_set(store, args.id)
        store.delete(args.id)
        output.info(f"deleted pattern set {args.id}")
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``train`` and ``pattern-sets`` to the subcommands."""
    p = sub.add_parser(
        "train",
        help="train and store a pattern set (like POST /v1/pattern-sets)",
        **examples(
            "backlash train --channel a1 --c 1.0",
            "backlash train --channel omega1 --c 1.4 --kind paper --max-epochs 200",
            "backlash train --channel a1 --c 1.0 --effect motor_coulomb_friction=0.02",
        ),
    )
    p.add_argument("--channel", required=True, choices=CHANNELS)
    p.add_argument("--c", type=finite, required=True, help="apparent-viscosity group [pu]")
    p.add_argument(
        "--J1", type=finite, nargs="+", help="J1 values [kg m^2] (default the paper's grid, scaled to the drive's J1)"
    )
    add_drive_option(p)
    p.add_argument(
        "--kind", choices=sorted(IDENTIFIERS), help=f"identifier kind (default {DEFAULT_KIND}: the template identifier)"
    )
    p.add_argument("--l", type=finite, help="paper kind: learning coefficient l")
    p.add_argument("--delta1", type=finite, help="paper kind: stop at RMS < delta1")
    p.add_argument("--max-epochs", type=int, help="paper kind: epoch cap per network")
    p.add_argument(
        "--param",
        type=param,
        action="append",
        metavar="NAME=VALUE",
        help="further identifier hyper-parameter; VALUE is JSON (e.g. window=600)",
    )
    p.add_argument(
        "--effect",
        type=effect,
        action="append",
        metavar="NAME=VALUE",
        help="unmodelled effect applied to every training case (repeatable); names and ranges: "
        + effects_help(simulated=True),
    )
    add_db_option(p)
    p.set_defaults(func=cmd_train)

    p = sub.add_parser(
        "pattern-sets",
        help="list, show or delete stored pattern sets",
        **examples(
            "backlash pattern-sets list --channel a1",
            "backlash pattern-sets show ID",
            "backlash pattern-sets delete ID",
        ),
    )
    p.add_argument("action", choices=["list", "show", "delete"])
    p.add_argument("id", nargs="?", help="pattern-set id (show, delete)")
    p.add_argument("--channel", choices=CHANNELS)
    p.add_argument("--c", type=finite)
    p.add_argument("--kind", choices=sorted(IDENTIFIERS), help="only sets of this identifier kind")
    add_drive_option(p)
    add_db_option(p)
    p.set_defaults(func=cmd_pattern_sets)


def check_usage(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """``pattern-sets show`` and ``delete`` need an id (argparse error, exit 2)."""
    if args.command == "pattern-sets" and args.action in ("show", "delete") and not args.id:
        parser.error(f"pattern-sets {args.action} needs the pattern-set id")
