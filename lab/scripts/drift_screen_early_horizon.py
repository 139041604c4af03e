"""Experiment (not kept): rank the part-parameter drifts by the first stage of their global search.

Development data only. The locus's joint fits (``engine/diagnosis/locus/_starts.py``, ``joint_fits``)
fit every drift of a ``PART_FIELDS`` parameter with K, J1 and c by a global search, about 1.4 s
each. A screen that fitted only the best few would need to rank the true field high. This ranks
the fields by the least chi2 of the global search's Sobol points (256, the escalated fits'
settings) on its first two horizons, and prints the true field's rank per record::

    python lab/scripts/drift_screen_early_horizon.py out/dev-locus-seed303 case0000,case0002,...

Result (seed 303, the 15 drift records): the true field in the top 3 in 10 of 15 on the first
horizon, 11 of 15 on the second; a screen would lose the rest (``README.md`` of that folder).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import qmc

#: The field each drift of the development family sets.
FIELD = {"supply_frequency_drift": "f", "resilient_damping_drift": "d2", "load_mass_drift": "T3"}


def main(argv: list[str]) -> int:
    from engine.diagnosis.calibration import calibrate
    from engine.diagnosis.candidate import ESCALATED_FITS
    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.diagnosis.locus._cases import is_coulomb, part_terms
    from engine.diagnosis.locus._starts import _drift_effect
    from engine.diagnosis.noise import noise_weights
    from engine.diagnosis.objective import Objective
    from engine.diagnosis.space import default_space
    from engine.simulation import DISTURBANCE_LOCI, SolverSettings
    from engine.validation.layout import RunLayout

    layout = RunLayout(Path(argv[0]))
    cs = ESCALATED_FITS
    m = 1 << max(3, int(np.ceil(np.log2(cs.n_global))))
    for cid in argv[1].split(","):
        truth = next(iter(layout.key_entries([cid]))).effects[0].name
        record, _ = layout.read_case(cid).test_window()
        nominal = calibrate(record, default_space(record), DiagnosisSettings().calibration)
        space = default_space(record)
        sigma = noise_weights(record, nominal.noise)
        horizons = cs.horizons(record)
        coarse = SolverSettings(max_step=cs.search_step)
        scores: dict[str, tuple[float, float]] = {}
        t0 = time.perf_counter()
        for locus in DISTURBANCE_LOCI:
            for field in part_terms(locus, list(nominal.values)):
                if is_coulomb(field):
                    continue
                es = space.with_effect(_drift_effect(locus, field))
                U = qmc.Sobol(es.dim, scramble=True, seed=cs.seed).random(m)
                C = Objective(record, es, sigma).chi2(U, horizons[:2], coarse)
                scores[field] = (float(np.min(C[:, 0])), float(np.min(C[:, 1])))
        ranks = [sorted(scores, key=lambda f: scores[f][0]), sorted(scores, key=lambda f: scores[f][1])]
        tf = FIELD.get(truth)
        where = ["-" if tf is None else str(r.index(tf) + 1) for r in ranks]
        print(cid, truth, "true field's rank, first/second horizon:", "/".join(where), "top 3:", ranks[0][:3],
              ranks[1][:3], f"screen {time.perf_counter() - t0:.1f} s", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
