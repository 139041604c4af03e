"""Logging of the service and the engine."""

from __future__ import annotations

import logging

FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def setup_logging(level: str) -> None:
    """Send ``app`` and ``engine`` log records at ``level`` and above to stderr."""
    root = logging.getLogger()
    if not root.handlers:
        logging.basicConfig(level=logging.WARNING, format=FORMAT)
    for name in ("app", "engine"):
        logging.getLogger(name).setLevel(level)
