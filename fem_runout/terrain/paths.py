"""The data folder of real-terrain inputs: ``${FEM_RUNOUT_DATA}`` in case-file paths.

Here, below :mod:`fem_runout.config`, so that both the case keys (:mod:`fem_runout.config.geo`,
which re-exports these names) and the terrain readers use it without importing each other.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["DATA_ENV", "DATA_PLACEHOLDER", "data_folder", "expand_data_path"]

DATA_ENV = "FEM_RUNOUT_DATA"
DATA_PLACEHOLDER = "${FEM_RUNOUT_DATA}"


def data_folder() -> Path:
    """Return the data folder: ``$FEM_RUNOUT_DATA``, else ``../shared/data`` from the project root.

    The project root is the folder holding the ``fem_runout`` package (a source checkout).
    """
    env = os.environ.get(DATA_ENV)
    if env:
        return Path(env).expanduser()
    return (Path(__file__).resolve().parents[2] / ".." / "shared" / "data").resolve()


def expand_data_path(text: str) -> str:
    """Replace ``${FEM_RUNOUT_DATA}`` in a path by :func:`data_folder`."""
    return text.replace(DATA_PLACEHOLDER, str(data_folder()))
