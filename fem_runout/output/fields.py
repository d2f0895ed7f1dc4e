"""Field output for ParaView (VTX/ADIOS2 ``.bp`` and VTK ``.pvd``) and a reader of the ``.bp``."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import TYPE_CHECKING

from mpi4py import MPI  # noqa: F401 - before dolfinx

# isort: split

import numpy as np
from dolfinx import fem, io

from fem_runout.errors import OutputError
from fem_runout.output.gather import sorted_node_order

if TYPE_CHECKING:
    from fem_runout.callbacks import StepInfo
    from fem_runout.solver_api import Solver

__all__ = ["FIELD_NAMES", "FieldWriter", "read_vtx_bp4"]

FIELD_NAMES: tuple[str, ...] = ("h", "hu", "hv", "velocity", "z", "eta")


class FieldWriter:
    """Callback writing ``h, hu, hv, velocity, z, eta`` at every output time.

    One VTX file ``out_dir/fields.bp`` (ADIOS2 engine ``BP4`` by default, which ParaView's
    "ADIOS2VTXReader" opens) holds all fields on the Q1 nodes; ``velocity`` is a 2-vector
    (padded to 3 components in the file), ``(hu, hv) / h`` where ``h > threshold`` and 0
    elsewhere; ``eta = h + z`` is the free surface. The mesh is written once (it is static).

    With ``pvd=True`` (the default) the same fields are also written to ``out_dir/fields.pvd``
    (a VTK collection of ``.vtu``/``.pvtu`` files, one per output time), which ParaView and
    pyvista (``pyvista.get_reader``) open without ADIOS2 support.
    """

    def __init__(
        self,
        out_dir: str | Path,
        solver: Solver,
        threshold: float = 1e-6,
        engine: str = "BP4",
        pvd: bool = True,
    ) -> None:
        """Create the output functions (the file is opened at :meth:`start`).

        Args:
            out_dir: Output folder (created on rank 0 if missing).
            solver: The solver whose fields are written.
            threshold: Dry threshold [m] for the velocity.
            engine: ADIOS2 engine (``"BP4"`` or ``"BP5"``).
            pvd: Also write the VTK companion ``fields.pvd``.
        """
        self.out_dir = Path(out_dir)
        self.path = self.out_dir / "fields.bp"
        self.threshold = float(threshold)
        self.engine = engine
        self.pvd_path: Path | None = self.out_dir / "fields.pvd" if pvd else None
        V = solver.V
        W = fem.functionspace(V.mesh, ("Lagrange", 1, (V.mesh.geometry.dim,)))
        self.velocity = fem.Function(W, name="velocity")
        self.eta = fem.Function(V, name="eta")
        for name in ("h", "hu", "hv", "z"):
            solver.fields[name].name = name
        self._functions = [
            solver.fields["h"],
            solver.fields["hu"],
            solver.fields["hv"],
            self.velocity,
            solver.fields["z"],
            self.eta,
        ]
        self._node_of = _matching_nodes(V, W)
        self._writer: io.VTXWriter | None = None
        self._pvd: io.VTKFile | None = None
        self.times: list[float] = []
        self.part = 0  # a restarted run continues in fields.part<k>.bp / .pvd
        self._part_start = 0  # index in times of this part's first output

    def update(self, solver: Solver) -> None:
        """Recompute ``velocity`` and ``eta`` on all local nodes (ghosts included).

        Args:
            solver: The solver (ghost values of its fields must be up to date).
        """
        h, hu, hv, z = (solver.fields[k].x.array for k in ("h", "hu", "hv", "z"))
        wet = h > self.threshold
        inv_h = np.zeros_like(h)
        inv_h[wet] = 1.0 / h[wet]
        vel = self.velocity.x.array.reshape(-1, self.velocity.function_space.dofmap.index_map_bs)
        nodes = self._node_of
        vel[:, 0] = (hu * inv_h)[nodes]
        vel[:, 1] = (hv * inv_h)[nodes]
        self.eta.x.array[:] = h + z

    def save_state(self) -> dict:
        """Return the output times written so far and the file part (for a checkpoint)."""
        return {"times": np.asarray(self.times, dtype=np.float64), "part": self.part}

    def resume(self, state: dict) -> None:
        """Continue after a checkpoint: the next outputs go to the next file part.

        ADIOS2 files cannot be appended to by a new VTXWriter, so a restarted run writes
        ``fields.part1.bp`` (``fields.part2.bp`` after a second restart, …) next to
        ``fields.bp``; ParaView opens them as one series (docs/usage.md).
        """
        self.times = np.asarray(state["times"], dtype=np.float64).tolist()
        self._part_start = len(self.times)
        self.part = int(state["part"]) + 1
        suffix = f".part{self.part}"
        self.path = self.out_dir / f"fields{suffix}.bp"
        if self.pvd_path is not None:
            self.pvd_path = self.out_dir / f"fields{suffix}.pvd"

    def start(self, solver: Solver, info: StepInfo) -> None:
        """Open ``fields.bp`` and ``fields.pvd`` (collective)."""
        if solver.comm.rank == 0:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        solver.comm.barrier()
        self._writer = io.VTXWriter(
            solver.comm,
            self.path,
            self._functions,
            engine=self.engine,
            mesh_policy=io.VTXMeshPolicy.reuse,
        )
        if self.pvd_path is not None:
            self._pvd = io.VTKFile(solver.comm, self.pvd_path, "w")

    def step(self, solver: Solver, info: StepInfo) -> None:
        """Nothing to do after a step."""

    def output(self, solver: Solver, info: StepInfo) -> None:
        """Write all fields at time ``info.t`` (collective)."""
        if self._writer is None:
            raise RuntimeError("FieldWriter.output() called before start()")
        self.update(solver)
        try:
            self._writer.write(info.t)
            if self._pvd is not None:
                self._pvd.write_function(self._functions, info.t)
        except RuntimeError as exc:  # ADIOS2 / VTK I/O failures
            reason = str(exc).split("couldn't")[-1].split("[0m")[0].strip(" :")
            raise OutputError(f"cannot write the fields at t = {info.t:.6g} s to "
                              f"{self.path.parent}: {reason or exc}") from None
        self.times.append(info.t)
        if self._pvd is not None and solver.comm.rank == 0:
            self._write_pvd_index()

    def _write_pvd_index(self) -> None:
        """Rewrite the ``.pvd`` collection after every output (atomically).

        DOLFINx writes it only when the file is closed; a run that ends early (a full disk, a
        kill) would leave its ``.pvtu`` files without an index.
        """
        stem = self.pvd_path.stem
        rows = "\n".join(f'    <DataSet timestep="{t!r}" part="0" file="{stem}{k:06d}.pvtu" />'
                         for k, t in enumerate(self.times[self._part_start:]))
        text = ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                f"  <Collection>\n{rows}\n  </Collection>\n</VTKFile>\n")
        tmp = self.pvd_path.with_suffix(".pvd.tmp")
        tmp.write_text(text)
        tmp.replace(self.pvd_path)

    def finish(self, solver: Solver, info: StepInfo) -> None:
        """Close the files (collective)."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if self._pvd is not None:
            self._pvd.close()
            self._pvd = None


