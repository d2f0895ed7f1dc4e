"""Vector assembly of a compiled linear form over chosen entities, in numba (issue 16).

:func:`dolfinx.fem.assemble_vector` packs every coefficient of a form and crosses the
Python/C++ boundary on each call: about 3 ms per call even on a handful of cells, which is
most of a step when the flow covers a few percent of a real DEM. :class:`VectorAssembler`
keeps the form's FFCx kernels (compiled once, the UFL form stays the one definition of the
equations) and calls them from numba on the entities it is given, packing coefficients,
constants and cell geometry exactly as DOLFINx does (``dolfinx/fem/pack.h``,
``assemble_vector_impl.h``): the same kernel on the same inputs, added in the same order,
gives the same bits as :func:`dolfinx.fem.assemble_vector` (tested).

Supported: linear forms of scalar type float64 on one cell type, with cell, interior-facet
and exterior-facet integrals, and elements without dof transformations (Lagrange and DG on
quadrilaterals: what the TG2-PC forms use).
"""

from __future__ import annotations

import numba
import numpy as np
from dolfinx import fem
from dolfinx.cpp.mesh import cell_num_entities
from dolfinx.fem import IntegralType
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

__all__ = ["VectorAssembler"]


@intrinsic
def _tabulate(typingctx, addr, A, w, offset, c, coords, local, perm):
    """Call the FFCx kernel at address ``addr`` (``ufcx_tabulate_tensor_float64``).

    The coefficients are ``w.ravel()[offset:]`` (a pointer, no array view per call).
    """
    sig = types.void(addr, A, w, offset, c, coords, local, perm)

    def codegen(context, builder, signature, args):
        ptr = ir.IntType(8).as_pointer()
        data = []
        for ty, val in zip(signature.args[1:], args[1:], strict=True):
            if isinstance(ty, types.Integer):
                continue
            ary = context.make_array(ty)(context, builder, value=val)
            data.append(ary.data)
        data[1] = builder.gep(data[1], [args[3]])  # w + offset
        fnty = ir.FunctionType(ir.VoidType(), [ptr] * 7)
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(fn, [*(builder.bitcast(d, ptr) for d in data), ir.Constant(ptr, None)])
        return context.get_dummy_value()

    return sig, codegen


@numba.njit(cache=True)
def _pack(W, cells, pos, v, dm, bs):
    """Pack one coefficient (values ``v``, dofmap ``dm``, block size ``bs``) of ``cells``.

    Cell ``cells[e]``'s dofs go to ``W[e, pos:]`` in dof order, blocks interleaved.
    """
    nd = dm.shape[1]
    for e in range(cells.shape[0]):
        row = W[e]
        cell = cells[e]
        if bs == 1:
            for i in range(nd):
                row[pos + i] = v[dm[cell, i]]
        else:
            for i in range(nd):
                d = dm[cell, i] * bs
                for j in range(bs):
                    row[pos + i * bs + j] = v[d + j]


@numba.njit(cache=True, inline="always")
def _coords(out, base, cell, xdofs, x):
    """Copy the geometry nodes of ``cell`` into ``out[base:]`` (3 coordinates each)."""
    for i in range(xdofs.shape[1]):
        n, k = xdofs[cell, i], base + 3 * i
        out[k] = x[n, 0]
        out[k + 1] = x[n, 1]
        out[k + 2] = x[n, 2]


@numba.njit(cache=True, inline="always")
def _add(b, A, base, tdofs, cell, tbs):
    """``b[tdofs[cell]] += A[base:]`` with block size ``tbs``."""
    if tbs == 3:  # unrolled, the vector spaces of (h, hu, hv)
        for i in range(tdofs.shape[1]):
            d, a = tdofs[cell, i] * 3, base + i * 3
            b[d] += A[a]
            b[d + 1] += A[a + 1]
            b[d + 2] += A[a + 2]
        return
    for i in range(tdofs.shape[1]):
        d = tdofs[cell, i] * tbs
        for j in range(tbs):
            b[d + j] += A[base + i * tbs + j]


