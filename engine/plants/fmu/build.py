"""Build a source FMU (``modelDescription.xml`` and ``sources/``) into a ``.fmu`` with the system C compiler.

The project's example FMUs are shipped as C sources of the project's FMI 2.0 framework
(``engine/plants/fmu/c``: :file:`model.h`, the contract a model implements, and :file:`fmi2_cs.c`,
every FMI function around it). :func:`build_fmu` copies a model's folder and the framework into a
temporary folder, compiles the platform binary with FMPy's CMake project
(:func:`fmpy.build.build_platform_binary`, which uses the FMI headers FMPy ships and the system C
compiler) and zips the result (:func:`fmpy.util.create_zip_archive`). Nothing is downloaded.

A build is cached: the ``.fmu`` is named by the SHA-256 of every source file, so building the same
sources again returns the existing file.
"""

from __future__ import annotations

import hashlib
import logging
import shutil
import subprocess
import tempfile
from pathlib import Path

__all__ = ["FRAMEWORK_DIR", "FmuBuildError", "build_fmu", "source_digest"]

log = logging.getLogger(__name__)

#: The framework's C files, copied into every model's ``sources/``.
FRAMEWORK_DIR: Path = Path(__file__).parent / "c"
_FRAMEWORK_FILES: tuple[str, ...] = ("model.h", "fmi2_cs.c")


class FmuBuildError(RuntimeError):
    """Raised when a source FMU cannot be built (missing files, compiler errors); the message says which."""


def _source_files(source_dir: Path) -> list[Path]:
    files = [source_dir / "modelDescription.xml"]
    files += sorted(p for p in (source_dir / "sources").rglob("*") if p.is_file() and p.suffix in {".c", ".h"})
    files += [FRAMEWORK_DIR / name for name in _FRAMEWORK_FILES]
    return files


def source_digest(source_dir: str | Path) -> str:
    """SHA-256 (hex) of a source FMU's description, its C sources and the framework's files.

    Raises
    ------
    FmuBuildError
        When ``modelDescription.xml`` or ``sources/`` is missing.
    """
    source_dir = Path(source_dir)
    if not (source_dir / "modelDescription.xml").is_file() or not (source_dir / "sources").is_dir():
        raise FmuBuildError(f"{source_dir} is not a source FMU: it needs modelDescription.xml and a sources/ folder")
    h = hashlib.sha256()
    for path in _source_files(source_dir):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def build_fmu(source_dir: str | Path, out_dir: str | Path) -> Path:
    """Build the source FMU in ``source_dir`` into ``out_dir``; return the ``.fmu``'s path.

    Parameters
    ----------
    source_dir : str or Path
        A folder with ``modelDescription.xml`` (FMI 2.0, co-simulation or model exchange or both under
        one model identifier, whose ``<SourceFiles>`` list the model's C files and ``fmi2_cs.c``) and ``sources/`` (the model's C files).
    out_dir : str or Path
        Where the ``.fmu`` is written (created if absent), as ``<modelIdentifier>-<digest>.fmu``.

    Returns
    -------
    Path
        The built FMU (an existing one of the same sources is returned as it is).

    Raises
    ------
    FmuBuildError
        When the folder is not a source FMU, or CMake or the compiler fails (their output is in the
        message).
    """
    from fmpy import read_model_description
    from fmpy.util import create_zip_archive

    source_dir = Path(source_dir)
    digest = source_digest(source_dir)
    description = read_model_description(str(source_dir / "modelDescription.xml"))
    interfaces = [i for i in (description.coSimulation, description.modelExchange) if i is not None]
    if not interfaces:
        raise FmuBuildError(f"{source_dir}: modelDescription.xml declares neither <CoSimulation> nor <ModelExchange>")
    identifiers = {i.modelIdentifier for i in interfaces}
    if len(identifiers) > 1:  # the framework builds one library that serves both
        raise FmuBuildError(f"{source_dir}: the interfaces' modelIdentifiers differ ({sorted(identifiers)}); use one")
    (identifier,) = identifiers
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{identifier}-{digest[:16]}.fmu"
    if target.is_file():
        return target
    with tempfile.TemporaryDirectory(prefix=f"fmu-{identifier}-") as tmp:
        unzipdir = Path(tmp) / "fmu"
        build_dir = Path(tmp) / "build"
        build_dir.mkdir()
        shutil.copytree(
            source_dir,
            unzipdir,
            ignore=shutil.ignore_patterns("*.fmu", "__pycache__", "*.toml", "*.csv", "*.md", "*.py"),
        )
        for name in _FRAMEWORK_FILES:
            shutil.copy2(FRAMEWORK_DIR / name, unzipdir / "sources" / name)
        _compile(unzipdir, build_dir, identifier, source_dir)
        partial = out_dir / f".{target.name}.partial"
        create_zip_archive(partial, unzipdir)
        partial.replace(target)  # atomic: a concurrent build never sees half a file
    log.info("built %s from %s", target.name, source_dir)
    return target


def _cmake() -> str | None:
    """The CMake of the ``cmake`` package (a dependency of FMPy), else the one on the PATH."""
    try:
        import cmake

        exe = Path(cmake.CMAKE_BIN_DIR) / "cmake"
        if exe.is_file():
            return str(exe)
    except (ImportError, AttributeError):
        pass
    return shutil.which("cmake")


def _compile(unzipdir: Path, build_dir: Path, identifier: str, source_dir: Path) -> None:
    """The platform binary of the FMU unpacked in ``unzipdir``: FMPy's CMake project and settings, output captured.

    The same two CMake calls as :func:`fmpy.build.build_platform_binary`, whose output would go to the
    terminal; here it is kept, and raised with the error.
    """
    import fmpy
    from fmpy.build import create_cmake_settings

    create_cmake_settings(unzipdir, build_dir)
    project = Path(fmpy.__file__).parent / "c-code"
    cmake = _cmake()
    if cmake is None:
        raise FmuBuildError("building an FMU needs CMake (the cmake package, a dependency of FMPy) on the PATH")
    for command in (
        [cmake, "-S", str(project), "-B", str(build_dir)],
        [cmake, "--build", str(build_dir), "--target", "install", "--config", "Release"],
    ):
        out = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, check=False)
        if out.returncode != 0:
            raise FmuBuildError(f"building {identifier} from {source_dir} failed ({command[1]}):\n{out.stdout[-4000:]}")
