"""Model 1.4: what the second sealed family SEALED2 alone has (docs/model-changes.md, version 1.4).

Simulation only. SEALED2 is kept for scoring: nothing here diagnoses, calibrates, locates or
validates a record of these effects.

The checks model 1.4 shares with 1.1 to 1.3 run for its effects from the table of
``tests/test_simulation_model_versions.py``: every new term exactly neutral at zero (also inside
the kernel's extended path, ``P_EXTENDED``, on top of a held-back effect, of every held-out and of
every sealed effect), the kernel against the independent scipy reference for every effect at its
upper bound and in the combinations where two terms meet (with the measured errors in that
module's docstring), each effect visible at 40 dB at half its upper bound, the family disjoint from
the catalogue and every earlier family, one effect per locus, registered as the family ``sealed2``
(``backlash validate --held-back sealed2``), and drawn by the case generator of protocol 2. Here,
each term at the state, against its definition (the kernel's right-hand side with and without it),
and the sample-and-hold on the record:

* the DC offset adds v u to the alpha component of the stator voltage only;
* the core-loss resistance takes w_b v (i_s + i_r) off both flux equations and leaves m_el;
* the bearing friction acts only while the clutch transmits a torque;
* the squeeze film grows as the gap closes, is v (w_1 - w_2) in contact, beside the contact and
  unclipped, and leaves the clutch's modes alone;
* the hub's play shifts the resilient spring by v once the twist is large;
* the bump's force peaks at v and is against the motion up to the crest;
* omega1 is held between hold instants on the record, and agrees with the reference on a grid that
  reaches back before switch-on;
* bench/family_visibility.py prints the rule's table of docs/model-changes.md (tested with model 1.3's, in
  tests/test_simulation_model_1_3.py, for both families).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from kernel_terms import NOMINAL, STATE, vectors
from kernel_terms import rhs as _rhs
from kernel_terms import with_state as _with

from engine.constants import CHANNELS, H_SQUEEZE, THETA_BUMP, W_BUMP
from engine.records import SampleGrid
from engine.simulation import CATALOGUE, SEALED2, Case, SensorParameters, simulate_batch
from engine.simulation import _kernel as kern
from engine.simulation.reference import reference_simulate

PLANT = {"K": 0.005, "J1": 0.87, "c": 1.0}  # NOMINAL, by MODEL.md's names
A1, M_EL, OMEGA1, A2 = (CHANNELS.index(c) for c in ("a1", "m_el", "omega1", "a2"))


def _vectors(name: str, value: float, case: Case | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The parameter vectors without and with one SEALED2 effect (:func:`kernel_terms.vectors`)."""
    return vectors(SEALED2, name, value, case)


def test_the_dc_offset_adds_v_u_to_the_alpha_voltage() -> None:
    v = 0.01
    P0, P1 = _vectors("supply_dc_offset", v, Case(NOMINAL.replace(u=0.9)))
    (d0, _), (d1, _) = _rhs(P0), _rhs(P1)
    assert d1[0] - d0[0] == pytest.approx(P0[kern.P_W_B] * v * 0.9, rel=1e-9)
    assert d1[1] == d0[1] and d1[2:4].tobytes() == d0[2:4].tobytes()  # beta and the rotor unchanged


def test_the_core_loss_takes_the_magnetising_current_s_drop_off_both_loops() -> None:
    v = 0.1
    P0, P1 = _vectors("core_loss_resistance", v)
    (d0, c0), (d1, c1) = _rhs(P0), _rhs(P1)
    x_s, x_r, x_m = NOMINAL.x_s, NOMINAL.x_r, NOMINAL.x_m
    det = x_s * x_r - x_m**2
    psi_s, psi_r = complex(STATE[0], STATE[1]), complex(STATE[2], STATE[3])
    i_m = ((x_r - x_m) * psi_s + (x_s - x_m) * psi_r) / det  # i_s + i_r
    drop = P0[kern.P_W_B] * v * i_m
    np.testing.assert_allclose(d0[[0, 1]] - d1[[0, 1]], [drop.real, drop.imag], rtol=1e-9)
    np.testing.assert_allclose(d0[[2, 3]] - d1[[2, 3]], [drop.real, drop.imag], rtol=1e-9)
    assert c1[M_EL] == c0[M_EL]  # the torque of the same fluxes is unchanged


def test_the_bearing_friction_acts_only_while_the_clutch_transmits() -> None:
    v = 0.02
    P0, P1 = _vectors("motor_bearing_load_friction", v)
    assert _rhs(P1)[0].tobytes() == _rhs(P0)[0].tobytes()  # inside the zone: no load on the bearings
    b = NOMINAL.b
    contact = _with(STATE, th1=0.04 + b + 0.002)  # pushing: 2 mrad beyond the edge, w1 > w2
    (d0, _), (d1, _) = _rhs(P0, contact), _rhs(P1, contact)
    m_c = NOMINAL.k12 * 0.002 + NOMINAL.d12 * (STATE[4] - STATE[5])
    T1 = NOMINAL.T1
    assert (d0[4] - d1[4]) * T1 == pytest.approx(v * m_c * math.tanh(STATE[4] / 1e-3), rel=1e-6)
    assert d1[5] == d0[5]  # the wheel feels the contact, not the motor's bearings


