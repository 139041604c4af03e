"""An FMU archive as a file someone sent: checked before anything in it is unpacked or run (issue 55).

An FMU is a zip archive of a ``modelDescription.xml`` and shared libraries, native code that runs
in the process that instantiates it. A service that accepts FMUs from its clients checks the
archive as a file first (:func:`inspect_archive`): its size, what it would unpack to, that no
member would land outside its folder, that it is an FMI 2.0 FMU (co-simulation, model exchange or
both), and that it has a binary for this machine's platform for each interface it offers. Only an archive that passes is stored and later run (by
:class:`~engine.plants.fmu.runner.FmuModel`, in the service's worker processes).
"""

from __future__ import annotations

import hashlib
import io
import zipfile
from dataclasses import dataclass
from pathlib import PurePosixPath

__all__ = ["MAX_MEMBERS", "FmuArchiveError", "FmuSummary", "inspect_archive"]

#: Most members an FMU archive may have (an FMU has a handful; a hundred thousand is a zip bomb's shape).
MAX_MEMBERS: int = 10_000


class FmuArchiveError(ValueError):
    """An FMU archive refused as a file; the message says what is wrong with it and what to send instead."""


@dataclass(frozen=True)
class FmuSummary:
    """What an accepted FMU archive is.

    Attributes
    ----------
    sha256 : str
        SHA-256 of the archive's bytes (hex): the FMU's identity.
    size : int
        The archive's size [bytes].
    unpacked : int
        What its members unpack to [bytes].
    model_name, fmi_version, guid, identifier : str
        From its ``modelDescription.xml`` (``identifier``: the model identifier of its first interface
        of ``interfaces``).
    interfaces : tuple of str
        The FMI 2.0 interfaces it offers, by a plant description's names for them
        (``co-simulation``, ``model-exchange``).
    platforms : tuple of str
        The platforms it has binaries for (FMPy's names, e.g. ``linux64``).
    inputs, outputs, parameters : tuple of str
        Its real variables by causality (what a plant description may name).
    """

    sha256: str
    size: int
    unpacked: int
    model_name: str
    fmi_version: str
    guid: str
    identifier: str
    platforms: tuple[str, ...]
    interfaces: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    parameters: tuple[str, ...]


def inspect_archive(content: bytes, max_unpacked: int) -> FmuSummary:
    """Check an FMU archive given as bytes; what it is.

    Parameters
    ----------
    content : bytes
        The ``.fmu`` file's bytes.
    max_unpacked : int
        Most bytes its members may unpack to, in total [bytes].

    Raises
    ------
    FmuArchiveError
        Not a zip archive; more than :data:`MAX_MEMBERS` members or more than ``max_unpacked`` bytes
        unpacked; a member with an absolute path or ``..``; no or an unreadable ``modelDescription.xml``;
        not FMI 2.0, or with neither interface; no binary for this machine's platform.
    """
    import fmpy
    from fmpy import read_model_description

    if not zipfile.is_zipfile(io.BytesIO(content)):
        raise FmuArchiveError("the file is not an FMU: an FMU is a zip archive (send the .fmu file as it was exported)")
    try:
        with zipfile.ZipFile(io.BytesIO(content)) as archive:
            members = archive.infolist()
            if len(members) > MAX_MEMBERS:
                raise FmuArchiveError(f"the FMU has {len(members)} members; at most {MAX_MEMBERS} are accepted")
            unpacked = sum(m.file_size for m in members)
            if unpacked > max_unpacked:
                raise FmuArchiveError(
                    f"the FMU unpacks to {unpacked} bytes; at most {max_unpacked} are accepted "
                    "(the service's BACKLASH_MAX_FMU_UNPACKED_BYTES)"
                )
            for m in members:
                path = PurePosixPath(m.filename.replace("\\", "/"))
                if path.is_absolute() or ".." in path.parts or (path.parts and ":" in path.parts[0]):
                    raise FmuArchiveError(f"the FMU's member {m.filename!r} would unpack outside its folder")
            names = {m.filename for m in members}
            if "modelDescription.xml" not in names:
                raise FmuArchiveError("the archive has no modelDescription.xml at its top level: it is not an FMU")
    except zipfile.BadZipFile as exc:
        raise FmuArchiveError(f"the FMU is not a readable zip archive: {exc}") from None
    try:
        md = read_model_description(io.BytesIO(content))
    except Exception as exc:  # FMPy raises several kinds for a malformed or invalid model description
        raise FmuArchiveError(f"the FMU's modelDescription.xml cannot be read: {exc}") from None
    offered = {
        name: kind.modelIdentifier
        for name, kind in (("co-simulation", md.coSimulation), ("model-exchange", md.modelExchange))
        if kind is not None
    }
    if md.fmiVersion != "2.0" or not offered:
        raise FmuArchiveError(
            f"the plant needs an FMI 2.0 FMU (co-simulation or model exchange); this is FMI {md.fmiVersion}"
            f"{' with neither interface' if not offered else ''}: export it as FMI 2.0"
        )
    platforms = tuple(fmpy.supported_platforms(io.BytesIO(content)))
    for interface, identifier in offered.items():
        binary = f"binaries/{fmpy.platform}/{identifier}{fmpy.sharedLibraryExtension}"
        if binary not in names:
            raise FmuArchiveError(
                f"the FMU has no {interface} binary for this machine ({binary}; its platforms: "
                f"{', '.join(platforms) or 'none'}): export it with a {fmpy.platform} binary, or as a source "
                "FMU built on the service's machine"
            )
    real = [v for v in md.modelVariables if v.type == "Real"]
    return FmuSummary(
        sha256=hashlib.sha256(content).hexdigest(),
        size=len(content),
        unpacked=unpacked,
        model_name=md.modelName,
        fmi_version=md.fmiVersion,
        guid=md.guid,
        identifier=next(iter(offered.values())),
        platforms=platforms,
        interfaces=tuple(offered),
        inputs=tuple(v.name for v in real if v.causality == "input"),
        outputs=tuple(v.name for v in real if v.causality == "output"),
        parameters=tuple(v.name for v in real if v.causality == "parameter"),
    )
