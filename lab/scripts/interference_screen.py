"""How much the sensor library's periodic interference lowers its BIC, record by record.

Development data only (a scored run's cases, read). The interference
(:mod:`engine.diagnosis.locus._interference`) changes one score of the locus estimate: the sensor
library's BIC. Whether it moves an answer is then known from that drop alone, beside a row of
:mod:`locus_cases` on the code before it (``delta_bic["sensors"]``, the sensors' BIC above the
best): the answer becomes ``sensors`` when the drop exceeds it. This runs the nominal calibration
and the locus's response batch only (a few seconds a record, not the whole estimate) and prints
one JSON line per case: the true effect and locus, the drop [chi2 units], the frequency and the
channels taken, and, given ``--before ROWS.jsonl``, the sensors' margin before and whether the
answer would turn to ``sensors``. The last line is a summary.

    python lab/scripts/interference_screen.py out/dev-sealed2-263 --before rows263.jsonl > screen263.jsonl
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

from _runs import add_run_arguments, chosen_entries


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(ap, "case ids, comma-separated (default: every held-back case)")
    ap.add_argument("--before", type=Path, help="rows of lab/scripts/locus_cases.py on the code before")
    ap.add_argument("--log-level", default="WARNING", help="log level (default WARNING)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)

    import numpy as np

    from engine.constants import CHANNELS
    from engine.diagnosis.calibration import calibrate
    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.diagnosis.locus import LocusSettings
    from engine.diagnosis.locus._estimate import sensor_fit
    from engine.diagnosis.locus._interference import segment_gain
    from engine.diagnosis.locus._linear import linear_fit, orth, project
    from engine.diagnosis.locus._responses import responses
    from engine.diagnosis.space import default_space

    before = {}
    if args.before is not None:
        for line in args.before.read_text().splitlines():
            row = json.loads(line)
            if "case" in row:
                before[row["case"]] = row
    layout, entries = chosen_entries(ap, args, "held_back")
    settings, locus_settings = DiagnosisSettings(), LocusSettings()
    turned, taken, n = [], 0, 0
    for k in entries:
        record, _ = layout.read_case(k.case_id).test_window()
        t0 = time.perf_counter()
        cal = calibrate(record, default_space(record), settings.calibration)
        sim = cal.simulated_record(record)
        names = list(record.channels)
        rows = [CHANNELS.index(c) for c in names]
        sigma = np.array([cal.sigma[c] for c in names])
        r = ((np.stack([record[c] for c in names]) - np.stack([sim[c] for c in names])) / sigma[:, None]).ravel()
        resp = responses(record, cal, sigma, rows, locus_settings)
        Q = orth(resp.params, r.size)
        rp = project(Q, r[:, None])[:, 0]
        t = record.grid.time
        fit = sensor_fit(resp, Q, rp, t, names, sigma, cal, locus_settings)
        hum = fit.interference
        drop = 0.0 if hum is None else fit.base_rss - hum.rss - hum.penalty
        ns = {}
        if hum is not None:  # the stationarity rule's statistic on the channels taken
            design = np.hstack([project(Q, resp.sensors), project(Q, resp.crosstalk[:, fit.cross])])
            _, _, c0 = linear_fit(design, rp, Q.shape[1])
            e = (rp - design @ c0).reshape(len(rows), -1)
            whole, gain = segment_gain(e, t - t[0], hum.frequency_hz, 4)
            ns = {names[j]: round(float(gain[j] / whole[j]), 4) for j in hum.channels}
        truth = k.effects[0] if k.effects else None
        row = {
            "case": k.case_id,
            "truth": None if truth is None else truth.name,
            "true_locus": None if truth is None else truth.locus,
            "drop": round(drop, 1),
            "frequency_hz": None if hum is None else round(hum.frequency_hz, 3),
            "channels": [] if hum is None else [names[j] for j in hum.channels],
            "segment_share": ns,
            "seconds": round(time.perf_counter() - t0, 1),
        }
        n += 1
        taken += hum is not None
        if k.case_id in before:
            b = before[k.case_id]
            margin = b["delta_bic"].get("sensors")
            row["locus_before"] = b["locus"]
            row["sensors_margin_before"] = margin
            row["turns_to_sensors"] = bool(margin is not None and margin > 0 and drop > margin)
            if row["turns_to_sensors"]:
                turned.append((k.case_id, row["true_locus"]))
        print(json.dumps(row), flush=True)
    print(json.dumps({"summary": f"interference taken in {taken}/{n}", "turns_to_sensors": turned}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
