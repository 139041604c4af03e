"""Drawing the cases of a protocol-v2 validation: records with known, strong enough causes.

Each case has a kind (:data:`~engine.validation.protocol.CASE_KINDS`): one catalogue
effect, two or three distinct catalogue effects, one effect of the held-back family
(never in the library the diagnosis gets), or none. For every case the generator
draws an operating point from :data:`~engine.validation.protocol.OPERATING_BOX`
(c1 = 0.2 is the record's only condition), the effects' values (uniform in their
bounds; log-uniform for the effects fitted on a log scale and for any effect whose
positive bounds span two decades), the recorded channels (all five, or a subset),
and the noise (white or coloured, a per-channel SNR).

**On a described drive** (``drive``, :class:`~engine.simulation.drive.DriveDescription`) the
same draws are made on that drive: the operating point from its plausible box
(:func:`~engine.validation.protocol.operating_box`), c1 its nominal ``drive.c1``, the records
simulated on its plant with its ``t_event_max`` and on its own grid, the absorption refit on its
plant and box. The reference drive draws exactly the cases it drew before drives were described.

**Strength rule** (protocol v1's, per effect): an effect counts when it moves some
recorded channel by more than 3 noise standard deviations (RMS of the noiseless
difference). In a compound case every effect must pass it both on its own (record
with it alone minus the clean record) and within the set (record with every effect
minus the record with the others). A draw that fails is drawn again (values,
operating point, channels and noise; after
:data:`~engine.validation.protocol.MAX_DRAWS_PER_EFFECT_SET` failures, the effects
too), so every kind keeps its count and no weak draw is relabelled.

**Absorption rule** (added after the seed-105 progress run; docs/validation-v2.md): an effect
also counts only when the rest of the model cannot mimic it. For each effect of a case the
noiseless record is refitted without it, by a local least-squares fit of the plant's calibrated
parameters (K, J1, c, in the plausible box) and the case's other effects (in their bounds),
started at the truth (:func:`absorbed_strength`); the largest channel RMS of what the refit
leaves must exceed the same 3 noise RMS. A wide backlash shifted by a small clutch offset, or a
third effect whose signature a slightly different c reproduces, moves the record by more than 3
noise RMS and yet leaves nothing once the calibration moves: no diagnosis can name it, and a
case built on it scored every method wrong (seed 105: three of the six triples, two held-back
clutch offsets). The rule is applied to every kind with effects, after the strength rule.

Effects of one compound case are never the same physics: not two on the same field,
not two of a :data:`~engine.validation.protocol.SAME_PHYSICS` group.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from engine.constants import CHANNELS
from engine.diagnosis.calibration import CalibrationError, CalibrationSettings, calibrate
from engine.diagnosis.space import LOG_SCALED_EFFECTS, default_space
from engine.diagnosis.validation import same_physics_names
from engine.records import Record
from engine.simulation import Case, Effect, EffectLibrary, ParameterError, SimulationError
from engine.simulation import simulate_batch as _simulate_batch
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription
from engine.simulation.noise import noise_std
from engine.validation.key import KeyEntry, TrueEffect, on_operating_range
from engine.validation.noise import NoiseSpec, render_noise
from engine.validation.protocol import (
    CASE_KINDS,
    CHANNEL_SUBSETS,
    COLOURED_CUTOFF_FS,
    COLOURED_ORDERS,
    COLOURED_SHARE,
    DEFAULT_MIX,
    MAX_CHANNEL_SNR_SPREAD_DB,
    MAX_DRAWS_PER_CASE,
    MAX_DRAWS_PER_EFFECT_SET,
    REFIT_FD_STEP,
    REFIT_NFEV,
    SNR_RANGE_DB,
    STRENGTH_THRESHOLD,
    SUBSET_SHARE,
    c1_condition,
    operating_box,
)

logger = logging.getLogger(__name__)

__all__ = ["BlindCase", "absorbed_strength", "admissible_sets", "case_counts", "generate_cases", "same_physics"]

#: Ratio of the bounds beyond which a positive-valued effect is drawn log-uniformly (two decades).
LOG_DRAW_RATIO: float = 100.0


@dataclass(frozen=True)
class BlindCase:
    """What the diagnosis is given: an id and a record (nothing else)."""

    case_id: str
    record: Record


def case_counts(n_cases: int, mix: Mapping[str, float] | None = None) -> dict[str, int]:
    """Number of cases of each kind: the mix's shares of ``n_cases``, rounded by largest remainder.

    Parameters
    ----------
    n_cases : int
        Total number of cases.
    mix : mapping of str to float, optional
        Share of each kind (any positive scale; normalised); default :data:`DEFAULT_MIX`.

    Returns
    -------
    dict of str to int
        Counts per kind of :data:`CASE_KINDS`, summing to ``n_cases``.

    Raises
    ------
    ValueError
        An unknown kind, a negative share, or no positive share.
    """
    mix = dict(DEFAULT_MIX if mix is None else mix)
    unknown = set(mix) - set(CASE_KINDS)
    if unknown:
        raise ValueError(f"unknown case kind(s) {', '.join(sorted(unknown))}; kinds: {', '.join(CASE_KINDS)}")
    if any(v < 0 or not math.isfinite(v) for v in mix.values()) or sum(mix.values()) <= 0:
        raise ValueError(f"the mix needs non-negative shares, at least one positive; got {mix}")
    total = sum(mix.values())
    exact = {k: n_cases * mix.get(k, 0.0) / total for k in CASE_KINDS}
    counts = {k: math.floor(v) for k, v in exact.items()}
    by_remainder = sorted(CASE_KINDS, key=lambda k: (-(exact[k] - counts[k]), CASE_KINDS.index(k)))
    for k in by_remainder[: n_cases - sum(counts.values())]:
        counts[k] += 1
    return counts


def same_physics(a: Effect, b: Effect) -> bool:
    """Whether two effects are the same physics on a record (same field, or one
    :data:`~engine.validation.protocol.SAME_PHYSICS` group, :func:`~engine.diagnosis.validation.same_physics_names`)."""
    return (a.target, a.field) == (b.target, b.field) or same_physics_names(a.name, b.name)


def admissible_sets(library: EffectLibrary, size: int) -> list[tuple[str, ...]]:
    """Every set of ``size`` distinct effects of ``library`` with no two the same physics, in library order."""
    return [
        combo
        for combo in itertools.combinations(library, size)
        if not any(same_physics(library[a], library[b]) for a, b in itertools.combinations(combo, 2))
    ]


class _Pool:
    """Items in random order, every item once per round: balanced but unpredictable."""

    def __init__(self, items: Sequence[tuple[str, ...]], rng: np.random.Generator):
        self._items = list(items)
        self._rng = rng
        self._left: list[tuple[str, ...]] = []

    def next(self) -> tuple[str, ...]:
        if not self._left:
            self._left = [self._items[i] for i in self._rng.permutation(len(self._items))]
        return self._left.pop()


def _draw_value(effect: Effect, rng: np.random.Generator) -> float:
    lo, hi = effect.bounds
    if lo > 0 and (effect.name in LOG_SCALED_EFFECTS or hi / lo >= LOG_DRAW_RATIO):
        return float(lo * (hi / lo) ** rng.uniform())
    return float(rng.uniform(lo, hi))


def _draw_noise(channels: Sequence[str], sample_interval: float, rng: np.random.Generator) -> NoiseSpec:
    lo_db, hi_db = SNR_RANGE_DB
    spread = rng.uniform(0.0, min(MAX_CHANNEL_SNR_SPREAD_DB, hi_db - lo_db))
    base = rng.uniform(lo_db, hi_db - spread)
    snr = {ch: float(base + rng.uniform(0.0, spread)) for ch in channels}
    if rng.uniform() >= COLOURED_SHARE:
        return NoiseSpec(snr)
    fs = 1.0 / sample_interval
    f_lo, f_hi = COLOURED_CUTOFF_FS
    order = int(COLOURED_ORDERS[int(rng.integers(len(COLOURED_ORDERS)))])
    cutoff = float(fs * f_lo * (f_hi / f_lo) ** rng.uniform())
    return NoiseSpec(snr, order, cutoff)


def _draw_channels(rng: np.random.Generator) -> tuple[str, ...]:
    if rng.uniform() >= SUBSET_SHARE:
        return CHANNELS
    subset = CHANNEL_SUBSETS[int(rng.integers(len(CHANNEL_SUBSETS)))]
    return tuple(c for c in CHANNELS if c in subset)


@dataclass(frozen=True)
class _Draw:
    K: float
    J1: float
    c: float
    effects: tuple[Effect, ...]
    values: tuple[float, ...]
    channels: tuple[str, ...]
    noise: NoiseSpec
    drive: DriveDescription = REFERENCE_DRIVE


def _variants(n: int) -> list[tuple[int, ...]]:
    """Subsets of the effects simulated for the strength rule: none, each alone, each left out, all."""
    subsets: set[tuple[int, ...]] = {(), tuple(range(n))}
    for i in range(n):
        subsets.add((i,))
        subsets.add(tuple(j for j in range(n) if j != i))
    return sorted(subsets, key=lambda s: (len(s), s))


def _simulate(draw: _Draw, variants: list[tuple[int, ...]]) -> np.ndarray:
    """The noiseless records of a draw with each subset of its effects, on its drive's plant, solver and grid."""
    drive = draw.drive
    base = Case(drive.plant(K=draw.K, J1=draw.J1, c=draw.c, c1=c1_condition(drive)))
    cases = []
    for subset in variants:
        case = base
        for i in subset:
            case = draw.effects[i].apply(case, draw.values[i])
        cases.append(case)
    return _simulate_batch(cases, solver=drive.solver(), grid=drive.grid()).channels


