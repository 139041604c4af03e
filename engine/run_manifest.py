"""The manifest of a resumable validation run: what draws its cases, and whether they are all written.

Both validation protocols (:mod:`engine.diagnosis.validation`, protocol 1;
:mod:`engine.validation.run`, protocol 2) keep ``<out>/run.json``. It holds a fingerprint of every
setting the cases depend on and a ``complete`` flag: written ``false`` before the cases are drawn,
``true`` after the last one. One rule decides, for both, whether a directory holds a new run, this
very run (resumed), or another one (refused; nothing is overwritten). The fingerprint covers the
settings and the effect library, not the generator's code.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["MANIFEST", "fingerprint", "must_draw_cases", "read_manifest"]

logger = logging.getLogger(__name__)

MANIFEST = "run.json"
"""Name of the manifest in a run's directory."""


def read_manifest(root: Path) -> dict[str, Any] | None:
    """The manifest of the run in ``root``, or None when there is none.

    Parameters
    ----------
    root : Path
        The run's directory.

    Returns
    -------
    dict or None
        The manifest as written (its ``complete`` flag says whether every case is).

    Raises
    ------
    FileExistsError
        ``root/run.json`` exists but is not a JSON object (foreign or damaged): the directory is not
        taken for a run of ours, nor for an empty one.
    """
    path = root / MANIFEST
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FileExistsError(f"{path} is not a run manifest ({exc}); choose a new output directory") from exc
    if not isinstance(data, dict):
        raise FileExistsError(f"{path} is not a run manifest (not a JSON object); choose a new output directory")
    return data


def fingerprint(spec: Mapping[str, Any]) -> str:
    """Short hash of the settings that draw a run's cases.

    Parameters
    ----------
    spec : mapping
        JSON-serialisable settings (key order does not matter).

    Returns
    -------
    str
        The first 16 hexadecimal digits of the SHA-256 of ``spec`` as sorted JSON.
    """
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:16]


def must_draw_cases(root: Path, held: Mapping[str, Any] | None, mine: str, has_files: bool) -> bool:
    """Whether a run must draw its cases now in ``root``, else that ``root`` holds this very run, complete.

    Parameters
    ----------
    root : Path
        The run's directory (for the messages).
    held : mapping or None
        The manifest found in ``root`` (None when there is none).
    mine : str
        The fingerprint of the run asked for (:func:`fingerprint`).
    has_files : bool
        Whether ``root`` holds cases or results.

    Returns
    -------
    bool
        True when ``root`` holds no run yet, or this run with its cases not all written (the same
        settings draw the same cases again); False when it holds this run's cases, all written.

    Raises
    ------
    FileExistsError
        ``root`` holds another run (another fingerprint), or cases or results without a manifest
        (a run written before manifests, or foreign files): mixing two runs would corrupt the scores.
    """
    if held is not None:
        if held.get("fingerprint") != mine:
            raise FileExistsError(
                f"{root} holds another validation run (protocol {held.get('protocol')}, seed {held.get('seed')}, "
                f"{held.get('n_cases')} cases); to resume it give the same settings, else choose a new output directory"
            )
        if held.get("complete"):
            logger.info("keeping the %s cases of %s (seed %s)", held.get("n_cases"), root, held.get("seed"))
            return False
        return True
    if has_files:
        raise FileExistsError(
            f"{root} already holds a validation run (cases or results) without a manifest ({MANIFEST}): a run "
            f"written before manifests or foreign files; choose a new output directory or delete it, as mixing "
            f"two runs would corrupt the scores"
        )
    return True
