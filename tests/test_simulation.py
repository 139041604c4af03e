"""Protocol, batch, effects and error behaviour of the simulator."""

import numpy as np
import pytest

from engine.constants import CHANNELS, EVENT_INDEX, N_SAMPLES, OMEGA_B, SAMPLE_INTERVAL
from engine.simulation import (
    CATALOGUE,
    Case,
    ParameterError,
    PlantParameters,
    SensorParameters,
    SimulationError,
    SolverSettings,
    UnknownEffectError,
    add_white_noise,
    apply_effects,
    full_grid,
    simulate,
    simulate_batch,
)

NOMINAL = PlantParameters(K=0.005, J1=0.87, c=1.0)


@pytest.fixture(scope="module")
def nominal():
    return simulate(NOMINAL)


def test_record_layout_and_event(nominal):
    assert set(nominal.channels) == set(CHANNELS)
    assert all(v.shape == (N_SAMPLES,) for v in nominal.channels.values())
    m_el = nominal["m_el"]
    # motor torque is zeroed from the event on, and present before it
    assert np.all(m_el[EVENT_INDEX:] == 0.0)
    assert np.all(np.abs(m_el[:EVENT_INDEX]) > 1e-3)
    assert 0.0 < nominal.event_time < 1.0
    assert nominal.conditions == {"J1": 0.87, "c": 1.0, "c1": 0.2, "K": 0.005}


def test_channel_units_are_consistent(nominal):
    # a1 is r * Omega_b * dw1/dt and omega1 is Omega_b * w1, so a1 ~ r * d(omega1)/dt
    # wherever the acceleration is smooth (away from impacts)
    a1, omega1 = nominal["a1"], nominal["omega1"]
    fd = 0.1 * np.gradient(omega1, SAMPLE_INTERVAL)
    smooth = np.abs(np.diff(a1, prepend=a1[0])) < 0.05 * np.ptp(a1)
    smooth &= np.arange(N_SAMPLES) > EVENT_INDEX + 1
    assert smooth.sum() > 500
    np.testing.assert_allclose(fd[smooth], a1[smooth], atol=0.02 * np.ptp(a1))
    # v2 = r * Omega_b * w3 stays below the mass's physical speed range (|w3| < 1 pu)
    assert np.max(np.abs(nominal["v2"])) < 0.1 * OMEGA_B


@pytest.mark.serial  # with numba's threads on every core: the parallel part runs one per worker (Makefile)
def test_batch_equals_single_runs():
    cases = [PlantParameters(K=K, J1=J1, c=c) for K, J1, c in [(0.0025, 0.8, 0.8), (0.009, 0.9, 1.4)]]
    batch = simulate_batch(cases)
    for i, case in enumerate(cases):
        single = simulate(case)
        np.testing.assert_array_equal(batch.channels[i], np.stack([single[c] for c in CHANNELS]))


def test_defaults_are_model_md_constants():
    """PlantParameters' defaults are MODEL.md's values from engine.constants; the step derives from Ts."""
    from engine import constants as const

    expected = {
        "K": const.K_NOMINAL,
        "J1": const.J1_NOMINAL,
        "J2": const.J2,
        "T3": const.T3,
        "c": const.C_NOMINAL,
        "c1": const.C1_NOMINAL,
        "r": const.WHEEL_RADIUS,
        "k12": const.K12,
        "d12": const.D12,
        "k2": const.K2,
        "d2": const.D2,
        "r_s": const.R_S,
        "r_r": const.R_R,
        "x_s": const.X_S,
        "x_r": const.X_R,
        "x_m": const.X_M,
        "u": const.U_SUPPLY,
        "f": const.F_SUPPLY,
        "tau_C1": 0.0,
        "b_1": 0.0,
        # model 1.1 extensions (docs/model-changes.md), neutral by default
        "tau_ripple3": 0.0,
        "clutch_offset": 0.0,
        "tau_cog": 0.0,
        "tau_C2": 0.0,
        "m_off": 0.0,
        "disturbance": None,
        # model 1.2 extensions (the held-out family), neutral by default
        "u_neg": 0.0,
        "sat": 0.0,
        "b_2": 0.0,
        "k_pre": 0.0,
        "hard2": 0.0,
        "k_3": 0.0,
        # model 1.3 extensions (the sealed family), neutral by default
        "u_flicker": 0.0,
        "x_leak": 0.0,
        "tau_S1": 0.0,
        "prog12": 0.0,
        "tau_dry2": 0.0,
        "b_3": 0.0,
        # model 1.4 extensions (the second sealed family), neutral by default
        "u_dc": 0.0,
        "r_m": 0.0,
        "mu_1": 0.0,
        "sq12": 0.0,
        "play2": 0.0,
        "bump3": 0.0,
        # model 1.5 extensions (the third sealed family), neutral by default
        "r_con": 0.0,
        "r_bar": 0.0,
        "tau_brake": 0.0,
        "hyst12": 0.0,
        "mesh2": 0.0,
        "eddy3": 0.0,
        # model 1.6 extensions (the fourth sealed family), neutral by default
        "t_pole": 0.0,
        "bypass_a": 0.0,
        "tau_rub": 0.0,
        "seal12": 0.0,
        "gear2": 0.0,
        "bind3": 0.0,
        # model 1.7 extensions (the fifth sealed family), neutral by default
        "u_h57": 0.0,
        "psi_r0": 0.0,
        "tau_mis1": 0.0,
        "ecc12": 0.0,
        "tau_unb2": 0.0,
        "buf3": 0.0,
        # the per-unit base values (issue 52: parameters, MODEL.md's by default)
        "w_b": const.W_B,
        "pole_pairs": const.POLE_PAIRS,
        "tm_per_j": const.TM_PER_J,
    }
    assert PlantParameters().as_dict() == expected
    assert SolverSettings().max_step == SAMPLE_INTERVAL / 3


