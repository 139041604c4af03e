"""The users' own simulators as plants of the service: FMUs uploaded once by hash, descriptions stored as plants.

A client sends its FMU's archive (:func:`add_fmu`: checked as a file by
:func:`engine.plants.fmu.archive.inspect_archive`, stored under its SHA-256), then a plant
description whose ``fmu`` names it as ``"sha256:<hex>"`` (:func:`add_plant`: checked against the
FMU's variables as a ``--plant plant.toml`` is, stored under an id of both). A diagnosis request
then names the plant by that id (``"plant": "fmu-..."``) and its record is read and diagnosed by
:class:`engine.plants.fmu.FmuPlant`, in the service's worker processes.

An FMU is native code. Nothing of it runs in the service's own process: uploading and describing
only read the archive and its ``modelDescription.xml``; the FMU is instantiated and stepped only by
a diagnosis, and diagnoses run in worker processes. The whole feature is off unless the operator
turns it on (``BACKLASH_ALLOW_FMU_PLANTS``).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import tempfile
import threading
from dataclasses import asdict
from pathlib import Path
from typing import Any

from app.core.config import Settings
from app.db.plants import PlantRepository, StoredFmu, StoredPlant
from app.services.errors import (
    ConflictError,
    ForbiddenError,
    InvalidInputError,
    NotFoundError,
    StorageFullError,
    TooLargeError,
)
from engine.plants.fmu.archive import inspect_archive
from engine.plants.fmu.description import DescriptionError, PlantDescription, parse_description
from engine.storage import PatternStore

logger = logging.getLogger(__name__)

__all__ = [
    "FMU_REF",
    "OFF_MESSAGE",
    "PLANT_ID",
    "add_fmu",
    "add_plant",
    "delete_plant",
    "fmu_cache_dir",
    "is_stored_plant",
    "load",
    "require_enabled",
]

#: A stored plant's id: ``fmu-`` and 16 hex digits of the SHA-256 of its description (with its FMU's hash).
PLANT_ID = re.compile(r"^fmu-[0-9a-f]{16}$")
#: How a description sent to the service names a stored FMU.
FMU_REF = re.compile(r"^sha256:([0-9a-f]{64})$")
#: Stored plants a process keeps loaded (each holds its FMU unpacked in a temporary folder).
LOADED_PLANTS = 8

#: Why a request naming an uploaded plant is refused where FMU plants are off.
OFF_MESSAGE = (
    "FMU plants are turned off on this service: an FMU is native code the service's workers would run. "
    "An operator who trusts every client turns them on with BACKLASH_ALLOW_FMU_PLANTS=1 (docs/fmu-plant.md); "
    "without the service, run `backlash diagnose RECORD.csv --plant plant.toml` on your own machine"
)


def is_stored_plant(name: str | None) -> bool:
    """Whether ``name`` is a stored plant's id (``fmu-`` and 16 hex digits)."""
    return name is not None and PLANT_ID.match(name) is not None


def require_enabled(settings: Settings) -> None:
    """Raise :class:`ForbiddenError` (403) unless the operator turned FMU plants on."""
    if not settings.allow_fmu_plants:
        raise ForbiddenError(OFF_MESSAGE)


def add_fmu(store: PatternStore, settings: Settings, content: bytes) -> tuple[StoredFmu, bool]:
    """Check an FMU archive as a file and store it under its SHA-256; it and whether it is new.

    Raises
    ------
    ForbiddenError
        FMU plants are off (403).
    TooLargeError
        The archive is larger than ``BACKLASH_MAX_FMU_BYTES`` (413).
    engine.plants.fmu.archive.FmuArchiveError
        Not an FMI 2.0 FMU (either interface) with a binary for this machine, or one that would unpack beyond
        ``BACKLASH_MAX_FMU_UNPACKED_BYTES`` or outside its folder (422); the message says what to send.
    """
    require_enabled(settings)
    if len(content) > settings.max_fmu_bytes:
        raise TooLargeError(
            f"the FMU is {len(content)} bytes; this service accepts at most {settings.max_fmu_bytes} "
            "(BACKLASH_MAX_FMU_BYTES)"
        )
    summary = inspect_archive(content, settings.max_fmu_unpacked_bytes)
    stored, created = PlantRepository(store).add_fmu(summary.sha256, asdict(summary), content)
    if created:
        logger.info("stored FMU %s (%s, %d bytes)", summary.sha256, summary.model_name, summary.size)
    return stored, created


