"""Write ``record.csv``: a synthetic rig test of the quarter-car FMU at nominal values, with sensor noise.

The post's displacement (``z_road``) is a 2 s test sampled at 1 kHz: a rest, a 20 mm haversine bump
(a raised cosine of 0.15 s), a rest, then an exponential sine sweep of 5 mm from 0.5 to 20 Hz, which
passes the body mode (about 1.2 Hz) and the wheel hop (about 11.8 Hz). The FMU (built from this
folder with :func:`engine.plants.fmu.build.build_fmu`) is driven by it at its start values (nominal
parameters, neutral effects, no unknown inputs) with a 1 ms communication step; white Gaussian
noise of the levels in :data:`NOISE` is added to the measured outputs (``z_road`` is the rig
controller's displacement, kept noise-free). Deterministic: NumPy's ``default_rng(SEED)``.

Run from anywhere: ``python engine/plants/fmu/examples/quarter_car/make_record.py``.
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

#: Sample interval of the record [s] and its duration [s].
DT: float = 1e-3
DURATION: float = 2.0
#: Seed of the sensor noise.
SEED: int = 20550
#: Standard deviation of the white sensor noise per output, in the output's unit.
NOISE: dict[str, float] = {"a_body": 0.02, "x_susp": 5e-5, "a_wheel": 0.2}
#: The FMU's outputs in the record, in column order.
OUTPUTS: tuple[str, ...] = ("a_body", "x_susp", "a_wheel")


def road_profile(t: np.ndarray) -> np.ndarray:
    """The post's displacement [m] of the rig test at times ``t`` [s].

    Parameters
    ----------
    t : numpy.ndarray
        Times [s], 0 to 2.

    Returns
    -------
    numpy.ndarray
        ``z_road`` [m]: rest to 0.1 s, a 20 mm haversine bump 0.1 to 0.25 s, rest to 0.6 s, an
        exponential sine sweep of 5 mm amplitude from 0.5 Hz (at 0.6 s) to 20 Hz (at 2.0 s).
    """
    t = np.asarray(t, dtype=float)
    z = np.zeros_like(t)
    t_bump, length, height = 0.1, 0.15, 0.02  # start [s], duration [s], height [m]
    on = (t >= t_bump) & (t <= t_bump + length)
    z[on] = 0.5 * height * (1.0 - np.cos(2.0 * np.pi * (t[on] - t_bump) / length))
    t0, t1, f0, f1, amp = 0.6, 2.0, 0.5, 20.0, 0.005  # sweep start/end [s], [Hz], amplitude [m]
    on = t >= t0
    tau = t[on] - t0
    rate = np.log(f1 / f0) / (t1 - t0)  # [1/s]
    phase = 2.0 * np.pi * f0 * (np.exp(rate * tau) - 1.0) / rate  # [rad]
    z[on] = amp * np.sin(phase)
    return z


def simulate(
    fmu: str | Path,
    t: np.ndarray,
    z_road: np.ndarray,
    parameters: Mapping[str, float] | None = None,
    outputs: Sequence[str] = OUTPUTS,
) -> np.ndarray:
    """Drive the FMU with ``z_road`` held over each interval of ``t``; return its outputs at ``t``.

    Parameters
    ----------
    fmu : str or Path
        The built quarter-car FMU.
    t : numpy.ndarray
        Communication points [s], increasing, from the experiment's start.
    z_road : numpy.ndarray
        The post's displacement [m] at ``t``; ``z_road[k]`` is held from ``t[k]`` to ``t[k + 1]``.
    parameters : mapping of str to float, optional
        Parameters set before initialisation (by name); the rest keep their start values.
    outputs : sequence of str
        The variables returned.

    Returns
    -------
    numpy.ndarray
        Shape ``(len(t), len(outputs))``: row ``k`` is the outputs at ``t[k]`` (row 0 after
        initialisation).
    """
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    description = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in description.modelVariables}
    unzipdir = extract(str(fmu))
    slave = FMU2Slave(
        guid=description.guid,
        unzipDirectory=unzipdir,
        modelIdentifier=description.coSimulation.modelIdentifier,
        instanceName="quarter_car",
    )
    try:
        slave.instantiate()
        slave.setupExperiment(startTime=float(t[0]))
        slave.enterInitializationMode()
        params = dict(parameters or {})
        if params:
            slave.setReal([vr[name] for name in params], [float(value) for value in params.values()])
        slave.setReal([vr["z_r"]], [float(z_road[0])])
        slave.exitInitializationMode()
        out_vr = [vr[name] for name in outputs]
        y = np.empty((len(t), len(out_vr)))
        y[0] = slave.getReal(out_vr)
        z_vr = [vr["z_r"]]
        for k in range(len(t) - 1):
            slave.setReal(z_vr, [float(z_road[k])])
            slave.doStep(currentCommunicationPoint=float(t[k]), communicationStepSize=float(t[k + 1] - t[k]))
            y[k + 1] = slave.getReal(out_vr)
        slave.terminate()
    finally:
        slave.freeInstance()
    return y


def make_record(path: str | Path = HERE / "record.csv") -> Path:
    """Build the FMU, simulate the rig test, add the sensor noise and write the record.

    Parameters
    ----------
    path : str or Path
        The CSV written (columns ``t, z_road, a_body, x_susp, a_wheel``).

    Returns
    -------
    Path
        ``path``.
    """
    from engine.plants.fmu.build import build_fmu

    n = round(DURATION / DT) + 1
    t = np.arange(n) * DT
    z_road = road_profile(t)
    with tempfile.TemporaryDirectory(prefix="quarter-car-") as tmp:
        y = simulate(build_fmu(HERE, tmp), t, z_road)
    rng = np.random.default_rng(SEED)
    noisy = y + rng.standard_normal(y.shape) * np.array([NOISE[name] for name in OUTPUTS])
    path = Path(path)
    table = np.column_stack([t, z_road, noisy])
    header = ",".join(["t", "z_road", *OUTPUTS])
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt=["%.3f", "%.9e", "%.6e", "%.6e", "%.6e"])
    return path


if __name__ == "__main__":
    import logging

    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("make_record").info("wrote %s", make_record())
