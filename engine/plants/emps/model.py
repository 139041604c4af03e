"""The EMPS plant: the published rigid model in its PD loop, with the candidate effects written in.

Published model (Janot, Gautier, Brunot, "Data Set and Reference Models of EMPS", section 3 and
the Simulink files ``Simulink_EMPS_Rigide(_Pulse).slx`` of the benchmark)::

    M q'' = g_tau v - Fv q' - Fc sign(q') - offset

with M = 95.1089 kg, Fv = 203.5034 N s/m, Fc = 20.3935 N, offset = -3.1648 N; the gains kp, kv,
g_tau are read from each record. Controller, transcribed block by block from the Simulink
diagram: ``u_k = kv (kp (qg_k - q_k) - (qf_k - qf_{k-1}) / Ts)`` with ``qf_k = (q_k + q_{k-1})/2``,
a unit delay, saturation at +-10 V, then (pulse record) the pulse signal added in volts; the force
``g_tau v`` is held over the sample interval. The Simulink model integrates with ode23tb
(MaxStep Ts/10, zero crossings off); we integrate with fixed-step RK4, :data:`N_SUBSTEPS` steps per
sample, which is what the kernel :mod:`engine.plants.emps._kernel` does.

Simulated channels are the plant's states at the samples (position, velocity, acceleration as the
right-hand side at the sample) and ``g_tau v`` with v the command after delay, saturation and
pulse, as the authors' script compares them (``Force1_s = gtau*vir_s``).

Beyond the catalogue (issue 52): the held-back family (:data:`~engine.plants.emps.catalogue.HELD_BACK`,
four effects in the loop's kernel, the logger's skew after it), the plant's entries
(:data:`ENTRIES`: an additive force on the motor side, an additive error of the recorded position)
and per locus the signals a missing term there would follow (:meth:`EmpsPlant.locus_signals`).

The sealed family (:data:`~engine.plants.emps.catalogue.SEALED`, kept for scoring a diagnosis
once): gain asymmetry, guide contamination and the screw's load friction in the kernel, the floor
vibration added to the kernel's external force here (:func:`vibration_force`), the encoder's slip
after the loop (:func:`slipped_position`); their fixed parts are the constants
:data:`CONTAMINATION_POSITION`, :data:`CONTAMINATION_WIDTH`, :data:`VIBRATION_FREQUENCY`,
:data:`SLIP_SHARE`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from engine.plants.base import CalibratedParameter, CandidateEffect, Channel, LocusSignal, checked_inputs, within_span
from engine.plants.emps import _kernel as k
from engine.plants.emps.catalogue import (
    CATALOGUE,
    EFFECT_FIELDS,
    HELD_BACK,
    HELD_BACK_FIELDS,
    LOCI,
    SEALED,
    SEALED_FIELDS,
)
from engine.plants.emps.channels import N_BORDER, measured_channels, process
from engine.plants.emps.record import SAMPLE_INTERVAL, EmpsRecord, load_mat, load_record
from engine.plants.noise import NoiseLevel, finest_level_sigma, integrated_time, white_noise_level

__all__ = [
    "CALIBRATED",
    "CHANNELS",
    "CONTAMINATION_POSITION",
    "CONTAMINATION_WIDTH",
    "ENCODER_QUANTUM",
    "ENTRIES",
    "FLEX_DAMPING_RATIO",
    "FLEX_MASS_RATIO",
    "N_SUBSTEPS",
    "POSITION_FRICTION_PERIOD",
    "PUBLISHED",
    "SLIP_SHARE",
    "STRIBECK_VELOCITY",
    "VIBRATION_FREQUENCY",
    "V_SATURATION",
    "EmpsParameters",
    "EmpsPlant",
    "logged_position",
    "slipped_position",
    "vibration_force",
]

#: The published rigid model (report, section 3): M [kg], Fv [N s/m], Fc [N], offset [N].
PUBLISHED: dict[str, float] = {"M": 95.1089, "Fv": 203.5034, "Fc": 20.3935, "offset": -3.1648}
#: Control saturation [V] (``viradm`` of the authors' script).
V_SATURATION: float = 10.0
#: RK4 sub-steps per sample (0.1 ms at 1 kHz, the Simulink model's MaxStep Ts/10).
N_SUBSTEPS: int = 10
#: Stribeck velocity v_s [m/s] of the ``stribeck`` effect: a documented choice, about a tenth of the
#: record's typical constant-speed phases (0.1-0.2 m/s).
STRIBECK_VELOCITY: float = 0.01
#: Share of the mass behind the spring in the ``flexibility`` effect (carriage side): a documented
#: choice, half the moving mass on each side.
FLEX_MASS_RATIO: float = 0.5
#: Damping ratio of the flexible mode in the ``flexibility`` effect: a documented choice (lightly
#: damped steel transmission).
FLEX_DAMPING_RATIO: float = 0.05
#: Period of the ``position_friction`` effect [m]: one screw revolution on the load side, from the
#: encoder's 50 000 counts per revolution (report, section 2.2) and the files' position quantum of
#: 50 nm (the smallest step of qm): 50 000 x 50 nm = 2.5 mm.
POSITION_FRICTION_PERIOD: float = 2.5e-3

#: Centre q_d [m] of the contaminated stretch of the sealed ``guide_contamination``: the middle of
#: the travel of the shipped record DATA_EMPS (its first 12 s, and the whole record, run from
#: about 0 to 0.2464 m, middle 0.1232 m), rounded to 5 mm.
CONTAMINATION_POSITION: float = 0.125
#: Width w_d [m] of the contaminated stretch (the Gaussian's 1/e half-width): a documented choice.
CONTAMINATION_WIDTH: float = 0.02
#: Frequency f_v [Hz] of the floor vibration of the sealed ``load_vibration``: a documented choice.
VIBRATION_FREQUENCY: float = 8.0
#: Share of the record's duration at which the sealed ``encoder_slip`` steps the recorded position
#: (from the first sample at or after it): a documented choice.
SLIP_SHARE: float = 0.4

#: Step of the diagnosis' finite differences, as a share of a parameter's interval. Coarse on
#: purpose: the simulation with Coulomb friction chatters at standstill, so its cost is rough on
#: scales of 1e-3 of an interval and finer differences send the solver the roughness, not the slope
#: (a fit of DATA_EMPS stopped at its start with 1e-3).
DIFF_STEP: float = 1e-2

#: Span around a pulse edge that counts as the edge's transient [s]: from 20 ms before to 80 ms
#: after (the closed loop rings about 60 ms).
EVENT_SPAN: tuple[float, float] = (-0.02, 0.08)

#: The benchmark's records shipped with the package (estimation, validation) and where they are.
EXAMPLES: tuple[str, ...] = ("DATA_EMPS", "DATA_EMPS_PULSES")
DATA_DIR: Path = Path(__file__).resolve().parent / "data"

#: The encoder's position quantum, load side [m]: the smallest step of qm in the files.
ENCODER_QUANTUM: float = 5e-8

#: Seed of the quantisation error drawn to carry the encoder's noise through the channels' chain
#: (:meth:`EmpsPlant.noise`; fixed, so a record's noise model is the same at every call).
QUANTUM_NOISE_SEED: int = 0
#: Phases of the count grid the quantisation error is drawn on (:meth:`EmpsPlant.noise`).
N_QUANTUM_PHASES: int = 4

#: The plant's additive inputs (``inputs=`` of :meth:`EmpsPlant.simulate`), name -> unit: ``force``
#: a force on the motor side in the loop, positive forward like the drive's, held over each sample
#: interval; ``position`` an error added to the recorded raw position qm (after the loop, before
#: the measurement chain), like a sensor's.
ENTRIES: dict[str, str] = {"force": "N", "position": "m"}

#: The channels of this plant.
CHANNELS: tuple[Channel, ...] = (
    Channel("position", "m", "qm, zero-phase Butterworth low-pass (4th order, 100 Hz)"),
    Channel("velocity", "m/s", "central difference of the filtered position"),
    Channel("acceleration", "m/s^2", "central difference of the velocity"),
    Channel("force", "N", "g_tau times the controller output vir"),
)

#: The calibrated parameters: the published values and plausible intervals (about +-50 % and, for
#: the offset, +-20 N).
CALIBRATED: tuple[CalibratedParameter, ...] = (
    CalibratedParameter("M", 50.0, 150.0, "kg", nominal=PUBLISHED["M"]),
    CalibratedParameter("Fv", 100.0, 300.0, "N s/m", nominal=PUBLISHED["Fv"]),
    CalibratedParameter("Fc", 5.0, 40.0, "N", nominal=PUBLISHED["Fc"]),
    CalibratedParameter("offset", -20.0, 20.0, "N", nominal=PUBLISHED["offset"]),
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
class EmpsParameters:
    """Every parameter of the EMPS model; the defaults are the published rigid model.

    Parameters
    ----------
    M : float
        Moving mass [kg].
    Fv, Fc : float
        Viscous [N s/m] and Coulomb [N] friction.
    offset : float
        Constant force offset [N].
    dFc, dFv, Fs, f_flex, gain_err, d_offset, A_pos, delay : float
        Scalars of the candidate effects (:mod:`engine.plants.emps.catalogue`), neutral at 0.
    dead_band, c_quad, A_ripple, k_cable, log_skew : float
        Scalars of the held-back effects (:data:`~engine.plants.emps.catalogue.HELD_BACK`), neutral
        at 0: the amplifier's dead band v0 [V], the quadratic drag c_q [N s^2/m^2], the screw's
        force ripple A [N], the cable carrier's stiffness k_c [N/m], the logger's skew delta [s].
    gain_asym, F_contam, mu_screw, A_vib, slip : float
        Scalars of the sealed effects (:data:`~engine.plants.emps.catalogue.SEALED`), neutral at 0:
        the drive's gain asymmetry eps [-], the guide contamination's friction F_d [N], the screw's
        load-friction coefficient mu [-], the floor vibration's amplitude A [N], the encoder slip's
        step Delta [m].
    v_sat : float
        Saturation of the controller's command [V] (effect ``command_limit``; published: 10 V).
    rho_flex, zeta_flex : float
        Carriage share of the mass [-] and damping ratio [-] of the ``flexibility`` effect (the
        documented choices :data:`FLEX_MASS_RATIO`, :data:`FLEX_DAMPING_RATIO`).
    """

    M: float = PUBLISHED["M"]
    Fv: float = PUBLISHED["Fv"]
    Fc: float = PUBLISHED["Fc"]
    offset: float = PUBLISHED["offset"]
    dFc: float = 0.0
    dFv: float = 0.0
    Fs: float = 0.0
    f_flex: float = 0.0
    gain_err: float = 0.0
    d_offset: float = 0.0
    A_pos: float = 0.0
    delay: float = 0.0
    v_sat: float = V_SATURATION
    rho_flex: float = FLEX_MASS_RATIO
    zeta_flex: float = FLEX_DAMPING_RATIO
    dead_band: float = 0.0
    c_quad: float = 0.0
    A_ripple: float = 0.0
    k_cable: float = 0.0
    log_skew: float = 0.0
    gain_asym: float = 0.0
    F_contam: float = 0.0
    mu_screw: float = 0.0
    A_vib: float = 0.0
    slip: float = 0.0

    def vector(self, record: EmpsRecord, n_substeps: int = N_SUBSTEPS) -> np.ndarray:
        """The kernel's parameter vector for a record (its gains and sample interval)."""
        p = np.zeros(k.N_P)
        p[k.P_M], p[k.P_FV], p[k.P_FC], p[k.P_OFFSET] = self.M, self.Fv, self.Fc, self.offset
        p[k.P_DFC], p[k.P_DFV], p[k.P_FS], p[k.P_VS] = self.dFc, self.dFv, self.Fs, STRIBECK_VELOCITY
        p[k.P_F_FLEX], p[k.P_RHO_FLEX], p[k.P_ZETA_FLEX] = self.f_flex, self.rho_flex, self.zeta_flex
        p[k.P_GAIN_ERR], p[k.P_D_OFFSET] = self.gain_err, self.d_offset
        p[k.P_A_POS], p[k.P_PERIOD_POS], p[k.P_DELAY] = self.A_pos, POSITION_FRICTION_PERIOD, self.delay
        p[k.P_KP], p[k.P_KV], p[k.P_GTAU] = record.kp, record.kv, record.gtau
        p[k.P_V_SAT], p[k.P_TS], p[k.P_NSUB] = self.v_sat, record.ts, n_substeps
        p[k.P_DEAD_BAND], p[k.P_QUAD_DRAG] = self.dead_band, self.c_quad
        p[k.P_RIPPLE], p[k.P_CABLE_K] = self.A_ripple, self.k_cable
        p[k.P_GAIN_ASYM], p[k.P_CONTAM_F], p[k.P_SCREW_MU] = self.gain_asym, self.F_contam, self.mu_screw
        p[k.P_CONTAM_Q], p[k.P_CONTAM_W] = CONTAMINATION_POSITION, CONTAMINATION_WIDTH
        return p