@numba.njit(cache=True)
def _one_sided(addr, b, cells, facets, W, tdofs, tbs, xdofs, x, const, perms):
    """Cell integral (``facets`` empty) or exterior-facet integral on ``cells``."""
    A = np.empty(tdofs.shape[1] * tbs)
    coords = np.empty(3 * xdofs.shape[1])
    local = np.zeros(2, dtype=np.int32)
    perm = np.zeros(2, dtype=np.uint8)
    for e in range(cells.shape[0]):
        cell = cells[e]
        if facets.shape[0]:
            local[0] = facets[e]
            if perms.shape[0]:
                perm[0] = perms[cell, facets[e]]
        _coords(coords, 0, cell, xdofs, x)
        A[:] = 0.0
        _tabulate(addr, A, W, e * W.shape[1], const, coords, local, perm)
        _add(b, A, 0, tdofs, cell, tbs)


@numba.njit(cache=True)
def _interior(addr, b, ents, W, tdofs, tbs, xdofs, x, const, perms):
    """Interior-facet integral over the ``(cell0, lf0, cell1, lf1)`` rows of ``ents``.

    Geometry of the two cells one after the other, element vector of cell0 then cell1
    (``assemble_vector_impl.h``).
    """
    n = tdofs.shape[1] * tbs
    A = np.empty(2 * n)
    coords = np.empty(6 * xdofs.shape[1])
    local = np.zeros(2, dtype=np.int32)
    perm = np.zeros(2, dtype=np.uint8)
    nx = 3 * xdofs.shape[1]
    for e in range(ents.shape[0]):
        c0, c1 = ents[e, 0], ents[e, 2]
        local[0], local[1] = ents[e, 1], ents[e, 3]
        if perms.shape[0]:
            perm[0], perm[1] = perms[c0, ents[e, 1]], perms[c1, ents[e, 3]]
        _coords(coords, 0, c0, xdofs, x)
        _coords(coords, nx, c1, xdofs, x)
        for i in range(2 * n):
            A[i] = 0.0
        _tabulate(addr, A, W, e * W.shape[1], const, coords, local, perm)
        _add(b, A, 0, tdofs, c0, tbs)
        _add(b, A, n, tdofs, c1, tbs)


