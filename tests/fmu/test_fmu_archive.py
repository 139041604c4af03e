"""An FMU archive checked as a file before it is stored or run (engine/plants/fmu/archive.py).

The reference archive is the quarter-car example built from its sources; every refusal is made
from it by one change (a member removed or renamed, the version changed, the limit lowered).
"""

from __future__ import annotations

import hashlib
import io
import zipfile

import pytest

from engine.plants.fmu import EXAMPLES_DIR
from engine.plants.fmu.archive import FmuArchiveError, inspect_archive
from engine.plants.fmu.build import build_fmu

LIMIT = 64 << 20


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    return build_fmu(EXAMPLES_DIR / "quarter_car", tmp_path_factory.mktemp("qc")).read_bytes()


def rezip(content: bytes, change: dict[str, bytes | None]) -> bytes:
    """``content`` with members replaced (bytes), removed (None) or added (a new name)."""
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(content)) as src, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            if info.filename in change:
                continue
            dst.writestr(info, src.read(info))
        for name, data in change.items():
            if data is not None:
                dst.writestr(name, data)
    return out.getvalue()


def test_an_fmu_is_described_by_its_hash_and_variables(archive: bytes) -> None:
    summary = inspect_archive(archive, LIMIT)
    assert summary.sha256 == hashlib.sha256(archive).hexdigest()
    assert summary.size == len(archive) and summary.unpacked > summary.size
    assert (summary.fmi_version, summary.identifier) == ("2.0", "quarter_car")
    assert "linux64" in summary.platforms
    assert set(summary.inputs) == {"z_r", "F_body", "F_wheel"}
    assert {"a_body", "x_susp", "a_wheel"} == set(summary.outputs)
    assert {"m_s", "c_s", "F_c", "k3"} <= set(summary.parameters)


def test_what_is_not_an_fmu_is_refused_with_what_to_send(archive: bytes) -> None:
    with pytest.raises(FmuArchiveError, match="zip archive"):
        inspect_archive(b"MZ\x90\x00 not a zip at all", LIMIT)
    with pytest.raises(FmuArchiveError, match=r"no modelDescription\.xml"):
        inspect_archive(rezip(archive, {"modelDescription.xml": None}), LIMIT)
    with pytest.raises(FmuArchiveError, match="cannot be read"):
        inspect_archive(rezip(archive, {"modelDescription.xml": b"<not xml"}), LIMIT)
    with zipfile.ZipFile(io.BytesIO(archive)) as z:
        xml = z.read("modelDescription.xml")
    fmi3 = xml.replace(b'fmiVersion="2.0"', b'fmiVersion="3.0"')
    assert fmi3 != xml
    with pytest.raises(FmuArchiveError, match=r"cannot be read|FMI 2\.0 co-simulation"):  # FMPy validates it first
        inspect_archive(rezip(archive, {"modelDescription.xml": fmi3}), LIMIT)


def test_an_archive_that_would_escape_or_explode_is_refused_before_unpacking(archive: bytes) -> None:
    with pytest.raises(FmuArchiveError, match="outside its folder"):
        inspect_archive(rezip(archive, {"../evil.so": b"x"}), LIMIT)
    with pytest.raises(FmuArchiveError, match="outside its folder"):
        inspect_archive(rezip(archive, {"/etc/evil": b"x"}), LIMIT)
    summary = inspect_archive(archive, LIMIT)
    with pytest.raises(FmuArchiveError, match=f"unpacks to {summary.unpacked} bytes; at most 1024"):
        inspect_archive(archive, 1024)
    bomb = rezip(archive, {"resources/zeros.bin": bytes(8 << 20)})  # compresses to a few kB
    assert len(bomb) < len(archive) + 100_000
    with pytest.raises(FmuArchiveError, match="unpacks to"):
        inspect_archive(bomb, 4 << 20)


def test_an_fmu_without_a_binary_for_this_machine_is_refused(archive: bytes) -> None:
    with zipfile.ZipFile(io.BytesIO(archive)) as z:
        binaries = [n for n in z.namelist() if n.startswith("binaries/")]
    assert binaries
    with pytest.raises(FmuArchiveError, match="no co-simulation binary for this machine"):
        inspect_archive(rezip(archive, dict.fromkeys(binaries)), LIMIT)