def logged_position(q: np.ndarray, delta: float, ts: float) -> np.ndarray:
    """The position as a logger skewed by ``delta`` records it (held-back ``position_log_skew``).

    Parameters
    ----------
    q : ndarray, shape (n,)
        True position at the samples [m].
    delta : float
        Lag of the logged position behind the logged force [s]; 0 returns ``q`` itself.
    ts : float
        Sample interval [s].

    Returns
    -------
    ndarray, shape (n,)
        ``q(t_i - delta)`` [m], linearly interpolated on the uniform sample grid, the samples
        before the first one held at its value.
    """
    if delta == 0.0:
        return q
    grid = np.arange(q.size, dtype=float)
    return np.interp(grid - delta / ts, grid, q)


def vibration_force(t: np.ndarray, amplitude: float) -> np.ndarray:
    """The floor vibration's force on the carriage per sample [N] (sealed ``load_vibration``).

    Parameters
    ----------
    t : ndarray, shape (n,)
        The record's sample instants [s].
    amplitude : float
        Its amplitude A [N].

    Returns
    -------
    ndarray, shape (n,)
        ``A sin(2 pi f_v (t_i - t_0))`` with f_v = :data:`VIBRATION_FREQUENCY`, positive forward
        like the drive's force (the kernel holds it over each sample interval).
    """
    t = np.asarray(t, dtype=float)
    return amplitude * np.sin(2.0 * math.pi * VIBRATION_FREQUENCY * (t - t[0]))


