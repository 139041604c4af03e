"""The ``backlash`` parser and entry point: one subcommand module per command group, errors mapped to exit codes."""

from __future__ import annotations

import argparse
import logging
from collections.abc import Sequence

from app import output
from app.cli import batch, diagnose, evaluation, identify, pattern_sets, serve, simulate, store
from app.cli.common import EXIT_FAILURE, EXIT_INTERRUPTED, EXIT_USAGE, settings, user_errors

logger = logging.getLogger(__name__)


def build_parser() -> argparse.ArgumentParser:
    """The ``backlash`` argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="backlash",
        description="Backlash diagnosis: simulate the backlash test, train pattern sets, identify the backlash width, "
        "diagnose why a simulator does not match a record (the gap, its cause, its locus), serve it over HTTP.",
        epilog="start with: backlash simulate --K 0.0068 --out rec.csv && backlash diagnose rec.csv; "
        "each command's --help has examples",
    )
    parser.add_argument(
        "--log-level",
        choices=["DEBUG", "INFO", "WARNING", "ERROR"],
        type=str.upper,
        help="log level (default $BACKLASH_LOG_LEVEL or INFO)",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in (simulate, pattern_sets, identify, diagnose, batch, serve, store, evaluation):
        group.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``backlash`` console command; returns the exit status.

    0 success; 2 bad usage or input rejected (the message says what to fix);
    1 unexpected failure; 130 interrupted.
    """
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and not getattr(args, "passthrough", False):
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.args = extra
    pattern_sets.check_usage(parser, args)
    from app.core.logging import setup_logging

    try:
        setup_logging(settings(args).log_level)
        return int(args.func(args))
    except user_errors() as exc:
        output.error(getattr(exc, "cli_message", None) or str(exc))  # the CLI's wording where it differs
        return EXIT_USAGE
    except KeyboardInterrupt:
        output.error("interrupted")
        return EXIT_INTERRUPTED
    except Exception as exc:
        logger.debug("unexpected failure", exc_info=True)
        output.error(f"unexpected failure: {type(exc).__name__}: {exc} (run with --log-level DEBUG for details)")
        return EXIT_FAILURE
