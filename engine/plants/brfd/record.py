"""A BRFD record as its makers distribute it: the data set's JSON file, or the same in CSV.

The data set (Coble, Huggins, Cao, Ricles, Downey, "Dataset-Friction-Damper-with-Backlash", ARTS
Lab, 2022, CC BY-SA 4.0) stores one JSON object per test: ``data``, one row per sample with the
columns ``time [s], displacement [in], friction force [kip], velocity [in/s], actuator force 1
[lb], actuator force 2 [lb]``, and ``dt``, ``sampling freq`` and the unit keys
(``displacement units`` = ``in``, ``friction force units`` = ``kip``, ``time units`` = ``s``).

Inches and kips are converted **here, once**: a :class:`BrfdRecord` holds SI units only
(displacement [m], force [N]). A file whose unit keys say anything else is refused rather than
misread. The CSV form has one header line naming at least the columns ``time,displacement,
friction_force`` and one comment line per unit before it (``# displacement units = in``,
``# friction force units = kip``); SI units (``m``, ``N``) are accepted as well.
"""

from __future__ import annotations

import gzip
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from engine.records import RecordError
from engine.records.csv_table import numeric_rows
from engine.records.limits import require_length, require_magnitude

__all__ = [
    "FORCE_UNITS",
    "LENGTH_UNITS",
    "BrfdRecord",
    "from_json_object",
    "load_csv",
    "load_json",
    "load_record",
    "record_from_arrays",
]

#: Length units a record may be given in -> metres.
LENGTH_UNITS: dict[str, float] = {"in": 0.0254, "mm": 1e-3, "m": 1.0}
#: Force units a record may be given in -> newtons (1 kip = 1000 lbf = 4448.2216152605 N).
FORCE_UNITS: dict[str, float] = {"kip": 4448.2216152605, "lb": 4.4482216152605, "kN": 1e3, "N": 1.0}
#: The data set's sample rate [Hz] and the relative jitter of the stored instants accepted around
#: the record's own interval.
SAMPLE_JITTER: float = 0.01
#: Fewest samples a record needs (a second at the data set's 1024 Hz).
MIN_SAMPLES: int = 1024
#: First bytes of a gzip stream.
GZIP_MAGIC: bytes = b"\x1f\x8b"
#: Columns of the JSON ``data`` matrix, in order.
JSON_COLUMNS: tuple[str, ...] = (
    "time",
    "displacement",
    "friction_force",
    "velocity",
    "actuator_force_1",
    "actuator_force_2",
)


@dataclass(frozen=True)
class BrfdRecord:
    """One BRFD test on its sample grid, in SI units.

    Parameters
    ----------
    t : ndarray
        Sample instants [s], uniform.
    x : ndarray
        Displacement imposed by the actuator [m].
    force : ndarray
        Measured friction force [N].
    name : str
        Where the record came from (file name).
    tension : float or None
        Band tension [lb] as the file name states it (None when it does not).
    meta : dict
        The file's other keys, for provenance.
    """

    t: np.ndarray
    x: np.ndarray
    force: np.ndarray
    name: str = ""
    tension: float | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def ts(self) -> float:
        """Sample interval [s]."""
        return float((self.t[-1] - self.t[0]) / (self.n - 1))

    def head(self, seconds: float) -> BrfdRecord:
        """The first ``seconds`` of the record (at least :data:`MIN_SAMPLES`)."""
        n = max(MIN_SAMPLES, min(self.n, round(seconds / self.ts) + 1))
        return BrfdRecord(self.t[:n], self.x[:n], self.force[:n], self.name, self.tension, self.meta)


def _tension(name: str) -> float | None:
    m = re.search(r"(\d+(?:\.\d+)?)lbtension", name)
    return float(m.group(1)) if m else None


