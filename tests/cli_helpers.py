"""The command line called in the test's process (the same code as ``python -m fem_runout``,
without its seconds of start-up)."""

import subprocess
from pathlib import Path

import pytest


def main_in(cwd: Path, args: list[str], capsys: pytest.CaptureFixture[str],
            monkeypatch: pytest.MonkeyPatch) -> subprocess.CompletedProcess[str]:
    """:func:`fem_runout.cli.main` run in ``cwd`` in this process, as a finished process."""
    from fem_runout.cli import main

    monkeypatch.chdir(cwd)
    capsys.readouterr()
    code = main(args)
    out = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, out.out, out.err)
