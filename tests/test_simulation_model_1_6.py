"""Model 1.6: what the fourth sealed family SEALED4 alone has (docs/model-changes.md, version 1.6).

Simulation only. SEALED4 is kept for scoring: nothing here diagnoses, calibrates, locates or
validates a record of these effects.

The checks model 1.6 shares with 1.1 to 1.5 run for its effects from the table of
``tests/test_simulation_model_versions.py``: every new term exactly neutral at zero (also inside
the kernel's extended path, ``P_EXTENDED``, on top of a held-back effect and of every effect of each
earlier family), the kernel against the independent scipy reference for every effect at its upper
bound and in the combinations where two terms meet, each effect visible at 40 dB at half its upper
bound, the event at the upper bound across the plausible box, the family disjoint from the catalogue
and every earlier family, one effect per locus, registered as the family ``sealed4``
(``backlash validate --held-back sealed4``). Here, each term at the state, against its definition
(the kernel's right-hand side with and without it), and the current sensor on the record:

* the late pole keeps phase c's current at zero until it closes, leaves the line voltage's axis to the
  supply, and the integrator's steps end just before and just after its closing instant;
* the bypassed turns give the alpha axis its own inductances and resistance, leave the beta axis, and
  m_el is the torque on the rotor;
* the rotor's rub is v |psi_s|^2 against the motor's motion while the motor is on, none after;
* the clutch seal's drag acts between J1 and J2 inside the zone and in contact;
* the gear's loss is v |m_s| against the wheel's motion;
* the guides' binding grows with the load's travel, v at THETA_BIND;
* the current sensor's error is in m_el only, before the event only;
* bench/family_visibility.py prints the rule's table of docs/model-changes.md.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from bench_scripts import load_bench
from kernel_terms import NOMINAL, STATE, vectors
from kernel_terms import rhs as _rhs
from kernel_terms import with_state as _with

from engine.constants import CHANNELS, EVENT_INDEX, T_POLE_GUARD, THETA_BIND, W_SMOOTH
from engine.simulation import SEALED4, Case, SensorParameters, simulate_batch
from engine.simulation import _kernel as kern
from engine.simulation.simulator import parameter_vector

M_EL = CHANNELS.index("m_el")
#: The axis of phase c, e^(j 4 pi / 3).
E_C = (-0.5, -0.5 * math.sqrt(3.0))


def _currents(y: tuple[float, ...]) -> tuple[complex, complex]:
    """(i_s, i_r) [pu] of the fluxes in y, nominal reactances."""
    x_s, x_r, x_m = NOMINAL.x_s, NOMINAL.x_r, NOMINAL.x_m
    det = x_s * x_r - x_m**2
    psi_s, psi_r = complex(y[0], y[1]), complex(y[2], y[3])
    return (x_r * psi_s - x_m * psi_r) / det, (x_s * psi_r - x_m * psi_s) / det


def test_the_late_pole_keeps_phase_c_s_current_at_zero_until_it_closes() -> None:
    v = SEALED4["supply_late_pole"].bounds[1]
    P0, P1 = vectors(SEALED4, "supply_late_pole", v)
    (d0, c0), (d1, c1) = _rhs(P0, t=0.5 * v), _rhs(P1, t=0.5 * v)
    x_r, x_m = NOMINAL.x_r, NOMINAL.x_m
    # d i_c / dt = 0: x_r dpsi_s . e_c = x_m dpsi_r . e_c
    along_s = d1[0] * E_C[0] + d1[1] * E_C[1]
    along_r = d1[2] * E_C[0] + d1[3] * E_C[1]
    assert x_r * along_s == pytest.approx(x_m * along_r, rel=1e-9, abs=1e-9)
    # the line voltage's axis (perpendicular to e_c) is the supply's, the rotor unchanged
    line = (-E_C[1], E_C[0])
    assert d1[0] * line[0] + d1[1] * line[1] == pytest.approx(d0[0] * line[0] + d0[1] * line[1], rel=1e-12)
    assert d1[2:].tobytes() == d0[2:].tobytes() and c1.tobytes() == c0.tobytes()
    for t in (v, 1.5 * v):  # closed from its instant on: the plant's own equations
        assert _rhs(P1, t=t)[0].tobytes() == _rhs(P0, t=t)[0].tobytes()


def test_the_integrator_s_steps_end_just_before_and_just_after_the_late_pole_closes() -> None:
    v = SEALED4["supply_late_pole"].bounds[1]
    _, P1 = vectors(SEALED4, "supply_late_pole", v)
    h = 1e-4
    t = v - 0.5 * h
    assert kern.step_to_knot(t, h, P1) == pytest.approx(v - T_POLE_GUARD - t, rel=1e-9)
    t = v - T_POLE_GUARD
    assert kern.step_to_knot(t, h, P1) == pytest.approx(2.0 * T_POLE_GUARD, rel=1e-6)
    assert kern.step_to_knot(v + T_POLE_GUARD, h, P1) == h
    assert kern.step_to_knot(0.0, h, parameter_vector(Case(NOMINAL))) == h


def test_the_bypassed_turns_give_the_alpha_axis_its_own_inductances() -> None:
    v = SEALED4["stator_coil_bypass"].bounds[1]
    P0, P1 = vectors(SEALED4, "stator_coil_bypass", v)
    (d0, _), (d1, c1) = _rhs(P0), _rhs(P1)
    x_s, x_r, x_m, r_s = NOMINAL.x_s, NOMINAL.x_r, NOMINAL.x_m, NOMINAL.r_s
    n = 1.0 - 2.0 / 3.0 * v
    a11 = n * n * x_m + (1.0 - 4.0 / 3.0 * v + 2.0 / 3.0 * v * v) * (x_s - x_m)
    i_sa, i_ra = np.linalg.solve([[a11, n * x_m], [n * x_m, x_r]], [STATE[0], STATE[2]])
    i_s, i_r = _currents(STATE)  # the beta axis's currents are the nominal ones
    w_b = P0[kern.P_W_B]
    assert d1[0] - d0[0] == pytest.approx(-w_b * (n * r_s * i_sa - r_s * i_s.real), rel=1e-9)
    assert d1[2] - d0[2] == pytest.approx(-w_b * NOMINAL.r_r * (i_ra - i_r.real), rel=1e-9)
    assert d1[1] == d0[1] and d1[3] == d0[3]  # the beta axis unchanged
    assert c1[M_EL] == pytest.approx(STATE[3] * i_ra - STATE[2] * i_r.imag, rel=1e-12)  # the torque on the rotor
    # off the switch-off, the decaying torque starts from the same torque
    P1[kern.P_M_OFF] = 0.2
    assert kern.electromagnetic_torque(STATE, P1) == pytest.approx(c1[M_EL], rel=1e-12)


def test_the_rotor_s_rub_follows_the_flux_and_stops_with_the_motor() -> None:
    v = SEALED4["motor_rotor_rub"].bounds[1]
    P0, P1 = vectors(SEALED4, "motor_rotor_rub", v)
    T1 = NOMINAL.T1
    rub = v * (STATE[0] ** 2 + STATE[1] ** 2) * math.tanh(STATE[4] / W_SMOOTH)
    assert (_rhs(P0)[0][4] - _rhs(P1)[0][4]) * T1 == pytest.approx(rub, rel=1e-9)
    assert _rhs(P1, motor_on=False)[0].tobytes() == _rhs(P0, motor_on=False)[0].tobytes()
    assert _rhs(P1)[1][M_EL] == _rhs(P0)[1][M_EL]  # not in m_el


@pytest.mark.parametrize("deflection", [0.03, 0.0505], ids=["inside-the-zone", "in-contact"])
def test_the_seal_s_drag_acts_between_the_clutch_s_halves_at_every_deflection(deflection: float) -> None:
    v = SEALED4["clutch_seal_drag"].bounds[1]
    P0, P1 = vectors(SEALED4, "clutch_seal_drag", v)
    y = _with(STATE, th1=STATE[8] + deflection)
    (d0, _), (d1, _) = _rhs(P0, y), _rhs(P1, y)
    drag = v * math.tanh((STATE[4] - STATE[5]) / W_SMOOTH)
    assert (d0[4] - d1[4]) * NOMINAL.T1 == pytest.approx(drag, rel=1e-9)
    assert (d1[5] - d0[5]) * NOMINAL.T2 == pytest.approx(drag, rel=1e-9)
    assert d1[6] == d0[6]


def test_the_gear_s_loss_is_a_share_of_the_resilient_torque_against_the_wheel() -> None:
    v = SEALED4["resilient_gear_loss"].bounds[1]
    P0, P1 = vectors(SEALED4, "resilient_gear_loss", v)
    (d0, _), (d1, _) = _rhs(P0), _rhs(P1)
    m_s = NOMINAL.k2 * (STATE[8] - STATE[9]) + NOMINAL.d2 * (STATE[5] - STATE[6])
    loss = v * abs(m_s) * math.tanh(STATE[5] / W_SMOOTH)
    assert (d0[5] - d1[5]) * NOMINAL.T2 == pytest.approx(loss, rel=1e-9)
    assert d1[4] == d0[4] and d1[6] == d0[6]


def test_the_guides_bind_harder_the_further_the_load_travels() -> None:
    v = SEALED4["load_guide_binding"].bounds[1]
    P0, P1 = vectors(SEALED4, "load_guide_binding", v)

    def force(theta3: float) -> float:
        y = _with(STATE, th3=theta3, w3=1.0)  # well above the smoothing speed: the full friction
        return float((_rhs(P0, y)[0][6] - _rhs(P1, y)[0][6]) * NOMINAL.T3)

    assert force(0.0) == 0.0
    assert force(THETA_BIND) == pytest.approx(v, rel=1e-12)
    assert force(-0.5 * THETA_BIND) == pytest.approx(0.5 * v, rel=1e-12)


def test_the_current_sensor_s_error_is_in_m_el_only_and_before_the_event_only() -> None:
    v = SEALED4["torque_current_gain"].bounds[1]
    P0, P1 = vectors(SEALED4, "torque_current_gain", v)
    (d0, c0), (d1, c1) = _rhs(P0), _rhs(P1)
    i_s, _ = _currents(STATE)
    assert c1[M_EL] - c0[M_EL] == pytest.approx(v * i_s.real * (STATE[0] / math.sqrt(3.0) - STATE[1]), rel=1e-9)
    assert d1.tobytes() == d0.tobytes()  # the plant itself unchanged
    res = simulate_batch([Case(NOMINAL), Case(NOMINAL, SensorParameters(igain_a=v))])
    assert res.event_times[0] == res.event_times[1]
    others = [j for j in range(len(CHANNELS)) if j != M_EL]
    assert res.channels[1, others].tobytes() == res.channels[0, others].tobytes()
    diff = res.channels[1, M_EL] - res.channels[0, M_EL]
    assert np.any(diff[:EVENT_INDEX] != 0.0) and np.all(diff[EVENT_INDEX:] == 0.0)


def test_the_visibility_script_prints_the_rule_s_table() -> None:
    """bench/family_visibility.py (the table of docs/model-changes.md, 1.6): one row per effect, simulation only."""
    script = load_bench("family_visibility")
    rows = script.visibility("sealed4", 0.5)
    assert [r.name for r in rows] == list(SEALED4)
    text = script.table(rows, 0.5)
    assert text.count("\n") == len(SEALED4) + 1 and "| torque_current_gain 0.025 | " in text
