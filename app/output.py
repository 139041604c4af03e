"""The CLI's output: results to stdout, messages to stderr (no bare print in library code)."""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from typing import Any

#: Cells of the residual map the summary names.
SUMMARY_CELLS: int = 2


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


def summary_lines(answer: dict[str, Any], plots: Sequence[str] = ()) -> list[str]:
    """The lines of a diagnosis answer a person reads first.

    The verdict with its probability, the width with its 95 % interval, where the gap lies (the
    largest cells of the residual map), how far it shrinks once the named effects are added, the
    missing term of a gap the catalogue does not close (the locus estimate's), every warning, and
    the plot files written.
    """
    lines = []
    verdict = answer.get("verdict") or {}
    status = verdict.get("status") or answer.get("status")
    named = ", ".join(str(e.get("effect")) for e in verdict.get("effects") or () if isinstance(e, dict))
    line = f"verdict: {status}" + (f" ({named})" if named else "")
    if verdict.get("locus") and not named:
        group = [str(g) for g in verdict.get("locus_group") or () if g != verdict["locus"]]
        line += f", locus {verdict['locus']}" + (f" (not told from {', '.join(group)})" if group else "")
    if isinstance(verdict.get("confidence"), int | float):
        line += f", probability right {100 * verdict['confidence']:.0f} %"
    if isinstance(verdict.get("locus_confidence"), int | float):
        line += f" (locus {100 * verdict['locus_confidence']:.0f} %)"
    lines.append(line)
    width = answer.get("width")
    if isinstance(width, dict):
        if width.get("identifiable") and width.get("K") is not None:
            lo, hi = width.get("interval_95") or (None, None)
            span = f", 95 % interval {1e3 * lo:.4f}-{1e3 * hi:.4f} mm" if lo is not None and hi is not None else ""
            lines.append(f"backlash width: {1e3 * width['K']:.4f} mm{span} (from {width.get('from')})")
        else:
            lines.append(f"backlash width: not identifiable ({width.get('reason')})")
    cells = [c for c in answer.get("cells") or () if isinstance(c, dict) and c.get("share")]
    if cells:
        where = "; ".join(
            f"{c['channel']} {c['window_ms'][0]:.3g} to {c['window_ms'][1]:.3g} ms from the event, "
            f"{c['band_hz'][0]:.3g}-{c['band_hz'][1]:.3g} Hz ({100 * c['share']:.0f} %)"
            for c in cells[:SUMMARY_CELLS]
        )
        lines.append(f"where the gap lies: {where}")
    gap = answer.get("gap") or {}
    before, after = (gap.get("before") or {}).get("rms_over_noise"), (gap.get("after") or {}).get("rms_over_noise")
    if isinstance(before, int | float) and isinstance(after, int | float):
        lines.append(
            f"how far it shrinks: residual {before:.3g} -> {after:.3g} x noise RMS once {named or 'the fix'} is added"
        )
    elif isinstance(before, int | float):
        lines.append(f"gap: residual {before:.3g} x noise RMS (nothing added)")
    locus = answer.get("locus")
    if isinstance(locus, dict) and locus.get("locus"):
        term = (locus.get("term") or {}).get("description")
        conf = locus.get("confidence")
        text = f"missing term: at the {locus['locus']}"
        text += f" ({100 * conf:.0f} %)" if isinstance(conf, int | float) else ""
        text += f", {term}" if term else ""
        note = locus.get("note") or "; ".join(str(n) for n in locus.get("notes") or ())  # plant or drive answer
        text += f" [{note}]" if note else ""
        lines.append(text)
    for w in answer.get("warnings") or ():
        if isinstance(w, dict):
            lines.append(f"warning: {w.get('message')}")
    lines.extend(f"plot: {p}" for p in plots)
    return lines


def summary(answer: dict[str, Any], plots: Sequence[str] = (), to_stdout: bool = False) -> None:
    """:func:`summary_lines` on stderr (beside a JSON answer on stdout) or, with ``to_stdout``, as the result."""
    for line in summary_lines(answer, plots):
        if to_stdout:
            write(line)
        elif line.startswith("warning: "):
            warning(line.removeprefix("warning: "))
        else:
            info(line)


def error(text: str) -> None:
    """An error message on stderr."""
    info(f"backlash: error: {text}")
