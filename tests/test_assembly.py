"""The numba assembler gives DOLFINx's assembled vectors bit for bit (issue 16).

Run serially and under ``mpiexec -n 2`` (tests/mpi/test_assembly_mpi.py imports these): the
TG2-PC forms (cells, interior facets with permutations, open-side exterior facets) with
random coefficients, on the whole mesh and on a subset of cells.
"""

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from fem_runout.assembly import VectorAssembler
from fem_runout.config import load_case
from fem_runout.tg2.active import restrict
from fem_runout.tg2.solver import build_tg2


def _transport(comm):
    case = load_case("cases/inclined_dam_break.yaml",
                     [("domain.cells", [40, 6]), ("numerics.active_set", False)])
    t = build_tg2(case, comm).transport.high
    rng = np.random.default_rng(17 + comm.rank)
    for f in (t.h, t.hu, t.hv, *t.velocity, t.eta_t, t.Qk, t.uk, t.etak, t.z):
        f.x.array[:] = rng.random(f.x.array.size) - 0.3
    t.dt.value = 0.37
    return t


def check_whole_mesh(comm) -> None:
    """Every form, every integral type: the same bits as ``fem.assemble_vector``."""
    t = _transport(comm)
    forms = [t.pred_form, *t.corr_form]
    kinds = set()
    for form in forms:
        expected = fem.assemble_vector(form).array
        got = np.zeros_like(expected)
        asm = VectorAssembler(form)
        kinds |= {kind.name for kind, _, ents in asm.integrals if ents.size}
        asm.assemble(got)
        assert np.abs(expected).max() > 0.1
        assert np.array_equal(got, expected)
    kinds = set().union(*comm.allgather(kinds))  # a rank may own no open side
    assert kinds == {"cell", "interior_facet", "exterior_facet"}


def check_subset(comm) -> None:
    """Coefficients zero off a region: the cells near it give DOLFINx's whole-mesh bits.

    The active-set claim of :mod:`fem_runout.tg2.active`: every term carries ``h`` or ``q``,
    so cells (and facets) away from where they are non-zero contribute exact zeros.
    """
    t = _transport(comm)
    d = t.disc
    cut = 10.0 * d.spacing[0] + d.extent[0]
    node_off = d.coords[:, 0] > cut
    for f in (t.h, t.hu, t.hv, *t.velocity):
        f.x.array[node_off] = 0.0
    xc = d.coords[d.cell_nodes, 0].mean(axis=1)
    for f in (t.Qk, t.uk, t.etak, t.eta_t):  # DG: each dof belongs to one cell
        bs = f.function_space.dofmap.bs
        f.x.array.reshape(-1, bs)[f.function_space.dofmap.list[xc > cut].ravel()] = 0.0
    active = xc < cut + 2.0 * d.spacing[0]
    assert 0 < active.sum() < active.size or comm.size > 1
    for form in [t.pred_form, *t.corr_form]:
        expected = fem.assemble_vector(form).array
        got = np.zeros_like(expected)
        sub = restrict(VectorAssembler(form), active)
        sub.assemble(got)
        assert sum(e.size for _, _, e in sub.integrals) < sum(
            e.size for _, _, e in VectorAssembler(form).integrals) or not np.all(active)
        assert np.array_equal(got, expected)


def test_whole_mesh_bitwise() -> None:
    check_whole_mesh(MPI.COMM_WORLD)


def test_subset_entities() -> None:
    check_subset(MPI.COMM_WORLD)
