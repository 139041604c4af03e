"""The quarter-car FMU (engine/plants/fmu/examples/quarter_car) against independent references.

The FMU is built from its C sources into pytest's ``tmp_path`` and driven through FMPy's FMI 2.0
co-simulation interface. References: SciPy's exact zero-order-hold simulation
(:func:`scipy.signal.lsim`) of the linear quarter car, written here from the equations of motion;
the static gain of a gravity-free quarter car on a post (body and wheel follow the post); each
effect's departure from the linear response; the FMU's refusal of an impossible parameter.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np
import pytest
from scipy import linalg, signal
from scipy.integrate import solve_ivp

from engine.plants.fmu.build import build_fmu

EXAMPLE = Path(__file__).resolve().parents[2] / "engine" / "plants" / "fmu" / "examples" / "quarter_car"
OUTPUTS = ("a_body", "x_susp", "a_wheel")
#: Nominal parameters (the FMU's start values): a passenger car corner.
NOMINAL = {"m_s": 300.0, "m_u": 40.0, "k_s": 20000.0, "c_s": 1500.0, "k_t": 200000.0, "c_t": 50.0}


@pytest.fixture(scope="module")
def fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The FMU built from the example's sources."""
    return build_fmu(EXAMPLE, tmp_path_factory.mktemp("quarter_car_fmu"))


@pytest.fixture(scope="module")
def record() -> dict[str, np.ndarray]:
    """The example record's columns by name."""
    table = np.genfromtxt(EXAMPLE / "record.csv", delimiter=",", names=True)
    return {name: np.asarray(table[name]) for name in table.dtype.names}


#: ctypes callbacks that FMPy's logger proxy may point to: FMPy's proxy (fmpy.logging.addLoggerProxy)
#: formats the FMU's variadic messages and hands them to ONE process-wide Python logger, the last one
#: registered, so every logger registered here is kept alive for the life of the process.
_KEEP_ALIVE: list[object] = []


def _callbacks(logger: Callable[[object, bytes, int, bytes, bytes], None]) -> object:
    """FMI 2.0 callbacks with ``logger`` (made the proxy's target) and FMPy's memory functions."""
    from fmpy import calloc, free
    from fmpy.fmi2 import (
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
    )
    from fmpy.logging import addLoggerProxy

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    addLoggerProxy(ctypes.byref(callbacks))
    _KEEP_ALIVE.append(callbacks)
    return callbacks


class _Log:
    """The FMU's log messages, kept in a list."""

    def __init__(self) -> None:
        self.messages: list[str] = []

        def logger(component: object, instance: bytes, status: int, category: bytes, message: bytes) -> None:
            self.messages.append(message.decode("utf-8"))

        self.callbacks = _callbacks(logger)


@pytest.fixture(scope="module")
def log() -> Iterator[_Log]:
    """The module's FMU log; afterwards FMPy's proxy prints messages again (its default)."""
    from fmpy.fmi1 import printLogMessage

    yield _Log()
    _callbacks(printLogMessage)


class _Slave:
    """One instance of the FMU, driven step by step."""

    def __init__(self, fmu: Path, log: _Log) -> None:
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        description = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in description.modelVariables}
        self.log = log
        self.slave = FMU2Slave(
            guid=description.guid,
            unzipDirectory=extract(str(fmu)),
            modelIdentifier=description.coSimulation.modelIdentifier,
            instanceName="quarter_car_test",
        )
        self.slave.instantiate(callbacks=self.log.callbacks)

    def run(
        self,
        t: np.ndarray,
        z_road: np.ndarray,
        parameters: Mapping[str, float] | None = None,
        outputs: Sequence[str] = OUTPUTS,
    ) -> np.ndarray:
        """Outputs at ``t`` with ``z_road[k]`` held from ``t[k]`` to ``t[k + 1]``, shape ``(len(t), len(outputs))``."""
        s = self.slave
        self.log.messages.clear()
        s.reset()
        s.setupExperiment(startTime=float(t[0]))
        s.enterInitializationMode()
        params = dict(parameters or {})
        if params:
            s.setReal([self.vr[name] for name in params], [float(v) for v in params.values()])
        s.setReal([self.vr["z_r"]], [float(z_road[0])])
        s.exitInitializationMode()
        out_vr = [self.vr[name] for name in outputs]
        z_vr = [self.vr["z_r"]]
        y = np.empty((len(t), len(out_vr)))
        y[0] = s.getReal(out_vr)
        for k in range(len(t) - 1):
            s.setReal(z_vr, [float(z_road[k])])
            s.doStep(currentCommunicationPoint=float(t[k]), communicationStepSize=float(t[k + 1] - t[k]))
            y[k + 1] = s.getReal(out_vr)
        return y

    def close(self) -> None:
        self.slave.freeInstance()


