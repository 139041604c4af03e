"""Model-exchange FMUs: the runner integrates an FMU's derivatives on the record's grid (issue 55).

The quarter car of ``engine/plants/fmu/examples/quarter_car`` offers both FMI 2.0 interfaces. Its
model-exchange form is checked against an independent reference: SciPy's exact first-order-hold
simulation (:func:`scipy.signal.lsim` with ``interp=True``: the input linear between samples, as the
runner gives it) of the linear quarter car, written here from the equations of motion. Then: the
plant interface runs it when its description says ``interface = "model-exchange"``; the tyre's
lift-off, an event indicator, is located by the solver and agrees with a fine-stepped reference; a
failure inside the solver reaches the caller; an FMU without that interface is refused with a
message; and an archive that offers only model exchange is accepted as a file.
"""

from __future__ import annotations

import io
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import solve_ivp

from engine.plants.fmu.archive import inspect_archive
from engine.plants.fmu.build import build_fmu
from engine.plants.fmu.description import load_description, parse_description
from engine.plants.fmu.plant import FmuPlant
from engine.plants.fmu.runner import FmuModel, FmuSimulationError

EXAMPLES = Path(__file__).resolve().parents[2] / "engine" / "plants" / "fmu" / "examples"
QUARTER_CAR = EXAMPLES / "quarter_car"
OUTPUTS = ["a_body", "x_susp", "a_wheel"]
#: Nominal parameters (the FMU's start values).
NOMINAL = {"m_s": 300.0, "m_u": 40.0, "k_s": 20000.0, "c_s": 1500.0, "k_t": 200000.0, "c_t": 50.0}


@pytest.fixture(scope="module")
def fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The quarter car built from its sources (both interfaces)."""
    return build_fmu(QUARTER_CAR, tmp_path_factory.mktemp("me_fmu"))


@pytest.fixture(scope="module")
def record() -> dict[str, np.ndarray]:
    """The example record's columns by name."""
    table = np.genfromtxt(QUARTER_CAR / "record.csv", delimiter=",", names=True)
    return {name: np.asarray(table[name]) for name in table.dtype.names}


def first_order_hold_reference(t: np.ndarray, z_r: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    """The linear quarter car's ``a_body, x_susp, a_wheel`` with the post linear between samples.

    States ``(z_s, v_s, z_u, v_u)``, input ``z_r``; the tyre's damper acts on the wheel's velocity
    (the model-exchange form has no input derivative, ``model.c``)::

        m_s dv_s/dt = F_s,  F_s = -k_s (z_s - z_u) - c_s (v_s - v_u),
        m_u dv_u/dt = -F_s + k_t (z_r - z_u) - c_t v_u.
    """
    m_s, m_u, k_s, c_s, k_t, c_t = (p[n] for n in ("m_s", "m_u", "k_s", "c_s", "k_t", "c_t"))
    a = np.array(
        [
            [0.0, 1.0, 0.0, 0.0],
            [-k_s / m_s, -c_s / m_s, k_s / m_s, c_s / m_s],
            [0.0, 0.0, 0.0, 1.0],
            [k_s / m_u, c_s / m_u, -(k_s + k_t) / m_u, -(c_s + c_t) / m_u],
        ]
    )
    b = np.array([[0.0], [0.0], [0.0], [k_t / m_u]])
    _, _, x = signal.lsim(signal.StateSpace(a, b, np.eye(4), np.zeros((4, 1))), U=z_r, T=t, interp=True)
    z_s, v_s, z_u, v_u = x.T
    f_s = -k_s * (z_s - z_u) - c_s * (v_s - v_u)
    return np.column_stack([f_s / m_s, z_s - z_u, (-f_s + k_t * (z_r - z_u) - c_t * v_u) / m_u])


def _rel_rms(y: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean((y - ref) ** 2, axis=0) / np.mean(ref**2, axis=0))


def test_model_exchange_agrees_with_scipy(fmu: Path, record: dict[str, np.ndarray]) -> None:
    """On the record's grid the integrated derivatives give SciPy's exact response within 1e-3 (tolerance 1e-6)."""
    t, z = record["t"], record["z_road"]
    y = FmuModel(fmu, interface="model-exchange").simulate(t, 0.0, {}, {"z_r": z}, OUTPUTS).T
    rel = _rel_rms(y, first_order_hold_reference(t, z, NOMINAL))
    assert np.all(rel < 1e-3), dict(zip(OUTPUTS, rel, strict=True))


def test_other_parameters_and_an_even_finer_reference(fmu: Path) -> None:
    """Other masses and stiffnesses on an uneven grid: the reference on a 0.02 ms grid, the FMU within 1e-3."""
    rng = np.random.default_rng(5)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5e-3, 4e-3, 400))])
    z = 0.01 * np.sin(2 * np.pi * 3.0 * t) * np.exp(-t)
    p = {"m_s": 450.0, "m_u": 55.0, "k_s": 35000.0, "c_s": 2500.0, "k_t": 280000.0, "c_t": 200.0}
    y = FmuModel(fmu, interface="model-exchange").simulate(t, 0.0, p, {"z_r": z}, OUTPUTS).T
    fine = np.linspace(0.0, t[-1], 40001)
    ref_fine = first_order_hold_reference(fine, np.interp(fine, t, z), p)  # the same linear post
    ref = np.column_stack([np.interp(t, fine, ref_fine[:, i]) for i in range(len(OUTPUTS))])
    assert np.all(_rel_rms(y, ref) < 1e-3)


