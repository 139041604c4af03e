"""Model 1.1: the additive unknown input, and what the held-back family alone has (docs/model-changes.md).

The checks model 1.1 shares with the later versions run for its held-back effects and its unknown
input from the table of ``tests/test_simulation_model_versions.py``: the kernel against the
independent scipy reference (engine.simulation.reference) for every held-back effect at its bound
and for an unknown input at every locus (MODEL.md section 4's spec, plus a regression guard at
about twice the worst error measured; the measured errors are in that module's docstring), every
new term neutral at its neutral value (the record is bit for bit model 1.0's) and acting
otherwise, the family outside the catalogue, known to the reference and registered by its name,
and a clutch offset beyond the half-width refused. Here:

* the unknown input means what its locus says: in m_el or not, the same physics as the
  parametric terms where both exist (a constant zone offset, a constant supply deviation, a
  sampled ripple), and a step from the switch-off on; a malformed one is refused with the reason;
* the held-back family, older than the one-effect-per-locus rule of 1.2, covers several loci.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.constants import CHANNELS, LOAD_RIPPLE_HZ
from engine.simulation import (
    CATALOGUE,
    HELD_BACK,
    LOCI,
    Case,
    Disturbance,
    ParameterError,
    PlantParameters,
    simulate_batch,
)

NOMINAL = PlantParameters(K=0.005, J1=0.87, c=1.0)
M_EL = CHANNELS.index("m_el")


def test_held_back_family_covers_several_loci() -> None:
    loci = {e.locus for e in HELD_BACK.values()}
    assert loci <= set(LOCI) and len(loci) >= 5


def test_an_all_zero_input_is_neutral_to_integrator_accuracy() -> None:
    """A schedule of zeros only makes the integrator cut its steps at the knots."""
    plant = NOMINAL
    zero = Disturbance("load", 0.0, 2.5e-3, (0.0,) * 100)
    res = simulate_batch([Case(plant), Case(plant.replace(disturbance=zero))])
    rel = np.max(np.abs(res.channels[1] - res.channels[0]), axis=1) / np.ptp(res.channels[0], axis=1)
    assert np.all(rel < 2e-4)


def _with(locus: str, values: tuple[float, ...], dt: float = 2.5e-3, step: float = 0.0) -> Case:
    plant = NOMINAL
    return Case(plant.replace(disturbance=Disturbance(locus, 0.0, dt, values, step)))


def test_electromagnetic_input_shows_in_m_el_and_a_shaft_torque_does_not() -> None:
    res = simulate_batch([Case(NOMINAL), _with("motor_electrical", (0.05,) * 120), _with("motor_shaft", (0.05,) * 120)])
    after = slice(49, 1500)  # the motor is off: the model's m_el is zero
    plain, elec, shaft = res.channels
    assert np.all(plain[M_EL, after] == 0.0)
    np.testing.assert_allclose(elec[M_EL, after], 0.05, rtol=1e-12)
    assert np.all(shaft[M_EL, after] == 0.0)
    assert np.max(np.abs(shaft - plain)) > 1e-2  # but it moves the shaft


def test_a_step_acts_from_the_switch_off_on() -> None:
    res = simulate_batch([_with("motor_electrical", (0.0,) * 120, step=0.1)])
    m_el = res.channels[0, M_EL]
    np.testing.assert_allclose(m_el[48:1500], 0.1, rtol=1e-12)
    assert np.all(np.abs(m_el[:48]) > 0.2)  # before: the motor's own torque, no step


def test_a_constant_clutch_input_is_the_clutch_offset() -> None:
    offset = 0.002
    res = simulate_batch([_with("clutch", (offset,) * 120), HELD_BACK["clutch_offset"].apply(Case(NOMINAL), offset)])
    # the schedule ramps up over [-dt, 0] (before switch-on): from t = 0 on the two are the same
    rel = np.max(np.abs(res.channels[0] - res.channels[1]), axis=1) / np.ptp(res.channels[1], axis=1)
    assert np.all(rel < 1e-3)
    assert abs(res.event_times[0] - res.event_times[1]) < 1e-8


def test_a_sampled_load_input_is_the_load_torque_ripple() -> None:
    """The ripple sampled at 1 ms knots moves the record as the parametric ripple does, within 3 %."""
    amp, dt = 0.04, 1e-3
    t = dt * np.arange(256)
    values = tuple(float(v) for v in amp * np.sin(2 * np.pi * LOAD_RIPPLE_HZ * t))
    plant = NOMINAL
    res = simulate_batch(
        [Case(plant), _with("load", values, dt=dt), HELD_BACK["load_torque_ripple"].apply(Case(plant), amp)]
    )
    plain, sampled, parametric = res.channels
    change = np.ptp(parametric - plain, axis=1)
    assert np.all(np.max(np.abs(sampled - parametric), axis=1) < 0.03 * change)


def test_a_constant_supply_input_is_a_scaled_voltage() -> None:
    res = simulate_batch([_with("supply", (-0.1,) * 120), CATALOGUE["supply_voltage"].apply(Case(NOMINAL), 0.9)])
    rel = np.max(np.abs(res.channels[0] - res.channels[1]), axis=1) / np.ptp(res.channels[1], axis=1)
    assert np.all(rel < 1e-3)


@pytest.mark.parametrize(
    ("dist", "match"),
    [
        (Disturbance("gearbox", 0.0, 1e-3, (0.0,)), "is not one of"),
        (Disturbance("load", 0.0, 0.0, (0.0,)), "spacing"),
        (Disturbance("load", -1.0, 1e-3, (0.0,)), "since switch-on"),
        (Disturbance("load", 0.0, 1e-3, (0.0,) * 300), "knot values"),
        (Disturbance("load", 0.0, 1e-3, (float("nan"),)), "finite"),
        (Disturbance("supply", 0.0, 1e-3, (-1.5,)), "positive"),
    ],
)
def test_a_malformed_input_is_refused_with_the_reason(dist: Disturbance, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        PlantParameters(disturbance=dist).validate()


def test_disturbance_at_matches_its_definition() -> None:
    d = Disturbance("load", 0.01, 0.01, (1.0, 3.0), step=0.5)
    t = np.array([0.0, 0.005, 0.01, 0.015, 0.02, 0.025, 0.03, 0.04])
    np.testing.assert_allclose(d.at(t), [0.0, 0.5, 1.0, 2.0, 3.0, 1.5, 0.0, 0.0])
    np.testing.assert_allclose(d.at(t, t_event=0.02), [0.0, 0.5, 1.0, 2.0, 3.5, 2.0, 0.5, 0.5])
