"""Model 1.7: what the fifth sealed family SEALED5 alone has (docs/model-changes.md, version 1.7).

Simulation only. SEALED5 is kept for scoring: nothing here diagnoses, calibrates, locates or
validates a record of these effects.

The checks model 1.7 shares with 1.1 to 1.6 run for its effects from the table of
``tests/test_simulation_model_versions.py``: every new term exactly neutral at zero (also inside
the kernel's extended path, ``P_EXTENDED``, on top of a held-back effect and of every effect of each
earlier family), the kernel against the independent scipy reference for every effect at its upper
bound and in the combinations where two terms meet, each effect visible at 40 dB at half its upper
bound, the event at the upper bound across the plausible box, the family disjoint from the catalogue
and every earlier family, one effect per locus, registered as the family ``sealed5``
(``backlash validate --held-back sealed5``). Here, each term at the state, against its definition
(the kernel's right-hand side with and without it):

* the harmonics add the 5th (negative sequence) and the 7th (positive sequence) to the stator's
  voltage only;
* the residual flux is the initial state, with no stator current, and it changes the record;
* the misaligned shaft's torque is -v sin(2 theta_1) on J1, the wheel's imbalance -v sin(theta_2) on J2;
* the hub's runout widens the zone with theta_1 (contact, modes and the event's zone alike);
* the end buffer acts beyond THETA_STOP only, v at THETA_STOP of compression;
* a1's saturation is tanh(v a1) / v in a1 only, a2's cross-talk reading the true a1;
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

from engine.constants import CHANNELS, THETA_STOP
from engine.simulation import SEALED5, Case, SensorParameters, simulate_batch
from engine.simulation import _kernel as kern

A1, A2 = CHANNELS.index("a1"), CHANNELS.index("a2")


def test_the_harmonics_add_the_5th_and_the_7th_to_the_stator_s_voltage() -> None:
    v = SEALED5["supply_harmonics"].bounds[1]
    P0, P1 = vectors(SEALED5, "supply_harmonics", v)
    t = 0.0123
    (d0, c0), (d1, c1) = _rhs(P0, t=t), _rhs(P1, t=t)
    ang = NOMINAL.f * P0[kern.P_W_B] * t
    u_h = v * NOMINAL.u * (np.exp(-5j * ang) + np.exp(7j * ang))
    w_b = P0[kern.P_W_B]
    assert d1[0] - d0[0] == pytest.approx(w_b * u_h.real, rel=1e-9)
    assert d1[1] - d0[1] == pytest.approx(w_b * u_h.imag, rel=1e-9)
    assert d1[2:].tobytes() == d0[2:].tobytes() and c1.tobytes() == c0.tobytes()  # the state's rates only
    assert _rhs(P1, t=t, motor_on=False)[0].tobytes() == _rhs(P0, t=t, motor_on=False)[0].tobytes()


def test_the_residual_flux_is_the_initial_state_with_no_stator_current() -> None:
    v = SEALED5["rotor_residual_flux"].bounds[1]
    P0, P1 = vectors(SEALED5, "rotor_residual_flux", v)
    assert kern.initial_state(P0) == (0.0,) * kern.N_STATES
    y0 = kern.initial_state(P1)
    x_s, x_r, x_m = NOMINAL.x_s, NOMINAL.x_r, NOMINAL.x_m
    assert y0[2] == v and y0[0] == pytest.approx(x_m / x_r * v, rel=1e-15)
    assert y0[1] == y0[3] == 0.0 and not any(y0[4:])
    i_sa = (x_r * y0[0] - x_m * y0[2]) / (x_s * x_r - x_m**2)
    assert i_sa == pytest.approx(0.0, abs=1e-15)  # no stator current at switch-on
    assert _rhs(P1)[0].tobytes() == _rhs(P0)[0].tobytes()  # the right-hand side is unchanged
    res = simulate_batch([Case(NOMINAL), SEALED5["rotor_residual_flux"].apply(Case(NOMINAL), v)])
    assert res.event_times[0] != res.event_times[1]


@pytest.mark.parametrize("theta1", [0.07, -0.4, 1.2])
def test_the_misaligned_shaft_s_torque_is_twice_per_revolution(theta1: float) -> None:
    v = SEALED5["shaft_misalignment"].bounds[1]
    P0, P1 = vectors(SEALED5, "shaft_misalignment", v)
    y = _with(STATE, th1=theta1, th2=theta1 - 0.03)
    (d0, _), (d1, _) = _rhs(P0, y), _rhs(P1, y)
    assert (d1[4] - d0[4]) * NOMINAL.T1 == pytest.approx(-v * math.sin(2.0 * theta1), rel=1e-9)
    assert d1[5] == d0[5] and d1[6] == d0[6]


@pytest.mark.parametrize("theta2", [0.04, -0.3, 2.0])
def test_the_wheel_s_imbalance_is_a_gravity_torque_on_j2(theta2: float) -> None:
    v = SEALED5["wheel_imbalance"].bounds[1]
    P0, P1 = vectors(SEALED5, "wheel_imbalance", v)
    y = _with(STATE, th2=theta2, th1=theta2 + 0.03)
    (d0, _), (d1, _) = _rhs(P0, y), _rhs(P1, y)
    assert (d1[5] - d0[5]) * NOMINAL.T2 == pytest.approx(-v * math.sin(theta2), rel=1e-9)
    assert d1[4] == d0[4] and d1[6] == d0[6]


def test_the_hub_s_runout_widens_the_zone_with_the_motor_s_angle() -> None:
    v = SEALED5["clutch_hub_runout"].bounds[1]
    P0, P1 = vectors(SEALED5, "clutch_hub_runout", v)
    b = NOMINAL.K / NOMINAL.r
    theta1 = 0.2
    wide = b * (1.0 + v * math.sin(theta1))
    assert kern.half_width(_with(STATE, th1=theta1), P1, True) == pytest.approx(wide, rel=1e-15)
    assert kern.half_width(_with(STATE, th1=theta1), P0, True) == b
    # a deflection between b and the wider half-width: in contact without the runout, in the zone with it
    d = 0.5 * (b + wide)
    y = _with(STATE, th1=theta1, th2=theta1 - d, w1=0.02, w2=0.0)
    assert kern.zone(0.01, y, P0, True) == 1 and kern.zone(0.01, y, P1, True) == 0
    (d0, _), (d1, _) = _rhs(P0, y), _rhs(P1, y)
    m_c = NOMINAL.k12 * (d - b) + NOMINAL.d12 * 0.02  # the contact's torque the runout removes
    assert (d1[4] - d0[4]) * NOMINAL.T1 == pytest.approx(m_c, rel=1e-9)
    # beyond both: the penetration is measured from the wider edge (the same penetration, the same torque)
    y_wide = _with(STATE, th1=theta1, th2=theta1 - (wide + 0.002), w1=0.02, w2=0.0)
    y_plain = _with(STATE, th1=theta1, th2=theta1 - (b + 0.002), w1=0.02, w2=0.0)
    assert _rhs(P1, y_wide)[0][4] == pytest.approx(_rhs(P0, y_plain)[0][4], rel=1e-9)


def test_the_end_buffer_acts_beyond_its_point_only() -> None:
    v = SEALED5["load_end_buffer"].bounds[1]
    P0, P1 = vectors(SEALED5, "load_end_buffer", v)

    def force(theta3: float) -> float:
        y = _with(STATE, th3=theta3, th2=theta3 + 0.03, th1=theta3 + 0.06)
        return float((_rhs(P1, y)[0][6] - _rhs(P0, y)[0][6]) * NOMINAL.T3)

    assert force(0.0) == 0.0 and force(THETA_STOP) == 0.0 and force(-2.0 * THETA_STOP) == 0.0
    assert force(2.0 * THETA_STOP) == pytest.approx(-v, rel=1e-12)
    assert force(1.5 * THETA_STOP) == pytest.approx(-0.25 * v, rel=1e-12)


def test_a1_s_saturation_is_in_a1_only_and_a2_s_crosstalk_reads_the_true_a1() -> None:
    v = SEALED5["accelerometer_saturation"].bounds[1]
    base = Case(NOMINAL, SensorParameters(xtalk2=0.1))
    P0, P1 = vectors(SEALED5, "accelerometer_saturation", v, base)
    y = _with(STATE, th1=STATE[8] + 0.06)  # 0.01 rad into the contact: a large a1
    (d0, c0), (d1, c1) = _rhs(P0, y), _rhs(P1, y)
    assert abs(c0[A1]) > 10.0
    assert c1[A1] == pytest.approx(math.tanh(v * c0[A1]) / v, rel=1e-12)
    assert d1.tobytes() == d0.tobytes()
    others = [j for j in range(len(CHANNELS)) if j != A1]
    assert c1[others].tobytes() == c0[others].tobytes()  # a2 (with its cross-talk of a1) unchanged


def test_the_visibility_script_prints_the_rule_s_table() -> None:
    """bench/family_visibility.py (the table of docs/model-changes.md, 1.7): one row per effect, simulation only."""
    script = load_bench("family_visibility")
    rows = script.visibility("sealed5", 0.5)
    assert [r.name for r in rows] == list(SEALED5)
    text = script.table(rows, 0.5)
    assert text.count("\n") == len(SEALED5) + 1 and "| accelerometer_saturation 0.025 | " in text
