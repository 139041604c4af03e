"""Running an FMI 2.0 FMU on a record's grid, through FMPy: co-simulation, or model exchange with SciPy's solver.

:class:`FmuModel` opens an FMU once (its model description read, the archive extracted into a
temporary folder that lives as long as the object) and simulates it as often as a diagnosis asks:
each thread that calls it gets its own instance, instantiated once and reset between simulations.
(The plant runs simultaneous simulations on worker processes, :mod:`engine.plants.fmu.pool`, one
instance per process, so an FMU that keeps global state is run safely too.)

One simulation (:meth:`FmuModel.simulate`): reset, the experiment set up at the start time, the
parameters set in initialization mode, the inputs of the first sample set, one step to the first
sample, then a communication step per sample interval, each input held at its sample's value over
the interval that sample starts (zero-order hold), the outputs read at every sample. A step the FMU
refuses raises :class:`FmuSimulationError` with the FMU's own message.

A model-exchange FMU (``interface="model-exchange"``) has no solver of its own: the simulation
integrates its derivatives with SUNDIALS' CVode (BDF, the solver FMPy ships and runs model exchange
with, :class:`fmpy.sundials.CVodeSolver`), set for the record's grid: at most one sample interval per
step, the solver stopped at every sample to read the outputs there, each input linear between its
samples (a model-exchange FMU sees the input between samples, where co-simulation holds it).
Tolerances: :data:`ME_RTOL` relative, :data:`ME_ATOL` times each state's nominal value absolute.
Events are handled as FMI 2.0 describes: CVode locates a zero crossing of the FMU's event indicators
(a state event), the solver stops at the FMU's next time event, and the FMU is asked after each step
when it needs it (``completedIntegratorStep``); at each, the event iteration runs and the solver
restarts from the FMU's states if it changed them.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import math
import shutil
import tempfile
import threading
import weakref
from bisect import bisect_right
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

__all__ = ["INTERFACES", "ME_ATOL", "ME_RTOL", "FmuModel", "FmuSimulationError", "FmuVariable", "Interface"]

#: An FMI 2.0 interface a plant can run, by the description's name for it.
Interface = Literal["co-simulation", "model-exchange"]
#: The FMI 2.0 interfaces a plant can run.
INTERFACES: tuple[str, ...] = get_args(Interface)
#: Relative tolerance of the model-exchange integration.
ME_RTOL: float = 1e-6
#: Most iterations of a model-exchange FMU's event iteration after its initialisation.
ME_EVENT_ITERATIONS: int = 100
#: Absolute tolerance of the model-exchange integration, as a share of each state's nominal value.
ME_ATOL: float = 1e-8
#: Most internal CVode steps between two samples (or a sample and an event).
ME_MAX_STEPS: int = 5000

log = logging.getLogger(__name__)


class FmuSimulationError(RuntimeError):
    """Raised when the FMU refuses a call (initialisation, a step); the message carries the FMU's own."""


#: Messages of each instance, by instance name: what the FMU said, for the error that follows a refusal.
_MESSAGES: dict[str, list[str]] = {}


def _forget(names: list[str]) -> None:
    for name in names:
        _MESSAGES.pop(name, None)


def _log_message(env: Any, name: Any, status: int, category: Any, message: Any) -> None:
    """The one logger of every FMU instance: the message to its instance's list and to the log."""
    inst = name.decode("utf-8", "replace") if isinstance(name, bytes) else str(name)
    text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
    into = _MESSAGES.get(inst)
    if into is not None:
        into.append(text)
    log.debug("FMU %s: %s", inst, text)


_LOGGER: Any = None  # the ctypes callback of _log_message, created once and never freed


def _callbacks() -> Any:
    """FMI 2.0 callback functions whose logger is :func:`_log_message` (through FMPy's formatting proxy)."""
    global _LOGGER
    from fmpy.fmi2 import defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

    if _LOGGER is None:
        _LOGGER = fmi2CallbackLoggerTYPE(_log_message)
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = _LOGGER
    callbacks.allocateMemory = defaultCallbacks.allocateMemory
    callbacks.freeMemory = defaultCallbacks.freeMemory
    _proxy(callbacks)
    return callbacks


