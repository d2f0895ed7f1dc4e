"""SIGTERM and SIGINT (what schedulers and Ctrl-C send) ask the run to stop cleanly.

The handler only remembers the signal. The runner checks it after every step on every rank (one
integer reduction, so a signal that reaches one rank stops them all at the same step), writes a
checkpoint and the outputs so far and raises :class:`~fem_runout.errors.RunInterrupted`; the
command line then exits with ``128 + signal`` (143 for SIGTERM, 130 for SIGINT). A second signal
while stopping ends the process at once (the default action).
"""

from __future__ import annotations

import signal

__all__ = ["StopFlag"]


class StopFlag:
    """Callable flag set by SIGTERM/SIGINT: returns the signal number, 0 before any."""

    SIGNALS = (signal.SIGTERM, signal.SIGINT)

    def __init__(self) -> None:
        self.signum = 0
        self._previous: dict[int, object] = {}

    def __call__(self) -> int:
        """Return the signal received (0: none yet)."""
        return self.signum

    def install(self) -> StopFlag:
        """Handle the signals (main thread only); return self.

        PETSc (initialised here if it was not yet) would otherwise catch SIGTERM itself and
        abort the job; its handler is removed first.
        """
        try:
            import dolfinx_solver  # noqa: F401  (before petsc4py, as the stack requires)
            from petsc4py import PETSc

            PETSc.Sys.popSignalHandler()
        except ImportError:  # pragma: no cover - petsc4py comes with the DOLFINx wheel
            pass
        for sig in self.SIGNALS:
            self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def uninstall(self) -> None:
        """Restore the previous handlers."""
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    def _handle(self, signum: int, frame) -> None:
        if self.signum:  # asked twice: stop now
            signal.signal(signum, signal.SIG_DFL)
            signal.raise_signal(signum)
        self.signum = signum
