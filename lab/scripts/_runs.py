"""Shared by the development scripts of ``lab/scripts/`` that re-run cases of a finished validation run.

:func:`add_run_arguments` gives a script the run directory, the case ids and ``--seed``/``--cases``
(to draw the cases again when the directory holds none); :func:`chosen_entries` opens the run and
returns the answer-key entries of the chosen cases (the given ids, else every case of one kind);
:func:`run_library` the effect library the run gave every case, which a re-run must diagnose with, and
:func:`run_drive` the drive its cases were simulated on (a run of ``validate --drive``), which it must diagnose on.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from engine.simulation import CATALOGUE, EffectLibrary
from engine.simulation.drive import DriveDescription
from engine.validation.blind import drive_of_run, library_of_run
from engine.validation.key import KeyEntry
from engine.validation.layout import RunLayout
from engine.validation.run import prepare_cases

#: Groups of issue 10's time budgets and the case kinds in each.
GROUPS: dict[str, tuple[str, ...]] = {"single": ("single",), "compound": ("pair", "triple")}
#: Issue 10's 90th-percentile budgets [s], one diagnosis on 2 cores.
BUDGET_P90_S: dict[str, float] = {"single": 10.0, "compound": 60.0}


def add_run_arguments(ap: argparse.ArgumentParser, ids_help: str) -> None:
    """Add ``run``, ``ids``, ``--seed`` and ``--cases`` to a script's parser."""
    ap.add_argument("run", type=Path, help="directory of a validation run (its cases/ and key/)")
    ap.add_argument("ids", nargs="?", default="", help=ids_help)
    ap.add_argument("--seed", type=int, help="seed of the run's case generator (with --cases: draw them if absent)")
    ap.add_argument("--cases", dest="n_cases", type=int, help="number of cases of the run (with --seed)")


def chosen_entries(
    ap: argparse.ArgumentParser, args: argparse.Namespace, kind: str | None
) -> tuple[RunLayout, list[KeyEntry]]:
    """The run and the key entries of the given ids, or (none given) of every case of ``kind`` (None: all).

    Exits through ``ap.error`` with a message when ``--seed`` and ``--cases`` are not given
    together, or the run or an id is not there.
    """
    if (args.seed is None) != (args.n_cases is None):
        ap.error("--seed and --cases go together")
    layout = RunLayout(args.run)
    try:
        if args.seed is not None:
            prepare_cases(layout, args.n_cases, args.seed)
        ids = [c for c in args.ids.split(",") if c]
        if not ids:
            ids = [k.case_id for k in layout.key_entries(layout.case_ids()) if kind is None or k.kind == kind]
        return layout, list(layout.key_entries(ids))
    except (FileNotFoundError, FileExistsError, KeyError) as e:
        ap.error(str(e.args[0]))


def run_library(ap: argparse.ArgumentParser, layout: RunLayout) -> EffectLibrary:
    """The run's effect library (:func:`engine.validation.blind.library_of_run`, from the catalogue).

    Exits through ``ap.error`` with a message when the run's cases are not completely written.
    """
    try:
        return library_of_run(layout, CATALOGUE)
    except FileNotFoundError as e:
        ap.error(str(e.args[0]))


def run_drive(ap: argparse.ArgumentParser, layout: RunLayout) -> DriveDescription:
    """The drive the run's cases were simulated on (:func:`engine.validation.blind.drive_of_run`; the reference
    plant for a run without one). Exits through ``ap.error`` when the run's manifest is incomplete or edited."""
    try:
        return drive_of_run(layout)
    except FileNotFoundError as e:
        ap.error(str(e.args[0]))
    except ValueError as e:
        ap.error(str(e))


def updated(settings: Any, changes: dict[str, Any]) -> Any:
    """``settings`` (a dataclass) with ``changes``; a dict given for a dataclass field updates that field.

    Raises TypeError, naming the known fields, for a name that is not a field of ``settings``."""
    from dataclasses import fields as fields_of
    from dataclasses import is_dataclass, replace

    if not isinstance(changes, dict):
        raise TypeError(f"give the {type(settings).__name__} fields as a JSON object, not {changes!r}")
    known = {f.name for f in fields_of(settings)}
    unknown = sorted(set(changes) - known)
    if unknown:
        raise TypeError(
            f"{type(settings).__name__} has no field {', '.join(unknown)} (fields: {', '.join(sorted(known))})"
        )
    fields = {}
    for name, value in changes.items():
        old = getattr(settings, name)
        fields[name] = updated(old, value) if is_dataclass(old) and isinstance(value, dict) else value
    return replace(settings, **fields)