def _matching_nodes(V: fem.FunctionSpace, W: fem.FunctionSpace) -> np.ndarray:
    """For each local node of the blocked space ``W``, the local dof of ``V`` at the same point."""
    xv = V.tabulate_dof_coordinates()
    xw = W.tabulate_dof_coordinates()
    if xv.shape == xw.shape and np.array_equal(xv, xw):
        return np.arange(xv.shape[0])
    if xv.shape != xw.shape:
        raise ValueError("velocity space and scalar space have different nodes")
    node_of = np.empty(xw.shape[0], dtype=np.int64)
    node_of[sorted_node_order(xw[:, 0], xw[:, 1])] = sorted_node_order(xv[:, 0], xv[:, 1])
    return node_of


# --- A minimal reader of BP4 files as written by dolfinx's VTXWriter ---------------------
# VTK/pyvista wheels ship no ADIOS2 reader, so tests and scripts read ``.bp`` back with this.
# It walks the process-group ("[PGI") and variable ("[VMD") records of ``data.*``; each
# variable's payload is the last ``count * itemsize`` bytes of its record.

_BP_DTYPES: dict[int, np.dtype] = {
    0: np.dtype("i1"),
    1: np.dtype("<i2"),
    2: np.dtype("<i4"),
    4: np.dtype("<i8"),
    5: np.dtype("<f4"),
    6: np.dtype("<f8"),
    50: np.dtype("u1"),
    51: np.dtype("<u2"),
    52: np.dtype("<u4"),
    54: np.dtype("<u8"),
}