@pytest.fixture(scope="module")
def slave(fmu: Path, log: _Log) -> Iterator[_Slave]:
    """One FMU instance for the module (reset before each run)."""
    s = _Slave(fmu, log)
    yield s
    s.close()


def linear_reference(t: np.ndarray, z_road: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    """The linear quarter car's outputs ``a_body, x_susp, a_wheel`` at ``t``, by SciPy's exact ZOH simulation.

    The post's displacement is the staircase ``z_road[k]`` on ``[t[k], t[k + 1])``; the tyre damper's
    term ``c_t dz_r/dt`` (impulses at the stairs) is kept exact by the state ``w = m_u v_u - c_t z_r``,
    continuous across the stairs. States ``(z_s, v_s, z_u, w)``, input ``z_r``:

        m_s dv_s/dt = F_s,  F_s = -k_s (z_s - z_u) - c_s (v_s - v_u),
        dw/dt = -F_s + k_t (z_r - z_u) - c_t v_u,  v_u = (w + c_t z_r) / m_u.

    The outputs at ``t[k]`` (``k >= 1``) are taken with the input held over the step that ends there
    (``z_road[k - 1]``), as the FMU reports them.
    """
    m_s, m_u, k_s, c_s, k_t, c_t = (p[n] for n in ("m_s", "m_u", "k_s", "c_s", "k_t", "c_t"))
    # v_u = (w + c_t z_r) / m_u = row_vu @ x + d_vu z_r
    row_vu = np.array([0.0, 0.0, 0.0, 1.0 / m_u])
    d_vu = c_t / m_u
    # F_s = row_fs @ x + d_fs z_r
    row_fs = np.array([-k_s, -c_s, k_s, 0.0]) + c_s * row_vu
    d_fs = c_s * d_vu
    a = np.vstack(
        [
            [0.0, 1.0, 0.0, 0.0],
            row_fs / m_s,
            row_vu,
            -row_fs + np.array([0.0, 0.0, -k_t, 0.0]) - c_t * row_vu,
        ]
    )
    b = np.array([[0.0], [d_fs / m_s], [d_vu], [-d_fs + k_t - c_t * d_vu]])
    dt = np.diff(t)
    if np.allclose(dt, dt[0], rtol=1e-9, atol=0.0):
        system = signal.StateSpace(a, b, np.eye(4), np.zeros((4, 1)))
        _, _, x = signal.lsim(system, U=z_road, T=t, interp=False)
    else:  # lsim wants an even grid: the same exact ZOH step, exp([[A, B], [0, 0]] dt), per interval
        x = np.zeros((len(t), 4))
        aug = np.zeros((5, 5))
        aug[:4, :4], aug[:4, 4:] = a, b
        for k, h in enumerate(dt):
            phi = linalg.expm(aug * h)
            x[k + 1] = phi[:4, :4] @ x[k] + phi[:4, 4] * z_road[k]
    u_held = np.concatenate([z_road[:1], z_road[:-1]])
    z_s, v_s, z_u, w = x.T
    v_u = (w + c_t * u_held) / m_u
    f_s = -k_s * (z_s - z_u) - c_s * (v_s - v_u)
    a_body = f_s / m_s
    a_wheel = (-f_s + k_t * (u_held - z_u) - c_t * v_u) / m_u
    return np.column_stack([a_body, z_s - z_u, a_wheel])


def _rms(y: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(y**2, axis=0))


def test_linear_agrees_with_scipy(slave: _Slave, record: dict[str, np.ndarray]) -> None:
    """At neutral effects, the FMU's response to the record's input is SciPy's linear quarter car to 1e-3."""
    t, z = record["t"], record["z_road"]
    y = slave.run(t, z)
    ref = linear_reference(t, z, NOMINAL)
    rel_rms = _rms(y - ref) / _rms(ref)
    rel_max = np.max(np.abs(y - ref), axis=0) / np.max(np.abs(ref), axis=0)
    assert np.all(rel_rms < 1e-3), dict(zip(OUTPUTS, rel_rms, strict=True))
    assert np.all(rel_max < 1e-3), dict(zip(OUTPUTS, rel_max, strict=True))
    # the record is this response plus its sensor noise (record.md: 0.02 m/s^2, 50 µm, 0.2 m/s^2)
    noise = _rms(np.column_stack([record[name] for name in OUTPUTS]) - ref)
    assert np.allclose(noise, [0.02, 5e-5, 0.2], rtol=0.1), noise


def test_other_parameters_and_steps_agree(slave: _Slave) -> None:
    """Other masses and stiffnesses and a coarser, uneven communication grid agree with the reference too."""
    rng = np.random.default_rng(5)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5e-3, 4e-3, 400))])
    z = 0.01 * np.sin(2 * np.pi * 3.0 * t) * np.exp(-t)
    p = {"m_s": 450.0, "m_u": 55.0, "k_s": 35000.0, "c_s": 2500.0, "k_t": 280000.0, "c_t": 200.0}
    y = slave.run(t, z, p)
    ref = linear_reference(t, z, p)
    assert np.all(_rms(y - ref) / _rms(ref) < 1e-3)


