"""``backlash simulate``: the backlash test of one case or a file of cases (like ``POST /v1/simulate``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app import output
from app.cli.common import EXIT_OK, CommandError, effect, finite
from engine.constants import C1_NOMINAL, C_NOMINAL, J1_NOMINAL

if TYPE_CHECKING:
    from engine.records import Record


def _specs(args: argparse.Namespace) -> list[tuple[float, float | None, float | None, float | None, dict[str, float]]]:
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
    if args.K is None:
        raise CommandError("give the backlash width with --K (or a file of cases with --cases)")
    return [(args.K, args.J1, args.c, args.c1, dict(args.effect or []))]


def _measured_like(record: Record, args: argparse.Namespace) -> Record:
    """``record`` with white noise at ``--snr-db`` and only the ``--known`` conditions, as a user would measure it."""
    import numpy as np

    from engine.records import Record
    from engine.simulation import add_white_noise

    rng = np.random.default_rng(args.seed)
    channels = {
        k: v if args.snr_db is None else add_white_noise(v, args.snr_db, rng) for k, v in record.channels.items()
    }
    known = record.conditions if args.known is None else {k: v for k, v in record.conditions.items() if k in args.known}
    return Record(channels, record.sample_interval, record.event_index, known, record.event_time)


def cmd_simulate(args: argparse.Namespace) -> int:
    """Simulate the cases and write their records (JSON on stdout, or a .json / .csv file)."""
    from app.records_io import write_record
    from app.services import simulation

    specs = _specs(args)
    cases = simulation.prepare([simulation.make_case(*s[:4]) for s in specs], [s[4] for s in specs])
    records = simulation.run(cases).records
    if args.cases is not None:
        data: dict[str, Any] = {"data": [r.to_dict() for r in records], "count": len(records)}
        if args.out is None:
            output.write_json(data)
        else:
            Path(args.out).write_text(json.dumps(data, allow_nan=False), encoding="utf-8")
            output.info(f"wrote {len(records)} records to {args.out}")
        return EXIT_OK
    record = records[0]
    if args.snr_db is not None or args.known is not None:
        record = _measured_like(record, args)
    if args.out is None:
        output.write_json(record.to_dict())
    else:
        write_record(record, args.out)
        output.info(f"wrote the record (event at t_e = {records[0].event_time:.6f} s) to {args.out}")
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``simulate`` to the subcommands."""
    p = sub.add_parser("simulate", help="simulate the backlash test of a case (like POST /v1/simulate)")
    p.add_argument("--K", type=finite, help="backlash zone width [m]")
    p.add_argument("--J1", type=finite, help=f"motor-side inertia [kg m^2] (default {J1_NOMINAL:g})")
    p.add_argument("--c", type=finite, help=f"apparent viscosity [pu] (default {C_NOMINAL:g})")
    p.add_argument("--c1", type=finite, help=f"absorber discontinuity [pu] (default {C1_NOMINAL:g})")
    p.add_argument(
        "--effect", type=effect, action="append", metavar="NAME=VALUE", help="unmodelled effect (repeatable)"
    )
    p.add_argument("--cases", type=Path, help="JSON file with a list of cases (the batch form); writes JSON")
    p.add_argument("--out", type=Path, help="output file, .json or .csv (default: JSON on stdout)")
    p.add_argument("--snr-db", type=finite, help="add white noise at this SNR [dB] to every channel (single case)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise (default 0)")
    p.add_argument(
        "--known",
        nargs="*",
        choices=["K", "J1", "c", "c1"],
        help="conditions the record states (default all; e.g. --known c1 hides K, J1 and c)",
    )
    p.set_defaults(func=cmd_simulate)
