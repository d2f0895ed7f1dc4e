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
