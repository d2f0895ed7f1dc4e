"""Small MPI helpers: agree on input errors so that no rank is left waiting."""

from __future__ import annotations

from collections.abc import Callable

from fem_runout.errors import CaseError


def agree_on_errors[T](comm, fn: Callable[[], T]) -> T:
    """Call ``fn`` on every rank; if it raised CaseError on any rank, raise it on all.

    Input checks that depend on the local part of the mesh (an expression that gives NaN in
    one corner, say) fail on some ranks only; without this, the others would wait forever in
    the next collective.

    Args:
        comm: Communicator (collective).
        fn: The local work.

    Returns:
        What ``fn`` returned on this rank.
    """
    value, message = None, None
    try:
        value = fn()
    except CaseError as exc:
        message = str(exc)
    messages = comm.allgather(message) if comm.size > 1 else [message]
    first = next((m for m in messages if m is not None), None)
    if first is not None:
        raise CaseError(first)
    return value  # type: ignore[return-value]
