"""The BRFD as a plant: displacement in, friction force out.

Nominal model (a documented choice, see ``docs/brfd.md``): a **Dahl-type friction element**, i.e.
LuGre with its micro-damping sigma1 = 0, integrated in the displacement domain (exact exponential
per sample, :mod:`engine.plants.brfd._kernel`). Two calibrated parameters: the Coulomb level Fc [N]
and the pre-sliding stiffness sigma0 [N/m]. Why Dahl/LuGre: the makers model the device with LuGre;
the pre-sliding stiffness gives the force's finite slope after a reversal (an elasto-plastic
element has it too but with a corner a record does not show); sigma1 matters only for the
micro-motion dynamics, which an imposed 1024 Hz displacement does not resolve; Stribeck,
asymmetry and viscous terms enter LuGre's g(v) and sigma2 as catalogue effects. Bouc-Wen would add
shape parameters the catalogue's effects would then compete with.

Input: the measured displacement, low-passed with a zero-phase 4th-order Butterworth at
:data:`INPUT_CUTOFF` (the transducer's 1.5 um quantum would otherwise dither the element at every
sample), delayed by the ``delay`` effect (linear interpolation). Output: the load cell's force,
``gain F + offset``. The scored samples start after :data:`SETTLE` (the element starts unloaded,
which the record need not).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from engine.plants.base import (
    CalibratedParameter,
    CandidateEffect,
    Channel,
    LocusSignal,
    checked_inputs,
    retimed_instants,
)
from engine.plants.brfd import _kernel as k
from engine.plants.brfd.catalogue import (
    CATALOGUE,
    EFFECT_FIELDS,
    HELD_BACK,
    HELD_BACK_FIELDS,
    LOCI,
    SEALED,
    SEALED_FIELDS,
)
from engine.plants.brfd.record import BrfdRecord, load_json, load_record
from engine.plants.noise import NoiseLevel, white_noise_level
from engine.records import RecordError

__all__ = [
    "CALIBRATED",
    "CHANNELS",
    "DIFF_STEP",
    "EXAMPLES",
    "BrfdParameters",
    "BrfdPlant",
]

#: Cut-off of the zero-phase low-pass on the displacement input [Hz] (the sinusoidal tests run at
#: 0.1-2 Hz; the earthquake histories hold little above 10 Hz).
INPUT_CUTOFF: float = 30.0
#: Velocity scale of the Stribeck effect [m/s].
STRIBECK_VELOCITY: float = 0.01
#: Retreat from the running extreme of x that counts as a reversal [m] (the wind-up of the
#: self-energizing effect restarts there; 0.1 mm, far above the transducer's 1.5 um quantum).
REVERSAL_TOLERANCE: float = 1e-4
#: Travel after a reversal within which the backlash regime lies [m]: the unloading of the element
#: (Fc / sigma0, about 4 mm at the sine tests' 9 kN and 2.2e6 N/m) and the play (3-4 mm).
REGIME_TRAVEL: float = 0.008
#: Wind-up scale of the held-back ``band_relaxation`` effect [m] (a fifth of the sine tests' 25 mm stroke).
RELAXATION_WINDUP: float = 0.005
#: Where the sealed ``end_stop`` engages [m] (|x| beyond it; the 1-inch sine tests reach 25 mm).
STOP_ENGAGE: float = 0.015
#: Stroke scale of the sealed ``tapered_drum`` [m] (the 1-inch sine tests' amplitude).
TAPER_SCALE: float = 0.025
#: Additive inputs :meth:`BrfdPlant.simulate` accepts, name -> unit: a displacement lost or gained in
#: the linkage before the friction element, and a force on the load cell's reading.
ENTRIES: dict[str, str] = {"displacement": "m", "force": "N"}
#: Time at the start of a record not scored [s] (the element starts unloaded).
SETTLE: float = 0.25
#: Share of the force's RMS drawn as white noise on a synthetic record's force.
SYNTHETIC_NOISE_SHARE: float = 0.02
#: Step of the diagnosis' finite differences, as a share of a parameter's interval (the force is
#: piecewise smooth in the parameters; the play's edges make finer steps noisy).
DIFF_STEP: float = 1e-3
#: The shipped records (``engine/plants/brfd/data``) and where they are.
EXAMPLES: tuple[str, ...] = (
    "dataset-2_1Hz30lbtension1amplitude",
    "dataset-2_2Hz30lbtension0.5amplitude",
    "dataset-2_1Hz36lbtension1amplitude",
    "dataset-2_0.5Hz36lbtension1amplitude",
    "dataset-2_ImperialValleyDBE",
    "dataset-2_KocaeliDBE",
)
DATA_DIR: Path = Path(__file__).resolve().parent / "data"

#: The channels of this plant.
CHANNELS: tuple[Channel, ...] = (Channel("force", "N", "friction force from the load cell (the file's kip x 4448.22)"),)

#: The calibrated parameters: nominal values and plausible intervals.
CALIBRATED: tuple[CalibratedParameter, ...] = (
    CalibratedParameter("Fc", 200.0, 40_000.0, "N", True, nominal=8000.0),
    CalibratedParameter("sigma0", 1e5, 1e9, "N/m", True, nominal=1e7),
)

#: Every name ``simulate`` accepts -> the parameters' field it sets: the calibrated parameters, then
#: the catalogue's, the held-back and the sealed effects.
_FIELDS: dict[str, str] = {
    **{p.name: p.name for p in CALIBRATED},
    **EFFECT_FIELDS,
    **HELD_BACK_FIELDS,
    **SEALED_FIELDS,
}


@dataclass(frozen=True)
class BrfdParameters:
    """Every parameter of the model, in SI units (module docstring; effects' neutral values as defaults)."""

    Fc: float = 8000.0
    sigma0: float = 1e7
    play: float = 0.0
    kappa: float = 0.0
    stribeck: float = 0.0
    asym: float = 0.0
    sigma2: float = 0.0
    c_link: float = 0.0
    offset: float = 0.0
    gain: float = 1.0
    delay: float = 0.0
    k_return: float = 0.0
    fade: float = 0.0
    relax: float = 0.0
    drift: float = 0.0
    k_stop: float = 0.0
    taper: float = 0.0
    kappa2: float = 0.0
    gain_drift: float = 0.0

    def vector(self) -> np.ndarray:
        """The kernel's parameter vector (the linkage compliance folded into the element's stiffness)."""
        p = np.zeros(k.N_PARAMS)
        p[k.P_SIGMA0] = self.sigma0 / (1.0 + self.sigma0 * self.c_link)
        p[k.P_FC] = self.Fc
        p[k.P_SIGMA2] = self.sigma2
        p[k.P_FS] = self.stribeck * self.Fc
        p[k.P_VS] = STRIBECK_VELOCITY
        p[k.P_ASYM] = self.asym
        p[k.P_PLAY] = self.play
        p[k.P_KAPPA] = self.kappa
        p[k.P_REV_TOL] = REVERSAL_TOLERANCE
        p[k.P_FADE] = self.fade
        p[k.P_RELAX] = self.relax
        p[k.P_W_RELAX] = RELAXATION_WINDUP
        p[k.P_TAPER] = self.taper
        p[k.P_X_TAPER] = TAPER_SCALE
        p[k.P_KAPPA2] = self.kappa2
        return p


#: The last record's filtered displacement: a fit simulates one record hundreds of times, and the
#: zero-phase filter is as costly as the kernel itself (one entry, keyed by the record's identity).
_LAST_INPUT: tuple[BrfdRecord | None, np.ndarray] = (None, np.empty(0))


def input_displacement(record: BrfdRecord) -> np.ndarray:
    """The displacement the model is driven with [m]: the record's, low-passed (module docstring).

    Raises
    ------
    RecordError
        For a sample rate at or below twice :data:`INPUT_CUTOFF` (the filter cannot be applied).
    """
    global _LAST_INPUT
    last, x = _LAST_INPUT
    if last is record:
        return x
    nyquist = 0.5 / record.ts
    if nyquist <= INPUT_CUTOFF:
        raise RecordError(
            f"{record.name}: sampled at {2 * nyquist:.4g} Hz; the model low-passes the displacement at "
            f"{INPUT_CUTOFF:g} Hz and needs more than {2 * INPUT_CUTOFF:g} Hz (the data set's records are 1024 Hz)"
        )
    from scipy.signal import butter, sosfiltfilt  # here: scipy.signal adds about 1 s to every service start

    sos = butter(4, INPUT_CUTOFF / nyquist, btype="low", output="sos")
    x = sosfiltfilt(sos, record.x)
    x.flags.writeable = False
    _LAST_INPUT = (record, x)
    return x


class BrfdPlant:
    """The banded rotary friction damper as a :class:`~engine.plants.base.Plant`."""

    name: str = "brfd"
    loci: tuple[str, ...] = LOCI
    channels: tuple[Channel, ...] = CHANNELS
    calibrated: tuple[CalibratedParameter, ...] = CALIBRATED
    catalogue: Mapping[str, CandidateEffect] = MappingProxyType(CATALOGUE)
    held_back: Mapping[str, CandidateEffect] = MappingProxyType(HELD_BACK)
    sealed: Mapping[str, CandidateEffect] = MappingProxyType(SEALED)
    entries: Mapping[str, str] = MappingProxyType(ENTRIES)
    diff_step: float = DIFF_STEP
    #: The kernel releases the GIL, but a simulation of a shipped record takes 0.1-1.3 ms and its Python
    #: share is the larger one: on threads its diagnoses ran 0.96-1.57x as long as on one, no gain beyond
    #: the 0.95-1.21x spread of two runs of the same code (``bench/bench_plant_diagnosis.py``,
    #: 2026-11-29), so its simulations run one after another.
    concurrent: bool = False

    @property
    def examples(self) -> tuple[str, ...]:
        """The shipped records: sinusoidal tests at 30 lb (1 Hz, 2 Hz) and 36 lb (1 Hz, 0.5 Hz), two earthquake histories."""
        return EXAMPLES

    def example(self, name: str | None = None, seconds: float | None = None) -> BrfdRecord:
        """A shipped record, its first ``seconds`` if given."""
        name = name or EXAMPLES[0]
        if name not in EXAMPLES:
            raise KeyError(f"unknown BRFD record {name!r}; shipped: {', '.join(EXAMPLES)}")
        record = load_json(DATA_DIR / f"{name}.json.gz")
        return record if seconds is None else record.head(seconds)

    def read(self, path: str | Path) -> BrfdRecord:
        """Read a ``.json`` (as distributed, or ``.json.gz``) or ``.csv`` record (:mod:`engine.plants.brfd.record`)."""
        return load_record(path)

    def fixed_by(self, record: BrfdRecord) -> dict[str, float]:
        """None: the band tension is known but not a model parameter."""
        return {}

    def measured(self, record: BrfdRecord) -> dict[str, np.ndarray]:
        """The load cell's force [N]."""
        return {"force": np.asarray(record.force, dtype=float)}

    def scored(self, record: BrfdRecord) -> slice:
        """Every sample after :data:`SETTLE`."""
        return slice(round(SETTLE / record.ts), None)

    def time(self, record: BrfdRecord) -> np.ndarray:
        """The record's sample instants [s]."""
        return record.t

    def retimed(self, record: BrfdRecord, factor: float) -> BrfdRecord:
        """The record read with its sample interval multiplied by ``factor`` (see :meth:`Plant.retimed`)."""
        return dataclasses.replace(record, t=retimed_instants(record.t, factor))

    def events(self, record: BrfdRecord) -> np.ndarray:
        """The reversals of the imposed displacement [s] (the backlash regime follows each)."""
        return record.t[k.reversals(input_displacement(record), REVERSAL_TOLERANCE)]

    def near_events(self, record: BrfdRecord) -> np.ndarray:
        """Samples of the backlash regime's reach: from a reversal until the displacement has
        travelled :data:`REGIME_TRAVEL` from it (or the next reversal)."""
        x = input_displacement(record)
        near = np.zeros(record.n, dtype=bool)
        for i in k.reversals(x, REVERSAL_TOLERANCE):
            far = np.flatnonzero(np.abs(x[i:] - x[i]) > REGIME_TRAVEL)
            near[i : i + (int(far[0]) if far.size else record.n - i)] = True
        return near

    def parameters(self, values: Mapping[str, float]) -> BrfdParameters:
        """Model parameters from calibrated and effect values by name (others nominal or neutral).

        Raises
        ------
        KeyError
            For an unknown name.
        """
        fields: dict[str, float] = {}
        for name, v in values.items():
            if name not in _FIELDS:
                raise KeyError(f"unknown BRFD parameter or effect {name!r}")
            fields[_FIELDS[name]] = float(v)
        return BrfdParameters(**fields)

    def _run(
        self, record: BrfdRecord, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The load cell's force [N] and the contact flags, per sample."""
        p = self.parameters(values)
        d = checked_inputs("BRFD", ENTRIES, record.n, inputs)
        x = input_displacement(record)
        if "displacement" in d:
            x = x + d["displacement"]
        if p.delay != 0.0:
            x = np.interp(record.t - p.delay, record.t, x)
        force = np.empty(record.n)
        contact = np.empty(record.n, dtype=np.int8)
        status = k.transmitted_force(x, record.ts, p.vector(), force, contact)
        if status != 0:
            raise RuntimeError(f"BRFD simulation failed (status {status}) at {dict(values)}")
        read = p.gain * force + p.offset
        if p.k_return != 0.0:
            read = read + p.k_return * x
        if p.drift != 0.0:
            read = read + p.drift * (record.t - record.t[0])
        if p.k_stop != 0.0:
            read = read + p.k_stop * np.sign(x) * np.maximum(np.abs(x) - STOP_ENGAGE, 0.0)
        if p.gain_drift != 0.0:
            read = read * (1.0 + p.gain_drift * (record.t - record.t[0]))
        if "force" in d:
            read = read + d["force"]
        return read, contact.astype(bool)

    def simulate(
        self, record: BrfdRecord, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None = None
    ) -> dict[str, np.ndarray]:
        """The force [N] simulated on the record's grid from its displacement, as the load cell reads it.

        ``inputs`` (:data:`ENTRIES`): ``displacement`` [m] added to the displacement the element sees,
        ``force`` [N] added to the load cell's reading.

        Raises
        ------
        KeyError
            For an unknown name or entry.
        ValueError
            For an input that is not one finite value per sample.
        RuntimeError
            When the kernel produces a non-finite force.
        """
        return {"force": self._run(record, values, inputs)[0]}

    def locus_signals(self, record: BrfdRecord, values: Mapping[str, float]) -> tuple[LocusSignal, ...]:
        """What each part of the damper sees, at ``values`` on ``record``'s grid.

        - linkage: a force following the displacement (a spring, a stop), and a displacement lost
          following the force (a compliance);
        - brake: a force following the velocity (a friction law), and a change of the friction level
          along the travel (wear, heat), in the direction of motion;
        - band: a change of the force's gain along the wind-up since the last reversal;
        - sensors: a reading error following the force (gain, offset, nonlinearity), the time (a
          drift) or the force's rate (a lag).
        """
        t = record.t - record.t[0]
        x = input_displacement(record)
        f = self.simulate(record, values)["force"]
        v = np.gradient(x, record.ts)
        sign_v = np.sign(v)
        travel = np.concatenate(([0.0], np.cumsum(np.abs(np.diff(x)))))
        windup = np.empty(record.n)
        rev = k.reversals(x, REVERSAL_TOLERANCE)
        starts = np.concatenate(([0], rev))
        for i, j in zip(starts, np.concatenate((rev, [record.n])), strict=True):
            windup[i:j] = np.abs(x[i:j] - x[i])
        return (
            LocusSignal("linkage", "force", "displacement", "m", x),
            LocusSignal("linkage", "displacement", "force", "N", f),
            LocusSignal("brake", "force", "velocity", "m/s", v),
            LocusSignal("brake", "force", "travel", "m", travel, sign_v, "direction of motion"),
            LocusSignal("band", "force", "wind-up", "m", windup, f, "force"),
            LocusSignal("sensors", "force", "force", "N", f),
            LocusSignal("sensors", "force", "time", "s", t),
            LocusSignal("sensors", "force", "force rate", "N/s", np.gradient(f, record.ts)),
        )

    def contact(self, record: BrfdRecord, values: Mapping[str, float]) -> np.ndarray:
        """Whether the linkage is in contact (True) or inside its play (False), per sample."""
        return self._run(record, values)[1]

    def figures(
        self, record: BrfdRecord, before: Mapping[str, float], after: Mapping[str, float] | None, out_dir: Path
    ) -> list[Path]:
        """The plant's own figure of a diagnosis: force against displacement, before and after."""
        from engine.plants.brfd.plots import plot_force_displacement

        return [plot_force_displacement(self, record, before, after, Path(out_dir) / "force_displacement.png")]

    def calibration_start(self, record: BrfdRecord) -> None:
        """None: the calibration's least squares starts at the nominal values (its cost is well behaved from there)."""
        return None

    def noise(self, record: BrfdRecord) -> dict[str, NoiseLevel]:
        """The load cell's noise, white: estimated from the record's finest wavelet level
        (:func:`engine.plants.noise.white_noise_level`; the shipped tests' force varies below 20 Hz at
        rates of 100 Hz and more, so that level holds noise only)."""
        return {"force": white_noise_level(self.measured(record)["force"][self.scored(record)])}

    def synthesize(self, record: BrfdRecord, values: Mapping[str, float], rng: np.random.Generator) -> BrfdRecord:
        """A record like ``record`` whose force is simulated at ``values`` plus white noise."""
        f = self.simulate(record, values)["force"]
        sd = SYNTHETIC_NOISE_SHARE * float(np.sqrt(np.mean(f**2)))
        return dataclasses.replace(record, force=f + rng.normal(0.0, sd, f.size), name=f"synthetic({record.name})")
