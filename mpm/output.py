"""Particle output for ParaView.

One VTK point cloud per output time (``particles/particles_NNNN.vtp``) and a
``particles.pvd`` collection with the times.

The writer runs inside the time loop on rank 0 while the other ranks wait at the next step's
first message, so it is kept cheap: pyvista (0.2–0.6 s to import) is imported when the writer
is built, not at the first output, and the arrays are compressed with LZ4 (ParaView and
VTK >= 8 read it), about 3 times faster than VTK's default zlib for files about 30 % larger
(avaKot's 51 000 particles: 44 ms and 4.7 MB against 135 ms and 3.6 MB).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import quoteattr

import numpy as np

if TYPE_CHECKING:
    from fem_runout.callbacks import StepInfo
    from mpm.solver import MPMSolver

__all__ = ["COMPRESSION", "ParticleWriter", "gather_particles"]

#: Compressor of the particle files' arrays (pyvista's ``compression``: "lz4", "zlib", None).
COMPRESSION = "lz4"


def gather_particles(solver: MPMSolver) -> dict[str, np.ndarray] | None:
    """All particles on rank 0, sorted by id (collective; None on other ranks).

    Keys: ``id, x, y, z`` (terrain elevation at the particle), ``h, u, v, volume, sxx, syy,
    sxy`` and ``rank`` (owner).
    """
    p, comm = solver.particles, solver.comm
    x, y = p.positions(solver.grid)
    local = {"x": x, "y": y, "z": solver.particle_elevation(), "h": p.h, "u": p.u,
             "v": p.v, "volume": p.volume, "sxx": p.sxx, "syy": p.syy, "sxy": p.sxy,
             "rank": np.full(len(p), float(comm.rank)), "id": p.id.astype(np.float64)}
    counts = np.asarray(comm.allgather(len(p)), dtype=np.int64)
    out = {}
    for key, values in local.items():
        values = np.ascontiguousarray(values, dtype=np.float64)
        recv = np.empty(int(counts.sum())) if comm.rank == 0 else None
        comm.Gatherv(values, (recv, counts) if comm.rank == 0 else None, root=0)
        out[key] = recv
    if comm.rank != 0:
        return None
    order = np.argsort(out["id"], kind="stable")
    data = {k: v[order] for k, v in out.items()}
    data["id"] = data["id"].astype(np.int64)
    return data


class ParticleWriter:
    """Callback writing the particle cloud at every output time (rank 0 writes).

    Args:
        out_dir: Output folder of the run.
    """

    def __init__(self, out_dir: str | Path) -> None:
        self.dir = Path(out_dir) / "particles"
        self.pvd = Path(out_dir) / "particles.pvd"
        self.entries: list[tuple[float, str]] = []
        import pyvista  # noqa: F401  (now, at setup, not at the first output in the loop)

    def save_state(self) -> dict:
        """Return the collection so far (times and files) for a checkpoint."""
        return {"times": np.asarray([t for t, _ in self.entries], dtype=np.float64),
                "files": "\n".join(f for _, f in self.entries)}

    def resume(self, state: dict) -> None:
        """Continue the collection of a checkpoint (``particles.pvd`` keeps its entries)."""
        files = [f for f in str(state["files"]).split("\n") if f]
        self.entries = list(zip(np.asarray(state["times"], dtype=float).tolist(), files,
                                strict=True))

    def start(self, solver: MPMSolver, info: StepInfo) -> None:
        """Create the particle folder."""
        if solver.comm.rank == 0:
            self.dir.mkdir(parents=True, exist_ok=True)
        solver.comm.barrier()

    def step(self, solver: MPMSolver, info: StepInfo) -> None:
        """Nothing between outputs."""
        pass

    def output(self, solver: MPMSolver, info: StepInfo) -> None:
        """Write the cloud of this output time and update the collection."""
        data = gather_particles(solver)
        if solver.comm.rank != 0 or data is None:
            return
        name = f"particles_{len(self.entries):04d}.vtp"
        write_vtp(self.dir / name, data)
        self.entries.append((info.t, f"particles/{name}"))
        self._write_pvd()

    def finish(self, solver: MPMSolver, info: StepInfo) -> None:
        """Wait for rank 0's files."""
        solver.comm.barrier()

    def _write_pvd(self) -> None:
        rows = "\n".join(f'    <DataSet timestep="{t:.12g}" part="0" file={quoteattr(f)}/>'
                         for t, f in self.entries)
        self.pvd.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                            f"  <Collection>\n{rows}\n  </Collection>\n</VTKFile>\n")


def write_vtp(path: Path, data: dict[str, np.ndarray]) -> None:
    """Write particles as VTK XML PolyData (points at the terrain surface, one vertex each)."""
    import pyvista as pv

    points = np.column_stack([data["x"], data["y"], data["z"]])
    cloud = pv.PolyData(points)
    for key in ("h", "volume", "sxx", "syy", "sxy", "rank"):
        cloud.point_data[key] = data[key]
    cloud.point_data["id"] = data["id"]
    cloud.point_data["velocity"] = np.column_stack([data["u"], data["v"], np.zeros_like(data["u"])])
    cloud.point_data["speed"] = np.hypot(data["u"], data["v"])
    cloud.save(str(path), binary=True, compression=COMPRESSION)

