"""The ``backlash`` command: the service's endpoints as subcommands, plus serve, the main job and benchmarks.

Exit status: 0 success; 2 bad usage or input rejected (the message says what to
fix), or a feature not available yet; 1 unexpected failure.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import inspect
import json
import logging
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from app import output

logger = logging.getLogger(__name__)

EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2


class CommandError(Exception):
    """A user-facing failure of a command (exit status 2)."""


# -- argument types -----------------------------------------------------------------


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def _effect(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: write an effect as NAME=VALUE, e.g. motor_coulomb_friction=0.02")
    return name.strip(), _finite(value)


def _param(text: str) -> tuple[str, Any]:
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: write a parameter as NAME=VALUE, e.g. window=600")
    try:
        return name.strip(), json.loads(value)
    except ValueError:
        return name.strip(), value


def _settings(args: argparse.Namespace, **overrides: Any):
    """The service settings from the environment, with command-line overrides."""
    from pydantic import ValidationError

    from app.core.config import Settings

    given = {k: v for k, v in overrides.items() if v is not None}
    if getattr(args, "db", None) is not None:
        given["db_path"] = args.db
    if getattr(args, "log_level", None) is not None:
        given["log_level"] = args.log_level
    try:
        return Settings(**given)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(map(str, e['loc'])) or 'settings'}: {e['msg']}" for e in exc.errors())
        raise CommandError(f"invalid settings (BACKLASH_* environment variables or options): {problems}") from None


def _store(args: argparse.Namespace):
    from engine.storage import PatternStore

    return PatternStore(_settings(args).db_path)


def _read_record(args: argparse.Namespace):
    from app.records_io import read_record

    conditions = {k: getattr(args, k) for k in ("J1", "c", "c1", "K") if getattr(args, k, None) is not None}
    return read_record(args.record, args.sample_interval, args.event_index, conditions)


# -- commands -----------------------------------------------------------------------


def cmd_simulate(args: argparse.Namespace) -> int:
    from app.records_io import write_record
    from app.services import simulation

    if args.cases is not None:
        from app.schemas.simulate import SimulateBatchCreate

        try:
            body = SimulateBatchCreate.model_validate({"cases": json.loads(Path(args.cases).read_text("utf-8"))})
        except (OSError, ValueError) as exc:
            raise CommandError(
                f'{args.cases}: expected a JSON list of cases like [{{"K": 0.005, "J1": 0.87, "effects": {{}}}}]: {exc}'
            ) from None
        specs = [(c.K, c.J1, c.c, c.c1, c.effects) for c in body.cases]
    else:
        if args.K is None:
            raise CommandError("give the backlash width with --K (or a file of cases with --cases)")
        specs = [(args.K, args.J1, args.c, args.c1, dict(args.effect or []))]
    cases = simulation.prepare([simulation.make_case(*s[:4]) for s in specs], [s[4] for s in specs])
    records = simulation.run(cases).records
    if args.cases is not None:
        data = {"data": [r.to_dict() for r in records], "count": len(records)}
        if args.out is None:
            output.write_json(data)
        else:
            Path(args.out).write_text(json.dumps(data, allow_nan=False), encoding="utf-8")
            output.info(f"wrote {len(records)} records to {args.out}")
        return EXIT_OK
    record = records[0]
    if args.snr_db is not None or args.known is not None:
        # a "measured-like" record: white noise, and only the conditions a user would know
        import numpy as np

        from engine.records import Record
        from engine.simulation import add_white_noise

        rng = np.random.default_rng(args.seed)
        channels = {
            k: v if args.snr_db is None else add_white_noise(v, args.snr_db, rng) for k, v in record.channels.items()
        }
        known = (
            record.conditions if args.known is None else {k: v for k, v in record.conditions.items() if k in args.known}
        )
        record = Record(channels, record.sample_interval, record.event_index, known, record.event_time)
    if args.out is None:
        output.write_json(record.to_dict())
    else:
        write_record(record, args.out)
        output.info(f"wrote the record (event at t_e = {records[0].event_time:.6f} s) to {args.out}")
    return EXIT_OK


def cmd_train(args: argparse.Namespace) -> int:
    from app.services import training
    from app.services.patterns import DEFAULT_KIND, describe
    from engine.constants import J1_GRID

    named = {"learning_rate": args.l, "delta1": args.delta1, "max_epochs": args.max_epochs}
    params = {**dict(args.param or []), **{k: v for k, v in named.items() if v is not None}}
    spec = training.TrainingSpec(
        channel=args.channel,
        c=args.c,
        J1_values=tuple(args.J1 or J1_GRID),
        kind=args.kind or DEFAULT_KIND,
        params=params,
        effects=dict(args.effect or []),
    )
    training.check(spec)
    store = _store(args)

    def progress(fraction: float, stage: str) -> None:
        output.info(f"[{fraction:4.0%}] {stage}")

    saved = training.train_pattern_set(spec, store, progress=progress)
    output.write_json(describe(saved))
    return EXIT_OK


def cmd_identify(args: argparse.Namespace) -> int:
    from app.services.identification import identify_from_store

    record = _read_record(args)
    output.write_json(
        identify_from_store(_store(args), record, args.channel, args.pattern_set, args.kind, continuous=args.continuous)
    )
    return EXIT_OK


def cmd_diagnose(args: argparse.Namespace) -> int:
    from app.services import diagnosis
    from engine.simulation import CATALOGUE

    record = _read_record(args)
    for name in args.effects or ():
        CATALOGUE[name]
    output.info("diagnosing (calibration, then one fit per candidate effect; typically 3-15 s on 2 cores)")
    result = diagnosis.run(record, args.effects)
    output.write_json(result.to_dict())
    if args.plots:
        for path in diagnosis.write_plots(record, result, args.plots):
            output.info(f"wrote {path}")
    return EXIT_OK


def cmd_pattern_sets(args: argparse.Namespace) -> int:
    from app.services.identification import get_pattern_set
    from app.services.patterns import describe

    store = _store(args)
    if args.action == "list":
        sets = store.list(channel=args.channel, c=args.c, kind=args.kind)
        output.write_json({"data": [describe(s) for s in sets], "count": len(sets)})
    elif args.action == "show":
        output.write_json(describe(get_pattern_set(store, args.id)))
    else:  # delete
        get_pattern_set(store, args.id)
        store.delete(args.id)
        output.info(f"deleted pattern set {args.id}")
    return EXIT_OK


def cmd_serve(args: argparse.Namespace) -> int:
    import uvicorn

    from engine.storage import PatternStore

    settings = _settings(args, workers=args.workers)
    PatternStore(settings.db_path)  # a store that cannot be opened stops here with its message (exit 2)
    from app.main import create_app

    uvicorn.run(create_app(settings), host=args.host, port=args.port, log_level=settings.log_level.lower())
    return EXIT_OK


def _optional_module(name: str, what: str):
    """Import ``name`` if it exists; CommandError naming ``what`` if it (or a parent package) does not."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        parts = name.split(".")
        if exc.name in {".".join(parts[: i + 1]) for i in range(len(parts))}:
            raise CommandError(f"{what} is not available yet in this version ({name} does not exist)") from None
        raise


