"""Exceptions that the command line turns into one clear message and exit code 2."""

from __future__ import annotations


class CaseError(ValueError):
    """Bad user input: a case file, an override or a command-line option.

    The message names the key path, what is wrong and what is allowed, for example
    ``"case.yaml: domain.cells: must be two positive integers, got [-1, 3]"``.
    """


class SimulationError(RuntimeError):
    """The run had to stop (NaN or negative depth); the last good state was saved."""
