"""``backlash serve``: the HTTP API under uvicorn."""

from __future__ import annotations

import argparse

from app.cli.common import EXIT_OK, add_db_option, examples, settings
from app.core.config import ENV_PREFIX, Settings


def cmd_serve(args: argparse.Namespace) -> int:
    """Take the database file's service lock, open the pattern store (either failing stops here, exit 2), then
    serve until interrupted; the lock is held until the server has stopped."""
    import uvicorn

    from app.core.instance import hold_database
    from app.core.server import check_exposure, uvicorn_config
    from engine.storage import PatternStore

    config = settings(args, workers=args.workers)
    check_exposure(config, args.host)  # no API key on an address other machines reach: refused (exit 2)
    with hold_database(config.db_path) as lock:  # before the store is opened: a refused start never migrates it
        PatternStore(config.db_path)
        from app.main import create_app  # after the checks: importing it builds the module-level app

        uvicorn.run(
            create_app(config, database_lock=lock),
            host=args.host,
            port=args.port,
            log_level=config.log_level.lower(),
            **uvicorn_config(config),
        )
    return EXIT_OK


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``serve`` to the subcommands."""
    workers = Settings.model_fields["workers"].default
    p = sub.add_parser(
        "serve",
        help="serve the HTTP API and the report page",
        **examples(
            "backlash serve                      # http://127.0.0.1:8000/ (page), /docs (API)",
            "BACKLASH_API_KEY=secret backlash serve --host 0.0.0.0 --port 8000",
            "backlash serve --workers 2 --db /srv/backlash/patterns.sqlite3",
        ),
    )
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to listen on (default 127.0.0.1; another than loopback needs an API key, "
        f"${ENV_PREFIX}API_KEY, or ${ENV_PREFIX}ALLOW_NO_KEY=1)",
    )
    p.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    p.add_argument(
        "--workers",
        type=int,
        help=f"pattern sets trained at once, each in a worker process (threads with ${ENV_PREFIX}TRAINING_RUNS_IN=thread; "
        f"default ${ENV_PREFIX}WORKERS or {workers})",
    )
    add_db_option(p)
    p.set_defaults(func=cmd_serve)
