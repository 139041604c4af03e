"""An EMPS record as its authors distribute it: the benchmark's ``.mat`` file, or the same in CSV.

The benchmark (Janot, Gautier, Brunot, "Data Set and Reference Models of EMPS") stores per record
``t`` [s], ``qm`` measured motor position (load side) [m], ``qg`` reference position [m], ``vir``
the controller output [V], the gains ``kp`` [1/s], ``kv`` [V/(m/s)], ``gtau`` [N/V], and in the
validation record ``pulses_N``, the pulse signal added to the command (a 0/5 signal; the authors'
Simulink model adds it to the command in volts, before the drive gain).

The CSV form has one header line naming the columns ``t,qm,qg,vir`` (and optionally
``pulses_N``) and, before it, one comment line per gain: ``# kp = 160.18``, ``# kv = 243.45``,
``# gtau = 35.15``. Everything is checked; a file that cannot be read as an EMPS record is refused
with a :class:`~engine.records.RecordError` that says what to fix.
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.records import RecordError
from engine.records.limits import require_length, require_magnitude

__all__ = ["SIGNALS", "EmpsRecord", "load_csv", "load_mat", "load_record", "record_from_arrays"]

#: Time series of a record, in order: name -> unit.
SIGNALS: dict[str, str] = {"t": "s", "qm": "m", "qg": "m", "vir": "V", "pulses_N": "V"}
#: Gains of a record: name -> unit.
GAINS: dict[str, str] = {"kp": "1/s", "kv": "V/(m/s)", "gtau": "N/V"}
#: Sample interval the controller runs at [s] and the relative spread of the stored instants
#: accepted around it (the files' t has float jitter of about 4e-5 s).
SAMPLE_INTERVAL: float = 1e-3
SAMPLE_JITTER: float = 0.01
#: Fewest samples a record needs (the authors' comparison drops the first 49 samples).
MIN_SAMPLES: int = 500


@dataclass(frozen=True)
class EmpsRecord:
    """One EMPS record on the controller's sample grid.

    Parameters
    ----------
    t : ndarray
        Sample instants [s], uniform at :data:`SAMPLE_INTERVAL`.
    qm : ndarray
        Measured motor position, load side [m].
    qg : ndarray
        Reference position [m].
    vir : ndarray
        Controller output as measured [V]; the force channel is ``gtau * vir`` [N].
    pulses : ndarray
        Pulse signal added to the command [V] (zeros in a record without pulses).
    kp, kv, gtau : float
        Position gain [1/s], velocity gain [V/(m/s)], drive gain [N/V].
    name : str
        Where the record came from (file name).
    """

    t: np.ndarray
    qm: np.ndarray
    qg: np.ndarray
    vir: np.ndarray
    pulses: np.ndarray
    kp: float
    kv: float
    gtau: float
    name: str = ""

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def ts(self) -> float:
        """Sample interval [s] (the mean of the stored instants' spacing)."""
        return float((self.t[-1] - self.t[0]) / (self.n - 1))

    def head(self, seconds: float) -> EmpsRecord:
        """The first ``seconds`` of the record (at least :data:`MIN_SAMPLES`)."""
        n = max(MIN_SAMPLES, min(self.n, round(seconds / self.ts) + 1))
        return EmpsRecord(
            self.t[:n], self.qm[:n], self.qg[:n], self.vir[:n], self.pulses[:n], self.kp, self.kv, self.gtau, self.name
        )

    @property
    def has_pulses(self) -> bool:
        """Whether pulses were applied."""
        return bool(np.any(self.pulses != 0.0))


def record_from_arrays(arrays: Mapping[str, np.ndarray], gains: Mapping[str, float | str], name: str) -> EmpsRecord:
    """An EMPS record from its signals and gains, checked (see the module docstring).

    Raises
    ------
    RecordError
        For a missing signal or gain, unequal lengths, a non-finite sample or one beyond
        +-1e12 (:data:`engine.records.limits.MAX_ABS_SAMPLE`), a grid that is not
        uniform at 1 kHz, too few samples, or a gain that is not a positive number.
    """
    missing = [k for k in ("t", "qm", "qg", "vir") if k not in arrays]
    if missing:
        raise RecordError(f"{name}: missing signal(s) {missing}; an EMPS record holds t, qm, qg, vir (and pulses_N)")
    missing = [k for k in GAINS if k not in gains]
    if missing:
        raise RecordError(f"{name}: missing gain(s) {missing}; an EMPS record holds kp, kv and gtau")
    n = arrays["t"].size
    require_length(n, f"{name}: t")
    out: dict[str, np.ndarray] = {}
    for key, unit in SIGNALS.items():
        if key not in arrays:
            continue
        a = np.asarray(arrays[key], dtype=float).ravel()
        if a.size != n:
            raise RecordError(f"{name}: {key} has {a.size} samples but t has {n}; every signal needs one value per t")
        if not np.all(np.isfinite(a)):
            bad = int(np.flatnonzero(~np.isfinite(a))[0])
            raise RecordError(f"{name}: {key} [{unit}] is not finite at sample {bad}; remove or repair the sample")
        require_magnitude(a, f"{name}: {key}", unit)
        out[key] = a
    if n < MIN_SAMPLES:
        raise RecordError(f"{name}: {n} samples; an EMPS record needs at least {MIN_SAMPLES}")
    dt = np.diff(out["t"])
    if np.any(np.abs(dt - SAMPLE_INTERVAL) > SAMPLE_JITTER * SAMPLE_INTERVAL):
        k = int(np.flatnonzero(np.abs(dt - SAMPLE_INTERVAL) > SAMPLE_JITTER * SAMPLE_INTERVAL)[0])
        raise RecordError(
            f"{name}: t is not uniform at {SAMPLE_INTERVAL * 1e3:g} ms (step {dt[k]:.6g} s after sample {k}); "
            "the EMPS controller runs at 1 kHz, give the record on its own grid"
        )
    vals: dict[str, float] = {}
    for key, unit in GAINS.items():
        try:
            v = float(gains[key])
        except (TypeError, ValueError):
            raise RecordError(f"{name}: gain {key} [{unit}] must be a number, got {gains[key]!r}") from None
        if not (math.isfinite(v) and v > 0.0):
            raise RecordError(f"{name}: gain {key} [{unit}] must be positive and finite, got {v!r}")
        vals[key] = v
    pulses = out.get("pulses_N", np.zeros(n))
    return EmpsRecord(
        t=out["t"],
        qm=out["qm"],
        qg=out["qg"],
        vir=out["vir"],
        pulses=pulses,
        kp=vals["kp"],
        kv=vals["kv"],
        gtau=vals["gtau"],
        name=name,
    )


def load_mat(source: str | Path | bytes, name: str | None = None) -> EmpsRecord:
    """Read the benchmark's ``.mat`` file as it is distributed.

    Parameters
    ----------
    source : str, Path or bytes
        Path of the file, or its content.
    name : str, optional
        Name of the record (default: the file name).

    Raises
    ------
    RecordError
        When the file is not a MATLAB file or lacks what an EMPS record holds.
    """
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    label = name or (Path(source).name if not isinstance(source, bytes) else "record.mat")
    try:
        data = loadmat(io.BytesIO(source) if isinstance(source, bytes) else source)
    except (
        MatReadError,
        ValueError,
        OSError,
        TypeError,
        IndexError,
        KeyError,
    ) as err:  # scipy raises any of these on junk
        raise RecordError(f"{label}: not a readable MATLAB .mat file ({err})") from None
    arrays = {k: np.asarray(v) for k, v in data.items() if k in SIGNALS}
    gains: dict[str, float] = {}
    for key in GAINS:
        if key in data:
            g = np.asarray(data[key], dtype=float)
            if g.size != 1:
                raise RecordError(f"{label}: gain {key} must be a scalar, got shape {g.shape}")
            gains[key] = float(g.item())
    return record_from_arrays(arrays, gains, label)


def load_csv(source: str | Path | bytes, name: str | None = None) -> EmpsRecord:
    """Read the CSV form (see the module docstring).

    Raises
    ------
    RecordError
        For a missing gain line, unknown or missing columns, non-numeric cells.
    """
    label = name or (Path(source).name if not isinstance(source, bytes) else "record.csv")
    try:
        text = source.decode("utf-8") if isinstance(source, bytes) else Path(source).read_text(encoding="utf-8")
    except (UnicodeDecodeError, OSError) as err:
        raise RecordError(f"{label}: cannot read the CSV file as UTF-8 text ({err})") from None
    lines = text.splitlines()
    gains: dict[str, float | str] = {}
    i = 0
    while i < len(lines) and (lines[i].startswith("#") or not lines[i].strip()):
        body = lines[i].lstrip("#").strip()
        if "=" in body:
            key, _, value = body.partition("=")
            gains[key.strip()] = value.strip()
        i += 1
    if i >= len(lines):
        raise RecordError(f"{label}: no header line; the CSV needs a line naming the columns t,qm,qg,vir")
    header = [h.strip() for h in lines[i].split(",")]
    unknown = [h for h in header if h not in SIGNALS]
    if unknown:
        raise RecordError(
            f"{label}: unknown column(s) {unknown}; the columns are t, qm, qg, vir and optionally pulses_N"
        )
    if len(set(header)) != len(header):
        raise RecordError(f"{label}: a column is named twice in the header {header}")
    try:
        table = np.loadtxt(lines[i + 1 :], delimiter=",", ndmin=2)
    except ValueError as err:
        raise RecordError(f"{label}: a cell is not a number ({err})") from None
    if table.shape[1] != len(header):
        raise RecordError(f"{label}: {table.shape[1]} columns of data but {len(header)} names in the header")
    arrays = {h: table[:, j] for j, h in enumerate(header)}
    return record_from_arrays(arrays, gains, label)


def load_record(path: str | Path) -> EmpsRecord:
    """Read a ``.mat`` or ``.csv`` EMPS record by its suffix.

    Raises
    ------
    RecordError
        For another suffix, or a file that cannot be read as an EMPS record.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".mat":
        return load_mat(path)
    if suffix == ".csv":
        return load_csv(path)
    raise RecordError(f"{Path(path).name}: an EMPS record is a .mat file (as distributed) or a .csv; got {suffix!r}")
