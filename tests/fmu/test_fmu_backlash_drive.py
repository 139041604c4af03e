"""The example FMU ``engine/plants/fmu/examples/backlash_drive``: MODEL.md's plant as a C source FMU.

The FMU (FMI 2.0 co-simulation, written in C against ``engine/plants/fmu/c/model.h``) is built with
:func:`engine.plants.fmu.build.build_fmu`, run with FMPy and compared with the native simulator
(:func:`engine.simulation.simulator.simulate`) at points of MODEL.md's grids: the event t_e within
1 us and every channel within 0.5 % of its peak-to-peak value at the native record's sample
instants (MODEL.md section 4).

The FMU's record is taken with two runs of one instance (:func:`fmu_record`). Run 1 steps to the
native record's instants before the event, then in steps of :data:`FINE_STEP` until the FMU reports
its event t_e. Run 2 (after ``fmi2Reset``) repeats run 1's communication steps exactly (so the same
path, bit for bit) up to the start of the step that held the event, steps to t_e itself (so that
sample 48 is the FMU's own t_e, where MODEL.md puts it: with the motor off), and then to the native
instants after the event. Every sample but sample 48 is thus at the native record's instant, and
sample 48 at the FMU's own event, within 1 us of it.
"""

from __future__ import annotations

import ctypes
import math
import shutil
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.logging import addLoggerProxy

from engine.constants import CHANNELS, EVENT_INDEX, OMEGA_B
from engine.plants.fmu.build import build_fmu
from engine.simulation.parameters import PlantParameters
from engine.simulation.simulator import simulate

SOURCE_DIR = Path(__file__).resolve().parents[2] / "engine" / "plants" / "fmu" / "examples" / "backlash_drive"

#: Communication step [s] of run 1 from the last sample before the event until the event: short
#: enough that the step holding the event holds no other change of the clutch's mode (the contact's
#: clip precedes the re-entry by about d12 / (k12 Omega_b) = 14 us).
FINE_STEP = 1e-6

#: Points (K [m], J1 [kg m^2], c) of MODEL.md's grids compared with the native simulator.
POINTS = [
    (0.0025, 0.7612, 0.8),
    (0.005, 0.87, 1.0),
    (0.0075, 0.8917, 1.25),
    (0.01, 0.9135, 1.4),
]


class Fmu:
    """One instance of the FMU, run by communication steps (FMPy's ``FMU2Slave``).

    Parameters
    ----------
    unzipped : Path
        The FMU's extracted folder (several instances may share one).
    """

    def __init__(self, unzipped: Path) -> None:
        self.description = read_model_description(str(unzipped))
        self.vr = {v.name: v.valueReference for v in self.description.modelVariables}
        self.outputs = [v.name for v in self.description.modelVariables if v.causality == "output"]
        self.slave = FMU2Slave(
            guid=self.description.guid,
            unzipDirectory=str(unzipped),
            modelIdentifier=self.description.coSimulation.modelIdentifier,
            instanceName="backlash_drive",
        )
        self.messages: list[str] = []  # what the FMU logged, formatted
        self._logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = self._logger
        self._callbacks.allocateMemory = defaultCallbacks.allocateMemory
        self._callbacks.freeMemory = defaultCallbacks.freeMemory
        addLoggerProxy(ctypes.byref(self._callbacks))
        self.slave.instantiate(callbacks=self._callbacks)
        self.t = 0.0

    def _log(self, env: object, name: object, status: int, category: object, message: object) -> None:
        self.messages.append(message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message))

    def start(self, values: dict[str, float]) -> dict[str, float]:
        """Reset the instance, set ``values`` (parameters and inputs by name), initialise at t = 0.

        Returns
        -------
        dict
            The outputs at t = 0.
        """
        # FMPy's formatting proxy hands every FMU's message to one process-wide Python logger, the
        # last one it was given (the runner gives it its own): this instance's again
        addLoggerProxy(ctypes.byref(self._callbacks))
        self.messages.clear()
        self.slave.reset()
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.set(values)
        self.slave.exitInitializationMode()
        self.t = 0.0
        return self.read()

    def set(self, values: dict[str, float]) -> None:
        """Set reals by name."""
        if values:
            self.slave.setReal([self.vr[n] for n in values], list(values.values()))

    def read(self) -> dict[str, float]:
        """Every output by name at the current time."""
        return dict(zip(self.outputs, self.slave.getReal([self.vr[n] for n in self.outputs]), strict=True))

    def step_to(self, t_next: float) -> dict[str, float]:
        """One communication step from the current time to ``t_next`` [s]; the outputs there."""
        self.slave.doStep(currentCommunicationPoint=self.t, communicationStepSize=t_next - self.t)
        self.t = t_next
        return self.read()

    def close(self) -> None:
        """Terminate and free the instance."""
        self.slave.terminate()
        self.slave.freeInstance()


