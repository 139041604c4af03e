"""Loading the scripts of ``bench/`` (benchmarks) and ``lab/scripts/`` (development replays) in tests, as running them does."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]

#: Where the scripts live: the benchmarks proper, then the lab's replays of validation cases.
FOLDERS = (ROOT / "bench", ROOT / "lab" / "scripts")


def load_bench(name: str) -> ModuleType:
    """The module of ``bench/<name>.py`` or ``lab/scripts/<name>.py``, with its folder on the path
    (the lab's scripts import their neighbour ``lab/scripts/_runs.py``, as when run from the
    repository root)."""
    folder = next((f for f in FOLDERS if (f / f"{name}.py").is_file()), None)
    assert folder is not None, f"no script {name}.py in {', '.join(str(f.relative_to(ROOT)) for f in FOLDERS)}"
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # as an import does: a dataclass of the script looks its module up there
    spec.loader.exec_module(module)
    return module
