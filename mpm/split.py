"""Particle domains: stretching with the flow and splitting (keeps the material resolved).

A particle's domain (:mod:`mpm.gimp`) has half-widths ``l_x, l_y`` that follow the flow's
stretch along the axes, ``l_a ← l_a (1 + Δt ∂v_a/∂x_a)`` (the diagonal of the deformation
gradient's rate, as in cpGIMP; the depth of seed eq. 42 uses the trace of the same gradient).

Where the flow stretches the material (a dam-break fan, the tip of any front) the particles
drift apart: at two per cell and direction, the Ritter fan leaves cells with no particle at all
and the front lags, at every grid size. A particle whose half-width exceeds the limit
``min(Δ/n, Δ/2)`` (``n`` particles per cell and direction at the start) is therefore split in
two along that axis, as in adaptive MPM refinement (Ma et al. 2009; Gracia et al. 2019): the
children sit at the centres of the two halves of the parent's domain, ``x_p ± l_x/2``, with
half-widths ``l_x/2`` and half the volume each; depth, velocity and stress are the parent's.
Mass, momentum and the volume-weighted depth are unchanged (halving is exact in floating
point), and so is the grid mass (the two halves cover the parent's domain exactly).

Two bounds keep the particle count proportional to the flow's footprint (without them it grew
from 3.5e3 to 1.7e6 in the first 80 s of the avaKot avalanche, docs/dampm.md):

* **Aspect ratio.** Axis-aligned domains cannot rotate: a flow that stretches along x and
  converges along y, then turns, leaves needles (``l_x/l_y`` up to 4e3 in avaKot) whose long
  axis splits again and again while their short axis never grows back. The stretch keeps the
  domain's area ``4 l_x l_y`` exactly but bounds its aspect ratio, in cell units,
  to :data:`MAX_ASPECT`; 1-D stretching (a dam-break fan, ratio at most 2) never meets it.
* **Thin particles.** A particle thinner than ``numerics.thin_depth`` (the depth below which
  the flow is not resolved, also TG2-PC's desingularisation depth) is not split; its domain
  stops growing at the split limit. Thin tails otherwise thin without bound (``h_p`` to 1e-11 m
  in avaKot's late run-out) and cover ever larger areas with ever more particles.

The first child keeps the parent's id; the second gets a new id, assigned in the order of the
parents' ids over all ranks, so ids do not depend on the rank count.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from mpm.grid import ParticleGrid
from mpm.particles import Particles

__all__ = ["MAX_ASPECT", "DomainSplitter", "PendingIds"]

#: Largest aspect ratio ``l_x/l_y`` (or ``l_y/l_x``) of a particle domain.
MAX_ASPECT = 4.0
#: The half-widths along x and y.
_KEYS = ("lx", "ly")


@numba.njit(cache=True)
def _stretch(lx, ly, h, dt, grad, cell, max_aspect, thin_depth, limit_x, limit_y):
    """Return the new half-widths (see :meth:`DomainSplitter.stretch`); ``cell = Δx/Δy``.

    ``cell``, ``limit_x``, ``limit_y``: per particle (the size of its cell).
    """
    n = lx.size
    out_x, out_y = np.empty(n), np.empty(n)
    for p in range(n):
        a = lx[p] * max(1.0 + dt * grad[p, 0, 0], 1e-3)
        b = ly[p] * max(1.0 + dt * grad[p, 1, 1], 1e-3)
        if a == 0.0 or b == 0.0:  # a point particle (no domain) stays one
            out_x[p], out_y[p] = 0.0, 0.0
            continue
        ratio = min(max(a / (b * cell[p]), 1.0 / max_aspect), max_aspect) * cell[p]
        area = a * b
        out_x[p], out_y[p] = np.sqrt(area * ratio), np.sqrt(area / ratio)
        if h[p] < thin_depth:
            out_x[p], out_y[p] = min(out_x[p], limit_x[p]), min(out_y[p], limit_y[p])
    return out_x, out_y


@dataclass(frozen=True)
class PendingIds:
    """The children of one :meth:`DomainSplitter.split_pair`, waiting for their ids.

    Attributes:
        start: Where the children start in the joined particles (x-children, then y).
        x_parents: This rank's x-parents' ids, in the order of the x-children.
        y_known: The y-parents that existed before the pair (their ids, in order).
        y_pending: The y-parents among the x-children (positions among them).
        wide: Whether a domain on this rank is still too wide.
    """

    start: int
    x_parents: np.ndarray
    y_known: np.ndarray
    y_pending: np.ndarray
    wide: bool

    @property
    def payload(self) -> tuple:
        """What the other ranks need (:meth:`DomainSplitter.settle`'s ``sent``).

        The id arrays travel as their bytes: a pickled message of bytes costs microseconds,
        one of NumPy arrays tens to a hundred (every step).
        """
        return (self.x_parents.tobytes(), self.y_known.tobytes(),
                self.x_parents[self.y_pending].tobytes(), bool(self.wide))


class DomainSplitter:
    """Stretch particle domains and split the stretched particles.

    Args:
        grid: The particle grid.
        per_direction: Particles per cell and direction at the start.
        next_id: First unused particle id (the same on every rank).
        thin_depth: Particles thinner than this [m] are not split (their domain is capped).
    """

    def __init__(self, grid: ParticleGrid, per_direction: int, next_id: int,
                 thin_depth: float = 0.0) -> None:
        self.grid = grid
        self.per_direction = int(per_direction)
        self.next_id = int(next_id)
        self.count = 0
        self.max_aspect = MAX_ASPECT
        self.thin_depth = float(thin_depth)

    def stretch(self, p: Particles, dt: float, grad: np.ndarray) -> None:
        """Half-widths times ``1 + Δt ∂v_a/∂x_a``, aspect ratio bounded (in place).

        The product ``l_x l_y`` (the domain's area) follows the stretch exactly; the shape
        only up to ``l_x/l_y`` in ``[1/r, r]``, ``r`` = :data:`MAX_ASPECT`: beyond it the
        domain is made less elongated at the same area (see the module docstring).
        """
        rates = self.grid.axis_rates(p, grad)
        p.lx, p.ly = _stretch(p.lx, p.ly, p.h, dt, rates, self.grid.aspect(p.cell),
                              self.max_aspect, self.thin_depth, *self.limits(p))

    def limits(self, p: Particles) -> tuple[np.ndarray, np.ndarray]:
        """Largest half-widths ``(l_x, l_y)`` of each particle's domain (its cell's size)."""
        return self.grid.split_limits(p.cell, self.per_direction)

    def split(self, p: Particles) -> Particles:
        """Split along x, then y, x, ... until every half-width is within the limit (collective).

        ``p`` is changed in place (the parents' halves); the result holds parents and children
        (in the order of splitting the joined set axis by axis). The passes go in pairs
        (:meth:`split_pair`, x then y) with one message per pair (:meth:`settle`), so the
        usual step (x, then y, or nothing to split) takes one message.
        """
        more = True
        while more:
            p, pending = self.split_pair(p)
            more = self.settle(p, pending, self.grid.comm.allgather(pending.payload))
        return p

    def split_pair(self, p: Particles) -> tuple[Particles, PendingIds]:
        """Split ``p`` along x, then y (local); the children's ids wait for :meth:`settle`.

        Returns the parents and children joined (one copy) and what :meth:`settle` needs.
        The caller may send :attr:`PendingIds.payload` with a message of its own (the solver
        sends it with the P2G bounds): every rank must call :meth:`settle` with every rank's
        payload before the ids or :attr:`next_id` are used.
        """
        idx = self._wide(p, 0)
        x_parents = p.id[idx]
        parts = [p] + ([self._halve(p, idx, 0)] if idx.size else [])
        idx = [self._wide(q, 1) for q in parts]
        y_known = p.id[idx[0]]
        y_pending = idx[1] if len(parts) > 1 else np.zeros(0, dtype=np.int64)
        parts += [self._halve(q, i, 1) for q, i in zip(parts, idx, strict=True) if i.size]
        pending = PendingIds(len(p), x_parents, y_known, y_pending,
                             self._any_wide_here(parts))
        return (p if len(parts) == 1 else Particles.concatenate(parts)), pending

    def settle(self, p: Particles, pending: PendingIds, sent: list[tuple]) -> bool:
        """Give the children of :meth:`split_pair` their ids (in ``p``, in place; no MPI).

        The ids are those of two passes with one message each: a pass's children take
        ``next_id`` plus their parents' rank among that pass's parents over all ranks, so
        they do not depend on the rank count.

        Args:
            p: The particles :meth:`split_pair` returned.
            pending: Its :class:`PendingIds`.
            sent: Every rank's :attr:`PendingIds.payload`, in rank order.

        Returns:
            Whether a domain on some rank is still too wide (split again).
        """
        ids = [[np.frombuffer(b, dtype=pending.x_parents.dtype) for b in s[:3]] for s in sent]
        all_x = np.sort(np.concatenate([s[0] for s in ids]))
        x_first = self.next_id
        y_first = x_first + all_x.size
        x_ids = x_first + np.searchsorted(all_x, pending.x_parents)
        pending_y = [x_first + np.searchsorted(all_x, s[2]) for s in ids]
        all_y = np.sort(np.concatenate([s[1] for s in ids] + pending_y))
        mine_y = np.concatenate([pending.y_known, x_ids[pending.y_pending]])
        y_ids = y_first + np.searchsorted(all_y, mine_y)
        start = pending.start
        p.id[start:start + x_ids.size] = x_ids
        p.id[start + x_ids.size:start + x_ids.size + y_ids.size] = y_ids
        self.next_id = y_first + all_y.size
        self.count += int(all_x.size + all_y.size)
        return any(s[3] for s in sent)

    def _any_wide_here(self, parts: list[Particles]) -> bool:
        """Whether a particle on this rank exceeds the limit (local)."""
        lim_x, lim_y = self._scalar_limits()
        return any(bool((p.lx > lim_x).any() or (p.ly > lim_y).any()) for p in parts)

    def _scalar_limits(self) -> tuple[float, float]:
        """Return the structured grid's split limits ``min(Δ/n, Δ/2)`` (one for every cell)."""
        g, n = self.grid, self.per_direction
        return min(g.dx / n, 0.5 * g.dx), min(g.dy / n, 0.5 * g.dy)

    def _wide(self, p: Particles, axis: int) -> np.ndarray:
        """Return the indices of the particles wider than the limit along ``axis`` (0: x, 1: y)."""
        return np.flatnonzero(getattr(p, _KEYS[axis]) > self._scalar_limits()[axis])

    def _halve(self, p: Particles, idx: np.ndarray, axis: int) -> Particles:
        """Halve particles ``idx`` of ``p`` along ``axis`` in place; return the other halves.

        The halves' ids are set by :meth:`settle`.
        """
        key = _KEYS[axis]
        half = 0.5 * getattr(p, key)[idx]
        getattr(p, key)[idx] = half  # in place: the solver owns the arrays
        p.volume[idx] *= 0.5
        child = p.select(idx)
        self._shift(p, idx, key, -half)
        self._shift(child, slice(None), key, half)
        if p.has_affine:  # APIC: each half moves with the affine velocity at its centre
            cu, cv = ("cxx", "cyx") if key == "lx" else ("cxy", "cyy")
            p.u[idx] -= getattr(p, cu)[idx] * half
            p.v[idx] -= getattr(p, cv)[idx] * half
            child.u += getattr(child, cu) * half
            child.v += getattr(child, cv) * half
        return child

    def _shift(self, p: Particles, idx, key: str, dist: np.ndarray) -> None:
        """Move particles ``idx`` by ``dist`` along x (``lx``) or y, kept inside the rectangle."""
        cell, xi, eta, swap = self.grid.shift_along(p.cell[idx], p.xi[idx], p.eta[idx],
                                                    0 if key == "lx" else 1, dist)
        p.cell[idx], p.xi[idx], p.eta[idx] = cell, xi, eta
        if swap is not None and swap.any():  # the new cell's axes are the old ones swapped
            at = np.asarray(idx) if not isinstance(idx, slice) else np.arange(len(p))
            at = at[swap]
            p.lx[at], p.ly[at] = p.ly[at].copy(), p.lx[at].copy()

