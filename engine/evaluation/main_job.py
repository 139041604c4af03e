"""The main job (``make run`` / ``backlash run``).

1. Simulates the paper grid of every c group and trains pattern sets for the
   4 c groups x 5 channels x identifier kinds into the pattern store.
2. Re-runs the paper's Tables 1-4 with the paper's identifier.
3. Scores every identifier per channel on held-out data (see
   :mod:`engine.evaluation.accuracy`).
4. Writes ``out/``: Markdown and CSV tables and PNG figures.

On a described drive (``drive``, ``backlash run --drive FILE``) the same job runs on the drive's nominal
plant: its c groups, J1 grid and six widths (:meth:`DriveDescription.c_groups`, ``j1_grid``, ``k_grid``), its
operating range for the held-out cases; the sets it stores carry the drive and replace only the main job's
earlier sets of the same drive. The paper's Tables 1-4 are the paper's plant's and are not re-run there.
"""

from __future__ import annotations

import csv
import logging
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from engine.constants import C_GROUPS, CHANNELS, J1_GRID, J1_NOMINAL
from engine.evaluation import figures
from engine.evaluation.accuracy import AccuracyRow, accuracy_markdown, evaluate, random_cases
from engine.evaluation.paper_tables import TableRow, rerun_tables, table_csv_rows, table_markdown
from engine.identification.selection import drive_fingerprint
from engine.identification.training import IDENTIFIERS, identifier_params, simulate_training_grid, train_pattern_set
from engine.simulation import paper_grid, simulate_batch
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.storage import PatternStore, default_store_path

logger = logging.getLogger(__name__)

#: Hyper-parameters of each identifier kind in the main job. The paper's
#: network uses the tables' l = 0.9, delta1 = 0.08.
MAIN_JOB_KINDS: dict[str, dict[str, Any]] = {
    "template": {},
    "paper": {"learning_rate": 0.9, "delta1": 0.08},
}
MAIN_JOB_SOURCE = "main-job"


@dataclass
class MainJobResult:
    tables: list[TableRow]
    accuracy: list[AccuracyRow]
    pattern_set_ids: list[str]
    out_dir: Path
    seconds: float
    drive: DriveDescription | None = None

    def report(self) -> str:
        """Human-readable summary (what ``backlash run`` prints)."""
        if self.drive is None:
            head = "## Paper's Tables 1-4, re-run with the paper's identifier\n\n" + table_markdown(self.tables)
        else:
            d = self.drive
            head = (
                f"## Drive {d.name} (fingerprint {d.fingerprint[:12]})\n\n"
                f"c groups {', '.join(f'{c:g}' for c in d.c_groups())} pu; widths "
                f"{', '.join(f'{k * 1e3:g}' for k in d.k_grid())} mm; J1 {', '.join(f'{j:g}' for j in d.j1_grid())} "
                "kg m^2. The paper's Tables 1-4 are the paper's plant's: not re-run on this drive.\n"
            )
        return (
            head
            + "\n## Accuracy on held-out data (per identifier and channel)\n\n"
            + accuracy_markdown(self.accuracy)
            + f"\n{len(self.pattern_set_ids)} pattern sets stored; outputs in {self.out_dir}/ ; {self.seconds:.0f} s\n"
        )


def _write_csv(path: Path, rows: list[dict]) -> None:
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def _step(i: int, n: int, text: str) -> None:
    logger.info("[%d/%d] %s", i, n, text)


def train_and_store(
    store: PatternStore,
    grids: Mapping,
    kinds: Mapping[str, Mapping[str, Any]],
    drive: DriveDescription | None = None,
) -> list[str]:
    """Train and save one pattern set per kind x c group x channel, replacing older main-job sets of the drive.

    ``drive``: the drive the grids were simulated on (None: MODEL.md's reference plant); a set of another drive is
    never replaced.
    """
    ids = []
    total = len(kinds) * len(grids) * len(CHANNELS)
    fingerprint = (drive or REFERENCE_DRIVE).fingerprint
    J1_values = J1_GRID if drive is None else drive.j1_grid()
    for kind, params in kinds.items():
        for c, grid in grids.items():
            for ch in CHANNELS:
                ps = train_pattern_set(ch, c, kind=kind, J1_values=J1_values, params=params, grid=grid, drive=drive)
                ps.params["source"] = MAIN_JOB_SOURCE
                for old in store.list(channel=ch, c=c, kind=kind):
                    if old.params.get("source") == MAIN_JOB_SOURCE and drive_fingerprint(old) == fingerprint:
                        store.delete(old.id)
                saved = store.save(ps)
                assert saved.id is not None  # the store assigns one on save
                ids.append(saved.id)
                logger.info("  trained %s pattern set %d/%d (channel %s, c %g)", kind, len(ids), total, ch, c)
    return ids


