"""The shared identifier contract (engine.identification.base) holds for every kind."""

import numpy as np
import pytest

from engine.constants import K_GRID
from engine.identification import IdentificationResult, Identifier, NotFittedError
from engine.identification.training import IDENTIFIERS, make_identifier
from engine.simulation import paper_grid, simulate_batch


@pytest.fixture(scope="module")
def grid():
    return simulate_batch(paper_grid(1.0, (0.8265, 0.87, 0.8917)))


@pytest.mark.parametrize("kind", sorted(IDENTIFIERS))
def test_every_kind_is_an_identifier_whose_fit_takes_groups_and_returns_self(kind, grid):
    est = make_identifier(kind, "v2", **({"max_epochs": 50} if kind == "paper" else {}))
    assert isinstance(est, Identifier)
    with pytest.raises(NotFittedError):
        est.identify(grid.channel("v2")[0])
    y = np.array([c.plant.K for c in grid.cases])
    g = np.array([c.plant.J1 for c in grid.cases])
    assert est.fit(grid.channel("v2"), y, groups=g) is est
    res = est.identify(grid.channel("v2")[0])
    assert isinstance(res, IdentificationResult) and res.width == K_GRID[res.index - 1]
    # persistence round trip through the protocol's to_arrays / from_arrays
    again = type(est).from_arrays(est.get_params(), est.to_arrays())
    np.testing.assert_array_equal(again.d_vectors(grid.channel("v2")), est.d_vectors(grid.channel("v2")))


def test_the_papers_fit_ignores_groups(grid):
    X = grid.channel("a2")
    y = np.array([c.plant.K for c in grid.cases])
    g = np.array([c.plant.J1 for c in grid.cases])
    a = make_identifier("paper", "a2", max_epochs=50).fit(X, y)
    b = make_identifier("paper", "a2", max_epochs=50).fit(X, y, groups=g)
    np.testing.assert_array_equal(a.d_vectors(X), b.d_vectors(X))


def test_an_object_missing_part_of_the_contract_is_not_an_identifier():
    class Half:
        channel = "v2"

        def fit(self, X, y, groups=None):
            return self

    assert not isinstance(Half(), Identifier)
