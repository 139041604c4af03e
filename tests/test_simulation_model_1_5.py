"""Model 1.5: what the third sealed family SEALED3 alone has (docs/model-changes.md, version 1.5).

Simulation only. SEALED3 is kept for scoring: nothing here diagnoses, calibrates, locates or
validates a record of these effects.

The checks model 1.5 shares with 1.1 to 1.4 run for its effects from the table of
``tests/test_simulation_model_versions.py``: every new term exactly neutral at zero (also inside
the kernel's extended path, ``P_EXTENDED``, on top of a held-back effect and of every effect of each
earlier family), the kernel against the independent scipy reference for every effect at its upper
bound and in the combinations where two terms meet, each effect visible at 40 dB at half its upper
bound, the event at the upper bound across the plausible box, the family disjoint from the catalogue
and every earlier family, one effect per locus, registered as the family ``sealed3``
(``backlash validate --held-back sealed3``). Here, each term at the state, against its definition
(the kernel's right-hand side with and without it), and the hum on the record:

* the loose connection takes (2/3) v i_s_alpha off the alpha voltage only;
* the broken bar takes w_b v r_r off the rotor's flux equation along the rotor's axis only, and
  leaves m_el;
* the brake holds at switch-on, lifts after T_BRAKE_RELEASE, and falls again T_BRAKE_APPLY after
  the switch-off;
* the hysteretic contact is (1 + v) times as stiff while the penetration deepens and (1 - v) while it
  recedes, and nothing inside the zone;
* the mesh stiffness varies the resilient spring by v sin(MESH_ORDER theta_2);
* the eddy-current brake's force is v at the critical speed, against the motion;
* the mains hum is in a1 and a2 only, v sin(f w_b t) at each sample's instant;
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

from engine.constants import CHANNELS, MESH_ORDER, T_BRAKE_APPLY, T_BRAKE_RELEASE, T_BRAKE_TRAVEL, W_EDDY, W_SMOOTH
from engine.simulation import SEALED3, Case, SensorParameters, simulate_batch
from engine.simulation import _kernel as kern

A1, M_EL, A2 = (CHANNELS.index(c) for c in ("a1", "m_el", "a2"))


def _vectors(name: str, value: float, case: Case | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The parameter vectors without and with one SEALED3 effect (:func:`kernel_terms.vectors`)."""
    return vectors(SEALED3, name, value, case)


def _currents(y: tuple[float, ...]) -> tuple[complex, complex]:
    """(i_s, i_r) [pu] of the fluxes in y, nominal reactances."""
    x_s, x_r, x_m = NOMINAL.x_s, NOMINAL.x_r, NOMINAL.x_m
    det = x_s * x_r - x_m**2
    psi_s, psi_r = complex(y[0], y[1]), complex(y[2], y[3])
    return (x_r * psi_s - x_m * psi_r) / det, (x_s * psi_r - x_m * psi_s) / det


def test_the_loose_connection_takes_two_thirds_of_its_drop_off_the_alpha_voltage() -> None:
    v = 0.05
    P0, P1 = _vectors("supply_loose_connection", v)
    (d0, c0), (d1, c1) = _rhs(P0), _rhs(P1)
    i_s, _ = _currents(STATE)
    assert d0[0] - d1[0] == pytest.approx(P0[kern.P_W_B] * 2.0 / 3.0 * v * i_s.real, rel=1e-9)
    assert d1[1] == d0[1] and d1[2:4].tobytes() == d0[2:4].tobytes()  # beta and the rotor unchanged
    assert c1[M_EL] == c0[M_EL]


@pytest.mark.parametrize("axis", [0.0, 0.5 * math.pi, 0.3], ids=["alpha", "beta", "between"])
def test_the_broken_bar_adds_resistance_along_the_rotor_s_axis_only(axis: float) -> None:
    """The rotor's electrical angle p theta_1 = ``axis``: the drop lies along it, of size w_b v r_r i_r there."""
    v = 0.2
    y = _with(STATE, th1=axis / NOMINAL.pole_pairs)
    P0, P1 = _vectors("rotor_broken_bar", v)
    (d0, c0), (d1, c1) = _rhs(P0, y), _rhs(P1, y)
    _, i_r = _currents(y)
    e = complex(math.cos(axis), math.sin(axis))
    drop = P0[kern.P_W_B] * v * NOMINAL.r_r * (i_r * e.conjugate()).real * e
    np.testing.assert_allclose(d0[[2, 3]] - d1[[2, 3]], [drop.real, drop.imag], rtol=1e-9, atol=1e-12)
    assert d1[0:2].tobytes() == d0[0:2].tobytes()  # the stator's equation unchanged
    assert c1[M_EL] == c0[M_EL]  # the torque of the same fluxes is unchanged


def test_the_brake_holds_at_switch_on_lifts_and_falls_again_after_the_switch_off() -> None:
    v = 1.0
    P0, P1 = _vectors("motor_brake", v)
    T1 = NOMINAL.T1
    full = v * math.tanh(STATE[4] / W_SMOOTH)

    def brake(t: float, motor_on: bool = True) -> float:
        return float((_rhs(P0, t=t, motor_on=motor_on)[0][4] - _rhs(P1, t=t, motor_on=motor_on)[0][4]) * T1)

    assert brake(0.0) == pytest.approx(full, rel=1e-12)  # applied at switch-on
    assert brake(T_BRAKE_RELEASE) == pytest.approx(full, rel=1e-12)
    assert brake(T_BRAKE_RELEASE + 0.5 * T_BRAKE_TRAVEL) == pytest.approx(0.5 * full, rel=1e-9)
    assert brake(T_BRAKE_RELEASE + T_BRAKE_TRAVEL) == 0.0  # lifted
    t_off = 0.03
    P0[kern.P_T_SWITCH_OFF] = P1[kern.P_T_SWITCH_OFF] = t_off
    assert brake(t_off + 0.9 * T_BRAKE_APPLY, False) == 0.0  # still lifted: the armature falls
    assert brake(t_off + T_BRAKE_APPLY + 0.5 * T_BRAKE_TRAVEL, False) == pytest.approx(0.5 * full, rel=1e-9)
    assert brake(t_off + T_BRAKE_APPLY + T_BRAKE_TRAVEL, False) == pytest.approx(full, rel=1e-12)
    y = _with(STATE, w1=0.0)
    assert _rhs(P1, y, t=0.0)[0].tobytes() == _rhs(P0, y, t=0.0)[0].tobytes()  # at rest: no torque