def test_the_two_interfaces_agree_where_the_post_moves_slowly(fmu: Path) -> None:
    """A 2 Hz post on a 1 ms grid: the body's channels, held (co-simulation) or linear (model exchange), within 1 %.

    The wheel's acceleration is not compared: the held post's stairs (0.13 mm here) each push the
    wheel by k_t dz_r / m_u (0.6 m/s^2) at the instant, where the slow post's own wheel acceleration
    is of that size: the two interfaces answer two different inputs there.
    """
    t = np.arange(1001) * 1e-3
    z = 0.01 * np.sin(2 * np.pi * 2.0 * t)
    params = {"F_c": 30.0, "k3": 1e6}  # nonlinear terms too: the derivatives' friction and progressive spring
    cs = FmuModel(fmu).simulate(t, 0.0, params, {"z_r": z}, OUTPUTS).T
    me = FmuModel(fmu, interface="model-exchange").simulate(t, 0.0, params, {"z_r": z}, OUTPUTS).T
    rel = _rel_rms(me[:, :2], cs[:, :2])
    assert np.all(rel < 1e-2), rel


def test_the_plant_runs_the_interface_its_description_names(tmp_path: Path, record: dict[str, np.ndarray]) -> None:
    """``interface = "model-exchange"`` in plant.toml: the plant's simulation is the model-exchange one."""
    data = load_description(QUARTER_CAR / "plant.toml").model_dump()
    assert data["interface"] == "co-simulation"  # the default
    plant = FmuPlant(
        parse_description({**data, "interface": "model-exchange"}), QUARTER_CAR, build_dir=tmp_path, processes=1
    )
    assert plant.model.interface == "model-exchange" and plant.model.n_states == 4
    example = plant.example()
    y = plant.simulate(example, {})
    direct = plant.model.simulate(record["t"], 0.0, {}, {"z_r": record["z_road"]}, OUTPUTS)
    for i, name in enumerate(OUTPUTS):
        np.testing.assert_allclose(y[name], direct[i], rtol=0, atol=1e-12 * np.max(np.abs(direct[i])))


def test_an_interface_the_fmu_lacks_is_refused(tmp_path: Path) -> None:
    """The backlash drive offers co-simulation only: asking for model exchange names what it has."""
    drive = build_fmu(EXAMPLES / "backlash_drive", tmp_path)
    with pytest.raises(ValueError, match=r"model-exchange interface.*co-simulation.*set interface = 'co-simulation'"):
        FmuModel(drive, interface="model-exchange")
    with pytest.raises(ValueError, match="interface 'euler'"):
        FmuModel(drive, interface="euler")