def _proxy(callbacks: Any) -> None:
    """Put FMPy's formatting proxy in front of ``callbacks``' logger.

    The proxy (``fmpy.logging``, C) formats an FMU's printf-style message and hands it to *one*
    process-wide Python logger, the last one it was given. Every instance here gives it
    :func:`_log_message`; :func:`_route_messages` gives it again before each simulation, in case other
    code (FMPy's own ``simulate_fmu``) gave it another since.
    """
    try:
        from fmpy.logging import addLoggerProxy
    except (ImportError, OSError):  # no proxy for this platform: the message is the format string
        return
    addLoggerProxy(ctypes.byref(callbacks))


def _route_messages() -> None:
    """Make :func:`_log_message` the proxy's logger again (see :func:`_proxy`)."""
    fresh = _callbacks()
    del fresh  # the proxy keeps the logger, not the struct


@dataclass(frozen=True)
class FmuVariable:
    """One real variable of the FMU's model description.

    Attributes
    ----------
    name : str
        Its name.
    value_reference : int
        Its value reference.
    causality : str
        ``parameter``, ``input``, ``output``, ``local``, ...
    unit : str
        Its declared unit (empty when none).
    start : float or None
        Its start value, when declared.
    """

    name: str
    value_reference: int
    causality: str
    unit: str
    start: float | None