def test_the_hysteretic_contact_is_stiffer_loading_and_softer_unloading() -> None:
    v = 0.3
    P0, P1 = _vectors("clutch_hysteretic_contact", v)
    b = NOMINAL.b
    T2 = NOMINAL.T2
    x = 0.002
    for side in (1.0, -1.0):
        for w1, loading in ((STATE[5] + 0.02 * side, True), (STATE[5] - 0.005 * side, False)):
            y = _with(STATE, th1=STATE[8] + side * (b + x), w1=w1)
            (d0, _), (d1, _) = _rhs(P0, y), _rhs(P1, y)
            spring = NOMINAL.k12 * side * x
            shape = math.tanh(side * (w1 - STATE[5]) / W_SMOOTH)
            assert (1.0 if loading else -1.0) * shape > 0.99
            m_c0 = NOMINAL.k12 * side * x + NOMINAL.d12 * (w1 - STATE[5])
            m_c1 = spring * (1.0 + v * shape) + NOMINAL.d12 * (w1 - STATE[5])
            clip = max if side > 0 else min
            assert (d1[5] - d0[5]) * T2 == pytest.approx(clip(0.0, m_c1) - clip(0.0, m_c0), rel=1e-6, abs=1e-12)
    assert _rhs(P1)[0].tobytes() == _rhs(P0)[0].tobytes()  # inside the zone: no contact, no hysteresis
    for gap, mode in ((1e-4, 0), (-1e-4, 1)):  # the zone's edges are unchanged
        y = _with(STATE, th1=0.04 + b - gap)
        assert kern.zone(0.01, y, P1, True) == kern.zone(0.01, y, P0, True) == mode


def test_the_mesh_stiffness_varies_the_resilient_spring_with_the_wheel_s_angle() -> None:
    v = 0.2
    P0, P1 = _vectors("resilient_mesh_stiffness", v)
    T2, T3 = NOMINAL.T2, NOMINAL.T3
    for theta2 in (0.04, math.pi / (2.0 * MESH_ORDER), 0.123):
        y = _with(STATE, th2=theta2, th3=0.01)
        (d0, _), (d1, _) = _rhs(P0, y), _rhs(P1, y)
        extra = NOMINAL.k2 * (theta2 - 0.01) * v * math.sin(MESH_ORDER * theta2)
        assert (d0[5] - d1[5]) * T2 == pytest.approx(extra, rel=1e-6, abs=1e-14)
        assert (d1[6] - d0[6]) * T3 == pytest.approx(extra, rel=1e-6, abs=1e-14)
    y = _with(STATE, th2=0.0, th3=0.01)  # sin(0) = 0: the nominal spring
    assert _rhs(P1, y)[0].tobytes() == _rhs(P0, y)[0].tobytes()


def test_the_eddy_current_brake_peaks_at_its_value_at_the_critical_speed() -> None:
    v = 0.05
    P0, P1 = _vectors("load_eddy_current_brake", v)
    T3 = NOMINAL.T3

    def force(w3: float) -> float:
        y = _with(STATE, w3=w3)
        return float((_rhs(P1, y)[0][6] - _rhs(P0, y)[0][6]) * T3)

    assert force(W_EDDY) == pytest.approx(-v, rel=1e-9)
    assert force(-W_EDDY) == pytest.approx(v, rel=1e-9)
    assert abs(force(3.0 * W_EDDY)) < abs(force(W_EDDY))  # falling beyond the critical speed
    assert force(1e-4 * W_EDDY) == pytest.approx(-v * 2e-4, rel=1e-6)  # linear at low speed


def test_the_mains_hum_is_v_sin_of_the_supply_s_angle_in_a1_and_a2_only() -> None:
    v = SEALED3["accelerometer_mains_hum"].bounds[1]
    res = simulate_batch([Case(NOMINAL), Case(NOMINAL, SensorParameters(hum=v))])
    assert res.event_times[0] == res.event_times[1]
    t = float(res.event_times[1]) + (np.arange(res.channels.shape[2]) - 48) * 1e-4
    hum = v * np.sin(NOMINAL.f * NOMINAL.w_b * t)
    for j in (A1, A2):
        np.testing.assert_allclose(res.channels[1, j] - res.channels[0, j], hum, atol=1e-9)
    others = [j for j in range(len(CHANNELS)) if j not in (A1, A2)]
    assert res.channels[1, others].tobytes() == res.channels[0, others].tobytes()


def test_the_visibility_script_prints_the_rule_s_table() -> None:
    """bench/family_visibility.py (the table of docs/model-changes.md, 1.5): one row per effect, simulation only."""
    script = load_bench("family_visibility")
    rows = script.visibility("sealed3", 0.5)
    assert [r.name for r in rows] == list(SEALED3)
    text = script.table(rows, 0.5)
    assert text.count("\n") == len(SEALED3) + 1 and "| accelerometer_mains_hum 0.5 | " in text
