"""Order-independent sums (issue 13): the result has the same bits in any order and split.

``fem_runout.cellsum`` (TG2-PC's nodal sums of cell contributions) and ``fem_runout.exact_sum``
(DAMPM's particle-to-grid sums) are what make 1, 2 and 3 ranks give the same bits; here the
order and the split between "ranks" are permuted serially, and the sums are compared with a
plain sum (accuracy).
"""

import numpy as np
import pytest
from mpi4py import MPI

from fem_runout import cellsum
from fem_runout.exact_sum import extractors
from fem_runout.mesh import build_discretization
from mpm.gimp import GimpBasis
from mpm.kernels import p2g_momentum

RNG = np.random.default_rng(13)


def _cell_sum(cells, slot, contrib, n_nodes):
    """Both paths of ``Discretization.cell_sum``: one rank, and slots then total (ranks)."""
    src = cellsum.sources(cells, slot, n_nodes)
    flat = np.ascontiguousarray(contrib.reshape(-1, 1))
    direct, out = np.empty((n_nodes, 1)), np.empty((n_nodes, 1))
    cellsum.gather_total(src, flat, direct)
    buf = np.empty((n_nodes, 4, 1))
    every = np.arange(n_nodes)
    cellsum.gather_on(src, flat, every, buf)
    cellsum.total_on(buf, every, out)
    assert np.array_equal(direct, out)
    return out[:, 0]


def test_cell_sum_does_not_depend_on_the_cell_order():
    disc = build_discretization(MPI.COMM_SELF, (0.0, 3.0, 0.0, 2.0), (30, 20), {})
    cells, slot = disc.cell_nodes, disc.slot
    contrib = RNG.normal(size=cells.shape) * 10.0 ** RNG.integers(-8, 8, size=cells.shape)
    n = disc.coords.shape[0]
    base = _cell_sum(cells, slot, contrib, n)
    for _ in range(3):
        order = RNG.permutation(cells.shape[0])
        assert np.array_equal(_cell_sum(cells[order], slot[order], contrib[order], n), base)
    plain = np.zeros(n)
    np.add.at(plain, cells.ravel(), contrib.ravel())
    assert np.abs(base - plain).max() <= 1e-15 * np.abs(contrib).max() * 4


def test_cell_slots_are_the_four_corners_and_reject_other_cells():
    square = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]])
    assert cellsum.cell_slots(square).tolist() == [[0, 1, 2, 3]]
    degenerate = np.array([[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 1.0]]])
    with pytest.raises(ValueError, match="four distinct corners"):
        cellsum.cell_slots(degenerate)


@pytest.mark.parametrize("spread", [0, 12], ids=["similar", "twelve-decades"])
def test_particle_sums_do_not_depend_on_order_or_split(spread):
    n_p, nx, ny = 5000, 6, 6  # 49 nodes, ~100 particles per node
    i0, j0 = RNG.integers(0, nx, size=n_p), RNG.integers(0, ny, size=n_p)
    wx, wy = RNG.uniform(0.0, 1.0, size=(n_p, 3)), RNG.uniform(0.0, 1.0, size=(n_p, 3))
    wx[:, 2] = 0.0  # a domain inside one cell along x: only two factors
    basis = GimpBasis(i0, j0, wx, 0 * wx, wy, 0 * wy, (nx, ny, 1.0, 1.0))
    nodes, weights, _ = basis.expand()
    n_nodes = (nx + 1) * (ny + 1)
    box = np.array([0, 0, ny + 1, nx + 1])  # the whole grid: box position = node index
    mass = 10.0 ** RNG.uniform(-spread, 0, size=n_p)
    u, v = RNG.normal(size=n_p) * 30.0, RNG.normal(size=n_p)
    affine = RNG.normal(size=(4, n_p))  # APIC's C_p; a node is within 2 cells of x̄_p
    bounds = [np.abs(mass * (np.abs(u) + 2 * np.abs(affine[:2]).sum(0))).max(),
              np.abs(mass * (np.abs(v) + 2 * np.abs(affine[2:]).sum(0))).max()]
    ext = extractors(bounds, n_p, MPI.COMM_SELF)

    def total(idx_groups):  # "ranks": sum each group's folds, then the groups
        folds = sum(p2g_momentum((i0[g], j0[g], wx[g], 0 * wx[g], wy[g], 0 * wy[g], nx, ny, 1.0,
                                  1.0), mass[g], u[g], v[g], affine[:, g], box, ext)
                    for g in idx_groups)
        return folds[..., 0] + folds[..., 1]

    base = total([np.arange(n_p)])
    for parts in (2, 3):
        order = RNG.permutation(n_p)
        assert np.array_equal(total(np.array_split(order, parts)), base)
    # node offsets from the weighted centre x̄_p = Σ_a w_a x_a (expanded order: a fastest)
    ax, ay = np.minimum(i0[:, None] + np.arange(3), nx), np.minimum(j0[:, None] + np.arange(3), ny)
    rx = np.tile(ax - (wx * ax).sum(1, keepdims=True), 3)
    ry = np.repeat(ay - (wy * ay).sum(1, keepdims=True), 3, axis=1)
    exact = np.zeros((n_nodes, 2))
    for c, vel in enumerate((u, v)):
        nodal_vel = vel[:, None] + affine[2 * c, :, None] * rx + affine[2 * c + 1, :, None] * ry
        np.add.at(exact[:, c], nodes.ravel(), (mass[:, None] * nodal_vel * weights).ravel())
    scale = np.abs(exact).max()
    assert np.abs(base - exact).max() <= 1e-12 * scale
