"""``backlash serve``: the HTTP API under uvicorn."""

from __future__ import annotations

import argparse

from app.cli.common import EXIT_OK, add_db_option, settings
from app.core.config import ENV_PREFIX, Settings


def cmd_serve(args: argparse.Namespace) -> int:
    """Open the pattern store (a store that cannot be opened stops here, exit 2), then serve until interrupted."""
    import uvicorn

    from engine.storage import PatternStore

    config = settings(args, workers=args.workers)
    PatternStore(config.db_path)
    from app.main import create_app  # after the checks: importing it builds the module-level app

    uvicorn.run(create_app(config), host=args.host, port=args.port, log_level=config.log_level.lower())
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``serve`` to the subcommands."""
    workers = Settings.model_fields["workers"].default
    p = sub.add_parser("serve", help="serve the HTTP API")
    p.add_argument("--host", default="127.0.0.1", help="interface to listen on (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    p.add_argument(
        "--workers", type=int, help=f"background training threads (default ${ENV_PREFIX}WORKERS or {workers})"
    )
    add_db_option(p)
    p.set_defaults(func=cmd_serve)
