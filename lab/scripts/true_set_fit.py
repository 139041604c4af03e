"""Can a compound record's true set reach the noise, and from where? (development, not blind)

For each chosen case of a scored protocol-2 run, the nominal model is calibrated as the diagnosis
does, and the case's *true* set of effects (from the run's answer key) is fitted jointly
(:func:`engine.diagnosis.sets._fit_set`, the set search's own fit) from two starts:

- ``truth``: the true effect values at the true operating point (K, J1, c);
- ``nominal_point``: the true effect values at the nominal calibration's operating point, where
  every set fit of the diagnosis starts.

A true set that reaches the noise from ``truth`` but not from ``nominal_point`` is a search
failure of the start, not a model the data reject. One JSON line per case and start. Used for the
seed-223 records case0025 and case0136 (``docs/validation/v2-seed223/README.md``)::

    python lab/scripts/true_set_fit.py out/validation-v2-seed223 case0025,case0136
"""

from __future__ import annotations

import argparse
import json
import logging
import sys

from _runs import add_run_arguments, chosen_entries

from engine.diagnosis.calibration import calibrate
from engine.diagnosis.diagnose import DiagnosisSettings
from engine.diagnosis.sets import _fit_set
from engine.diagnosis.space import default_space
from engine.simulation import CATALOGUE

logger = logging.getLogger("lab.true_set_fit")


def main(argv: list[str] | None = None) -> int:
    """Fit the true set of each chosen case from both starts; 2 when a chosen case has no catalogue set."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(ap, "case ids, comma-separated (e.g. case0025,case0136)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    layout, entries = chosen_entries(ap, args, None)
    settings = DiagnosisSettings().calibration
    failed = 0
    for k in entries:
        names = [e.name for e in k.effects]
        if not names or any(n not in CATALOGUE for n in names):
            logger.error("%s: its truth %s is not a set of catalogue effects", k.case_id, names or "(none)")
            failed += 1
            continue
        members = [CATALOGUE[n] for n in names]
        truth = {e.name: e.value for e in k.effects}
        record = layout.read_case(k.case_id).test_window()[0]
        space = default_space(record)
        nominal = calibrate(record, space, settings)
        at_nominal = {**nominal.values, **truth}
        true_point = {n: v for n, v in {"K": k.K, "J1": k.J1, "c": k.c}.items() if n in nominal.values}
        starts = {"truth": {**at_nominal, **true_point}, "nominal_point": at_nominal}
        for start, seed in starts.items():
            cal = _fit_set(record, space, members, settings, nominal.noise, [seed], True)
            row = {
                "case": k.case_id,
                "start": start,
                "truth": truth,
                "true_point": true_point,
                "values": None if cal is None else cal.values,
                "chi2n": None if cal is None else cal.reduced_chi2,
            }
            print(json.dumps(row), flush=True)
    return 2 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