def run(
    out_dir: str | Path = "out",
    db_path: str | Path | None = None,
    n_random: int = 240,
    kinds: Mapping[str, Mapping[str, Any]] | None = None,
    n_jobs: int | None = None,
    scheduler: str | None = None,
    drive: DriveDescription | None = None,
) -> MainJobResult:
    """Run the main job; see the module docstring.

    The held-out evaluations run on Dask (:mod:`engine.distributed`): ``n_jobs`` local single-threaded
    workers (default one per core; 0 in this process), or the cluster of ``scheduler`` /
    ``$BACKLASH_DASK_SCHEDULER``. ``drive``: a described drive (None, or the reference's description: MODEL.md's
    reference plant, the paper's experiment).
    """
    if drive is not None and drive.is_reference:
        drive = None
    t0 = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    kinds = dict(MAIN_JOB_KINDS if kinds is None else kinds)
    for k in kinds:
        if k not in IDENTIFIERS:
            raise ValueError(f"unknown identifier kind {k!r}; known: {', '.join(IDENTIFIERS)}")
    n_steps = 5
    if drive is None:
        _step(
            1, n_steps, f"simulating the paper grid (4 c groups x 6 widths x 7 J1) and {n_random} held-out random cases"
        )
        grids = {c: simulate_batch(paper_grid(c)) for c in C_GROUPS}
    else:
        groups, j1 = drive.c_groups(), drive.j1_grid()
        _step(
            1,
            n_steps,
            f"simulating drive {drive.name}'s grid ({len(groups)} c groups x 6 widths x {len(j1)} J1) and {n_random} "
            "held-out random cases",
        )
        grids = {c: simulate_training_grid(c, j1, drive=drive) for c in groups}
    random = random_cases(n_random, drive=drive)

    _step(
        2,
        n_steps,
        f"training {len(kinds) * len(grids) * len(CHANNELS)} pattern sets into {db_path or default_store_path()}",
    )
    store = PatternStore(db_path)
    ids = train_and_store(store, grids, kinds, drive)

    _step(
        3, n_steps, "re-running the paper's Tables 1-4" + ("" if drive is None else ": the paper's plant only, skipped")
    )
    tables = (
        rerun_tables(progress=lambda i, n: logger.info("  table case %d/%d", i, n), grids=grids)
        if "paper" in kinds and drive is None
        else []
    )

    _step(4, n_steps, "scoring identifiers on held-out data (leave-one-J1-out, random J1/c, 40 and 30 dB noise)")
    acc = evaluate(
        grids,
        random,
        # the paper's method on a drive is given the drive's width grid, as its stored sets are (train_pattern_set)
        {kind: {**params, **identifier_params(kind, drive)} for kind, params in kinds.items()},
        n_jobs=n_jobs,
        progress=lambda i, n, what: logger.info("  evaluation task %d/%d (%s)", i, n, what),
        scheduler=scheduler,
    )

    _step(5, n_steps, f"writing tables and figures to {out}/")
    if tables:
        (out / "paper_tables.md").write_text(table_markdown(tables))
        _write_csv(out / "paper_tables.csv", table_csv_rows(tables))
        figures.plot_table_d_vectors(tables, out / "table_d_vectors.png")
    (out / "accuracy.md").write_text(accuracy_markdown(acc))
    _write_csv(out / "accuracy.csv", [{**asdict(r), "accuracy": r.accuracy} for r in acc])
    if drive is None:
        figures.plot_channels_by_width(grids[1.0], J1_NOMINAL, out / "channels_by_width.png")
    else:  # the c group nearest the drive's nominal c, at its nominal J1
        nominal_c = min(grids, key=lambda c: abs(c - drive.c))
        figures.plot_channels_by_width(grids[nominal_c], drive.J1, out / "channels_by_width.png")
    figures.plot_accuracy_vs_noise(acc, out / "accuracy_vs_noise.png")
    result = MainJobResult(tables, acc, ids, out, time.perf_counter() - t0, drive)
    (out / "report.md").write_text(result.report())
    return result