@pytest.fixture(scope="module")
def fmu_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example built from its sources into a temporary folder (skips without a C compiler)."""
    if not any(shutil.which(cc) for cc in ("cc", "gcc", "clang")):
        pytest.skip("building the example FMU needs a C compiler on the PATH")
    return build_fmu(SOURCE_DIR, tmp_path_factory.mktemp("fmu_build"))


@pytest.fixture(scope="module")
def unzipped(fmu_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built FMU, extracted."""
    return Path(extract(str(fmu_path), unzipdir=str(tmp_path_factory.mktemp("fmu_unzip"))))


@pytest.fixture(scope="module")
def fmu(unzipped: Path) -> Iterator[Fmu]:
    """One instance of the FMU, reused (reset) by every test of the module."""
    instance = Fmu(unzipped)
    yield instance
    instance.close()


def fmu_record(fmu: Fmu, values: dict[str, float], t_native: np.ndarray) -> tuple[np.ndarray, float]:
    """The FMU's record on the native record's instants (sample 48 at the FMU's own event).

    Parameters
    ----------
    fmu : Fmu
        The instance (reset by this function).
    values : dict
        Parameters by name.
    t_native : ndarray
        The native record's sample instants since switch-on [s], sample 48 at the native t_e.

    Returns
    -------
    channels : ndarray, shape (5, n_samples)
        a1, m_el, omega1, a2, v2 (MODEL.md's order).
    t_event : float
        The FMU's event [s] (the instant of sample 48).
    """
    e = EVENT_INDEX
    # run 1: the pre-event instants, then fine steps until the event
    fmu.start(values)
    steps: list[float] = []
    rows: list[dict[str, float]] = []
    for tk in t_native[:e]:
        steps.append(float(tk))
        rows.append(fmu.step_to(float(tk)))
        assert rows[-1]["motor_on"] == 1.0, "the FMU's event came before the native record's sample 47"
    t_limit = float(t_native[e]) + 1e-4
    out = rows[-1]
    while out["motor_on"] == 1.0:
        assert fmu.t < t_limit, "the FMU's event came more than 0.1 ms after the native event"
        t_from = fmu.t
        steps.append(t_from + FINE_STEP)
        out = fmu.step_to(steps[-1])
    t_event = out["t_event"]
    steps[-1] = t_event  # the step that held the event, cut at the event
    # run 2: run 1's steps again (the same path), ending at the event, then the native instants after it
    fmu.start(values)
    for t_next in steps:
        out = fmu.step_to(t_next)
    assert out["motor_on"] == 0.0, "run 2 repeating run 1's steps must be past the event at run 1's t_e"
    assert abs(out["t_event"] - t_event) < 1e-11
    rows.append(out)
    for tk in t_native[e + 1 :]:
        rows.append(fmu.step_to(float(tk)))
    channels = np.array([[row[name] for row in rows] for name in CHANNELS])
    return channels, t_event


@pytest.mark.parametrize(("K", "J1", "c"), POINTS)
def test_fmu_matches_native_simulator(fmu: Fmu, K: float, J1: float, c: float) -> None:
    """MODEL.md section 4 between the FMU and the native simulator: t_e within 1 us, channels within 0.5 %."""
    native = simulate(PlantParameters(K=K, J1=J1, c=c))
    assert native.event_time is not None
    t_native = native.event_time + native.time
    channels, t_event = fmu_record(fmu, {"K": K, "J1": J1, "c": c}, t_native)
    assert abs(t_event - native.event_time) < 1e-6
    for i, name in enumerate(CHANNELS):
        ref = native.channels[name]
        err = np.max(np.abs(channels[i] - ref)) / np.ptp(ref)
        assert err < 0.005, f"{name}: {100 * err:.3f} % of peak-to-peak at K={K}, J1={J1}, c={c}"
    assert channels[CHANNELS.index("m_el"), EVENT_INDEX] == 0.0  # sample 48: the motor is off


