"""The long jobs: ``backlash run`` (the main job), ``backlash validate`` (blind validation) and ``backlash bench``."""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from app import output
from app.cli.common import EXIT_OK, CommandError

#: The simulator benchmark, relative to the repository root.
BENCH_SCRIPT = Path("bench") / "bench_simulator.py"


def cmd_run(args: argparse.Namespace) -> int:
    """The main job: train, evaluate, write tables and figures to ``--out``; print its summary."""
    from engine.evaluation import main_job

    result = main_job.run(Path(args.out))
    output.write(result.report())
    return EXIT_OK


def cmd_validate(args: argparse.Namespace) -> int:
    """Blind validation of the diagnosis, then the identification accuracy before/after the fix; reports to ``--out``."""
    from engine.diagnosis import validation
    from engine.evaluation import identification as scoring

    out = Path(args.out)
    try:
        report = validation.run_validation(n_cases=args.cases, seed=args.seed, out_dir=out, workers=args.workers)
    except FileExistsError as exc:
        raise CommandError(str(exc)) from None
    output.write(report.table())
    # identification before/after the fix: a second scoring pass over the finished cases
    scored = scoring.score_identification(out)
    ident = scoring.identification_markdown(scored)
    (out / "identification.md").write_text(ident)
    (out / "identification.json").write_text(json.dumps(scored, indent=1))
    output.write("\n## Identification accuracy before/after the fix\n\n" + ident)
    output.info(f"wrote the validation report to {args.out}")
    return EXIT_OK


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
    """Run ``bench/bench_simulator.py`` (of the working directory, else of the source tree) with the extra arguments."""
    roots = (Path.cwd(), Path(__file__).resolve().parents[2])
    path = next((root / BENCH_SCRIPT for root in roots if (root / BENCH_SCRIPT).is_file()), None)
    if path is None:
        raise CommandError(
            f"the benchmark is not available: {BENCH_SCRIPT.as_posix()} was not found (run from the repository root)"
        )
    spec = importlib.util.spec_from_file_location("bench_simulator", path)
    if spec is None or spec.loader is None:
        raise CommandError(f"{path} cannot be loaded as a Python module")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    if not hasattr(module, "main"):
        raise CommandError(f"{path} has no main() function")
    return _call_main(module.main, list(args.args), str(path))


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``run``, ``bench`` and ``validate`` to the subcommands."""
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
    p.set_defaults(func=cmd_validate)