def record_from_arrays(
    t: Sequence[float] | np.ndarray,
    x: Sequence[float] | np.ndarray,
    force: Sequence[float] | np.ndarray,
    name: str,
    length_unit: str = "m",
    force_unit: str = "N",
    meta: Mapping[str, Any] | None = None,
) -> BrfdRecord:
    """A record from its three series in the given units, converted to SI and checked.

    Raises
    ------
    RecordError
        Unknown units, series of unequal lengths, non-finite samples or samples beyond +-1e12 in SI
        units (:data:`engine.records.limits.MAX_ABS_SAMPLE`), too short a record, or instants that
        are not uniform.
    """
    if length_unit not in LENGTH_UNITS:
        raise RecordError(f"{name}: displacement unit {length_unit!r} is not one of {', '.join(LENGTH_UNITS)}")
    if force_unit not in FORCE_UNITS:
        raise RecordError(f"{name}: force unit {force_unit!r} is not one of {', '.join(FORCE_UNITS)}")
    arrays = {}
    for key, values in (("time", t), ("displacement", x), ("friction force", force)):
        try:
            a = np.asarray(values, dtype=float)
        except (TypeError, ValueError):
            raise RecordError(f"{name}: {key} holds values that are not numbers") from None
        if a.ndim != 1:
            raise RecordError(f"{name}: {key} must be one series of samples, got shape {a.shape}")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise RecordError(f"{name}: {key} holds a non-finite value at sample {int(bad[0])}")
        arrays[key] = a
    sizes = {k: a.size for k, a in arrays.items()}
    if len(set(sizes.values())) != 1:
        raise RecordError(f"{name}: series of unequal lengths {sizes}; every column needs one value per sample")
    n = sizes["time"]
    require_length(n, f"{name}: time")
    if n < MIN_SAMPLES:
        raise RecordError(f"{name}: {n} samples; a record needs at least {MIN_SAMPLES} (one second at 1024 Hz)")
    dt = np.diff(arrays["time"])
    ts = float(np.median(dt))
    if not ts > 0.0 or float(np.max(np.abs(dt - ts))) > SAMPLE_JITTER * ts:
        i = int(np.argmax(np.abs(dt - ts)))
        raise RecordError(
            f"{name}: time is not uniform (interval {dt[i]:.6g} s at sample {i + 1}, median {ts:.6g} s); "
            "give the samples on a uniform grid, in order"
        )
    with np.errstate(over="ignore"):  # a value the conversion overflows is refused just below
        x = arrays["displacement"] * LENGTH_UNITS[length_unit]
        force = arrays["friction force"] * FORCE_UNITS[force_unit]
    for what, values, unit, given in (
        ("time", arrays["time"], "s", "s"),
        ("displacement", x, "m", length_unit),
        ("friction force", force, "N", force_unit),
    ):
        require_magnitude(values, f"{name}: {what}" + ("" if given == unit else f" (given in {given})"), unit)
    return BrfdRecord(
        t=arrays["time"] - arrays["time"][0],
        x=x,
        force=force,
        name=name,
        tension=_tension(name),
        meta=dict(meta or {}),
    )


def from_json_object(obj: Any, name: str) -> BrfdRecord:
    """A record from the data set's JSON object, already parsed (module docstring)."""
    if not isinstance(obj, dict) or "data" not in obj:
        raise RecordError(f"{name}: not a BRFD record: a JSON object with a 'data' matrix is expected")
    units = {
        "time": obj.get("time units", "s"),
        "displacement": obj.get("displacement units"),
        "force": obj.get("friction force units"),
    }
    if units["time"] != "s":
        raise RecordError(f"{name}: time units {units['time']!r}; the reader takes seconds ('s')")
    try:
        data = np.asarray(obj["data"], dtype=float)
    except (TypeError, ValueError):
        raise RecordError(f"{name}: 'data' is not a numeric matrix (one row of numbers per sample)") from None
    if data.ndim != 2 or data.shape[1] < 3:
        raise RecordError(
            f"{name}: 'data' has shape {data.shape}; one row per sample with at least the columns "
            "time [s], displacement, friction force is expected"
        )
    if "dt" in obj:
        dt_file = float(obj["dt"])
        dt_data = float(np.median(np.diff(data[:, 0])))
        if not math.isclose(dt_file, dt_data, rel_tol=SAMPLE_JITTER):
            raise RecordError(f"{name}: 'dt' says {dt_file:.6g} s but the time column steps by {dt_data:.6g} s")
    missing = [
        key
        for key, unit in (("displacement units", units["displacement"]), ("friction force units", units["force"]))
        if unit is None
    ]
    if missing:
        raise RecordError(
            f"{name}: the record does not say its {' and '.join(repr(m) for m in missing)}; the data set's files give "
            "them ('in' and 'kip'): add them rather than let the reader guess"
        )
    meta = {k: v for k, v in obj.items() if k != "data"}
    return record_from_arrays(
        data[:, 0], data[:, 1], data[:, 2], name, str(units["displacement"]), str(units["force"]), meta
    )