class FmuModel:
    """An FMU opened for repeated simulation.

    Parameters
    ----------
    path : str or Path
        The ``.fmu`` file (FMI 2.0).
    interface : {"co-simulation", "model-exchange"}
        The FMU's interface to run (module docstring).

    Raises
    ------
    ValueError
        Not an FMI 2.0 FMU with that interface, or a file FMPy cannot read (the message says which).
    """

    def __init__(self, path: str | Path, interface: str = "co-simulation") -> None:
        from fmpy import extract, read_model_description

        self.path = Path(path)
        if interface not in INTERFACES:
            raise ValueError(f"interface {interface!r}: one of {', '.join(INTERFACES)}")
        try:
            md = read_model_description(str(self.path))
        except Exception as e:  # FMPy raises several kinds for a bad archive or XML
            raise ValueError(f"{self.path}: not an FMU FMPy can read: {e}") from None
        exchange = interface == "model-exchange"
        offered = md.modelExchange if exchange else md.coSimulation
        if md.fmiVersion != "2.0" or offered is None:
            have = [n for n, x in zip(INTERFACES, (md.coSimulation, md.modelExchange), strict=True) if x is not None]
            raise ValueError(
                f"{self.path}: the plant needs an FMI 2.0 FMU with a {interface} interface; this is FMI "
                f"{md.fmiVersion} with {', '.join(have) or 'no interface the plant runs'} (set interface = "
                f"{have[0]!r} in the description)"
                if have and md.fmiVersion == "2.0"
                else f"{self.path}: the plant needs an FMI 2.0 FMU with a {interface} interface; this is FMI "
                f"{md.fmiVersion}"
            )
        self.interface: str = interface
        self.model_description = md
        self.guid: str = md.guid
        self.identifier: str = offered.modelIdentifier
        self.n_states: int = len(md.derivatives) if exchange else 0
        self.n_event_indicators: int = int(md.numberOfEventIndicators or 0) if exchange else 0
        self._completed_step: bool = bool(exchange and md.modelExchange.needsCompletedIntegratorStep)
        #: Events (state, time and step events) of the last model-exchange simulation of this object.
        self.events_: int = 0
        self.variables: dict[str, FmuVariable] = {}
        for v in md.modelVariables:
            if v.type != "Real":
                continue
            start = None if v.start is None else float(v.start)
            self.variables[v.name] = FmuVariable(v.name, int(v.valueReference), v.causality, v.unit or "", start)
        self._dir = Path(tempfile.mkdtemp(prefix=f"fmu-{self.identifier}-"))
        weakref.finalize(self, shutil.rmtree, self._dir, True)
        self._unzipdir = extract(str(self.path), unzipdir=str(self._dir))
        self._local = threading.local()
        self._instances: list[Any] = []
        self._names: list[str] = []
        weakref.finalize(self, _forget, self._names)
        self._lock = threading.Lock()

    def variable(self, name: str, causality: str | Sequence[str] | None = None) -> FmuVariable:
        """The real variable ``name``, checked to have one of the given causalities.

        Raises
        ------
        KeyError
            For a name the FMU does not have as a real, or another causality; the message lists the
            FMU's variables of the wanted causality.
        """
        wanted = (causality,) if isinstance(causality, str) else tuple(causality or ())
        v = self.variables.get(name)
        if v is None or (wanted and v.causality not in wanted):
            have = sorted(n for n, x in self.variables.items() if not wanted or x.causality in wanted)
            kind = "/".join(wanted) or "real"
            if v is not None:
                raise KeyError(f"FMU variable {name!r} is a {v.causality}, not a {kind}; its {kind}s: {have}")
            raise KeyError(f"the FMU has no {kind} variable {name!r}; its {kind}s: {have}")
        return v

    def _instance(self) -> tuple[Any, list[str]]:
        """This thread's instance and its message list (instantiated on first use)."""
        inst = getattr(self._local, "fmu", None)
        if inst is not None:
            return inst, self._local.messages
        from fmpy.fmi2 import FMU2Model, FMU2Slave

        with self._lock:
            name = f"{self.identifier}-{id(self):x}-{len(self._instances)}"
        messages: list[str] = []
        _MESSAGES[name] = messages
        self._names.append(name)
        callbacks = _callbacks()
        kind = FMU2Model if self.interface == "model-exchange" else FMU2Slave
        inst = kind(guid=self.guid, unzipDirectory=self._unzipdir, modelIdentifier=self.identifier, instanceName=name)
        inst.instantiate(callbacks=callbacks)
        inst._backlash_callbacks = callbacks  # the FMU keeps a pointer to it: alive as long as the instance
        with self._lock:
            self._instances.append(inst)
        self._local.fmu = inst
        self._local.messages = messages
        return inst, messages

    def simulate(
        self,
        times: np.ndarray,
        start_time: float,
        parameters: Mapping[str, float],
        inputs: Mapping[str, np.ndarray],
        outputs: Sequence[str],
    ) -> np.ndarray:
        """The outputs at the sample instants ``times`` [s].

        Parameters
        ----------
        times : ndarray, shape (n,)
            Increasing sample instants [s], the first at or after ``start_time``.
        start_time : float
            The experiment's start [s].
        parameters : mapping
            FMU parameter name -> value, set in initialization mode (others keep their start values).
        inputs : mapping
            FMU input name -> one value per sample, held over the interval the sample starts
            (co-simulation) or linear between samples (model exchange).
        outputs : sequence of str
            FMU output names.

        Returns
        -------
        ndarray, shape (len(outputs), n)

        Raises
        ------
        FmuSimulationError
            When the FMU refuses initialisation or a step (its message included), or returns
            non-finite outputs.
        """
        from fmpy.fmi1 import FMICallException

        if self.interface == "model-exchange":
            return self._simulate_me(times, start_time, parameters, inputs, outputs)
        t = np.asarray(times, dtype=float)
        n = t.size
        inst, messages = self._instance()
        _route_messages()
        messages.clear()
        p_names, p_vr, p_val, u_names, u_vr, u_buf, y_vr, y_buf = self._buffers(parameters, inputs, outputs)
        nu, ny = len(u_names), len(outputs)
        # one row of inputs per sample, as Python floats (a ctypes buffer is filled per sample: cheaper than a
        # pointer into a numpy row, 1.4 us against 7.5 us a call, measured)
        u_rows = np.column_stack([np.asarray(inputs[k], dtype=float) for k in u_names]).tolist() if nu else []
        out = np.empty((n, ny))
        comp = inst.component
        fn = inst._functions
        set_real, get_real, do_step = fn["fmi2SetReal"], fn["fmi2GetReal"], fn["fmi2DoStep"]

        def failed(what: str) -> FmuSimulationError:
            return self._failure(messages, what)

        def set_inputs(k: int) -> int:
            u_buf[:] = u_rows[k]
            return int(set_real(comp, u_vr, nu, u_buf))

        try:
            inst.reset()
            inst.setupExperiment(startTime=float(start_time))
            inst.enterInitializationMode()
            if p_names and set_real(comp, p_vr, len(p_names), p_val) > 1:
                raise failed("setting the parameters")
            if nu and set_inputs(0) > 1:
                raise failed("setting the inputs")
            inst.exitInitializationMode()
        except FMICallException:
            raise failed("initialisation") from None
        now = float(start_time)
        times = t.tolist()
        if times[0] > now:
            if do_step(comp, now, times[0] - now, 1) > 1:
                raise failed(f"the step to the first sample (t = {times[0]:.6g} s)")
            now = times[0]
        if get_real(comp, y_vr, ny, y_buf) > 1:
            raise failed("reading the outputs")
        out[0] = y_buf
        for k in range(1, n):
            if nu and set_inputs(k - 1) > 1:
                raise failed(f"setting the inputs at t = {times[k - 1]:.6g} s")
            if do_step(comp, now, times[k] - now, 1) > 1:
                raise failed(f"the step from t = {now:.6g} s")
            now = times[k]
            if get_real(comp, y_vr, ny, y_buf) > 1:
                raise failed(f"reading the outputs at t = {now:.6g} s")
            out[k] = y_buf
        if not np.all(np.isfinite(out)):
            bad = int(np.argmax(~np.all(np.isfinite(out), axis=1)))
            raise FmuSimulationError(f"FMU {self.identifier}: non-finite outputs from t = {t[bad]:.6g} s on")
        return out.T.copy()

    def _buffers(
        self, parameters: Mapping[str, float], inputs: Mapping[str, np.ndarray], outputs: Sequence[str]
    ) -> tuple[list[str], Any, Any, list[str], Any, Any, Any, Any]:
        """ctypes arrays of one simulation: the parameters' value references and values, the inputs' value
        references and a buffer for one sample's values, the outputs' value references and their buffer."""
        p_names, u_names = list(parameters), list(inputs)
        vr = self.variables
        return (
            p_names,
            (ctypes.c_uint * len(p_names))(*(vr[k].value_reference for k in p_names)),
            (ctypes.c_double * len(p_names))(*(float(parameters[k]) for k in p_names)),
            u_names,
            (ctypes.c_uint * len(u_names))(*(vr[k].value_reference for k in u_names)),
            (ctypes.c_double * len(u_names))(),
            (ctypes.c_uint * len(outputs))(*(vr[k].value_reference for k in outputs)),
            (ctypes.c_double * len(outputs))(),
        )

    def _failure(self, messages: list[str], what: str) -> FmuSimulationError:
        """The error of a call the FMU refused, with what it logged."""
        said = "; ".join(m for m in messages if m) or "the FMU gave no message"
        return FmuSimulationError(f"FMU {self.identifier}: {what} failed: {said}")

    def _simulate_me(
        self,
        times: np.ndarray,
        start_time: float,
        parameters: Mapping[str, float],
        inputs: Mapping[str, np.ndarray],
        outputs: Sequence[str],
    ) -> np.ndarray:
        """:meth:`simulate` of a model-exchange FMU: its derivatives integrated by CVode (module docstring)."""
        from fmpy.fmi1 import FMICallException

        t = np.asarray(times, dtype=float)
        n, nx, nz = t.size, self.n_states, self.n_event_indicators
        if n and t[0] < start_time:
            raise FmuSimulationError(f"FMU {self.identifier}: the first sample precedes the start time")
        inst, messages = self._instance()
        _route_messages()
        messages.clear()
        fn, comp = inst._functions, inst.component
        set_real, get_real, set_time_fmu = fn["fmi2SetReal"], fn["fmi2GetReal"], fn["fmi2SetTime"]
        p_names, p_vr, p_val, u_names, u_vr, u_buf, y_vr, y_buf = self._buffers(parameters, inputs, outputs)
        nu, ny = len(u_names), len(outputs)
        u = np.vstack([np.asarray(inputs[k], dtype=float) for k in u_names]) if nu else np.empty((0, n))
        u_rows = [row.tolist() for row in u]
        slope_rows = [row.tolist() for row in (np.diff(u, axis=1) / np.diff(t) if n > 1 else np.zeros((nu, 0)))]
        t_list, last = t.tolist(), max(n - 2, 0)

        def failed(what: str) -> FmuSimulationError:
            return self._failure(messages, what)

        def call(name: str, *args: Any) -> None:
            if fn[name](comp, *args) > 1:
                raise failed(name)

        last_time = [math.nan]  # the time (and inputs) the FMU holds: CVode often asks twice at one instant

        def set_time(now: float) -> None:
            """The time and the inputs there (linear between samples; the first sample's before it)."""
            if now == last_time[0]:
                return
            last_time[0] = now
            if set_time_fmu(comp, now) > 1:
                raise failed(f"fmi2SetTime at t = {now:.6g} s")
            if nu:
                if n > 1:
                    k = min(max(bisect_right(t_list, now) - 1, 0), last)
                    h = max(now - t_list[k], 0.0)
                    u_buf[:] = [row[k] + s_row[k] * h for row, s_row in zip(u_rows, slope_rows, strict=True)]
                else:
                    u_buf[:] = [row[0] for row in u_rows]
                if set_real(comp, u_vr, nu, u_buf) > 1:
                    raise failed(f"setting the inputs at t = {now:.6g} s")

        enter, stop = ctypes.c_int(0), ctypes.c_int(0)  # fmi2Boolean outputs of fmi2CompletedIntegratorStep

        def completed_step() -> tuple[bool, bool]:
            """fmi2CompletedIntegratorStep: whether the FMU asks for an event now, or to terminate."""
            if fn["fmi2CompletedIntegratorStep"](comp, 1, ctypes.byref(enter), ctypes.byref(stop)) > 1:
                raise failed("fmi2CompletedIntegratorStep")
            return bool(enter.value), bool(stop.value)

        def event_iteration(when: str) -> tuple[bool, float | None]:
            """The FMU's event iteration; whether its states changed, and its next time event [s]."""
            changed = False
            for _ in range(ME_EVENT_ITERATIONS):
                needed, terminate, nominals, values, defined, next_time = inst.newDiscreteStates()
                changed = changed or bool(nominals) or bool(values)
                if terminate:
                    raise failed(f"the event iteration {when} (the FMU asked to terminate)")
                if not needed:
                    return changed, float(next_time) if defined else None
            raise failed(f"the event iteration {when} ({ME_EVENT_ITERATIONS} iterations)")

        try:
            inst.reset()
            inst.setupExperiment(startTime=float(start_time))
            inst.enterInitializationMode()
            if p_names and set_real(comp, p_vr, len(p_names), p_val) > 1:
                raise failed("setting the parameters")
            set_time(float(start_time))
            inst.exitInitializationMode()
            _, next_event = event_iteration("after initialisation")
            inst.enterContinuousTimeMode()
            solver = _cvode_solver()(
                nx=nx,
                nz=nz,
                get_x=lambda x, k: call("fmi2GetContinuousStates", x, k),
                set_x=lambda x, k: call("fmi2SetContinuousStates", x, k),
                get_dx=lambda dx, k: call("fmi2GetDerivatives", dx, k),
                get_z=lambda z, k: call("fmi2GetEventIndicators", z, k),
                # CVode's absolute tolerance is its relative one times this: ME_ATOL times each nominal
                get_nominals=lambda x, k: _scaled(fn["fmi2GetNominalsOfContinuousStates"](comp, x, k), x, k),
                set_time=set_time,
                input=_NoInput(),
                startTime=float(start_time),
                maxStep=float(np.min(np.diff(t))) if n > 1 else np.inf,
                relativeTolerance=ME_RTOL,
                maxNumSteps=ME_MAX_STEPS,
            )
            solver.bind(set_time, fn["fmi2SetContinuousStates"], fn["fmi2GetDerivatives"], fn["fmi2GetEventIndicators"])
            solver.comp, solver.failed = comp, failed
            now = float(start_time)
            out = np.empty((n, ny))
            self.events_ = 0
            for k in range(n):
                while now < t_list[k] and not math.isclose(now, t_list[k], rel_tol=1e-12, abs_tol=1e-15):
                    target = t_list[k] if next_event is None else min(t_list[k], next_event)
                    try:
                        state_event, _, now = solver.step(now, target)
                    except RuntimeError as exc:
                        said = solver.error_info[3] if solver.error_info else str(exc)
                        raise solver.failure or FmuSimulationError(
                            f"FMU {self.identifier}: the integration failed after t = {now:.6g} s: CVode: {said} "
                            "(a state that diverges, or dynamics far faster than the record's sampling: check the "
                            "parameters)"
                        ) from None
                    set_time(now)
                    step_event, terminate = completed_step() if self._completed_step else (False, False)
                    if terminate:
                        raise failed(f"the step to t = {now:.6g} s (the FMU asked to terminate)")
                    time_event = next_event is not None and math.isclose(now, next_event, rel_tol=1e-12)
                    if state_event or time_event or step_event:
                        self.events_ += 1
                        inst.enterEventMode()
                        changed, next_event = event_iteration(f"at t = {now:.6g} s")
                        inst.enterContinuousTimeMode()
                        if changed:
                            solver.reset(now)
                if now != t_list[k]:  # the first sample (at the start), or a step that ended within rounding
                    set_time(t_list[k])
                if get_real(comp, y_vr, ny, y_buf) > 1:
                    raise failed(f"reading the outputs at t = {t_list[k]:.6g} s")
                out[k] = y_buf
        except FMICallException:
            raise failed("an FMI call") from None
        if not np.all(np.isfinite(out)):
            bad = int(np.argmax(~np.all(np.isfinite(out), axis=1)))
            raise FmuSimulationError(f"FMU {self.identifier}: non-finite outputs from t = {t[bad]:.6g} s on")
        return out.T.copy()