def cmd_run(args: argparse.Namespace) -> int:
    module = _optional_module("engine.evaluation.main_job", "the main job")
    result = module.run(Path(args.out))
    report = getattr(result, "report", None)
    if callable(report):
        output.write(report())
    return result if isinstance(result, int) else EXIT_OK


def _call_main(main: Callable[..., Any], argv: list[str], prog: str) -> int:
    """Call a script's ``main``: with ``argv`` if it takes an argument, else with ``sys.argv`` set to it."""
    if inspect.signature(main).parameters:
        result = main(argv)
    else:
        saved = sys.argv
        sys.argv = [prog, *argv]
        try:
            result = main()
        finally:
            sys.argv = saved
    return result if isinstance(result, int) else EXIT_OK


def cmd_bench(args: argparse.Namespace) -> int:
    candidates = [
        Path.cwd() / "bench" / "bench_simulator.py",
        Path(__file__).resolve().parent.parent / "bench" / "bench_simulator.py",
    ]
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        raise CommandError(
            "the benchmark is not available: bench/bench_simulator.py was not found (run from the repository root)"
        )
    spec = importlib.util.spec_from_file_location("bench_simulator", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    if not hasattr(module, "main"):
        raise CommandError(f"{path} has no main() function")
    return _call_main(module.main, list(args.args), str(path))


def cmd_validate(args: argparse.Namespace) -> int:
    module = _optional_module("engine.diagnosis.validation", "the blind validation of the diagnosis")
    if hasattr(module, "main"):
        return _call_main(module.main, list(args.args), "backlash validate")
    if args.args:
        raise CommandError(f"unrecognized arguments: {' '.join(args.args)}")
    if not hasattr(module, "run_validation"):
        raise CommandError("engine.diagnosis.validation has neither main() nor run_validation()")
    try:
        report = module.run_validation(n_cases=args.cases, seed=args.seed, out_dir=Path(args.out), workers=args.workers)
    except FileExistsError as exc:
        raise CommandError(str(exc)) from None
    table = getattr(report, "table", None)
    output.write(table() if callable(table) else str(report))
    # identification before/after the fix: a second scoring pass over the finished cases
    from engine.diagnosis.identification import identification_markdown, score_identification

    scored = score_identification(Path(args.out))
    ident = identification_markdown(scored)
    (Path(args.out) / "identification.md").write_text(ident)
    (Path(args.out) / "identification.json").write_text(json.dumps(scored, indent=1))
    output.write("\n## Identification accuracy before/after the fix\n\n" + ident)
    output.info(f"wrote the validation report to {args.out}")
    return EXIT_OK


# -- parser -------------------------------------------------------------------------


def _record_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("record", type=Path, help="record file: .json (record format) or .csv (header of channel names)")
    p.add_argument("--sample-interval", type=_finite, help="Ts [s] of a CSV record (default 1e-4)")
    p.add_argument("--event-index", type=int, help="index of the sample at the event, CSV record (default 48)")
    for name, unit in (("J1", "kg m^2"), ("c", "pu"), ("c1", "pu"), ("K", "m")):
        p.add_argument(f"--{name}", type=_finite, help=f"known condition {name} [{unit}]")


def _db_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--db", type=Path, help="pattern-store file (default $BACKLASH_DB_PATH or ./data/patterns.sqlite3)")


def build_parser() -> argparse.ArgumentParser:
    from engine.constants import CHANNELS

    parser = argparse.ArgumentParser(
        prog="backlash",
        description="Backlash diagnosis: simulate the backlash test, train pattern sets, identify the backlash width.",
    )
    parser.add_argument(
        "--log-level",
        choices=["DEBUG", "INFO", "WARNING", "ERROR"],
        type=str.upper,
        help="log level (default $BACKLASH_LOG_LEVEL or INFO)",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("simulate", help="simulate the backlash test of a case (like POST /v1/simulate)")
    p.add_argument("--K", type=_finite, help="backlash zone width [m]")
    p.add_argument("--J1", type=_finite, help="motor-side inertia [kg m^2] (default 0.87)")
    p.add_argument("--c", type=_finite, help="apparent viscosity [pu] (default 1.0)")
    p.add_argument("--c1", type=_finite, help="absorber discontinuity [pu] (default 0.2)")
    p.add_argument(
        "--effect", type=_effect, action="append", metavar="NAME=VALUE", help="unmodelled effect (repeatable)"
    )
    p.add_argument("--cases", type=Path, help="JSON file with a list of cases (the batch form); writes JSON")
    p.add_argument("--out", type=Path, help="output file, .json or .csv (default: JSON on stdout)")
    p.add_argument("--snr-db", type=_finite, help="add white noise at this SNR [dB] to every channel (single case)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise (default 0)")
    p.add_argument(
        "--known",
        nargs="*",
        choices=["K", "J1", "c", "c1"],
        help="conditions the record states (default all; e.g. --known c1 hides K, J1 and c)",
    )
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("train", help="train and store a pattern set (like POST /v1/pattern-sets)")
    p.add_argument("--channel", required=True, choices=CHANNELS)
    p.add_argument("--c", type=_finite, required=True, help="apparent-viscosity group [pu]")
    p.add_argument("--J1", type=_finite, nargs="+", help="J1 values [kg m^2] (default the paper's grid)")
    p.add_argument("--kind", help="identifier kind (default: the engine's default kind)")
    p.add_argument("--l", type=_finite, help="paper kind: learning coefficient l")
    p.add_argument("--delta1", type=_finite, help="paper kind: stop at RMS < delta1")
    p.add_argument("--max-epochs", type=int, help="paper kind: epoch cap per network")
    p.add_argument(
        "--param",
        type=_param,
        action="append",
        metavar="NAME=VALUE",
        help="further identifier hyper-parameter; VALUE is JSON (e.g. window=600)",
    )
    p.add_argument(
        "--effect",
        type=_effect,
        action="append",
        metavar="NAME=VALUE",
        help="unmodelled effect applied to every training case (repeatable)",
    )
    _db_option(p)
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("identify", help="identify the backlash width of a record (like POST /v1/identify)")
    _record_options(p)
    p.add_argument("--channel", required=True, choices=CHANNELS)
    p.add_argument("--pattern-set", help="pattern-set id (default: the stored set with the nearest c)")
    p.add_argument("--kind", help="only choose pattern sets of this kind")
    p.add_argument(
        "--continuous",
        action="store_true",
        help="also the calibrated K as a continuous width with its uncertainty (a few seconds)",
    )
    _db_option(p)
    p.set_defaults(func=cmd_identify)

    p = sub.add_parser("diagnose", help="diagnose the sim-to-real gap of a record (like POST /v1/diagnose)")
    _record_options(p)
    p.add_argument("--effects", nargs="+", metavar="NAME", help="candidate effects (default the whole catalogue)")
    p.add_argument("--plots", type=Path, metavar="DIR", help="also write PNG plots (residual map, overlays) to DIR")
    p.set_defaults(func=cmd_diagnose)

    p = sub.add_parser("pattern-sets", help="list, show or delete stored pattern sets")
    p.add_argument("action", choices=["list", "show", "delete"])
    p.add_argument("id", nargs="?", help="pattern-set id (show, delete)")
    p.add_argument("--channel", choices=CHANNELS)
    p.add_argument("--c", type=_finite)
    p.add_argument("--kind")
    _db_option(p)
    p.set_defaults(func=cmd_pattern_sets)

    p = sub.add_parser("serve", help="serve the HTTP API")
    p.add_argument("--host", default="127.0.0.1", help="interface to listen on (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    p.add_argument("--workers", type=int, help="background training threads (default $BACKLASH_WORKERS or 1)")
    _db_option(p)
    p.set_defaults(func=cmd_serve)

    p = sub.add_parser("run", help="the main job: train, evaluate, write tables and figures")
    p.add_argument("--out", default="out", help="output directory (default out)")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser(
        "bench", help="benchmark the simulator (bench/bench_simulator.py); further arguments go to the benchmark"
    )
    p.set_defaults(func=cmd_bench, passthrough=True)

    p = sub.add_parser("validate", help="blind validation of the gap diagnosis")
    p.add_argument("--out", default="out/validation", help="working and report directory (default out/validation)")
    p.add_argument("--cases", type=int, default=200, help="number of blind cases (default 200)")
    p.add_argument(
        "--seed",
        type=int,
        default=53,
        help="seed of the case generator (default 53, the README's blind run of the current code)",
    )
    p.add_argument("--workers", type=int, default=2, help="parallel diagnosis processes (default 2)")
    p.set_defaults(func=cmd_validate, passthrough=True)
    return parser


def _user_errors() -> tuple[type[BaseException], ...]:
    from app.records_io import RecordFormatError
    from app.services.errors import ServiceError
    from engine.records import RecordError
    from engine.simulation import ParameterError, SimulationError
    from engine.storage import InvalidPatternSet, PatternStoreError

    return (
        CommandError,
        RecordFormatError,
        RecordError,
        ParameterError,
        SimulationError,
        InvalidPatternSet,
        PatternStoreError,
        ServiceError,
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``backlash`` console command."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and not getattr(args, "passthrough", False):
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.args = extra
    if args.command == "pattern-sets" and args.action in ("show", "delete") and not args.id:
        parser.error(f"pattern-sets {args.action} needs the pattern-set id")
    from app.core.logging import setup_logging

    try:
        setup_logging(_settings(args).log_level)
        return int(args.func(args))
    except _user_errors() as exc:
        output.error(str(exc))
        return EXIT_USAGE
    except KeyboardInterrupt:
        output.error("interrupted")
        return 130
    except Exception as exc:
        logger.debug("unexpected failure", exc_info=True)
        output.error(f"unexpected failure: {type(exc).__name__}: {exc} (run with --log-level DEBUG for details)")
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
