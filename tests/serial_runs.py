"""Serial reference runs of an MPI test module, dealt over the ranks (one core each)."""

from collections.abc import Callable, Hashable
from typing import Any

from tests.idle import idle_barrier


def serial_references(world, jobs: dict[Hashable, Callable[[], Any]]) -> dict | None:
    """Run every job serially, job ``i`` on rank ``i % size``; rank 0 gets every result.

    The MPI tests compare a parallel run with the same case run on one rank
    (``COMM_SELF``). Run by rank 0 after each parallel run, those serial runs leave the other
    cores idle; dealt over the ranks before the module's tests, they run side by side. Ranks
    that finish first wait asleep (:func:`tests.idle.idle_barrier`). Collective.

    Args:
        world: The communicator of the tests.
        jobs: Key -> a function that runs the reference on ``COMM_SELF`` and returns a
            picklable result (e.g. :class:`fem_runout.api.RunResult`).

    Returns:
        Key -> result on rank 0, None on the other ranks.
    """
    mine = {key: job() for i, (key, job) in enumerate(jobs.items())
            if i % world.size == world.rank}
    idle_barrier(world)
    parts = world.gather(mine, root=0)
    if world.rank != 0:
        return None
    return {key: value for part in parts for key, value in part.items()}
