"""The published simulation errors of the rigid EMPS model, and ours beside them.

The authors (report, section 3.5) simulate the rigid model with the published parameters in the PD
loop and compare its raw states with the measured channels (``Simulation_EMPS.m``): relative error
``100 ||y - y_sim|| / ||y||`` (eq. 11) from sample 50 on. :func:`reproduce` does the same with our
kernel (:meth:`~engine.plants.emps.model.EmpsPlant.states`).

Where ours differs (measured on the shipped records, see docs/emps.md, "The published errors, reproduced"):

- velocity, acceleration and force agree within :data:`TOLERANCE` (the largest difference is the
  pulse record's velocity, 0.40 % against 0.48 %: ours lower); the acceleration is sensitive, as the raw simulated acceleration chatters where the sign(v) of the Coulomb term
  flips at standstill and the published solver (ode23tb, variable step, zero crossings off) and
  ours (RK4, 0.1 ms) resolve that chatter differently (ours converges to 8.76 % / 18.65 % with 100
  sub-steps per sample, against the published 8.60 % / 19.82 %);
- our position error is several times below the published one (0.0016 % against 0.0138 %). At a
  standstill the PD loop leaves the axis anywhere within the friction dead band
  ``Fc / (g_tau kv kp)`` = 15 um of the reference, and the published error (20 um RMS) is of that
  order: where in the dead band each stop ends depends on the integrator. We have no MATLAB here to
  confirm this on their side; it is our reading, not a measurement.
"""

from __future__ import annotations

from engine.plants.base import relative_errors
from engine.plants.emps.model import PUBLISHED, EmpsPlant
from engine.plants.emps.record import EmpsRecord

__all__ = ["PUBLISHED_ERRORS", "TOLERANCE", "reproduce"]

#: The published relative errors [%] of the rigid model with the published parameters (report,
#: section 3.5; the values its scripts print).
PUBLISHED_ERRORS: dict[str, dict[str, float]] = {
    "DATA_EMPS": {"position": 0.013752, "velocity": 0.22911, "acceleration": 8.6036, "force": 5.848},
    "DATA_EMPS_PULSES": {"position": 0.0080248, "velocity": 0.47888, "acceleration": 19.8152, "force": 8.9409},
}
#: Accepted relative difference between our figure and the published one, for velocity,
#: acceleration and force (the position: below the published figure, module docstring).
TOLERANCE: float = 0.20


def reproduce(plant: EmpsPlant, record: EmpsRecord, through_chain: bool = False) -> dict[str, float]:
    """Relative errors [%] per channel of the published rigid model.

    Compared as the authors compare (raw simulated states), or, with ``through_chain``, like with
    like: the simulated position through the same filter and differences as the measured one.
    """
    sim = plant.simulate(record, PUBLISHED) if through_chain else plant.states(record, PUBLISHED)
    return relative_errors(plant.measured(record), sim, plant.scored(record))


def table() -> str:
    """Markdown table of ours beside the published errors, on the shipped records (and like with like)."""
    plant = EmpsPlant()
    lines = [
        "| record | channel | published [%] | ours [%] | ours, simulation through the measurement chain [%] |",
        "| --- | --- | ---: | ---: | ---: |",
    ]
    for name, published in PUBLISHED_ERRORS.items():
        record = plant.example(name)
        ours, chain = reproduce(plant, record), reproduce(plant, record, through_chain=True)
        lines += [f"| {name} | {c} | {published[c]:.4g} | {ours[c]:.4g} | {chain[c]:.4g} |" for c in published]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    import sys

    sys.stdout.write(table())
