"""TG2-PC's cell-by-cell predictor and corrector give the UFL forms' vectors to round-off.

The numba kernels (:mod:`fem_runout.tg2.predictor`, :mod:`fem_runout.tg2.edges`) against the
forms of :mod:`fem_runout.tg2.forms` assembled by DOLFINx, with random coefficients: dry
cells (the bank blend), per-cell ``G`` and the constant ``g``, open ends (the ghost-cell bed
slope), distorted cells. Run serially and under ``mpiexec -n 2`` and ``-n 3``
(tests/mpi/test_cell_kernels_mpi.py imports these): ghosts included.
"""

import basix.ufl
import numpy as np
from dolfinx import fem, la
from mpi4py import MPI

from fem_runout.config import load_case
from fem_runout.tg2.edges import corrector_cells, edge_dzdn
from fem_runout.tg2.forms import corrector_form, facet_measures, predictor_form
from fem_runout.tg2.predictor import predictor_cells
from fem_runout.tg2.solver import build_tg2

DT = 0.37


def _transport(comm):
    """The high-order part of a small TG2-PC run, with random fields (owners' on ghosts)."""
    case = load_case("cases/inclined_dam_break.yaml",
                     [("domain.cells", [40, 6]), ("numerics.active_set", False)])
    t = build_tg2(case, comm).transport.high
    rng = np.random.default_rng(17 + comm.rank)
    for f in (t.h, t.hu, t.hv, *t.velocity, t.eta_t, t.Qk, t.uk, t.etak, t.z):
        f.x.array[:] = rng.random(f.x.array.size) - 0.3
    t.gk.x.array[:] = 9.81 * (0.6 + 0.4 * rng.random(t.gk.x.array.size))
    h = t.Qk.x.array.reshape(-1, 3)[:, 0]
    h[rng.random(h.size) < 0.3] = 0.0  # dry cells
    for f in (t.h, t.hu, t.hv, *t.velocity, t.Qk, t.uk, t.etak, t.gk, t.z):
        f.x.scatter_forward()
    return t


def _gravities(t):
    """(g_const, UFL g) pairs: the slope form's per-cell ``G``, and the constant."""
    return ((-1.0, t.gk), (9.81, fem.Constant(t.disc.mesh, 9.81)))


def check_cell_by_cell_corrector(comm) -> None:
    """The rectangle's cell-by-cell corrector equals the UFL forms' per owned cell and node.

    The forms' vectors are summed across ranks (one facet term per dof and form); the two
    add the same terms in different orders: they agree to 1e-13 of the largest contribution.
    """
    t = _transport(comm)
    d, e = t.disc, t.edges
    msh = d.mesh
    owned = np.arange(d.n_owned_cells)
    dzdn = edge_dzdn(t.z.x.array, d.coords, d.cell_nodes, e.normal)
    Wd = fem.functionspace(msh, basix.ufl.element("DG", "quadrilateral", 1, shape=(3,)))
    dofd = np.asarray(Wd.dofmap.list[: d.n_owned_cells])
    opened = comm.allreduce(int((e.kind[owned] == 1).sum()))
    assert opened == 2 * 6  # both ends open
    for g_const, g in _gravities(t):
        got = np.empty((owned.size, 4, 3))
        corrector_cells(owned, t._dofs["dof0"], t._dofs["dofs0"], t.Qk.x.array, t.uk.x.array,
                        t.etak.x.array, t.gk.x.array, g_const, t.kappa, DT, e.neighbour,
                        e.kind, e.normal, e.length, e.depth, e.corner_edges, e.grad_centre,
                        dzdn, got)
        expected = np.zeros_like(got)
        forms = corrector_form(t.Qk, t.uk, t.etak, Wd, fem.Constant(msh, DT), g,
                               fem.Constant(msh, t.kappa), t.z, facet_measures(d), d.spacing)
        for form in forms:
            vec = la.vector(Wd.dofmap.index_map, 3)
            vec.array[:] = 0.0
            fem.assemble_vector(vec.array, form)
            vec.scatter_reverse(la.InsertMode.add)
            expected += vec.array.reshape(-1, 3)[dofd]
        scale = comm.allreduce(np.abs(expected).max(initial=0.0), op=MPI.MAX)
        assert scale > 1.0
        err = comm.allreduce(np.abs(got - expected).max(initial=0.0), op=MPI.MAX)
        assert err <= 1e-13 * scale, (g_const, err / scale)


def check_cell_by_cell_predictor(comm, distort: float = 0.0) -> None:
    """The cell-by-cell predictor equals the UFL form's on every owned cell.

    (DOLFINx assembles the owned cells; a ghost cell's kernel reads the owner's data.)
    With ``distort`` the mesh nodes are moved (non-affine cells: the same Gauss rule, so
    still round-off).
    """
    t = _transport(comm)
    d = t.disc
    msh = d.mesh
    coords = d.coords
    if distort:
        x = msh.geometry.x
        x[:, 1] += distort * np.sin(0.37 * x[:, 0]) * np.sin(0.2 * x[:, 1])
        coords = np.empty((d.coords.shape[0], 2))
        nc = d.cell_nodes.shape[0]
        coords[d.cell_nodes] = x[msh.geometry.dofmaps[0][:nc], :2]
    space = t.Qk.function_space
    cells = np.arange(d.cell_nodes.shape[0])
    dofs = t._dofs
    for g_const, g in _gravities(t):
        form = predictor_form((t.h, t.hu, t.hv), t.velocity, t.eta_t, space,
                              fem.Constant(msh, DT), g)
        expected = fem.assemble_vector(form).array
        got = np.zeros_like(expected)
        predictor_cells(cells, d.cell_nodes, coords, t.h.x.array, t.hu.x.array, t.hv.x.array,
                        t.velocity[0].x.array, t.velocity[1].x.array, t.eta_t.x.array,
                        dofs["dofsd"], t.gk.x.array, dofs["dofs0"], g_const, DT,
                        dofs["dof0"], got)
        own = dofs["dof0"][: d.n_owned_cells]
        got, expected = got.reshape(-1, 3)[own], expected.reshape(-1, 3)[own]
        scale = comm.allreduce(np.abs(expected).max(initial=0.0), op=MPI.MAX)
        assert scale > 0.1
        err = comm.allreduce(np.abs(got - expected).max(initial=0.0), op=MPI.MAX)
        assert err <= 1e-13 * scale, (g_const, err / scale)


def test_cell_by_cell_corrector_is_the_ufl_corrector() -> None:
    check_cell_by_cell_corrector(MPI.COMM_WORLD)


def test_cell_by_cell_predictor_is_the_ufl_predictor() -> None:
    check_cell_by_cell_predictor(MPI.COMM_WORLD)
    check_cell_by_cell_predictor(MPI.COMM_WORLD, distort=1.5)
