"""Particle migration between ranks: each rank owns the particles in the cells it owns."""

from __future__ import annotations

import numpy as np

from mpm.grid import ParticleGrid
from mpm.particles import FLOAT_FIELDS, Particles

__all__ = ["migrate"]

_WIDTH = len(FLOAT_FIELDS) + 2


def migrate(grid: ParticleGrid, particles: Particles) -> tuple[Particles, int]:
    """Send every particle to the rank that owns its cell (collective).

    Particles must lie inside the rectangle (valid ``cell``). The ones that stay keep their
    order; the received ones follow, by source rank.

    Args:
        grid: The particle grid (cell → owner table).
        particles: The particles of this rank after the position update.

    Returns:
        The particles now owned by this rank, and the number this rank sent.
    """
    comm = grid.comm
    if comm.size == 1:
        return particles, 0
    dest = grid.owner[particles.cell]
    leaving = np.flatnonzero(dest != comm.rank)
    order = leaving[np.argsort(dest[leaving], kind="stable")]
    send_counts = np.bincount(dest[leaving], minlength=comm.size).astype(np.int64)
    recv_counts = np.asarray(comm.alltoall(send_counts.tolist()), dtype=np.int64)
    send = np.ascontiguousarray(particles.select(order).pack()).reshape(-1)
    recv = np.empty(int(recv_counts.sum()) * _WIDTH)
    sc, rc = send_counts * _WIDTH, recv_counts * _WIDTH
    sd = np.concatenate([[0], np.cumsum(sc)[:-1]])
    rd = np.concatenate([[0], np.cumsum(rc)[:-1]])
    comm.Alltoallv([send, (sc, sd)], [recv, (rc, rd)])
    stay = np.ones(len(particles), dtype=bool)
    stay[leaving] = False
    merged = Particles.concatenate([particles.select(stay), Particles.unpack(recv)])
    return merged, int(leaving.size)
