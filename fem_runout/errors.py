"""Exceptions that the command line turns into one clear message and exit code 2."""

from __future__ import annotations


class CaseError(ValueError):
    """Bad user input: a case file, an override or a command-line option.

    The message names the key path, what is wrong and what is allowed, for example
    ``"case.yaml: domain.cells: must be two positive integers, got [-1, 3]"``.
    """


class SimulationError(RuntimeError):
    """The run had to stop (NaN or negative depth); the last good state was saved."""


class RunInterrupted(RuntimeError):
    """The run was asked to stop (SIGTERM, SIGINT); a checkpoint and the outputs were written.

    Attributes:
        signum: The signal number.
        t, step: Where the run stopped.
        checkpoint: The checkpoint written (None when the run writes nothing).
    """

    def __init__(self, signum: int, t: float, step: int, checkpoint=None) -> None:
        import signal

        self.signum, self.t, self.step, self.checkpoint = signum, t, step, checkpoint
        name = signal.Signals(signum).name
        where = f"; restart with --restart {checkpoint}" if checkpoint else ""
        super().__init__(f"stopped by {name} at t = {t:.6g} s (step {step}); outputs written"
                         f"{where}")


class OutputError(OSError):
    """An output file could not be written (disk full, permission denied, vanished folder).

    Raised for the native writers' failures (ADIOS2 reports them as RuntimeError) so that the
    command line treats every output failure alike: one message, exit code 4.
    """


def first_error_everywhere(comm, check) -> str | None:
    """Run ``check()`` on every rank; return the first CaseError message any rank got.

    Collective (one allgather). The message (folded to one line) is printed as
    ``error: ...`` by rank 0, so a command can return exit code 2 on every rank.
    """
    import sys

    error = None
    try:
        check()
    except CaseError as exc:
        error = " ".join(str(exc).split("\n"))
    error = next((e for e in comm.allgather(error) if e is not None), None)
    if error is not None and comm.rank == 0:
        print(f"error: {error}", file=sys.stderr, flush=True)
    return error