def test_staircase_converges_to_the_smooth_post(slave: _Slave) -> None:
    """On a fine grid the held post gives the continuous quarter car's response, tyre damping's c_t dz_r/dt included.

    Reference: :func:`scipy.integrate.solve_ivp` of the equations of motion with the smooth post
    motion and its derivative. A stiff tyre damper (c_t = 300 N s/m) at the wheel hop makes the
    c_t dz_r/dt term about 10 % of the tyre force, so a model that dropped it would fail.
    """
    p = {**NOMINAL, "c_t": 300.0}
    omega, amp = 2 * np.pi * 11.0, 0.005  # [rad/s], [m]
    t = np.arange(5001) * 1e-4  # 0.5 s at 0.1 ms

    def rhs(time: float, x: np.ndarray) -> list[float]:
        z_s, v_s, z_u, v_u = x
        z_r, dz_r = amp * np.sin(omega * time), amp * omega * np.cos(omega * time)
        f_s = -p["k_s"] * (z_s - z_u) - p["c_s"] * (v_s - v_u)
        f_t = p["k_t"] * (z_r - z_u) + p["c_t"] * (dz_r - v_u)
        return [v_s, f_s / p["m_s"], v_u, (-f_s + f_t) / p["m_u"]]

    sol = solve_ivp(rhs, (0.0, t[-1]), [0.0, 0.0, 0.0, 0.0], t_eval=t, rtol=1e-9, atol=1e-12)
    y = slave.run(t, amp * np.sin(omega * t), p, outputs=("z_body", "v_body", "z_wheel", "v_wheel"))
    rel = _rms(y - sol.y.T) / _rms(sol.y.T)
    assert np.all(rel < 1e-2), rel


def test_unknown_inputs_static(slave: _Slave) -> None:
    """A constant F_body lifts the body by F (1/k_s + 1/k_t); a constant F_wheel lifts both by F / k_t."""
    t = np.arange(401) * 0.01  # 4 s at 10 ms: the transient settles
    names = ("z_body", "z_wheel", "x_susp")
    force = 100.0  # [N]
    y = slave.run(t, np.zeros_like(t), {"F_body": force}, outputs=names)[-1]
    k_s, k_t = NOMINAL["k_s"], NOMINAL["k_t"]
    assert y == pytest.approx([force / k_s + force / k_t, force / k_t, force / k_s], rel=1e-3)
    y = slave.run(t, np.zeros_like(t), {"F_wheel": force}, outputs=names)[-1]
    assert y[:2] == pytest.approx([force / k_t, force / k_t], rel=1e-3)
    assert abs(y[2]) < 1e-6  # 0.02 % of the body's lift: the transient has settled


