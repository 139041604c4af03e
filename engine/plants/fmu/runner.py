"""Running an FMI 2.0 co-simulation FMU on a record's grid, through FMPy.

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
"""

from __future__ import annotations

import ctypes
import logging
import shutil
import tempfile
import threading
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["FmuModel", "FmuSimulationError", "FmuVariable"]

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
        The ``.fmu`` file (FMI 2.0 with a co-simulation interface).

    Raises
    ------
    ValueError
        Not an FMI 2.0 co-simulation FMU, or a file FMPy cannot read (the message says which).
    """

    def __init__(self, path: str | Path) -> None:
        from fmpy import extract, read_model_description

        self.path = Path(path)
        try:
            md = read_model_description(str(self.path))
        except Exception as e:  # FMPy raises several kinds for a bad archive or XML
            raise ValueError(f"{self.path}: not an FMU FMPy can read: {e}") from None
        if md.fmiVersion != "2.0" or md.coSimulation is None:
            raise ValueError(
                f"{self.path}: the plant needs an FMI 2.0 co-simulation FMU; this is FMI {md.fmiVersion}"
                f"{' without a co-simulation interface' if md.coSimulation is None else ''}"
            )
        self.model_description = md
        self.guid: str = md.guid
        self.identifier: str = md.coSimulation.modelIdentifier
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
        from fmpy.fmi2 import FMU2Slave

        with self._lock:
            name = f"{self.identifier}-{id(self):x}-{len(self._instances)}"
        messages: list[str] = []
        _MESSAGES[name] = messages
        self._names.append(name)
        callbacks = _callbacks()
        inst = FMU2Slave(
            guid=self.guid, unzipDirectory=self._unzipdir, modelIdentifier=self.identifier, instanceName=name
        )
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
            FMU input name -> one value per sample, held over the interval the sample starts.
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

        t = np.asarray(times, dtype=float)
        n = t.size
        inst, messages = self._instance()
        _route_messages()
        messages.clear()
        p_names = list(parameters)
        p_vr = (ctypes.c_uint * len(p_names))(*(self.variables[k].value_reference for k in p_names))
        p_val = (ctypes.c_double * len(p_names))(*(float(parameters[k]) for k in p_names))
        u_names = list(inputs)
        nu, ny = len(u_names), len(outputs)
        # one row of inputs per sample, as Python floats (a ctypes buffer is filled per sample: cheaper than a
        # pointer into a numpy row, 1.4 us against 7.5 us a call, measured)
        u_rows = np.column_stack([np.asarray(inputs[k], dtype=float) for k in u_names]).tolist() if nu else []
        u_vr = (ctypes.c_uint * nu)(*(self.variables[k].value_reference for k in u_names))
        u_buf = (ctypes.c_double * nu)()
        y_vr = (ctypes.c_uint * ny)(*(self.variables[k].value_reference for k in outputs))
        y_buf = (ctypes.c_double * ny)()
        out = np.empty((n, ny))
        comp = inst.component
        fn = inst._functions
        set_real, get_real, do_step = fn["fmi2SetReal"], fn["fmi2GetReal"], fn["fmi2DoStep"]

        def failed(what: str) -> FmuSimulationError:
            said = "; ".join(m for m in messages if m) or "the FMU gave no message"
            return FmuSimulationError(f"FMU {self.identifier}: {what} failed: {said}")

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