def _rms_over(x: np.ndarray, y: np.ndarray, rows: list[int], sd: np.ndarray) -> float:
    """Largest RMS of ``x - y`` over the channel ``rows``, in noise standard deviations ``sd``."""
    diff = x[rows] - y[rows]
    return float(np.max(np.sqrt(np.mean(diff * diff, axis=1)) / sd))


def _try(draw: _Draw) -> tuple[list[TrueEffect], np.ndarray, np.ndarray] | str:
    """Simulate a draw: its effects' strengths, the noiseless record and the noise levels, or why it failed."""
    n = len(draw.effects)
    variants = _variants(n)
    try:
        sims = _simulate(draw, variants)
    except (SimulationError, ParameterError) as exc:
        logger.debug("draw not simulable (%s); drawn again", exc)
        return str(exc)
    at = {s: sims[i] for i, s in enumerate(variants)}
    rows = [CHANNELS.index(ch) for ch in draw.channels]
    full = at[tuple(range(n))]
    snr = np.array([draw.noise.snr_db[ch] for ch in draw.channels])
    sd = np.array([noise_std(full[r], float(s))[0] for r, s in zip(rows, snr, strict=True)])
    truths = []
    for i, e in enumerate(draw.effects):
        alone = _rms_over(at[(i,)], at[()], rows, sd)
        others = tuple(j for j in range(n) if j != i)
        in_set = _rms_over(full, at[others], rows, sd)
        truths.append(TrueEffect(e.name, draw.values[i], e.unit, e.locus, alone, in_set))
    return truths, full, sd


