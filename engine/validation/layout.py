"""The working directory of a protocol-v2 validation run, and its files.

::

    <out>/run.json                the run's manifest: protocol, seed, mix, the effect library (same for every case)
    <out>/cases/<case_id>.json    the records, in the service's record format (no hint of their truth)
    <out>/key/answer_key.json     the answer key, apart (read by the scorer only)
    <out>/results/<case_id>.json  the diagnosis of each case (its existence marks the case done)
    <out>/report.json, report.md  the scores

Every file is written atomically (:mod:`engine.atomic`: a temporary file renamed over the
target), so an interrupted run never leaves a half-written case, key or result behind.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from engine.atomic import write_json_atomic
from engine.records import Record
from engine.run_manifest import MANIFEST, read_manifest
from engine.validation.key import KeyEntry

__all__ = ["RunLayout"]


@dataclass(frozen=True)
class RunLayout:
    """Paths of one run's working directory.

    Parameters
    ----------
    root : Path
        The run's directory (``--out``).
    """

    root: Path

    @property
    def manifest(self) -> Path:
        return self.root / MANIFEST

    @property
    def cases(self) -> Path:
        return self.root / "cases"

    @property
    def key(self) -> Path:
        return self.root / "key" / "answer_key.json"

    @property
    def results(self) -> Path:
        return self.root / "results"

    @property
    def report_json(self) -> Path:
        return self.root / "report.json"

    @property
    def report_md(self) -> Path:
        return self.root / "report.md"

    def case_path(self, case_id: str) -> Path:
        return self.cases / f"{case_id}.json"

    def result_path(self, case_id: str) -> Path:
        return self.results / f"{case_id}.json"

    # -- writing ------------------------------------------------------------------------
    def write_cases(self, cases: Iterable[tuple[str, Record]]) -> None:
        """Write each ``(case_id, record)`` to ``cases/<case_id>.json`` (the record format, nothing else)."""
        self.cases.mkdir(parents=True, exist_ok=True)
        for case_id, record in cases:
            write_json_atomic(self.case_path(case_id), record.to_dict())

    def write_key(self, key: Sequence[KeyEntry], header: dict[str, Any]) -> None:
        """Write the answer key (``header`` fields, then ``cases``) to ``key/answer_key.json``."""
        self.key.parent.mkdir(parents=True, exist_ok=True)
        write_json_atomic(self.key, {**header, "cases": [k.to_dict() for k in key]}, indent=1)

    def write_manifest(self, manifest: dict[str, Any]) -> None:
        """Write ``run.json`` (written last by the generator: its presence marks the cases complete)."""
        self.root.mkdir(parents=True, exist_ok=True)
        write_json_atomic(self.manifest, manifest, indent=1)

    def write_result(self, case_id: str, result: dict[str, Any]) -> None:
        """Write one case's diagnosis to ``results/<case_id>.json``."""
        self.results.mkdir(parents=True, exist_ok=True)
        write_json_atomic(self.result_path(case_id), result)

    # -- reading ------------------------------------------------------------------------
    def read_manifest(self) -> dict[str, Any] | None:
        """The manifest (:func:`engine.run_manifest.read_manifest`), or None before the generator wrote it."""
        return read_manifest(self.root)

    def case_ids(self) -> list[str]:
        """Ids of the cases in ``cases/``, sorted."""
        return sorted(p.stem for p in self.cases.glob("*.json"))

    def read_case(self, case_id: str) -> Record:
        """The record of one case."""
        return Record.from_dict(json.loads(self.case_path(case_id).read_text()))

    def done(self) -> set[str]:
        """Ids of the cases that have a result."""
        return {p.stem for p in self.results.glob("*.json")} if self.results.is_dir() else set()

    def read_result(self, case_id: str) -> dict[str, Any]:
        data: dict[str, Any] = json.loads(self.result_path(case_id).read_text())
        return data

    def read_key(self) -> tuple[dict[str, Any], list[KeyEntry]]:
        """The answer key: its header and its entries (for the scorer only, once every diagnosis is done)."""
        data = json.loads(self.key.read_text())
        entries = [KeyEntry.from_dict(d) for d in data.pop("cases")]
        return data, entries

    def key_entries(self, case_ids: Sequence[str]) -> list[KeyEntry]:
        """The answer key's entries of chosen cases, in the order given (development tools only).

        Raises
        ------
        FileNotFoundError
            When the directory holds no answer key.
        KeyError
            When some ids are not cases of the run (all of them named).
        """
        if not self.key.is_file():
            raise FileNotFoundError(f"{self.root} holds no validation run (no {self.key})")
        by_id = {k.case_id: k for k in self.read_key()[1]}
        unknown = [c for c in case_ids if c not in by_id]
        if unknown:
            raise KeyError(f"not cases of this run: {', '.join(unknown)}")
        return [by_id[c] for c in case_ids]