def slipped_position(q: np.ndarray, t: np.ndarray, delta: float) -> np.ndarray:
    """The recorded position after the encoder's count slipped once by ``delta`` (sealed ``encoder_slip``).

    Parameters
    ----------
    q : ndarray, shape (n,)
        The recorded position without the slip [m].
    t : ndarray, shape (n,)
        The record's sample instants [s].
    delta : float
        The step Delta [m]; 0 returns ``q`` itself.

    Returns
    -------
    ndarray, shape (n,)
        ``q`` plus ``delta`` from the first sample at or after :data:`SLIP_SHARE` of the record's
        duration (counted from its first sample) to the end.
    """
    if delta == 0.0:
        return q
    t = np.asarray(t, dtype=float)
    return q + np.where(t - t[0] >= SLIP_SHARE * (t[-1] - t[0]), delta, 0.0)


class EmpsPlant:
    """The EMPS positioning axis as a :class:`~engine.plants.base.Plant`.

    Parameters
    ----------
    n_substeps : int
        RK4 sub-steps per sample.
    fixed : mapping of str to float, optional
        Other values of :class:`EmpsParameters` fields that are neither calibrated nor effects
        (e.g. ``rho_flex``, ``zeta_flex`` for a sensitivity study of the documented choices).
    """

    name: str = "emps"
    loci: tuple[str, ...] = LOCI
    channels: tuple[Channel, ...] = CHANNELS
    calibrated: tuple[CalibratedParameter, ...] = CALIBRATED
    catalogue: Mapping[str, CandidateEffect] = MappingProxyType(CATALOGUE)
    held_back: Mapping[str, CandidateEffect] = MappingProxyType(HELD_BACK)
    #: The sealed family: effects kept for scoring a diagnosis once (:data:`~engine.plants.emps.catalogue.SEALED`).
    sealed: Mapping[str, CandidateEffect] = MappingProxyType(SEALED)
    entries: Mapping[str, str] = MappingProxyType(ENTRIES)
    diff_step: float = DIFF_STEP
    #: The kernel (:func:`~engine.plants.emps._kernel.simulate_loop`) releases the GIL: simulations run on threads.
    concurrent: bool = True

    def __init__(self, n_substeps: int = N_SUBSTEPS, fixed: Mapping[str, float] | None = None) -> None:
        self.n_substeps = n_substeps
        self.fixed = dict(fixed or {})
        unknown = set(self.fixed) - {f.name for f in dataclasses.fields(EmpsParameters)}
        if unknown:
            raise KeyError(f"unknown EMPS parameter(s) {sorted(unknown)}")

    @property
    def examples(self) -> tuple[str, ...]:
        """The benchmark's two records as distributed: estimation, then validation (pulses)."""
        return EXAMPLES

    def example(self, name: str | None = None, seconds: float | None = None) -> EmpsRecord:
        """A shipped record (``engine/plants/emps/data``), its first ``seconds`` if given."""
        name = name or EXAMPLES[0]
        if name not in EXAMPLES:
            raise KeyError(f"unknown EMPS record {name!r}; shipped: {', '.join(EXAMPLES)}")
        record = load_mat(DATA_DIR / f"{name}.mat")
        return record if seconds is None else record.head(seconds)

    def read(self, path: str | Path) -> EmpsRecord:
        """Read a ``.mat`` (as distributed) or ``.csv`` record (:mod:`engine.plants.emps.record`)."""
        return load_record(path)

    def measured(self, record: EmpsRecord) -> dict[str, np.ndarray]:
        """Measured channels (:func:`engine.plants.emps.channels.measured_channels`)."""
        return measured_channels(record)

    def fixed_by(self, record: EmpsRecord) -> dict[str, float]:
        """None: a record fixes the loop's gains, which are not calibrated parameters."""
        return {}

    def scored(self, record: EmpsRecord) -> slice:
        """The authors' comparison window: from sample 50 (1-based) to the end."""
        return slice(N_BORDER - 1, None)

    def time(self, record: EmpsRecord) -> np.ndarray:
        """The record's sample instants [s]."""
        return record.t

    def retimed(self, record: EmpsRecord, factor: float) -> EmpsRecord:
        """Never: an EMPS record is on the controller's 1 kHz grid, which its reader enforces."""
        raise ValueError(
            f"an EMPS record is read on the controller's {SAMPLE_INTERVAL * 1e3:g} ms grid only (the reader refuses "
            "any other interval)"
        )

    def events(self, record: EmpsRecord) -> np.ndarray:
        """The instants [s] where the pulse signal switches (none in a record without pulses)."""
        edges = np.flatnonzero(np.diff(record.pulses) != 0.0) + 1
        return record.t[edges]

    def near_events(self, record: EmpsRecord) -> np.ndarray:
        """Samples within :data:`EVENT_SPAN` of a pulse edge."""
        return within_span(record.t, self.events(record), EVENT_SPAN)

    def calibration_start(self, record: EmpsRecord) -> None:
        """None: the calibration's least squares starts at the nominal values (its cost is well behaved from there)."""
        return None

    def noise(self, record: EmpsRecord) -> dict[str, NoiseLevel]:
        """The encoder's quantum through the measurement chain, and the command's own noise.

        Position, velocity and acceleration: the quantisation error of the record's motion carried
        through the chain of :func:`~engine.plants.emps.channels.process` (zero-phase 100 Hz
        low-pass, two central differences): the position the nominal model simulates on the record's
        inputs (the closed loop follows the record's reference, so its speed profile is the record's),
        rounded to :data:`ENCODER_QUANTUM` on :data:`N_QUANTUM_PHASES` random phases of the count
        grid as :meth:`synthesize` reads it; the error's level and correlation time on the scored
        samples, pooled over the phases. (The record's own filtered position will not do: it lies on
        its count grid's phase, and re-rounding it gives an error that depends on the phase drawn.)
        The record's own finest-level estimate instead when it is larger (a noisier encoder than the
        benchmark's). Force: the command's white noise from its finest wavelet level (on a
        real record, the controller's reaction to the quantised position).
        """
        sl = self.scored(record)
        meas = self.measured(record)
        rng = np.random.default_rng(QUANTUM_NOISE_SEED)
        q = self.states(record, {})["position"]
        errs: dict[str, list[np.ndarray]] = {"position": [], "velocity": [], "acceleration": []}
        for phase in rng.uniform(0.0, ENCODER_QUANTUM, N_QUANTUM_PHASES):
            err = np.round((q + phase) / ENCODER_QUANTUM) * ENCODER_QUANTUM - phase - q
            chain = process(err, np.zeros(err.size), record.ts)
            for name, e in errs.items():
                e.append(chain[name][sl])
        out: dict[str, NoiseLevel] = {}
        for name, e in errs.items():
            sigma = float(np.sqrt(np.mean(np.square(e))))
            tau = float(np.mean([integrated_time(x) for x in e]))
            own = finest_level_sigma(meas[name][sl])
            out[name] = NoiseLevel(sigma, tau, "encoder quantum") if sigma >= own else NoiseLevel(own, 1.0, "record")
        out["force"] = white_noise_level(meas["force"][sl])
        return out

    def synthesize(self, record: EmpsRecord, values: Mapping[str, float], rng: np.random.Generator) -> EmpsRecord:
        """A record like ``record`` whose qm and vir are simulated at ``values``.

        qm is the simulated position read by the encoder (rounded to its :data:`ENCODER_QUANTUM`,
        with a random phase of the count grid); vir is the drive command the simulation applied,
        pulses included, as the measured vir holds them (``docs/real-data.md``).
        """
        x = self.states(record, values)
        phase = float(rng.uniform(0.0, ENCODER_QUANTUM))
        qm = np.round((x["position"] + phase) / ENCODER_QUANTUM) * ENCODER_QUANTUM - phase
        return dataclasses.replace(record, qm=qm, vir=x["force"] / record.gtau, name=f"synthetic({record.name})")

    def parameters(self, values: Mapping[str, float]) -> EmpsParameters:
        """The model's parameters with ``values`` (calibrated, effect, held-back and sealed names) applied.

        Raises
        ------
        KeyError
            For a name that is neither a calibrated parameter, an effect, a held-back nor a sealed effect.
        """
        changes: dict[str, float] = {}
        for name, value in values.items():
            if name not in _FIELDS:
                raise KeyError(f"unknown EMPS parameter or effect {name!r}")
            changes[_FIELDS[name]] = float(value)
        return dataclasses.replace(EmpsParameters(), **{**self.fixed, **changes})

    def _schedules(
        self, record: EmpsRecord, inputs: Mapping[str, np.ndarray] | None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The inputs at the plant's :data:`ENTRIES`, checked: the loop's force and the position error.

        Returns
        -------
        force : ndarray, shape (n,) or (0,)
            Additive force per sample [N], empty without a ``force`` input (the kernel skips it).
        position : ndarray, shape (n,), or None
            Additive error of the recorded position per sample [m], None without one.

        Raises
        ------
        KeyError
            For an entry not in :data:`ENTRIES`.
        ValueError
            For a schedule that is not one finite value per sample of the record.
        """
        given = checked_inputs("EMPS", ENTRIES, record.n, inputs)
        return given.get("force", np.zeros(0)), given.get("position")

    def _loop(self, record: EmpsRecord, params: EmpsParameters, force: np.ndarray) -> np.ndarray:
        """The kernel's closed-loop response (:func:`~engine.plants.emps._kernel.simulate_loop`).

        ``force`` is the ``force`` entry's schedule (empty for none); the sealed floor vibration
        (:func:`vibration_force`), when not neutral, is added to it as the kernel's external force.
        """
        if not math.isfinite(params.M) or params.M <= 0.0:
            raise ValueError(f"EMPS mass must be positive, got {params.M}")
        if params.A_vib != 0.0:
            vibration = vibration_force(record.t, params.A_vib)
            force = vibration if force.size == 0 else force + vibration
        return k.simulate_loop(params.vector(record, self.n_substeps), record.qg, record.pulses, force)

    @staticmethod
    def _recorded(record: EmpsRecord, params: EmpsParameters, q: np.ndarray) -> np.ndarray:
        """The motor position ``q`` as the logger records it: skewed (held-back), then slipped (sealed)."""
        return slipped_position(logged_position(q, params.log_skew, record.ts), record.t, params.slip)

    def states(
        self, record: EmpsRecord, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None = None
    ) -> dict[str, np.ndarray]:
        """The plant's states at the samples, as the authors' script compares them.

        Position [m] as the logger records it (qm: the motor position, delayed by the held-back
        logger skew, plus the sealed encoder slip's step and the ``position`` input, when given), velocity [m/s] and acceleration
        [m/s^2] (the right-hand side at the sample) of the motor side, and the force ``g_tau v`` [N]
        with v the command after delay, saturation and pulse (``Force1_s = gtau*vir_s``).
        ``inputs`` adds schedules at the plant's :data:`ENTRIES` (:meth:`_schedules`).

        Raises
        ------
        KeyError
            For an unknown name in ``values`` or an unknown entry in ``inputs``.
        ValueError
            For a non-positive mass or a schedule that is not one finite value per sample.
        FloatingPointError
            When the integration diverges.
        """
        params = self.parameters(values)
        force, position_error = self._schedules(record, inputs)
        out = self._loop(record, params, force)
        q = self._recorded(record, params, out[:, 0])
        if position_error is not None:
            q = q + position_error
        return {
            "position": q,
            "velocity": out[:, 1],
            "acceleration": out[:, 2],
            "force": record.gtau * out[:, 3],
        }

    def simulate(
        self, record: EmpsRecord, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None = None
    ) -> dict[str, np.ndarray]:
        """Channels simulated as the record's would read them: the states through the measurement chain.

        The simulated position passes the very filter and differences the measured one does
        (:func:`~engine.plants.emps.channels.process`), so a residual holds no difference of
        processing: a step of force is a step of the raw simulated acceleration but a 100 Hz-limited
        ramp of the measured one. (The authors compare the raw states, :meth:`states`.) ``inputs``
        as :meth:`states`: a ``position`` input reaches the channels through the filter.
        """
        x = self.states(record, values, inputs)
        return process(x["position"], x["force"], record.ts)

    def locus_signals(self, record: EmpsRecord, values: Mapping[str, float]) -> tuple[LocusSignal, ...]:
        """Per locus, the signals a missing term there would follow, from the states at ``values``.

        ``drive``: the command force ``g_tau v`` [N]; ``guide``: the motor-side velocity [m/s];
        ``transmission``: the screw angle, the position modulo :data:`POSITION_FRICTION_PERIOD` [m]
        (periodic); ``load``: the position [m] and the time [s]; all entering as a force at the
        ``force`` entry. ``sensors``: the position [m] and the velocity [m/s], entering as an error
        of the recorded position at the ``position`` entry. Raw states (before the measurement
        chain), no inputs (a sealed floor vibration in ``values`` is in the loop); the position is
        the motor's own (without a logger skew or an encoder slip) except at ``sensors``, where it
        is the recorded one. Every array has the record's n samples.
        """
        params = self.parameters(values)
        out = self._loop(record, params, np.zeros(0))
        q, v = out[:, 0].copy(), out[:, 1].copy()
        command = record.gtau * out[:, 3]
        logged = self._recorded(record, params, q).copy()
        return (
            LocusSignal("drive", "force", "command force", "N", command),
            LocusSignal("guide", "force", "velocity", "m/s", v),
            LocusSignal(
                "transmission",
                "force",
                "screw angle",
                "m",
                np.mod(q, POSITION_FRICTION_PERIOD),
                period=POSITION_FRICTION_PERIOD,
            ),
            LocusSignal("load", "force", "position", "m", q),
            LocusSignal("load", "force", "time", "s", np.array(self.time(record), dtype=float)),
            LocusSignal("sensors", "position", "position", "m", logged),
            LocusSignal("sensors", "position", "velocity", "m/s", v.copy()),
        )