def _strong(truths: Sequence[TrueEffect]) -> bool:
    return all(min(t.strength, t.strength_in_set) > STRENGTH_THRESHOLD for t in truths)


def _record(channels: Sequence[str], data: np.ndarray, drive: DriveDescription = REFERENCE_DRIVE) -> Record:
    """A case's record on its drive's grid (MODEL.md's protocol grid for the reference): ``data[j]`` is
    channel ``channels[j]``; its one condition is the drive's c1 [pu]."""
    grid = drive.grid()
    return Record(
        {ch: data[j] for j, ch in enumerate(channels)},
        grid.sample_interval,
        grid.event_index,
        conditions={"c1": c1_condition(drive)},
    )


def absorbed_strength(
    record: Record,
    truth: Mapping[str, float],
    effects: Sequence[Effect],
    left_out: int,
    sd: Mapping[str, float],
    drive: DriveDescription = REFERENCE_DRIVE,
) -> float:
    """What of one effect the rest of the model cannot mimic: the absorption rule's statistic.

    Parameters
    ----------
    record : Record
        The noiseless record of the case (every effect applied).
    truth : mapping of str to float
        The case's K [m], J1 [kg m^2], c [pu] and every effect's value (in its unit).
    effects : sequence of Effect
        The case's effects.
    left_out : int
        Index in ``effects`` of the effect tested.
    sd : mapping of str to float
        Noise standard deviation of each recorded channel (channel unit).
    drive : DriveDescription
        The drive the record was simulated on (default MODEL.md's reference plant): the refit's
        nominal plant, its box (:func:`~engine.diagnosis.space.drive_bounds`) and ``t_event_max``.

    Returns
    -------
    float
        Largest RMS over the recorded channels of the record minus the best local refit of the
        model without ``effects[left_out]`` (K, J1, c and the other effects refitted, started
        at the truth, at most :data:`REFIT_NFEV` evaluations), in noise standard deviations;
        inf when that model cannot be simulated near the truth (nothing can absorb the effect).

    Raises
    ------
    ValueError
        When ``truth`` lacks a refitted parameter (K, J1, c or another effect's value).
    """
    others = [e for i, e in enumerate(effects) if i != left_out]
    space = default_space(record, drive=drive).with_effects(others)
    missing = [k for k in space.names if k not in truth]
    if missing:  # the refit would start at the box centre instead of the truth
        raise ValueError(f"the truth lacks {', '.join(missing)}")
    seed = {k: v for k, v in truth.items() if k in space.names}
    settings = CalibrationSettings(n_global=0, max_nfev=REFIT_NFEV, polish_nfev=REFIT_NFEV, fd_step=REFIT_FD_STEP)
    try:
        cal = calibrate(record, space, settings, noise=sd, seeds=[seed])
    except CalibrationError:
        return math.inf
    if cal.simulation is None:
        return math.inf
    return max(
        float(np.sqrt(np.mean((cal.simulation[CHANNELS.index(ch)] - record.channels[ch]) ** 2))) / sd[ch]
        for ch in record.channels
    )


