"""Write ``record.csv``: a synthetic backlash test of the drive FMU at MODEL.md's nominal plant, with noise.

MODEL.md's test (section 2): at rest at t = 0, the motor switched on direct-on-line, switched off at
the event t_e (the clutch re-entering its zone). The FMU (built from this folder with
:func:`engine.plants.fmu.build.build_fmu`) is sampled every :data:`DT` from the switch-on to
:data:`AFTER` after the event, at its start values (K 5 mm, J1 0.87, c 1.0, c1 0.2, neutral effects,
no unknown inputs), and white Gaussian noise of :data:`NOISE_SHARE` of each channel's RMS is added
(40 dB). Deterministic: NumPy's ``default_rng(SEED)``.

Run from the repository root: ``python engine/plants/fmu/examples/backlash_drive/make_record.py``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

#: Sample interval [s] (MODEL.md: 0.1 ms) and the time kept after the event [s].
DT: float = 1e-4
AFTER: float = 0.2
#: Seed of the noise and its level, as a share of each channel's RMS.
SEED: int = 20551
NOISE_SHARE: float = 0.01
#: The channels, in column order.
CHANNELS: tuple[str, ...] = ("a1", "m_el", "omega1", "a2", "v2")


def main() -> None:
    """Simulate, add the noise, write ``record.csv`` beside this file."""
    from engine.plants.fmu.build import build_fmu
    from engine.plants.fmu.runner import FmuModel

    with tempfile.TemporaryDirectory() as tmp:
        model = FmuModel(build_fmu(HERE, tmp))
        probe = np.arange(0.0, 1.0, DT)
        t_event = model.simulate(probe, 0.0, {}, {}, ["t_event"])[0]
        te = float(t_event[t_event > 0][0])
        t = np.arange(0, round((te + AFTER) / DT) + 1) * DT
        y = model.simulate(t, 0.0, {}, {}, list(CHANNELS))
    rng = np.random.default_rng(SEED)
    noisy = [row + rng.normal(0.0, NOISE_SHARE * float(np.sqrt(np.mean(row**2))), row.size) for row in y]
    header = "t [s],a1 [m/s2],m_el [pu],omega1 [rad/s],a2 [m/s2],v2 [m/s]"
    data = np.column_stack([t, *noisy])
    np.savetxt(HERE / "record.csv", data, delimiter=",", header=header, comments="", fmt="%.10g")


if __name__ == "__main__":
    main()
