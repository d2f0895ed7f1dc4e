"""A barrier whose waiting ranks sleep (for tests where rank 0 runs a serial reference)."""

import time

#: Sleep between two polls of the barrier [s].
IDLE_POLL = 0.002


def idle_barrier(comm) -> None:
    """Wait for every rank of ``comm`` without spinning (collective).

    MPICH waits in a collective by polling and yielding in a loop: on 2 cores a rank that
    waits there while rank 0 runs a serial reference (``COMM_SELF``) takes CPU from it (one
    spinning rank with ``-n 2``, two with ``-n 3``). Polling a nonblocking barrier with a sleep
    in between leaves the cores to the ranks that still work.
    """
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(IDLE_POLL)