def test_full_grid_is_168_distinct_cases():
    grid = full_grid()
    assert len(grid) == 168
    assert len({(c.plant.K, c.plant.J1, c.plant.c) for c in grid}) == 168


def test_wider_backlash_delays_the_event():
    res = simulate_batch([PlantParameters(K=K) for K in (0.0025, 0.005, 0.01)])
    assert np.all(np.diff(res.event_times) > 0)


def test_no_event_raises_with_reason():
    with pytest.raises(SimulationError, match="no backlash event"):
        simulate(NOMINAL, solver=SolverSettings(t_event_max=0.005))


@pytest.mark.parametrize(
    "overrides,match",
    [
        ({"K": -0.001}, "K = -0.001"),
        ({"J1": float("nan")}, "finite"),
        ({"x_m": 1.95}, "x_s \\* x_r"),
        ({"u": 5.0}, "u = 5.0"),
    ],
)
def test_absurd_parameters_raise(overrides, match):
    with pytest.raises(ParameterError, match=match):
        simulate(NOMINAL.replace(**overrides))


def test_unknown_parameter_and_effect_raise():
    with pytest.raises(ParameterError, match="unknown parameter"):
        NOMINAL.replace(J3=1.0)
    with pytest.raises(UnknownEffectError, match="known effects"):
        simulate(NOMINAL, effects={"gremlins": 1.0})
    with pytest.raises(ParameterError, match="outside its range"):
        simulate(NOMINAL, effects={"supply_voltage": 1.5})


def test_every_effect_is_neutral_at_its_neutral_value_and_acts_otherwise(nominal):
    base = np.stack([nominal[c] for c in CHANNELS])
    cases, labels = [], []
    for name, eff in CATALOGUE.items():
        if eff.name == "sensor_lowpass":  # neutral (0 = off) lies outside the accepted range
            continue
        cases.append(apply_effects(Case(NOMINAL), {name: eff.neutral}))
        labels.append((name, "neutral"))
        strong = eff.bounds[1] if eff.neutral != eff.bounds[1] else eff.bounds[0]
        cases.append(apply_effects(Case(NOMINAL), {name: strong}))
        labels.append((name, "strong"))
    cases.append(apply_effects(Case(NOMINAL), {"sensor_lowpass": 200.0}))
    labels.append(("sensor_lowpass", "strong"))
    res = simulate_batch(cases)
    for (name, kind), rec in zip(labels, res.channels, strict=True):
        diff = np.max(np.abs(rec - base))
        if kind == "neutral":
            assert diff == 0.0, f"{name} at its neutral value changed the record"
        else:
            assert diff > 1e-3, f"{name} at full strength left the record unchanged"


def test_measurement_delay_shifts_samples():
    delayed = simulate(NOMINAL, effects={"measurement_delay": 2 * SAMPLE_INTERVAL})
    plain = simulate(NOMINAL)
    for c in ("omega1", "v2", "a2"):
        np.testing.assert_allclose(delayed[c][2:], plain[c][:-2], atol=1e-6 * np.ptp(plain[c]))