def test_the_squeeze_film_grows_as_the_gap_closes_and_stays_in_contact_unclipped() -> None:
    v = 2.0
    P0, P1 = _vectors("clutch_squeeze_film", v)
    b = NOMINAL.b
    T1, T2 = NOMINAL.T1, NOMINAL.T2
    # 20 mrad and one film scale inside the zone, at its edge, 2 mrad in contact; then parting in
    # contact (w1 < w2, the contact clipped to nothing), where the film alone pulls
    for gap, w1 in ((0.02, 0.02), (H_SQUEEZE, 0.02), (0.0, 0.02), (-0.002, 0.02), (-0.0002, 0.002)):
        y = _with(STATE, th1=0.04 + b - gap, w1=w1)
        (d0, _), (d1, _) = _rhs(P0, y), _rhs(P1, y)
        m_sq = v * (H_SQUEEZE / (H_SQUEEZE + max(gap, 0.0))) ** 3 * (w1 - STATE[5])
        assert (d0[4] - d1[4]) * T1 == pytest.approx(m_sq, rel=1e-6)
        assert (d1[5] - d0[5]) * T2 == pytest.approx(m_sq, rel=1e-6)
    for gap, mode in ((1e-4, 0), (-1e-4, 1)):  # the clutch's modes are the contact's alone
        y = _with(STATE, th1=0.04 + b - gap)
        assert kern.zone(0.01, y, P1, True) == kern.zone(0.01, y, P0, True) == mode


def test_the_hub_play_shifts_the_resilient_spring_by_its_width() -> None:
    v = 0.005
    P0, P1 = _vectors("resilient_hub_play", v)
    T2 = NOMINAL.T2
    for twist in (0.05, -0.05):  # ten widths: tanh is 1 to 4e-9
        y = _with(STATE, th2=0.01 + twist, th3=0.01)
        (d0, _), (d1, _) = _rhs(P0, y), _rhs(P1, y)
        assert (d1[5] - d0[5]) * T2 == pytest.approx(math.copysign(NOMINAL.k2 * v, twist), rel=1e-8)
    at_rest = _with(STATE, th2=0.01, th3=0.01)
    assert _rhs(P1, at_rest)[0].tobytes() == _rhs(P0, at_rest)[0].tobytes()  # no twist, no torque


def test_the_bump_s_force_peaks_at_its_value_against_the_motion_up_to_the_crest() -> None:
    v = 0.05
    P0, P1 = _vectors("load_track_bump", v)
    T3 = NOMINAL.T3

    def force(theta3: float) -> float:
        y = _with(STATE, th3=theta3)
        return float((_rhs(P1, y)[0][6] - _rhs(P0, y)[0][6]) * T3)

    assert force(THETA_BUMP - W_BUMP / math.sqrt(2.0)) == pytest.approx(-v, rel=1e-9)  # climbing
    assert force(THETA_BUMP + W_BUMP / math.sqrt(2.0)) == pytest.approx(v, rel=1e-9)  # beyond the crest
    assert force(THETA_BUMP) == 0.0
    assert abs(force(0.0)) < 1e-9 * v  # where the test starts, the bump is 5 widths away (exp(-25))


def test_the_nominal_load_passes_the_bump_within_the_record() -> None:
    """theta_3 (the integral of v2 / r) passes the bump's far flank in the nominal plant's record."""
    res = simulate_batch([Case(NOMINAL)])
    theta3 = np.cumsum(res.channels[0, CHANNELS.index("v2")]) * 1e-4 / NOMINAL.r
    assert theta3[-1] > THETA_BUMP + 1.5 * W_BUMP


def test_the_sample_and_hold_holds_omega1_between_hold_instants() -> None:
    """omega1 changes from one sample to the next only where a hold instant lies between them.

    Not at every such instant: inside the zone after the event the motor coasts at a constant speed.
    The values themselves are checked against the reference (the versions' module and below).
    """
    h = 0.001
    res = simulate_batch([Case(NOMINAL), Case(NOMINAL, SensorParameters(hold1=h))])
    t_e = float(res.event_times[1])
    t = t_e + (np.arange(res.channels.shape[2]) - 48) * 1e-4
    instant = np.floor(t / h)
    held = res.channels[1, OMEGA1]
    changed, new_instant = np.diff(held) != 0.0, np.diff(instant) != 0.0
    assert not np.any(changed & ~new_instant) and np.count_nonzero(changed) > 20
    assert res.event_times[0] == res.event_times[1]
    others = [j for j in range(len(CHANNELS)) if j != OMEGA1]
    assert res.channels[1, others].tobytes() == res.channels[0, others].tobytes()


@pytest.mark.parametrize("lowpass", [0.0, 1000.0], ids=["no-lowpass", "lowpass-1kHz"])
def test_the_sample_and_hold_agrees_with_the_reference_from_switch_on(lowpass: float) -> None:
    """On a grid reaching 40 ms before the event (its first samples before switch-on), at the bound.

    The kernel's hold starts from rest here (the first hold instant lies after the path's start),
    where on MODEL.md's grid it starts from a checkpoint (the versions' module).
    """
    h = SEALED2["speed_sample_hold"].bounds[1]
    grid = SampleGrid(1e-4, 800, 400)
    effects = {"speed_sample_hold": h, **({"sensor_lowpass": lowpass} if lowpass else {})}
    sim = simulate_batch([Case(NOMINAL)], effects, grid=grid, library=CATALOGUE + SEALED2)
    ref = reference_simulate(PLANT, effects, grid=grid)
    rel = np.max(np.abs(sim.channels[0] - ref.channels), axis=1) / np.ptp(ref.channels, axis=1)
    assert abs(float(sim.event_times[0]) - ref.event_time) < 5e-8
    assert np.all(rel < 4e-4), dict(zip(CHANNELS, rel.round(6), strict=True))
    assert np.all(sim.channels[0, :, :10] == 0.0)  # before switch-on: at rest
