"""Members handed out dynamically to groups of ranks (the engine clusters already run: MPI).

``mpirun -n N`` splits the world into ``N / ranks_per_member`` sub-communicators. World rank 0
keeps the queue of members still to run and answers requests; it also computes in its own
group, so it answers between its own time steps (a runner callback, :meth:`MemberPool.serve`)
— no rank is spent on bookkeeping, and no one-sided MPI is needed (passive-target RMA waits
for the target to enter MPI, seconds when it is in a kernel). A group that finishes a member
asks for the next one, so fast members do not wait for slow ones.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from fem_runout.errors import CaseError

__all__ = ["MemberPool"]

_ASK, _GIVE = 7101, 7102
_NONE = -1


class MemberPool:
    """A queue of member indices shared by the groups of ``ranks_per_member`` ranks.

    Args:
        world: The communicator of the whole ensemble.
        todo: Member indices to run, in order.
        ranks_per_member: Ranks of each group (must divide the world's size).
        on_done: Called on world rank 0 with ``(member, done_count)`` when any group
            reports a finished member (for the progress bar).
    """

    def __init__(self, world, todo: list[int], ranks_per_member: int,
                 on_done: Callable[[int, int], None] | None = None) -> None:
        if world.size % ranks_per_member:
            raise CaseError(f"ranks_per_member: {ranks_per_member} does not divide the "
                            f"{world.size} ranks of the run; allowed: a divisor of {world.size}")
        self.world = world
        self.group = world.Split(world.rank // ranks_per_member, world.rank)
        self.leader = self.group.rank == 0
        self.queue = list(todo) if world.rank == 0 else []
        self.done = 0
        self.closed = 0  # leaders told "no more" (rank 0 only)
        self.leaders = world.size // ranks_per_member
        self.on_done = on_done

    def serve(self) -> None:
        """Answer every pending request (world rank 0; a no-op elsewhere)."""
        from mpi4py import MPI

        if self.world.rank != 0:
            return
        status = MPI.Status()
        while self.world.Iprobe(source=MPI.ANY_SOURCE, tag=_ASK, status=status):
            finished = np.empty(1, dtype=np.int64)
            self.world.Recv(finished, source=status.Get_source(), tag=_ASK)
            self._reply(status.Get_source(), int(finished[0]))

    def _reply(self, rank: int, finished: int) -> None:
        self._count(finished)
        member = self.queue.pop(0) if self.queue else _NONE
        self.closed += member == _NONE
        self.world.Send(np.array([member], dtype=np.int64), dest=rank, tag=_GIVE)

    def _count(self, finished: int) -> None:
        if finished != _NONE:
            self.done += 1
            if self.on_done is not None:
                self.on_done(finished, self.done)

    def next(self, finished: int = _NONE) -> int | None:
        """Report ``finished`` (or nothing) and get this group's next member.

        Collective on the group; returns None when the queue is empty.
        """
        member = _NONE
        if self.leader and self.world.rank == 0:
            self._count(finished)
            member = self.queue.pop(0) if self.queue else _NONE
            self.closed += member == _NONE
        elif self.leader:
            self.world.Send(np.array([finished], dtype=np.int64), dest=0, tag=_ASK)
            answer = np.empty(1, dtype=np.int64)
            self.world.Recv(answer, source=0, tag=_GIVE)
            member = int(answer[0])
        member = self.group.bcast(member, root=0)
        return None if member == _NONE else member

    def close(self) -> None:
        """End the pool (collective): rank 0 answers until every leader was told "no more"."""
        if self.world.rank == 0:
            from mpi4py import MPI

            status = MPI.Status()
            while self.closed < self.leaders:
                finished = np.empty(1, dtype=np.int64)
                self.world.Recv(finished, source=MPI.ANY_SOURCE, tag=_ASK, status=status)
                self._reply(status.Get_source(), int(finished[0]))
        self.world.Barrier()
        self.group.Free()