def test_static_gain(slave: _Slave) -> None:
    """A slow ramp of the post to 10 mm, then a hold: body and wheel follow it, the suspension returns to rest."""
    t = np.arange(501) * 0.01  # 5 s at 10 ms
    z = 0.005 * (1.0 - np.cos(np.pi * np.minimum(t / 3.0, 1.0)))  # a smooth 10 mm ramp in 3 s, then held
    names = ("z_body", "z_wheel", "x_susp", "a_body", "a_wheel")
    y = slave.run(t, z, outputs=names)
    z_body, z_wheel, x_susp, a_body, a_wheel = y.T
    held = np.concatenate([z[:1], z[:-1]])  # the post's position over the step that ends at t[k]
    # during the ramp body and wheel follow the post: the body within 3 % of the travel, the wheel
    # within 0.3 % (the lags of the post's acceleration over the body and the wheel-hop modes)
    assert np.max(np.abs(z_body - held)) < 3e-4
    assert np.max(np.abs(z_wheel - held)) < 3e-5
    # after 2 s of hold: static gain 1 (gravity-free: no sag), suspension at rest
    assert z_body[-1] == pytest.approx(0.01, rel=1e-3)
    assert z_wheel[-1] == pytest.approx(0.01, rel=1e-3)
    assert abs(x_susp[-1]) < 1e-5
    assert abs(a_body[-1]) < 1e-3
    assert abs(a_wheel[-1]) < 1e-3


#: Each effect away from neutral (plausible values) and the input scale that shows it.
EFFECTS: dict[str, tuple[dict[str, float], float]] = {
    "F_c": ({"F_c": 50.0}, 1.0),
    "k3": ({"k3": 2e6}, 1.0),
    "damper_asymmetry": ({"damper_asymmetry": 1.0}, 1.0),
    "k_bump": ({"k_bump": 1e5, "bump_stop_gap": 0.01}, 1.0),
    "bump_stop_gap": ({"k_bump": 1e5, "bump_stop_gap": 0.005}, 1.0),
    "tyre_lift": ({"tyre_lift": 1.0}, 3.0),
    "m_extra": ({"m_extra": 30.0}, 1.0),
}


@pytest.mark.parametrize("effect", list(EFFECTS))
def test_each_effect_changes_an_output(slave: _Slave, record: dict[str, np.ndarray], effect: str) -> None:
    """Each effect parameter away from neutral changes an output by more than 1 % of its RMS."""
    params, scale = EFFECTS[effect]
    t, z = record["t"], scale * record["z_road"]
    base = {"k_bump": 1e5, "bump_stop_gap": 0.01} if effect == "bump_stop_gap" else {}
    y0 = slave.run(t, z, base)
    y = slave.run(t, z, params)
    change = np.max(np.abs(y - y0), axis=0) / _rms(y0)
    assert np.max(change) > 0.01, dict(zip(OUTPUTS, change, strict=True))


def test_tyre_lift_loses_contact(slave: _Slave, record: dict[str, np.ndarray]) -> None:
    """With tyre_lift the contact force never pulls; without it, the tripled rig input makes it pull."""
    t, z = record["t"], 3.0 * record["z_road"]
    f_free = slave.run(t, z, outputs=("F_tyre",))[:, 0]
    f_lift = slave.run(t, z, {"tyre_lift": 1.0}, outputs=("F_tyre",))[:, 0]
    assert f_free.min() < 0.0
    assert f_lift.min() >= 0.0


@pytest.mark.parametrize(("name", "value"), [("m_s", 0.0), ("m_s", -300.0)])
def test_impossible_parameter_fails_initialisation(slave: _Slave, name: str, value: float) -> None:
    """A body mass <= 0 makes fmi2ExitInitializationMode fail, with a message naming it."""
    from fmpy.fmi1 import FMICallException

    with pytest.raises(FMICallException, match="fmi2ExitInitializationMode"):
        slave.run(np.array([0.0, 1e-3]), np.zeros(2), {name: value})
    assert any("m_s" in message and "positive" in message for message in slave.log.messages), slave.log.messages


def test_diverging_state_fails_the_step(slave: _Slave, record: dict[str, np.ndarray]) -> None:
    """A degressive spring without bound (k3 < 0) under the bump diverges: the step fails, with a message."""
    from fmpy.fmi1 import FMICallException

    t, z = record["t"][:400], 5.0 * record["z_road"][:400]
    with pytest.raises(FMICallException):
        slave.run(t, z, {"k3": -1e9})
    assert any("non-finite state" in message for message in slave.log.messages), slave.log.messages
