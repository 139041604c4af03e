"""The CLI's output: results to stdout, messages to stderr (no bare print in library code)."""

from __future__ import annotations

import json
import sys
from typing import Any


def write(text: str) -> None:
    """A result line (or block) on stdout."""
    sys.stdout.write(text if text.endswith("\n") else text + "\n")
    sys.stdout.flush()


def write_json(data: Any) -> None:
    """A JSON result on stdout."""
    write(json.dumps(data, indent=2, allow_nan=False))


def info(text: str) -> None:
    """A progress or status message on stderr."""
    sys.stderr.write(text if text.endswith("\n") else text + "\n")
    sys.stderr.flush()


def error(text: str) -> None:
    """An error message on stderr."""
    info(f"backlash: error: {text}")
