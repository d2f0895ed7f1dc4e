"""A communicator that counts its collective calls (tests of how many messages a step sends)."""

from __future__ import annotations

from collections import Counter

#: The mpi4py methods that are collective (lower- and upper-case forms).
COLLECTIVES = frozenset({
    "allreduce", "Allreduce", "allgather", "Allgather", "Allgatherv", "alltoall", "Alltoall",
    "Alltoallv", "bcast", "Bcast", "gather", "Gather", "Gatherv", "scatter", "Scatter",
    "Barrier", "barrier", "exscan", "Exscan", "scan", "Scan", "reduce", "Reduce",
})


class CountingComm:
    """Forward everything to ``comm``; count the collective calls by name in :attr:`calls`."""

    def __init__(self, comm) -> None:
        self._comm = comm
        self.calls: Counter[str] = Counter()

    def __getattr__(self, name: str):
        attr = getattr(self._comm, name)
        if name not in COLLECTIVES:
            return attr

        def counted(*args, **kwargs):
            self.calls[name] += 1
            return attr(*args, **kwargs)

        return counted

    @property
    def total(self) -> int:
        """Collective calls so far."""
        return sum(self.calls.values())
