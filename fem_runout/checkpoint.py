"""Checkpoints: the whole state of a run in one HDF5 file that does not depend on the ranks.

A checkpoint holds the solver's state (nodal fields in the global ``(y, x)`` node order of
:func:`~fem_runout.output.gather.gather_nodal`; DAMPM's particles sorted by id), the runner's
clock and rest test, every restartable callback's state (series so far, peak maps, output
counters) and the resolved case. Rank 0 writes it to ``<name>.h5.tmp`` and renames it, so a
crash while writing leaves the previous checkpoint valid; only the newest ``keep`` are kept.

The tree is nested dicts of numpy arrays, numbers and strings: dicts become HDF5 groups,
arrays datasets, numbers and strings attributes.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.errors import CaseError

__all__ = ["FORMAT", "Checkpointer", "MeshMismatch", "check_nodes", "domain_differences",
           "read_checkpoint", "read_tree", "scatter_nodal", "write_tree"]

FORMAT = "fem_runout-checkpoint-1"
_NONE = "__none__"


class MeshMismatch(CaseError):
    """A checkpoint's nodes are not the case's (:func:`scatter_nodal`)."""


def domain_differences(saved_case: str, case_text: str) -> list[str]:
    """Return the ``domain`` keys whose values differ between two resolved cases.

    Args:
        saved_case: The resolved case stored in a checkpoint (YAML text).
        case_text: The resolved case of the run (YAML text).

    Returns:
        One line per differing key, ``"domain.<key>: <checkpoint's> in the checkpoint, <ours>
        here"`` (``absent`` for a key one of them lacks, e.g. a key added after the
        checkpoint was written), in the case's key order.
    """
    import yaml

    def domain(text: str) -> dict[str, Any]:
        data = yaml.safe_load(text) if text else None
        return data.get("domain", {}) if isinstance(data, dict) else {}

    old, new = domain(saved_case), domain(case_text)
    keys = list(new) + [k for k in old if k not in new]
    return [f"domain.{k}: {old.get(k, 'absent')} in the checkpoint, {new.get(k, 'absent')} here"
            for k in keys if old.get(k) != new.get(k)]


def write_tree(group, tree: dict[str, Any]) -> None:
    """Write a nested dict into an h5py group (see the module docstring)."""
    for key, value in tree.items():
        if isinstance(value, dict):
            write_tree(group.create_group(key), value)
        elif isinstance(value, np.ndarray):
            group.create_dataset(key, data=value)
        elif isinstance(value, (list, tuple)):
            group.create_dataset(key, data=np.asarray(value, dtype=np.float64))
        else:
            group.attrs[key] = _NONE if value is None else value


def read_tree(group) -> dict[str, Any]:
    """Read what :func:`write_tree` wrote."""
    import h5py

    tree: dict[str, Any] = {}
    for key, attr in group.attrs.items():
        value = attr.item() if isinstance(attr, np.generic) else attr
        tree[key] = None if isinstance(value, str) and value == _NONE else value
    for key, item in group.items():
        tree[key] = read_tree(item) if isinstance(item, h5py.Group) else item[()]
    return tree


def scatter_nodal(V, nodes: dict[str, np.ndarray] | None) -> dict[str, np.ndarray]:
    """Inverse of :func:`~fem_runout.output.gather.gather_nodal` (collective).

    Args:
        V: The scalar Q1 space.
        nodes: On rank 0, arrays in the global ``(y, x)`` order with the coordinates ``x``,
            ``y`` (other ranks: anything).

    Returns:
        Every array on this rank's local dofs (owned and ghosts), matched by coordinates.

    Raises:
        MeshMismatch: On every rank, if the nodes are not ``V``'s (:func:`check_nodes`).
    """
    nodes = V.mesh.comm.bcast(nodes if V.mesh.comm.rank == 0 else None, root=0)
    pos = _positions(V, nodes)
    return {k: np.asarray(v)[pos] for k, v in nodes.items() if k not in ("x", "y")}


def check_nodes(V, nodes: dict[str, np.ndarray] | None) -> None:
    """Raise :class:`MeshMismatch` on every rank unless ``nodes`` are ``V``'s (collective).

    Args:
        V: The scalar Q1 space.
        nodes: On rank 0, a checkpoint's nodal arrays with the coordinates ``x``, ``y``
            (None: nothing to check).
    """
    nodes = V.mesh.comm.bcast(nodes if V.mesh.comm.rank == 0 else None, root=0)
    if nodes is not None:
        _positions(V, nodes)


def _positions(V, nodes: dict[str, np.ndarray]) -> np.ndarray:
    """Row of ``nodes`` of each local dof of ``V``, matched by coordinates (collective)."""
    comm = V.mesh.comm
    coords = V.tabulate_dof_coordinates()
    x0, y0 = float(nodes["x"].min()), float(nodes["y"].min())
    tol = max(float(np.ptp(nodes["x"])), float(np.ptp(nodes["y"])), 1.0) * 1e-9

    def key(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.round((y - y0) / tol).astype(np.int64) * (2 ** 31) + \
            np.round((x - x0) / tol).astype(np.int64)

    ref = key(nodes["x"], nodes["y"])
    order = np.argsort(ref, kind="stable")
    mine = key(coords[:, 0], coords[:, 1])
    pos = order[np.clip(np.searchsorted(ref[order], mine), 0, ref.size - 1)]
    same = np.array_equal(ref[pos], mine) and V.dofmap.index_map.size_global == ref.size
    if comm.allreduce(int(not same)):  # every rank raises
        raise MeshMismatch("the checkpoint's nodes are not this case's mesh")
    return pos


def read_checkpoint(path: str | Path, comm) -> dict[str, Any]:
    """Read a checkpoint on rank 0 and broadcast it (collective); CaseError if unreadable."""
    error, tree = None, None
    if comm.rank == 0:
        import h5py

        try:
            with h5py.File(path, "r") as f:
                tree = read_tree(f)
            if tree.get("format") != FORMAT:
                error = f"--restart: '{path}' is not a fem_runout checkpoint"
        except (OSError, KeyError, ValueError) as exc:
            error = f"--restart: cannot read checkpoint '{path}': {exc}"
    error = comm.bcast(error, root=0)
    if error:
        raise CaseError(error)
    return comm.bcast(tree, root=0)


class Checkpointer:
    """Writes checkpoints every ``every`` simulated seconds (and when asked), keeps ``keep``.

    Args:
        folder: Where the files go (``<output.dir>/checkpoints``).
        every: Interval [s] (None: only when the run is interrupted or goes bad).
        keep: Number of newest checkpoints kept.
        meta: The resolved case text and method, stored in every file.
    """

    def __init__(self, folder: Path, every: float | None, keep: int, meta: dict[str, Any]
                 ) -> None:
        self.folder = Path(folder)
        self.every = every
        self.keep = int(keep)
        self.meta = dict(meta)
        self.next_time = every if every else float("inf")
        # a restarted run keeps counting the files already there (``keep`` across restarts)
        self.written: list[Path] = sorted(self.folder.glob("checkpoint_*.h5"))

    def resume_at(self, t: float) -> None:
        """Continue the schedule of a run restarted at time ``t`` (next: after ``t``)."""
        if self.every:
            self.next_time = (math.floor(t / self.every + 1e-9) + 1) * self.every

    def due(self, t: float) -> bool:
        """Whether the schedule asks for a checkpoint at time ``t``."""
        return t >= self.next_time - 1e-12 * max(t, 1.0)

    def write(self, tree: dict[str, Any], step: int, t: float, comm) -> Path:
        """Write ``tree`` atomically on rank 0 (collective: the path is returned everywhere)."""
        path = self.folder / f"checkpoint_{step:08d}.h5"
        error = None
        if comm.rank == 0:
            try:
                self._write(path, tree)
            except OSError as exc:
                error = f"cannot write checkpoint '{path}': {exc.strerror or exc}"
        error = comm.bcast(error, root=0)
        if error:
            raise OSError(error)
        if self.every:
            while self.next_time <= t + 1e-12 * max(t, 1.0):
                self.next_time += self.every
        return path

    def _write(self, path: Path, tree: dict[str, Any]) -> None:
        import h5py

        self.folder.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".h5.tmp")
        with h5py.File(tmp, "w") as f:
            write_tree(f, {"format": FORMAT, "written": time.time(), "meta": self.meta, **tree})
        pause = os.environ.get("FEM_RUNOUT_CHECKPOINT_PAUSE")  # tests: a kill while writing
        if pause:
            time.sleep(float(pause))
        os.replace(tmp, path)
        if path not in self.written:
            self.written.append(path)
        while len(self.written) > self.keep:
            self.written.pop(0).unlink(missing_ok=True)
