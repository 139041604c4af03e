"""The policy that chooses a stored pattern set for a record (engine.identification.selection)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from engine.constants import K_GRID
from engine.identification.selection import nearest_pattern_set
from engine.storage import InvalidPatternSet, PatternSet, PatternSetNotFound, PatternStore


def make_set(seed: int, *, channel: str = "a1", c: float = 1.0, kind: str = "paper", **meta: Any) -> PatternSet:
    """A small pattern set whose arrays and ``params["seed"]`` are determined by ``seed``."""
    rng = np.random.default_rng(seed)
    return PatternSet(
        kind=kind,
        channel=channel,
        c=c,
        j1_values=[0.87],
        wavelet="sym5",
        params={"seed": seed},
        arrays={"patterns": rng.normal(size=(6, 15)), "widths": np.asarray(K_GRID)},
        **meta,
    )


@pytest.fixture
def store(tmp_path: Path) -> PatternStore:
    return PatternStore(tmp_path / "patterns.sqlite3")


def test_nearest_c_on_the_channel_newest_wins_ties_kind_and_model_version_filter(store: PatternStore) -> None:
    assert nearest_pattern_set(store, "a1", 1.0) is None
    low = store.save(make_set(0, c=0.8))
    mid_old = store.save(make_set(1, c=1.25))
    mid_new = store.save(make_set(2, c=1.25))
    high = store.save(make_set(3, c=1.4, kind="template"))
    store.save(make_set(4, channel="m_el", c=1.1))
    store.save(make_set(5, c=1.2, model_version="0.9"))  # nearer, but another model version

    assert nearest_pattern_set(store, "a1", 0.5).id == low.id
    assert nearest_pattern_set(store, "a1", 1.2).id == mid_new.id  # tie on c=1.25: newest
    assert nearest_pattern_set(store, "a1", 1.2) == mid_new  # full set with arrays
    assert nearest_pattern_set(store, "a1", 9.0).id == high.id
    assert nearest_pattern_set(store, "a1", 9.0, kind="paper").id == mid_new.id
    assert nearest_pattern_set(store, "a1", 1.2, model_version="0.9").params["seed"] == 5
    assert nearest_pattern_set(store, "a1", 1.2, model_version="2.0") is None
    assert nearest_pattern_set(store, "v2", 1.0) is None
    store.delete(mid_new.id)
    assert nearest_pattern_set(store, "a1", 1.2).id == mid_old.id
    with pytest.raises(InvalidPatternSet, match="finite"):
        nearest_pattern_set(store, "a1", float("nan"))
    with pytest.raises(InvalidPatternSet, match="unknown channel"):
        nearest_pattern_set(store, "speed", 1.0)
    with pytest.raises(InvalidPatternSet, match="model_version"):
        nearest_pattern_set(store, "a1", 1.0, model_version="")


def test_preferred_kind_wins_equally_near_sets_only(store: PatternStore) -> None:
    template = store.save(make_set(0, c=1.0, kind="template"))
    paper = store.save(make_set(1, c=1.0, kind="paper"))  # as near and newer
    assert nearest_pattern_set(store, "a1", 1.1).id == paper.id
    assert nearest_pattern_set(store, "a1", 1.1, prefer_kind="template").id == template.id
    # a difference far below the tie tolerance (rel 1e-9) is still a tie ...
    near_paper = store.save(make_set(2, c=1.0 + 1e-13, kind="paper"))
    assert nearest_pattern_set(store, "a1", 1.1).id == near_paper.id
    assert nearest_pattern_set(store, "a1", 1.1, prefer_kind="template").id == template.id
    # ... a real difference is not: the nearer set wins whatever its kind
    nearer = store.save(make_set(3, c=1.05, kind="paper"))
    assert nearest_pattern_set(store, "a1", 1.1, prefer_kind="template").id == nearer.id
    # with kind given the preference has nothing to choose from
    assert nearest_pattern_set(store, "a1", 1.1, kind="paper", prefer_kind="template").id == nearer.id
    assert nearest_pattern_set(store, "a1", 1.1, prefer_kind="other").id == nearer.id


def test_a_set_deleted_while_being_chosen_is_replaced_by_the_next_nearest(tmp_path: Path) -> None:
    class DeletedMeanwhile(PatternStore):
        """Another process deletes the chosen set between the listing and the read, once."""

        raced = False

        def get(self, set_id: str) -> PatternSet:
            if not self.raced:
                self.raced = True
                self.delete(set_id)
                raise PatternSetNotFound(set_id)
            return super().get(set_id)

    store = DeletedMeanwhile(tmp_path / "patterns.sqlite3")
    far = store.save(make_set(0, c=0.8))
    store.save(make_set(1, c=1.0))
    assert nearest_pattern_set(store, "a1", 1.0) == far
    assert store.raced and len(store) == 1
