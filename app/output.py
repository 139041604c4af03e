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


def warning(text: str) -> None:
    """A warning about the answer on stderr: something to check before acting on it."""
    info(f"backlash: warning: {text}")


def summary(answer: dict[str, Any]) -> None:
    """The lines of a diagnosis answer a person reads first, on stderr: the verdict, the width, the warnings."""
    verdict = answer.get("verdict") or {}
    status = verdict.get("status") or answer.get("status")
    named = ", ".join(str(e.get("effect")) for e in verdict.get("effects") or () if isinstance(e, dict))
    line = f"verdict: {status}" + (f" ({named})" if named else "")
    if verdict.get("locus") and not named:
        line += f", locus {verdict['locus']}"
    if isinstance(verdict.get("confidence"), int | float):
        line += f", probability right {100 * verdict['confidence']:.0f} %"
    if isinstance(verdict.get("locus_confidence"), int | float):
        line += f" (locus {100 * verdict['locus_confidence']:.0f} %)"
    info(line)
    width = answer.get("width")
    if isinstance(width, dict):
        if width.get("identifiable") and width.get("K") is not None:
            lo, hi = width.get("interval_95") or (None, None)
            span = f", 95 % interval {1e3 * lo:.4f}-{1e3 * hi:.4f} mm" if lo is not None and hi is not None else ""
            info(f"backlash width: {1e3 * width['K']:.4f} mm{span} (from {width.get('from')})")
        else:
            info(f"backlash width: not identifiable ({width.get('reason')})")
    for w in answer.get("warnings") or ():
        if isinstance(w, dict):
            warning(str(w.get("message")))


def error(text: str) -> None:
    """An error message on stderr."""
    info(f"backlash: error: {text}")
