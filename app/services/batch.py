"""Batch diagnosis of record files (``backlash diagnose-batch``): read here, diagnosed on Dask, one answer file each.

Every record file is read in this process (a file that cannot be read correctly is refused with
its message in the summary, never misread, and the others go on); the diagnoses run on the Dask
cluster (:mod:`engine.distributed`); each answer is written to ``OUT/<record>.json`` as it arrives
(atomically), and a record whose answer exists is not diagnosed again, so an interrupted batch
resumes. ``OUT/summary.csv`` and ``OUT/summary.md`` list every record with its verdict.
"""

from __future__ import annotations

import csv
import glob
import json
import logging
from pathlib import Path
from typing import Any

from engine.atomic import write_json_atomic
from engine.diagnosis.batch import SUMMARY_COLUMNS, diagnose_one, summary_row
from engine.plants import DEFAULT_PLANT, get_plant
from engine.simulation.drive import DriveDescription

__all__ = ["RECORD_SUFFIXES", "find_records", "run_batch"]

logger = logging.getLogger(__name__)

#: File names a batch takes from a directory.
RECORD_SUFFIXES: tuple[str, ...] = (".json", ".csv", ".json.gz", ".mat")


def _stem(path: Path) -> str:
    name = path.name
    for suffix in sorted(RECORD_SUFFIXES, key=len, reverse=True):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return path.stem


def find_records(source: str) -> list[Path]:
    """The record files of a directory (by :data:`RECORD_SUFFIXES`) or of a glob pattern, sorted.

    Raises
    ------
    FileNotFoundError
        When nothing matches (the message says what was looked for).
    """
    p = Path(source)
    if p.is_dir():
        files = [f for f in p.iterdir() if f.is_file() and f.name.lower().endswith(RECORD_SUFFIXES)]
    else:
        files = [Path(f) for f in glob.glob(source) if Path(f).is_file()]
    if not files:
        raise FileNotFoundError(
            f"no record files in {source!r} (a directory of {', '.join(RECORD_SUFFIXES)} or a glob)"
        )
    return sorted(files)


def _read(plant_name: str, path: Path, drive: DriveDescription | None = None) -> tuple[Any, DriveDescription | None]:
    """The record of ``path`` and the drive it is diagnosed on (``drive``, else the one the record states in full)."""
    if plant_name == DEFAULT_PLANT:
        from app.records_io import read_record, stated_provenance
        from app.services.identification import drive_for_record
        from app.services.simulation import check_units, record_interval

        drive = drive_for_record(drive, stated_provenance(path))  # a record of another drive: refused
        record = read_record(path, default_interval=record_interval(drive))  # without Ts or t: the drive's protocol's
        check_units(record.units, drive)  # omega1 in pu would be read with MODEL.md's base speed: refused
        return record, drive
    from app.services.plant_diagnosis import read_file

    return read_file(get_plant(plant_name), path), None


def run_batch(
    files: list[Path],
    out_dir: Path,
    plant_name: str = DEFAULT_PLANT,
    workers: int | None = None,
    scheduler: str | None = None,
    drive: DriveDescription | None = None,
) -> list[dict[str, Any]]:
    """Diagnose every file without an answer in ``out_dir`` yet; write the answers and the summary; return its rows.

    ``drive``: the backlash drive every record was measured on (None: each record's own drive when it states it in
    full, as a simulated record does, else MODEL.md's reference plant); a record that states another drive is
    refused.
    """
    from engine.distributed import dask_client, map_cases

    out_dir.mkdir(parents=True, exist_ok=True)
    names = {f: _stem(f) for f in files}
    if len(set(names.values())) != len(names):
        raise ValueError("two record files share a name (their answers would overwrite each other): rename one")
    rows: dict[str, dict[str, Any]] = {}
    inputs: dict[str, tuple[Any, ...]] = {}
    for f, name in names.items():
        answer_path = out_dir / f"{name}.json"
        if answer_path.is_file():
            rows[name] = summary_row(name, json.loads(answer_path.read_text()))
            continue
        try:
            inputs[name] = (plant_name, *_read(plant_name, f, drive))
        except (ValueError, OSError) as exc:  # RecordError, RecordFormatError, a unit error, an unreadable file
            logger.warning("%s refused: %s", f, exc)
            rows[name] = {c: None for c in SUMMARY_COLUMNS} | {"record": name, "status": "refused", "detail": str(exc)}
    if inputs:
        done = len(names) - len(inputs)
        with dask_client(scheduler, workers) as client:
            for name, answer in map_cases(client, diagnose_one, inputs, "record", done, len(names)):
                write_json_atomic(out_dir / f"{name}.json", answer, indent=1)
                rows[name] = summary_row(name, answer)
    table = [rows[n] for n in sorted(rows)]
    with (out_dir / "summary.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(SUMMARY_COLUMNS))
        writer.writeheader()
        writer.writerows(table)
    lines = ["| " + " | ".join(SUMMARY_COLUMNS) + " |", "|" + " --- |" * len(SUMMARY_COLUMNS)]
    for r in table:
        cells = [f"{v:.4g}" if isinstance(v, float) else ("" if v is None else str(v)) for v in r.values()]
        lines.append("| " + " | ".join(c.replace("|", "/") for c in cells) + " |")
    (out_dir / "summary.md").write_text("\n".join(lines) + "\n")
    return table