def test_start_values_match_the_description(fmu: Fmu) -> None:
    """Every parameter and input reads back its description's start value (value references in step)."""
    fmu.start({})
    for v in fmu.description.modelVariables:
        if v.causality in ("parameter", "input"):
            (got,) = fmu.slave.getReal([v.valueReference])
            assert got == float(v.start), v.name
    assert [v.valueReference for v in fmu.description.modelVariables] == list(
        range(len(fmu.description.modelVariables))
    )


def test_load_disturbance_changes_a2(fmu: Fmu) -> None:
    """d_load acts on the mass: a2 at t = 0 is r Omega_b d_load / T3 exactly, and the mass then moves."""
    d_load, r, T3 = 0.5, 0.1, 0.30  # d_load above the absorber's c1 (0.2 pu), so the mass moves
    instants = (0.005, 0.01, 0.015)
    base = fmu.start({})
    assert base["a2"] == 0.0
    base_later = [fmu.step_to(t)["a2"] for t in instants]
    pushed = fmu.start({"d_load": d_load})
    assert math.isclose(pushed["a2"], r * OMEGA_B * d_load / T3, rel_tol=1e-12)
    pushed_later = [fmu.step_to(t)["a2"] for t in instants]
    assert all(abs(b) < 1e-3 for b in base_later)  # without it the mass is still at rest
    assert all(p > 1.0 for p in pushed_later)  # with it the mass accelerates [m/s^2]


def test_motor_coulomb_friction_changes_omega1(fmu: Fmu) -> None:
    """tau_C1 brakes the motor: omega1 is lower than without it, before the clutch's first contact."""
    instants = (0.006, 0.012, 0.018)
    fmu.start({})
    base = [fmu.step_to(t)["omega1"] for t in instants]
    fmu.start({"tau_C1": 0.1})
    braked = [fmu.step_to(t)["omega1"] for t in instants]
    assert all(b - w > 0.01 for w, b in zip(braked, base, strict=True))  # [rad/s]


def test_no_event_is_an_error_that_says_so(fmu: Fmu) -> None:
    """With no supply the clutch never closes: the step that passes 1 s of simulated time fails, saying why."""
    fmu.start({"u": 0.0})
    with pytest.raises(FMICallException, match="fmi2DoStep"):
        for k in range(1, 12):
            fmu.step_to(0.1 * k)
    assert math.isclose(fmu.t, 0.9)  # the steps to 0.1 .. 0.9 s passed, the one to 1.0 s failed
    assert any("no backlash event" in m for m in fmu.messages)  # the FMU's log


def test_instances_are_independent_across_threads(fmu: Fmu, unzipped: Path) -> None:
    """Two instances stepped at once on two threads give each the record it gives alone (no shared state)."""
    cases = [{"K": 0.0025, "J1": 0.7612}, {"K": 0.01, "c": 1.4, "d_wheel": 0.02}]
    instants = np.arange(1, 501) * 1e-4  # 0 to 50 ms, past both events [s]

    def run(instance: Fmu, values: dict[str, float]) -> np.ndarray:
        instance.start(values)
        return np.array([list(instance.step_to(float(t)).values()) for t in instants])

    alone = [run(fmu, values) for values in cases]
    instances = [Fmu(unzipped), Fmu(unzipped)]
    try:
        with ThreadPoolExecutor(max_workers=2) as pool:
            together = list(pool.map(run, instances, cases))
    finally:
        for instance in instances:
            instance.close()
    for a, b in zip(alone, together, strict=True):
        np.testing.assert_array_equal(a, b)
    i_event = fmu.outputs.index("t_event")
    events = [a[-1, i_event] for a in alone]
    assert min(events) > 0.0 and events[0] != events[1]  # both had their event, each its own