def _absorption(draw: _Draw, truths: list[TrueEffect], full: np.ndarray, sd: np.ndarray) -> list[TrueEffect]:
    """The truths with their ``strength_refit`` (:func:`absorbed_strength`) filled in."""
    record = _record(draw.channels, full[[CHANNELS.index(ch) for ch in draw.channels]], draw.drive)
    sigma = {ch: float(s) for ch, s in zip(draw.channels, sd, strict=True)}
    truth = {
        "K": draw.K,
        "J1": draw.J1,
        "c": draw.c,
        **{e.name: v for e, v in zip(draw.effects, draw.values, strict=True)},
    }
    out = []
    for i, t in enumerate(truths):
        left = absorbed_strength(record, truth, draw.effects, i, sigma, draw.drive)
        out.append(replace(t, strength_refit=left))
        if not left > STRENGTH_THRESHOLD:  # the rest of the draw need not be refitted
            out.extend(truths[i + 1 :])
            break
    return out


def _unabsorbed(truths: Sequence[TrueEffect]) -> bool:
    return all(t.strength_refit > STRENGTH_THRESHOLD for t in truths)


def generate_cases(
    n_cases: int,
    seed: int,
    catalogue: EffectLibrary,
    held_back: EffectLibrary,
    mix: Mapping[str, float] | None = None,
    absorption: bool = True,
    drive: DriveDescription | None = None,
) -> tuple[list[BlindCase], list[KeyEntry]]:
    """Draw the cases of a protocol-v2 validation and their answer key (see the module notes).

    Parameters
    ----------
    n_cases : int
        Number of cases.
    seed : int
        Seed of the random generator (the same seed gives the same cases).
    catalogue : EffectLibrary
        The library handed to the diagnosis for every case; single, pair and triple cases draw from it.
    held_back : EffectLibrary
        The held-back family (disjoint from ``catalogue``); held-back cases draw from it.
    mix : mapping of str to float, optional
        Share of each kind (default :data:`DEFAULT_MIX`).
    absorption : bool
        Apply the absorption rule (see the module notes; a local refit per effect and draw, about
        a second each). Off only where the cases' other properties are tested.
    drive : DriveDescription, optional
        The drive the cases are simulated on (see the module notes); None, the default, is
        MODEL.md's reference plant (:data:`~engine.simulation.drive.REFERENCE_DRIVE`), which
        draws the same cases as before drives were described.

    Returns
    -------
    cases : list of BlindCase
        Ids ``case0000``, ``case0001``, ... in a random order of kinds.
    key : list of KeyEntry
        The truth, in the same order.

    Raises
    ------
    ValueError
        The libraries overlap, or a kind is asked for that they cannot supply.
    RuntimeError
        A case found no strong enough draw in :data:`MAX_DRAWS_PER_CASE` draws.
    """
    overlap = set(catalogue) & set(held_back)
    if overlap:
        raise ValueError(f"held-back effects must never be in the catalogue; both hold {', '.join(sorted(overlap))}")
    counts = case_counts(n_cases, mix)
    rng = np.random.default_rng(seed)
    kinds = [k for k in CASE_KINDS for _ in range(counts[k])]
    kinds = [kinds[i] for i in rng.permutation(len(kinds))]
    sources: dict[str, tuple[EffectLibrary, list[tuple[str, ...]]]] = {
        "single": (catalogue, [(n,) for n in catalogue]),
        "pair": (catalogue, admissible_sets(catalogue, 2)),
        "triple": (catalogue, admissible_sets(catalogue, 3)),
        "held_back": (held_back, [(n,) for n in held_back]),
        "clean": (catalogue, [()]),
    }
    for kind, (_, sets) in sources.items():
        if counts[kind] and not sets:
            raise ValueError(f"{counts[kind]} {kind} case(s) asked for, but the libraries give no such set of effects")
    pools = {k: _Pool(sets, rng) for k, (_, sets) in sources.items()}
    drive = REFERENCE_DRIVE if drive is None else drive
    grid = drive.grid()
    box = operating_box(drive)
    cases, key = [], []
    for i, kind in enumerate(kinds):
        case_id = f"case{i:04d}"
        library = sources[kind][0]
        names: tuple[str, ...] = ()
        why = "every draw too weak"
        for n_draw in range(1, MAX_DRAWS_PER_CASE + 1):
            if (n_draw - 1) % MAX_DRAWS_PER_EFFECT_SET == 0:
                names = pools[kind].next()
            effects = tuple(library[n] for n in names)
            point = {p: float(rng.uniform(lo, hi)) for p, (lo, hi, _) in box.items()}
            values = tuple(_draw_value(e, rng) for e in effects)
            channels = _draw_channels(rng)
            noise = _draw_noise(channels, grid.sample_interval, rng)
            draw = _Draw(point["K"], point["J1"], point["c"], effects, values, channels, noise, drive)
            tried = _try(draw)
            if isinstance(tried, str):
                why = f"last draw not simulable: {tried}"
            elif _strong(tried[0]):
                if not absorption:
                    break
                tried = (_absorption(draw, *tried), tried[1], tried[2])
                if _unabsorbed(tried[0]):
                    break
                why = "every draw too weak or absorbed by a refit of the rest of the model"
        else:
            raise RuntimeError(f"{case_id} ({kind}): no strong enough draw in {MAX_DRAWS_PER_CASE} draws ({why})")
        assert not isinstance(tried, str)  # the loop breaks only on a simulated, strong draw
        truths, full, sd = tried
        rows = [CHANNELS.index(ch) for ch in channels]
        noisy = full[rows] + render_noise((len(rows), full.shape[1]), sd, noise, grid.sample_interval, rng)
        record = _record(channels, noisy, drive)
        cases.append(BlindCase(case_id, record))
        on_range = on_operating_range(draw.K, draw.J1, draw.c, drive)
        key.append(
            KeyEntry(case_id, kind, tuple(truths), draw.K, draw.J1, draw.c, channels, noise.to_dict(), n_draw, on_range)
        )
        logger.debug("%s: %s %s after %d draw(s)", case_id, kind, ", ".join(names) or "-", n_draw)
    logger.info(
        "generated %d cases (%s) on %s; %d redraws for strength or absorption",
        n_cases,
        ", ".join(f"{counts[k]} {k}" for k in CASE_KINDS),
        "the reference drive" if drive.is_reference else f"drive {drive.name!r} ({drive.fingerprint[:12]})",
        sum(k.draws - 1 for k in key),
    )
    return cases, key
