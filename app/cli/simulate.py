"""``backlash simulate``: the backlash test of one case or a file of cases (like ``POST /v1/simulate``).

The records are rendered the ways a bench gives them (:class:`app.services.simulation.Rendering`):
any sample interval and span around the event, channels in other units, a subset of
channels, measurement noise, only some conditions stated, no event index.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app import output
from app.cli.common import (
    EXIT_OK,
    CommandError,
    add_drive_option,
    add_unit_options,
    effect,
    effects_help,
    examples,
    finite,
    read_drive,
    units_of,
)
from engine.constants import (
    C1_NOMINAL,
    C_NOMINAL,
    CHANNELS,
    J1_NOMINAL,
    POST_EVENT_TIME,
    PRE_EVENT_TIME,
    SAMPLE_INTERVAL,
)

if TYPE_CHECKING:
    from app.services.simulation import Rendering
    from engine.simulation.drive import DriveDescription


def _specs(
    args: argparse.Namespace,
) -> list[tuple[float | None, float | None, float | None, float | None, dict[str, float]]]:
    """(K, J1, c, c1, effects) of every case: from ``--cases`` or from the single-case options."""
    if args.cases is not None:
        from app.schemas.simulate import SimulateBatchCreate

        try:
            body = SimulateBatchCreate.model_validate({"cases": json.loads(Path(args.cases).read_text("utf-8"))})
        except (OSError, ValueError) as exc:
            raise CommandError(
                f'{args.cases}: expected a JSON list of cases like [{{"K": 0.005, "J1": 0.87, "effects": {{}}}}]: {exc}'
            ) from None
        return [(c.K, c.J1, c.c, c.c1, c.effects) for c in body.cases]
    if args.K is None and args.drive is None:
        raise CommandError("give the backlash width with --K (or a file of cases with --cases, or a --drive whose K)")
    return [(args.K, args.J1, args.c, args.c1, dict(args.effect or []))]


def _rendering(args: argparse.Namespace, drive: DriveDescription | None) -> Rendering:
    """The rendering options of the command line; the span not given is the drive's protocol's (else MODEL.md's)."""
    from app.services.simulation import Rendering, protocol_span

    span = protocol_span(drive)
    return Rendering(
        sample_interval=span["sample_interval"] if args.sample_interval is None else args.sample_interval,
        before=span["before"] if args.before is None else args.before,
        after=span["after"] if args.after is None else args.after,
        units=units_of(args),
        channels=args.channels,
        include_event_index=args.event_index,
        snr_db=args.snr_db,
        seed=args.seed,
        known=args.known,
        base_torque=args.base_torque,
    )


def cmd_simulate(args: argparse.Namespace) -> int:
    """Simulate the cases and write their records (JSON on stdout, or a .json / .csv file)."""
    from app.records_io import write_record
    from app.services import simulation

    drive = read_drive(args)
    specs = _specs(args)
    rendering = _rendering(args, drive)
    cases = simulation.prepare([simulation.make_case(*s[:4], drive) for s in specs], [s[4] for s in specs])
    records = simulation.render(cases, rendering, drive)
    if args.cases is not None:
        data: dict[str, Any] = {
            "data": [simulation.to_public(r, rendering, drive) for r in records],
            "count": len(records),
        }
        if args.out is None:
            output.write_json(data)
        else:
            Path(args.out).write_text(json.dumps(data, allow_nan=False), encoding="utf-8")
            output.info(f"wrote {len(records)} records to {args.out}")
        return EXIT_OK
    record = records[0]
    if args.out is None:
        output.write_json(simulation.to_public(record, rendering, drive))
    elif Path(args.out).suffix.lower() == ".json":
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        public = simulation.to_public(record, rendering, drive)
        Path(args.out).write_text(json.dumps(public, allow_nan=False), "utf-8")
        output.info(f"wrote the record (event at t_e = {record.event_time:.6f} s) to {args.out}")
    else:
        write_record(record, args.out, with_time=args.time_column)
        if drive is not None:
            output.info(f"the CSV form does not hold the drive description {drive.fingerprint[:12]}; .json keeps it")
        where = f"sample {record.event_index}" if args.event_index else "a sample the CSV does not state"
        output.info(
            f"wrote the record (event at t_e = {record.event_time:.6f} s, {where}; Ts = {record.sample_interval:g} s"
            f"{', units ' + str(dict(record.units)) if record.units else ''}) to {args.out}"
        )
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``simulate`` to the subcommands."""
    p = sub.add_parser(
        "simulate",
        help="simulate the backlash test of a case (like POST /v1/simulate)",
        description="The backlash test of MODEL.md on the reference plant, with unmodelled effects if asked: a "
        "record (a1, m_el, omega1, a2, v2) as JSON or CSV.",
        **examples(
            "backlash simulate --K 0.0068 --out rec.csv",
            "backlash simulate --K 0.0055 --effect load_inertia=1.3 --snr-db 40 --out rec.csv",
            "backlash simulate --K 0.005 --channels a1 omega1 --omega1-unit rpm --known c1 --out drive.csv",
            "backlash simulate --cases cases.json --out records.json",
            "backlash simulate --drive docs/examples/drive-60hz-conveyor.toml --out conveyor.json",
        ),
    )
    add_drive_option(p)
    p.add_argument("--K", type=finite, help="backlash zone width [m] (default with --drive: the drive's)")
    p.add_argument("--J1", type=finite, help=f"motor-side inertia [kg m^2] (default the drive's, else {J1_NOMINAL:g})")
    p.add_argument("--c", type=finite, help=f"apparent viscosity [pu] (default the drive's, else {C_NOMINAL:g})")
    p.add_argument("--c1", type=finite, help=f"absorber discontinuity [pu] (default the drive's, else {C1_NOMINAL:g})")
    p.add_argument(
        "--effect",
        type=effect,
        action="append",
        metavar="NAME=VALUE",
        help="unmodelled effect (repeatable); names and ranges: " + effects_help(simulated=True),
    )
    p.add_argument("--cases", type=Path, help="JSON file with a list of cases (the batch form); writes JSON")
    p.add_argument("--out", type=Path, help="output file, .json or .csv (default: JSON on stdout)")
    p.add_argument(
        "--sample-interval",
        type=finite,
        help=f"Ts [s] of the rendered record, 10 us to 1 ms (default the drive's protocol's, else {SAMPLE_INTERVAL:g})",
    )
    p.add_argument(
        "--before",
        type=finite,
        help=f"time rendered before the event [s] (default the drive's protocol's, else {PRE_EVENT_TIME:g}; "
        f"least {PRE_EVENT_TIME:g})",
    )
    p.add_argument(
        "--after",
        type=finite,
        help=f"time rendered from the event on [s] (default the drive's protocol's, else {POST_EVENT_TIME:g}; "
        f"least {POST_EVENT_TIME:g})",
    )
    add_unit_options(p, "to write")
    p.add_argument("--channels", nargs="+", choices=CHANNELS, help="channels to keep (default all)")
    p.add_argument(
        "--no-event-index",
        dest="event_index",
        action="store_false",
        help="leave the event index out of the record: a reader has to locate the event",
    )
    p.add_argument(
        "--time-column",
        action="store_true",
        help="CSV output: a first column t, the time of each sample [s] from the first one (carries Ts)",
    )
    p.add_argument("--snr-db", type=finite, help="add white noise at this SNR [dB] to every channel")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise (default 0)")
    p.add_argument(
        "--known",
        nargs="*",
        choices=["K", "J1", "c", "c1"],
        help="conditions the record states (default all; e.g. --known c1 hides K, J1 and c)",
    )
    p.set_defaults(func=cmd_simulate)
