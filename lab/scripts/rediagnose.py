"""Diagnose cases of a finished validation run again, with the current code (development, not blind).

A scored run's cases are development data once read: this re-runs chosen ones with the code at
hand and prints, per case, its truth (from the run's answer key), the new answer, whether it is
right by the case kind's main criterion (:func:`engine.validation.score.correct`) and the time.
Nothing in the run directory is changed. The run directory can be made again from its seed
(``backlash validate --cases N --seed S --out DIR``: the cases and key are drawn by the seed).

Example (six triples of the seed-101 progress run)::

    python lab/scripts/rediagnose.py out/validation-v2-progress-seed101 \\
        case0031,case0045,case0052,case0064,case0068,case0092

``--kind single`` takes every case of one kind in place of a list of ids; with ``--seed S --cases N``
a directory that holds no cases yet gets the run's cases drawn first (no diagnosis:
:func:`engine.validation.run.prepare_cases`). The single-effect comparison of docs/diagnosis.md 8b
(*Early escalation*)::

    python lab/scripts/rediagnose.py out/s101 --kind single --seed 101 --cases 120 --sets '{"n_escalate_first": 0}'
    python lab/scripts/rediagnose.py out/s105 --kind single --seed 105 --cases 60

``--sets`` updates the default :class:`~engine.diagnosis.sets.SetSettings` of the diagnosis
(e.g. ``--sets '{"n_escalate_first": 0}'`` for the order before the early escalation), and
``--candidates`` its :class:`~engine.diagnosis.candidate.CandidateSettings` (e.g.
``--candidates '{"reseed_seed_fits": null}'`` refines every seed of the pass-1b refits); a dict for a
field that is itself settings updates that field (``--candidates '{"seeded": {"max_nfev": 20}}'``).

One JSON line per case on stdout (with where its time went: ``stages``, wall seconds per stage of
the work); the diagnosis's log on stderr (``--log-level``).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time

from _runs import add_run_arguments, chosen_entries, run_drive, run_library, updated


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(ap, "case ids, comma-separated (e.g. case0018,case0040)")
    ap.add_argument("--kind", help="every case of this kind (single, pair, triple, held_back, clean) instead of ids")
    ap.add_argument("--sets", default="{}", help="SetSettings fields as JSON, e.g. '{\"n_escalate_first\": 0}'")
    ap.add_argument(
        "--candidates", default="{}", help="CandidateSettings fields as JSON, e.g. '{\"reseed_seed_fits\": null}'"
    )
    ap.add_argument("--log-level", default="WARNING", help="log level of the diagnosis (default WARNING)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)

    from dataclasses import replace

    from engine.diagnosis import diagnose
    from engine.diagnosis.diagnose import DiagnosisSettings
    from engine.validation.score import answer_of, correct

    ds = DiagnosisSettings()
    try:
        settings = replace(ds, sets=updated(ds.sets, json.loads(args.sets)))
    except (TypeError, ValueError) as e:
        ap.error(f"--sets: {e}")
    try:
        settings = replace(settings, candidates=updated(ds.candidates, json.loads(args.candidates)))
    except (TypeError, ValueError) as e:
        ap.error(f"--candidates: {e}")
    if bool(args.ids) == bool(args.kind):
        ap.error("give case ids or --kind, not both and not neither")
    layout, entries = chosen_entries(ap, args, args.kind)
    library = run_library(ap, layout)  # the library the run gave every case
    drive = run_drive(ap, layout)  # and the drive its cases were simulated on
    for k in entries:
        cid = k.case_id
        t0 = time.perf_counter()
        result = diagnose(layout.read_case(cid), library, settings=settings, drive=drive).to_dict(include_records=False)
        seconds = time.perf_counter() - t0
        a = answer_of(result)
        row = {
            "case": cid,
            "kind": k.kind,
            "truth": list(k.effect_names),
            "status": a.status,
            "effects": list(a.names),
            "alternatives": [list(x) for x in a.alternatives],
            "near_twins": [list(x) for x in a.near_twins],
            "locus": a.locus,
            "correct": correct(k, a),
            "seconds": round(seconds, 1),
            "stages": [[x["stage"], round(x["seconds"], 1)] for x in result.get("stages", [])],
        }
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