def add_plant(store: PatternStore, settings: Settings, description: dict[str, Any]) -> tuple[StoredPlant, bool]:
    """Check a plant description against its stored FMU and store it; it and whether it is new.

    The description is a plant description (docs/fmu-plant.md) as a JSON object, its ``fmu`` the
    stored archive's ``"sha256:<hex>"``; it ships no example files (``examples`` stays empty).

    Raises
    ------
    ForbiddenError
        FMU plants are off (403).
    InvalidInputError
        ``fmu`` is not a stored archive's hash, or ``examples`` is given (422).
    engine.plants.fmu.DescriptionError
        A description the plant cannot use (a key, a bound, a variable the FMU lacks, ...): 422.
    StorageFullError
        ``BACKLASH_MAX_PLANTS`` plants are stored (507).
    """
    require_enabled(settings)
    ref = description.get("fmu")
    match = FMU_REF.match(ref) if isinstance(ref, str) else None
    if match is None:
        raise InvalidInputError(
            f"description.fmu {str(ref)[:100]!r}: name the FMU by the hash POST /v1/fmus answered, as "
            '"sha256:<64 hex digits>"'
        )
    sha = match.group(1)
    repo = PlantRepository(store)
    if repo.get_fmu(sha) is None:
        raise InvalidInputError(f"no FMU with SHA-256 {sha} is stored: upload it first with POST /v1/fmus")
    if description.get("examples"):
        raise InvalidInputError(
            "description.examples: a plant sent to the service ships no example files; leave examples out"
        )
    parsed = parse_description(description, "description")
    checked = _plant_of(store, parsed)  # DescriptionError (422) for a variable the FMU lacks, or a name clash
    document = parsed.model_dump(mode="json")
    plant_id = "fmu-" + hashlib.sha256(json.dumps(document, sort_keys=True).encode()).hexdigest()[:16]
    if repo.get_plant(plant_id) is None and len(repo.list_plants(settings.max_plants)) >= settings.max_plants:
        raise StorageFullError(
            f"{settings.max_plants} plants are stored (BACKLASH_MAX_PLANTS): delete one with DELETE /v1/plants/{{id}}"
        )
    stored, created = repo.add_plant(plant_id, checked.name, sha, document)
    if created:
        logger.info("stored plant %s (%s, FMU %s)", plant_id, checked.name, sha)
    return stored, created


def get_plant(store: PatternStore, plant_id: str) -> StoredPlant:
    """A stored plant; :class:`NotFoundError` (404) when there is none."""
    stored = PlantRepository(store).get_plant(plant_id) if is_stored_plant(plant_id) else None
    if stored is None:
        raise NotFoundError(f"no plant {plant_id[:100]!r} is stored; GET /v1/plants lists the stored ones")
    return stored


def delete_plant(store: PatternStore, plant_id: str) -> None:
    """Delete a plant (and its FMU, when no other plant uses it) unless stored records name it.

    Raises
    ------
    NotFoundError
        No such plant (404).
    ConflictError
        Stored records name it (409): they would no longer read; delete them (or their diagnoses) first.
    """
    get_plant(store, plant_id)
    used = PlantRepository(store).delete_plant(plant_id)
    if used:
        raise ConflictError(
            f"{used} stored record(s) name plant {plant_id}; they could not be read again without it: delete them "
            "first (DELETE /v1/records/{id}), or keep the plant"
        )


def fmu_cache_dir(store_path: Path) -> Path:
    """Where a store's FMU archives are written out for FMPy to open: a folder beside the store's file."""
    return store_path.parent / f"{store_path.name}.fmus"


def _archive_file(store_path: Path, sha: str, content: bytes | None = None) -> Path:
    """The stored archive ``sha`` as a file (written atomically on first use, its hash checked when it exists)."""
    folder = fmu_cache_dir(store_path)
    path = folder / f"{sha}.fmu"
    if path.is_file() and hashlib.sha256(path.read_bytes()).hexdigest() == sha:
        return path
    if content is None:
        content = PlantRepository(PatternStore(store_path)).fmu_content(sha)
    if content is None or hashlib.sha256(content).hexdigest() != sha:
        raise NotFoundError(f"the FMU {sha} of this plant is not stored (or no longer matches its hash)")
    folder.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{sha[:12]}-", suffix=".part")
    try:
        with os.fdopen(fd, "wb") as out:
            out.write(content)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _plant_of(store: PatternStore, description: PlantDescription) -> Any:
    """The FMU plant of a checked description whose ``fmu`` is ``sha256:<hex>`` (runs nothing of the FMU)."""
    from engine.plants.fmu import FmuPlant

    match = FMU_REF.match(description.fmu)
    if match is None:
        raise DescriptionError(f"plant {description.name!r}: fmu {description.fmu!r} is not a stored FMU's hash")
    path = _archive_file(store.path, match.group(1))
    local = description.model_copy(update={"fmu": path.name})
    return FmuPlant(local, path.parent, processes=1)  # the service's workers run one diagnosis each: no pool


_loaded: dict[tuple[str, str], Any] = {}
_loaded_lock = threading.Lock()


def load(store_path: str | Path, plant_id: str) -> Any:
    """The stored plant ``plant_id`` of the store at ``store_path``, ready to read and diagnose records.

    Kept loaded for the next request in this process (at most :data:`LOADED_PLANTS`).

    Raises
    ------
    InvalidInputError
        No such plant is stored (422: the request names it).
    """
    store = PatternStore(store_path)
    stored = PlantRepository(store).get_plant(plant_id) if is_stored_plant(plant_id) else None
    if stored is None:  # asked every time: a plant deleted since it was loaded is not served from memory
        raise InvalidInputError(f"plant {plant_id[:100]!r} is not stored here; GET /v1/plants lists the stored plants")
    key = (str(store.path), plant_id)
    with _loaded_lock:
        if key in _loaded:
            return _loaded[key]
    plant = _plant_of(store, parse_description(stored.description, f"stored plant {plant_id}"))
    with _loaded_lock:
        while len(_loaded) >= LOADED_PLANTS:
            _loaded.pop(next(iter(_loaded)))
        return _loaded.setdefault(key, plant)