def _parse_variable(buf: bytes, pos: int) -> tuple[str, np.ndarray]:
    """Parse one ``[VMD`` record at ``pos`` into ``(name, values)``."""
    (length,) = struct.unpack_from("<Q", buf, pos + 4)
    (name_len,) = struct.unpack_from("<H", buf, pos + 16)
    name = buf[pos + 18 : pos + 18 + name_len].decode()
    p = pos + 18 + name_len + 2  # skip the (empty) path record
    dtype = _BP_DTYPES[buf[p]]
    ndims = buf[p + 2]
    p += 5  # dtype, is-dimension flag, ndims, dimensions length (uint16)
    counts = [struct.unpack_from("<Q", buf, p + 27 * d + 1)[0] for d in range(ndims)]
    n = int(np.prod(counts)) if ndims else 1
    end = pos + 4 + length
    values = np.frombuffer(buf, dtype=dtype, count=n, offset=end - n * dtype.itemsize)
    if ndims == 2 and counts[1] == 1:
        counts = counts[:1]  # scalar point data is stored as (n, 1)
    return name, values.reshape(counts) if ndims else values


def read_vtx_bp4(path: str | Path) -> list[dict[str, np.ndarray]]:
    """Read a BP4 ``.bp`` folder written by :class:`dolfinx.io.VTXWriter`.

    Blocks written by different ranks in one step are concatenated in rank order (ghost
    nodes included, as in the file).

    Args:
        path: The ``.bp`` folder.

    Returns:
        One dict per step, variable name to values (``step`` holds the time; scalar point
        data has shape ``(n,)``, vectors ``(n, 3)``, ``geometry`` ``(n, 3)``; with
        ``VTXMeshPolicy.reuse`` the mesh variables appear in the first step only). A step
        written only in part (a run stopped by a full disk or a kill while writing) is left
        out.

    Raises:
        ValueError: If the folder is not a BP4 file.
    """
    folder = Path(path)
    data_files = sorted(folder.glob("data.*"), key=lambda f: int(f.suffix[1:]))
    if not data_files or not (folder / "md.idx").is_file() or (folder / "mmd.0").exists():
        raise ValueError(f"{folder} is not a BP4 folder")
    blocks: dict[int, list[tuple[int, dict[str, np.ndarray]]]] = {}
    cut: set[int] = set()
    for data_file in data_files:
        buf = data_file.read_bytes()
        for pg, pg_end in _records(buf, b"[PGI", 0, len(buf)):
            (name_len,) = struct.unpack_from("<H", buf, pg + 13)
            p = pg + 15 + name_len
            (rank,) = struct.unpack_from("<I", buf, p)
            (ts_len,) = struct.unpack_from("<H", buf, p + 4)
            (step,) = struct.unpack_from("<I", buf, p + 6 + ts_len)
            try:
                variables = dict(_parse_variable(buf, v)
                                 for v, _ in _records(buf, b"[VMD", pg, pg_end))
            except (ValueError, KeyError, IndexError, struct.error):
                cut.add(step)  # written only in part (the run stopped while writing it)
                continue
            blocks.setdefault(step, []).append((rank, variables))
    steps = []
    for step in sorted(set(blocks) - cut):
        ranks = sorted(blocks[step], key=lambda item: item[0])
        names = dict.fromkeys(name for _, variables in ranks for name in variables)
        merged = {name: np.concatenate([v[name] for _, v in ranks if name in v]) for name in names}
        merged["step"] = ranks[0][1]["step"].copy() if "step" in ranks[0][1] else np.zeros(0)
        steps.append(merged)
    return steps


def _records(buf: bytes, tag: bytes, start: int, end: int) -> list[tuple[int, int]]:
    """``(start, end)`` of the consecutive ``tag`` records (length-prefixed) in ``buf[start:end]``.

    The first record is the first occurrence of ``tag``; each following one starts where the
    previous ends (its 8-byte length counts from the length field). Variable records end at
    the first gap; after a gap, a process group is looked for at the next ``[PGI``.
    """
    found = []
    pos = buf.find(tag, start, end)
    while 0 <= pos < end:
        (length,) = struct.unpack_from("<Q", buf, pos + 4)
        stop = min(pos + 4 + length, end)
        found.append((pos, stop))
        if buf[stop : stop + 4] == tag:
            pos = stop
        else:  # variables are contiguous; process groups may be padded
            pos = buf.find(tag, stop, end) if tag == b"[PGI" else -1
    return found
