"""Where a quantum set's rounded omega1 misses the record: samples in the wrong cell, and how near an edge.

Development, not blind: reads the stored diagnoses of a finished validation run. For each chosen
case, the best reported model that holds the speed quantum is simulated again from its stored
values (no fit): the unrounded omega1, and once more with each calibrated value moved by its
stored uncertainty. It prints, as one JSON line per case:

- ``off_cell``: the samples whose record value lies in another rounding cell than the model's
  (``|y - q round(x / q)| > q / 2``), and ``edge_q``: how far the unrounded model ``x`` is from
  the nearest cell edge there, in quanta;
- ``edge_sigma``: the same distance over ``sigma_x``, the spread of ``x`` from the fitted values'
  uncertainties propagated one parameter at a time (diagonal: correlations ignored, so it
  overstates the spread where parameters trade; a step is cut at the parameter's bound), and ``within_2sigma``: how many samples of the
  record lie within 2 ``sigma_x`` of an edge;
- ``chi2n_omega1`` and ``chi2n_omega1_in_cell``: omega1's chi2/n against the white noise level the
  fit reports, with every sample and without the off-cell ones.

Example (the quantum compounds answered ``unexplained`` on seed 191, docs/diagnosis.md 8b)::

    python lab/scripts/quantum_flips.py out/validation-v2-seed191 case0028,case0036,case0046,case0115
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from typing import Any

import numpy as np
from _runs import add_run_arguments, chosen_entries

from engine.constants import CHANNELS
from engine.diagnosis.budget import case_with
from engine.diagnosis.space import default_space
from engine.records import Record
from engine.simulation import CATALOGUE, SolverSettings, run_cases

logger = logging.getLogger(__name__)

QUANTUM = "speed_quantization"


def quantum_model(result: dict[str, Any]) -> dict[str, Any] | None:
    """The best reported model (single or set) that holds the speed quantum, or None."""
    for c in result["candidates"]:
        names = [e["effect"] for e in c["effects"]] if c.get("effects") else [c["effect"]]
        if QUANTUM in names and c.get("calibration"):
            return {"names": names, **c}
    return None


def moved(value: float, step: float, bounds: tuple[float, float]) -> float:
    """``value`` moved by ``step`` towards the inside of ``bounds``, at most to the bound (an
    uncertainty wider than the range, such as a member's that the record barely sees, moves it
    to the bound)."""
    lo, hi = bounds
    return min(value + step, hi) if hi - value >= value - lo else max(value - step, lo)


def flips(record: Record, model: dict[str, Any], bounds: dict[str, Any] | None) -> dict[str, Any]:
    """The off-cell samples of ``model``'s rounded omega1 on ``record`` (see the module notes).

    ``bounds`` are the search box the run's diagnoses used (None: the default box, as in every
    validation run). Raises ValueError when a stored value lies outside it (the model space would
    clip it) or a free parameter has no stored value, RuntimeError when a simulation fails.
    """
    cal = model["calibration"]
    values: dict[str, float] = dict(cal["values"])
    unc: dict[str, float] = cal["uncertainties"]
    q = float(values[QUANTUM])
    space = default_space(record, bounds)
    effects = [CATALOGUE[n] for n in model["names"] if n != QUANTUM]
    box = {p.name: (p.lo, p.hi) for p in space.params} | {e.name: e.bounds for e in effects}
    outside = [
        k for k, (lo, hi) in box.items() if k in values and not lo - 1e-9 * abs(lo) <= values[k] <= hi + 1e-9 * abs(hi)
    ]
    if outside:  # the model space would clip them: a run diagnosed with other bounds than the default box
        raise ValueError(
            f"stored values of {', '.join(outside)} lie outside the default search box "
            f"{ {k: box[k] for k in outside} }; pass the run's bounds"
        )
    free = [k for k in values if k in box and unc.get(k)]
    cases = [case_with(space, values, effects)]
    cases += [case_with(space, {**values, k: moved(values[k], unc[k], box[k])}, effects) for k in free]
    ch, _, status = run_cases(cases, SolverSettings(max_step=cal["step"]), record.grid)
    if np.any(status != 0):
        raise RuntimeError(f"a simulation of {'+'.join(model['names'])} failed (status {status.tolist()})")
    j = CHANNELS.index("omega1")
    x, y = ch[0, j], np.asarray(record["omega1"])
    sigma_x = np.sqrt(np.sum((ch[1:, j] - x) ** 2, axis=0))
    edge = (0.5 - np.abs(x / q - np.round(x / q))) * q  # distance to the nearest cell edge [rad/s]
    off = np.abs(y - q * np.round(x / q)) > q / 2.0
    r = (y - q * np.round(x / q)) / float(cal["noise"]["omega1"])
    return {
        "model": "+".join(model["names"]),
        "chi2n": cal["reduced_chi2"],
        "q": q,
        "off_cell": int(off.sum()),
        "edge_q": np.round(edge[off] / q, 4).tolist(),
        "edge_sigma": np.round(edge[off] / np.maximum(sigma_x[off], 1e-300), 3).tolist(),
        "within_2sigma": int(np.sum(edge < 2.0 * sigma_x)),
        "n": int(y.size),
        "chi2n_omega1": float(np.mean(r**2)),
        "chi2n_omega1_in_cell": float(np.mean(r[~off] ** 2)) if np.any(~off) else None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(ap, "case ids, comma-separated (default: every case)")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    layout, entries = chosen_entries(ap, args, None)
    failed = 0
    for entry in entries:
        result = layout.read_result(entry.case_id)
        model = quantum_model(result)
        if model is None:
            logger.warning("%s: no reported model holds the speed quantum", entry.case_id)
            continue
        record = layout.read_case(entry.case_id).test_window()[0]
        try:
            row = {"case": entry.case_id, **flips(record, model, None)}
        except (ValueError, RuntimeError) as exc:
            logger.error("%s: %s", entry.case_id, exc)
            failed += 1
            continue
        print(json.dumps(row), flush=True)
    if failed:
        sys.exit(f"{failed} of {len(entries)} cases could not be read (above)")


if __name__ == "__main__":
    main()
