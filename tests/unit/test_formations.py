"""The sheet's neighbour table: the k-d tree path equals the all-pairs reference, and a
sheet of any size is built in memory linear in N."""

from __future__ import annotations

import numpy as np
import pytest

from aes_ros import formations


@pytest.mark.parametrize(
    ("nominal", "radius"),
    [
        (formations.square_grid(1, 1, 0.2), 0.202),
        (formations.square_grid(1, 7, 0.2), 0.202),
        (formations.square_grid(10, 10, 0.2), 0.202),
        (formations.square_grid(7, 9, 0.2), 1.5 * 0.2),  # with diagonals
        (formations.hexagonal_sheet(5, 0.25), 1.01 * 0.25),
        (np.random.default_rng(0).uniform(0.0, 1.0, (300, 2)), 0.1),
        (np.zeros((4, 2)), 0.1),  # coincident robots are neighbours, not themselves
        (np.zeros((0, 2)), 0.1),
    ],
)
def test_tree_table_equals_the_all_pairs_table(nominal: np.ndarray, radius: float) -> None:
    neighbors, rest = formations.neighbor_table(nominal, radius)
    ref_neighbors, ref_rest = formations._neighbor_table_dense(nominal, radius)
    assert np.array_equal(neighbors, ref_neighbors)
    assert np.array_equal(rest, ref_rest)  # bit for bit: the same norm of the same pairs


def test_a_sheet_of_a_million_robots_is_built() -> None:
    """A grid of 10⁶ robots (the largest --robots): the distance matrix would need 16 TB."""
    neighbors, rest = formations.neighbor_table(formations.square_grid(1000, 1000, 0.2), 0.202)
    assert neighbors.shape == (10**6, 4)
    assert (neighbors >= 0).sum() == 2 * (2 * 1000 * 999)  # each spring from both ends
    assert rest.max() == pytest.approx(0.2)