class _NoInput:
    """FMPy's solver applies an ``input`` object in its root function; here :func:`set_time` sets the inputs."""

    def apply(self, time: float) -> None:
        """Nothing: the inputs were set with the time."""


def _scaled(status: int, x: Any, k: int) -> int:
    """The FMU's nominal state values in ``x`` scaled by ME_ATOL / ME_RTOL (1 where it has none)."""
    for i in range(k):
        nominal = abs(x[i]) if status <= 1 and math.isfinite(x[i]) and x[i] != 0.0 else 1.0
        x[i] = nominal * ME_ATOL / ME_RTOL
    return 0


@functools.cache
def _cvode_solver() -> type:
    """FMPy's CVode solver whose callbacks report a failure to CVode instead of dropping it.

    An exception raised in a ctypes callback is printed and lost, and CVode goes on with what the
    buffer held; this subclass keeps the first one (:attr:`failure`) and returns -1 (unrecoverable),
    so that :meth:`step` raises and the simulation raises the FMU's own message. Once bound
    (``bind``), its right-hand side and root functions call the FMU's C functions directly rather
    than through FMPy's wrappers, and the time and inputs only when the instant changes.
    """
    from fmpy.sundials import NV_DATA_S, CVodeSolver

    class _Solver(CVodeSolver):
        failure: Exception | None = None
        comp: Any = None
        failed: Any = None
        _fast: tuple[Any, ...] | None = None

        def bind(self, set_time: Any, set_x: Any, get_dx: Any, get_z: Any) -> None:
            """The right-hand side and root functions straight on the FMU's functions (not FMPy's wrappers)."""
            self._fast = (set_time, set_x, get_dx, get_z)

        def f(self, t: float, y: Any, ydot: Any, user_data: Any) -> int:
            try:
                if self._fast is None or self.discrete:
                    return int(super().f(t, y, ydot, user_data))
                set_time, set_x, get_dx, _ = self._fast
                set_time(t)
                if set_x(self.comp, NV_DATA_S(y), self.nx) > 1:
                    raise self.failed(f"fmi2SetContinuousStates at t = {t:.6g} s")
                if get_dx(self.comp, NV_DATA_S(ydot), self.nx) > 1:
                    raise self.failed(f"fmi2GetDerivatives at t = {t:.6g} s")
                return 0
            except Exception as exc:  # the FMU refused: CVode stops, the step raises
                self.failure = self.failure or exc
                return -1

        def g(self, t: float, y: Any, gout: Any, user_data: Any) -> int:
            try:
                if self._fast is None or self.discrete:
                    return int(super().g(t, y, gout, user_data))
                set_time, set_x, _, get_z = self._fast
                set_time(t)
                if set_x(self.comp, NV_DATA_S(y), self.nx) > 1:
                    raise self.failed(f"fmi2SetContinuousStates at t = {t:.6g} s")
                if get_z(self.comp, gout, self.nz) > 1:
                    raise self.failed(f"fmi2GetEventIndicators at t = {t:.6g} s")
                return 0
            except Exception as exc:
                self.failure = self.failure or exc
                return -1

    return _Solver