def _rewritten(fmu: Path, edit: re.Pattern[str], to: str, into: Path) -> Path:
    """A copy of ``fmu`` whose modelDescription.xml has ``edit`` replaced by ``to``."""
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(into, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                text, n = edit.subn(to, data.decode("utf-8"))
                assert n == 1, edit.pattern
                data = text.encode("utf-8")
            dst.writestr(item, data)
    return into


def tyre_lift_reference(t: np.ndarray, z_r: np.ndarray, p: Mapping[str, float], f_static: float) -> np.ndarray:
    """``a_body, x_susp, a_wheel`` of the quarter car whose tyre cannot pull (tyre_lift = 1), post linear.

    The tyre's force on the wheel about its static load is ``max(0, f_static + f) - f_static`` with
    ``f = k_t (z_r - z_u) - c_t v_u``: a kink where the contact opens. :func:`scipy.integrate.solve_ivp`
    (RK45, steps of at most 20 us, tolerance 1e-10) steps across the kinks by small steps, with no
    event location: an independent reference of the FMU's located events.
    """
    m_s, m_u, k_s, c_s, k_t, c_t = (p[n] for n in ("m_s", "m_u", "k_s", "c_s", "k_t", "c_t"))

    def forces(time: float | np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z_s, v_s, z_u, v_u = x
        f_s = -k_s * (z_s - z_u) - c_s * (v_s - v_u)
        f_t = np.maximum(0.0, f_static + k_t * (np.interp(time, t, z_r) - z_u) - c_t * v_u) - f_static
        return f_s, f_t

    def rhs(time: float, x: np.ndarray) -> list[float]:
        f_s, f_t = forces(time, x)
        return [x[1], f_s / m_s, x[3], (-f_s + f_t) / m_u]

    sol = solve_ivp(rhs, (t[0], t[-1]), np.zeros(4), t_eval=t, max_step=2e-5, rtol=1e-10, atol=1e-12)
    f_s, f_t = forces(t, sol.y)
    return np.column_stack([f_s / m_s, sol.y[0] - sol.y[2], (-f_s + f_t) / m_u])


def test_state_events_are_located(fmu: Path, record: dict[str, np.ndarray]) -> None:
    """The tyre leaves the post (its contact force an event indicator): CVode stops at each lift-off and
    landing, and the response agrees with a fine-stepped reference within 1e-3; with the tyre allowed
    to pull there is no event."""
    t, z = record["t"][:1001], 3.0 * record["z_road"][:1001]  # 1 s of the record, tripled: the tyre lifts
    model = FmuModel(fmu, interface="model-exchange")
    assert model.n_event_indicators == 2
    force = model.simulate(t, 0.0, {"tyre_lift": 1.0}, {"z_r": z}, ["F_tyre"])[0]
    lifted = model.events_
    y = model.simulate(t, 0.0, {"tyre_lift": 1.0}, {"z_r": z}, OUTPUTS).T
    assert force.min() >= -1e-6 * force[0] and np.mean(force < 1e-6 * force[0]) > 0.01  # off the post at times
    assert lifted >= 2  # at least one lift-off and one landing, located
    rel = _rel_rms(y, tyre_lift_reference(t, z, NOMINAL, f_static=force[0]))
    assert np.all(rel < 1e-3), dict(zip(OUTPUTS, rel, strict=True))
    model.simulate(t, 0.0, {}, {"z_r": z}, OUTPUTS)
    assert model.events_ == 0  # the indicators are constants while the effects are off


def test_a_failure_inside_the_solver_is_raised_with_the_fmus_words(fmu: Path, record: dict[str, np.ndarray]) -> None:
    """A refusal inside CVode's right-hand side reaches the caller (not lost in the ctypes callback), and a
    state that diverges stops the integration with CVode's reason and what to check."""
    t, z = record["t"][:400], record["z_road"][:400].copy()
    model = FmuModel(fmu, interface="model-exchange")
    z[200] = np.nan  # the FMU refuses it when the solver sets the post between samples 199 and 200
    with pytest.raises(FmuSimulationError, match=r"setting the inputs at t = 0\.19\d* s failed: .*non-finite"):
        model.simulate(t, 0.0, {}, {"z_r": z}, OUTPUTS)
    with pytest.raises(FmuSimulationError, match=r"integration failed after t = .* CVode: .*check the parameters"):
        model.simulate(t, 0.0, {"k3": -1e9}, {"z_r": 5.0 * record["z_road"][:400]}, OUTPUTS)
    assert model.simulate(t, 0.0, {}, {"z_r": record["z_road"][:400]}, OUTPUTS).shape == (3, 400)  # and runs again


def test_an_archive_with_model_exchange_only_is_accepted(fmu: Path, tmp_path: Path) -> None:
    """The service's archive check accepts either interface and says which the FMU offers."""
    both = inspect_archive(fmu.read_bytes(), 10**9)
    assert both.interfaces == ("co-simulation", "model-exchange")
    only = _rewritten(fmu, re.compile(r"<CoSimulation\b(?:[^>]*/>|.*?</CoSimulation>)", re.S), "", tmp_path / "me.fmu")
    summary = inspect_archive(only.read_bytes(), 10**9)
    assert summary.interfaces == ("model-exchange",)
    assert FmuModel(only, interface="model-exchange").n_states == 4
    with pytest.raises(ValueError, match=r"with model-exchange.*set interface = 'model-exchange'"):
        FmuModel(only)
    data = io.BytesIO()
    with zipfile.ZipFile(only) as src, zipfile.ZipFile(data, "w") as dst:  # the same without its binaries
        for item in src.infolist():
            if not item.filename.startswith("binaries/"):
                dst.writestr(item, src.read(item))
    with pytest.raises(ValueError, match="no model-exchange binary for this machine"):
        inspect_archive(data.getvalue(), 10**9)
