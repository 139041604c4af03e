"""The ``backlash`` command: the service's endpoints as subcommands, plus serve, the main job and benchmarks.

One module per command group: :mod:`~app.cli.simulate` (simulate),
:mod:`~app.cli.pattern_sets` (train, pattern-sets), :mod:`~app.cli.identify`,
:mod:`~app.cli.diagnose`, :mod:`~app.cli.serve` and :mod:`~app.cli.evaluation`
(run, validate, bench); :mod:`~app.cli.common` holds what they share and
:mod:`~app.cli.main` the parser and the entry point.

Exit status: 0 success; 2 bad usage or input rejected (the message says what to
fix); 1 unexpected failure; 130 interrupted.
"""

from app.cli.main import build_parser, main

__all__ = ["build_parser", "main"]