def test_speed_quantization_and_lowpass():
    q = simulate(NOMINAL, effects={"speed_quantization": 0.25})
    np.testing.assert_allclose(q["omega1"] / 0.25, np.round(q["omega1"] / 0.25), atol=1e-9)
    plain = simulate(NOMINAL)
    slow = simulate(NOMINAL, effects={"sensor_lowpass": 200.0})
    fast = simulate(NOMINAL, effects={"sensor_lowpass": 5000.0})
    # a 200 Hz sensor distorts a1 far more than a 5 kHz one (RMS over the record;
    # at the event sample both still read the pre-event value: a sensor state is continuous)
    keep = np.ones(N_SAMPLES, bool)
    keep[EVENT_INDEX : EVENT_INDEX + 2] = False  # the motor-off step itself
    e_slow = np.sqrt(np.mean((slow["a1"] - plain["a1"])[keep] ** 2))
    e_fast = np.sqrt(np.mean((fast["a1"] - plain["a1"])[keep] ** 2))
    assert e_fast < 0.2 * e_slow
    assert slow["a1"][EVENT_INDEX] == pytest.approx(plain["a1"][EVENT_INDEX - 1], rel=0.3)
    # a slow channel (v2) passes a 5 kHz low-pass almost unchanged
    assert np.abs(fast["v2"] - plain["v2"]).max() < 0.01 * np.ptp(plain["v2"])


def test_white_noise_has_requested_snr(nominal):
    rng = np.random.default_rng(1)
    x = np.tile(nominal["v2"], (200, 1))
    noisy = add_white_noise(x, 30.0, rng)
    snr = 10 * np.log10(np.var(x[0]) / np.var(noisy - x))
    assert abs(snr - 30.0) < 0.2


@pytest.mark.serial  # with numba's threads on every core: the parallel part runs one per worker (Makefile)
def test_simulation_is_safe_from_several_threads():
    from concurrent.futures import ThreadPoolExecutor

    cases = [PlantParameters(K=K) for K in (0.0025, 0.005, 0.0075, 0.01)]
    expected = simulate_batch(cases).channels
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda _: simulate_batch(cases).channels, range(8)))
    for r in results:
        np.testing.assert_array_equal(r, expected)


@pytest.mark.serial  # with numba's threads on every core: the parallel part runs one per worker (Makefile)
def test_serial_kernel_matches_the_parallel_one_and_runs_concurrently():
    from concurrent.futures import ThreadPoolExecutor

    from engine.simulation import serial_kernel

    cases = [PlantParameters(K=K, J1=J1) for K, J1 in ((0.003, 0.8), (0.006, 0.85), (0.009, 0.9))]
    expected = simulate_batch(cases).channels

    def on_one_core(_):
        with serial_kernel():
            return simulate_batch(cases).channels

    with ThreadPoolExecutor(4) as pool:  # no launch lock inside serial_kernel: threads really overlap
        results = list(pool.map(on_one_core, range(8)))
    for r in results:
        np.testing.assert_array_equal(r, expected)
    # single cases take the serial path too, and the context is left as it was
    np.testing.assert_array_equal(simulate_batch(cases[:1]).channels[0], expected[0])


def test_a_diverged_integration_is_a_failure_never_a_nan_record():
    """A sensor low-pass too fast for the RK4 step blows up; the result must say so, not hold NaNs."""
    from engine.simulation import _kernel as kern
    from engine.simulation.simulator import run_cases

    fast = Case(PlantParameters(), SensorParameters(lowpass_hz=50_000.0))
    out, _, status = run_cases([fast, Case()], SolverSettings())
    assert status.tolist() == [kern.NON_FINITE, kern.OK]
    assert np.all(np.isfinite(out[1]))


def test_a_lowpass_too_fast_for_the_step_is_refused_with_the_limit():
    from engine.simulation.simulator import LOWPASS_STEP_LIMIT

    solver = SolverSettings()
    f_max = LOWPASS_STEP_LIMIT / (2 * np.pi * solver.max_step)
    with pytest.raises(ParameterError, match=rf"at most {f_max:.0f} Hz"):
        simulate(Case(PlantParameters(), SensorParameters(lowpass_hz=20_000.0)), solver=solver)
    # just below the limit it simulates, and finer steps admit faster filters
    near = simulate(Case(PlantParameters(), SensorParameters(lowpass_hz=0.95 * f_max)))
    assert all(np.all(np.isfinite(x)) for x in near.channels.values())
    simulate(Case(PlantParameters(), SensorParameters(lowpass_hz=20_000.0)), solver=SolverSettings(max_step=1e-5))