def _stem(path: Path) -> str:
    """The file name without ``.json``, ``.json.gz`` or ``.csv``."""
    name = path.name
    for suffix in (".json.gz", ".json", ".csv"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return path.stem


def load_json(source: str | Path | bytes, name: str | None = None) -> BrfdRecord:
    """Read a record in the data set's JSON form (a path, or the file's bytes; gzip-compressed or not)."""
    raw = source if isinstance(source, bytes) else Path(source).read_bytes()
    label = name or ("record" if isinstance(source, bytes) else _stem(Path(source)))
    if raw[:2] == GZIP_MAGIC:
        try:
            raw = gzip.decompress(raw)
        except (OSError, EOFError) as exc:
            raise RecordError(f"{label}: a gzip file that cannot be decompressed ({exc})") from None
    text = raw.decode("utf-8", errors="replace")
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RecordError(f"{label}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    return from_json_object(obj, label)


def load_csv(source: str | Path | bytes, name: str | None = None) -> BrfdRecord:
    """Read a record in the CSV form (module docstring)."""
    if isinstance(source, bytes):
        text, label = source.decode("utf-8", errors="replace"), name or "record"
    else:
        path = Path(source)
        text, label = path.read_text(encoding="utf-8", errors="replace"), name or _stem(path)
    units: dict[str, str | None] = {"displacement": None, "friction force": None}
    lines = text.splitlines()
    body = [ln for ln in lines if not ln.lstrip().startswith("#")]
    for ln in lines:
        m = re.match(r"\s*#\s*(displacement|friction force) units\s*=\s*(\S+)", ln)
        if m:
            units[m.group(1)] = m.group(2)
    missing = [k for k, u in units.items() if u is None]
    if missing:
        raise RecordError(
            f"{label}: the CSV does not say its {' and '.join(missing)} units; add a comment line such as "
            "'# displacement units = in' and '# friction force units = kip' before the header"
        )
    if not body:
        raise RecordError(f"{label}: empty CSV")
    header = [h.strip() for h in body[0].split(",")]
    need = ("time", "displacement", "friction_force")
    absent = [c for c in need if c not in header]
    if absent:
        raise RecordError(f"{label}: CSV header {header} lacks the column(s) {absent}")
    rows = numeric_rows(body[1:], len(header), label)
    col = {c: rows[:, header.index(c)] for c in need}
    return record_from_arrays(
        col["time"],
        col["displacement"],
        col["friction_force"],
        label,
        str(units["displacement"]),
        str(units["friction force"]),
    )


def load_record(path: str | Path) -> BrfdRecord:
    """Read a ``.json`` (as distributed, or gzip-compressed ``.json.gz``) or ``.csv`` record.

    Raises
    ------
    RecordError
        An unknown suffix, or a file that cannot be read correctly as a BRFD record.
    """
    path = Path(path)
    name = path.name.lower()
    if name.endswith((".json", ".json.gz")):
        return load_json(path)
    if name.endswith(".csv"):
        return load_csv(path)
    raise RecordError(
        f"{path.name}: a BRFD record is a .json file as distributed (or .json.gz) or a .csv; "
        f"got {path.suffix or 'no suffix'}"
    )
