"""DAMPM's strips of ranks: equal estimated costs, particles and the cells that hold them."""

from types import SimpleNamespace

import numpy as np

from mpm.grid import CELL_COST
from mpm.migrate import balanced_destinations


class _OneOfTwo:
    """A communicator of two ranks in which the other rank holds no particle."""

    size, rank = 2, 0

    def Allreduce(self, sendbuf, recvbuf, op=None):  # noqa: N802 (mpi4py's name)
        """The sums and maxima of this rank's values are its values."""


def _grid(unit_cost: int, n_cells: int) -> SimpleNamespace:
    """A structured grid's balance interface: the cells are the strip units."""
    return SimpleNamespace(comm=_OneOfTwo(), n_rows=n_cells, unit_cost=unit_cost,
                           rows=lambda cell: cell, balance_weights=lambda p: None)


def _deposit_and_front() -> np.ndarray:
    """Cells of the particles: a thin margin (cells 0-399, one particle each), then a dense
    front (cells 400-439, 40 particles each)."""
    return np.concatenate([np.arange(400), np.repeat(np.arange(400, 440), 40)])


def test_a_cell_holding_particles_adds_its_nodes_cost_to_the_split():
    cells = _deposit_and_front()
    particles = SimpleNamespace(cell=cells)
    for unit_cost in (0, CELL_COST):
        dest = balanced_destinations(_grid(unit_cost, 1000), particles)
        assert np.all(np.diff(dest) >= 0)  # strips: the ranks follow the cells' order
        cost = np.where(dest == 0, 1.0, 0.0).sum() + unit_cost * np.unique(cells[dest == 0]).size
        total = cells.size + unit_cost * np.unique(cells).size
        # every rank's cost is half the total to within one cell's (a front cell: 40 + cost)
        assert abs(cost - total / 2) <= 40 + unit_cost
    # counts alone split the particles in half: the 400 margin cells and 15 of the front's
    # (1 000 particles, 415 cells); with 10 per cell (2 000 + 10 x 440 = 6 400, half 3 200)
    # the first 291 margin cells (11 each; the 291st's middle at 3 195.5) cost half: 291
    # particles, the other rank 1 709
    by_count = balanced_destinations(_grid(0, 1000), particles)
    by_cost = balanced_destinations(_grid(CELL_COST, 1000), particles)
    assert CELL_COST == 10
    assert np.count_nonzero(by_count == 0) == 1000
    assert np.count_nonzero(by_cost == 0) == 291