class VectorAssembler:
    """Assemble a compiled linear form with its FFCx kernels, called from numba.

    Args:
        form: A compiled linear form (float64).
        entities: Per integral, in the form's order (cell, exterior facet, interior facet
            within :class:`IntegralType`'s order), the integration entities to visit (the
            layout of ``Form.domains``); default: the form's own.
    """

    def __init__(self, form: fem.Form, entities: list[np.ndarray] | None = None) -> None:
        cpp, ufcx = form._cpp_object, form.ufcx_form
        self.form = form
        space = cpp.function_spaces[0]
        self._tdofs = np.asarray(space.dofmap.map(), dtype=np.int32)
        self._tbs = int(space.dofmap.bs)
        msh = cpp.mesh
        self._xdofs = np.asarray(msh.geometry.dofmaps[0], dtype=np.int32)
        self._x = msh.geometry.x
        coeffs = cpp.coefficients
        self._values = tuple(c.x.array for c in coeffs)
        self._dofmaps = tuple(np.asarray(c.function_space.dofmap.map(), dtype=np.int32)
                              for c in coeffs)
        self._bsizes = np.array([c.function_space.dofmap.bs for c in coeffs], dtype=np.int64)
        sizes = [d.shape[1] * bs for d, bs in zip(self._dofmaps, self._bsizes, strict=True)]
        self._offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self._constants = cpp.constants
        self._const = np.zeros(max(sum(np.asarray(c.value).size for c in cpp.constants), 1))
        self.integrals: list[tuple[IntegralType, int, np.ndarray]] = []
        #: per integral, the coefficients its kernel reads (FFCx's ``enabled_coefficients``):
        #: the others are not packed (their slots are never read, so the bits are the same)
        self._enabled: list[tuple[int, ...]] = []
        offsets = [ufcx.form_integral_offsets[i] for i in range(len(IntegralType) + 1)]
        needs_perm = False
        for kind in IntegralType:
            first, last = offsets[kind.value], offsets[kind.value + 1]
            for k, j in enumerate(range(first, last)):
                integral = ufcx.form_integrals[j]
                if kind not in (IntegralType.cell, IntegralType.exterior_facet,
                                IntegralType.interior_facet):
                    raise NotImplementedError(f"{kind.name} integrals")
                needs_perm |= bool(integral.needs_facet_permutations)
                addr = int(form.module.ffi.cast("uintptr_t", integral.tabulate_tensor_float64))
                ents = np.asarray(cpp.domains(kind, k), dtype=np.int32)
                self.integrals.append((kind, addr, ents))
                self._enabled.append(tuple(c for c in range(len(coeffs))
                                           if integral.enabled_coefficients[c]))
        if entities is not None:
            self.integrals = [(kind, addr, np.ascontiguousarray(e, dtype=np.int32))
                              for (kind, addr, _), e in zip(self.integrals, entities, strict=True)]
        self._perms = np.zeros((0, 4), dtype=np.uint8)
        if needs_perm:
            top = msh.topology
            top.create_entity_permutations()
            nf = cell_num_entities(top.cell_type, top.dim - 1)
            self._perms = np.asarray(top.get_facet_permutations(), dtype=np.uint8).reshape(-1, nf)

    def restricted(self, entities: list[np.ndarray]) -> VectorAssembler:
        """Return a copy visiting other entities (same kernels, coefficients and constants)."""
        new = object.__new__(VectorAssembler)
        new.__dict__.update(self.__dict__)
        new.integrals = [(kind, addr, np.ascontiguousarray(e, dtype=np.int32))
                         for (kind, addr, _), e in zip(self.integrals, entities, strict=True)]
        return new

    def assemble(self, b: np.ndarray) -> None:
        """Add the form's vector into ``b`` (local array, ghosts included; no scatter)."""
        pos = 0
        for c in self._constants:
            v = np.asarray(c.value).ravel()
            self._const[pos: pos + v.size] = v
            pos += v.size
        cst = max(int(self._offsets[-1]), 1)
        geo = (self._tdofs, self._tbs, self._xdofs, self._x, self._const, self._perms)
        none = np.zeros(0, dtype=np.int32)
        for (kind, addr, ents), enabled in zip(self.integrals, self._enabled, strict=True):
            if kind == IntegralType.interior_facet:
                pairs = ents.reshape(-1, 4)
                W = self._buffer(pairs.shape[0], 2 * cst)
                self._pack(W, pairs[:, 0], 0, 2, enabled)
                self._pack(W, pairs[:, 2], 1, 2, enabled)
                _interior(addr, b, pairs, W, *geo)
                continue
            if kind == IntegralType.cell:
                cells, facets = ents, none
            else:
                pairs = ents.reshape(-1, 2)
                cells, facets = pairs[:, 0], pairs[:, 1]
            W = self._buffer(cells.shape[0], cst)
            self._pack(W, cells, 0, 1, enabled)
            _one_sided(addr, b, cells, facets, W, *geo)

    def _pack(self, W: np.ndarray, cells: np.ndarray, side: int, sides: int,
              enabled: tuple[int, ...]) -> None:
        """Pack the ``enabled`` coefficients of ``cells`` into ``W`` (``pack.h``'s layout).

        Coefficient ``k`` goes to column ``sides * offsets[k] + side * size_k``: one cell per
        entity (``sides = 1``), or interior facets (``sides = 2``: per coefficient, the '+'
        cell, ``side = 0``, then the '-' cell, ``side = 1``).
        """
        off = self._offsets
        for k in enabled:
            v, dm, bs = self._values[k], self._dofmaps[k], self._bsizes[k]
            _pack(W, cells, int(sides * off[k] + side * (off[k + 1] - off[k])), v, dm, int(bs))

    def _buffer(self, rows: int, cols: int) -> np.ndarray:
        """Return a (rows, cols) scratch array for packed coefficients, reused between calls."""
        buf = self.__dict__.get("_w")
        if buf is None or buf.size < rows * cols:
            buf = self._w = np.zeros(max(rows * cols, 1))
        return buf[: rows * cols].reshape(rows, cols)
