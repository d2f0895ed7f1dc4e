"""Outline meshes kept once made: in the process and on disk (``FEM_RUNOUT_CACHE``).

gmsh meshes an outline in seconds to minutes (avaKot's corridor 6.8 s, the hemisphere's
0.25 m disc 8.4 s with its smoothing), and every run of the case used to pay it again: each
member of an ensemble, each method of a comparison, each rerun with another friction. The
mesh depends only on what :func:`fem_runout.meshing.outline.mesh_outline` reads, so it is
kept under a digest of exactly that (:func:`mesh_key`):

- the ``domain`` section as loaded (sizes, refine fields, smoothing, boundary);
- the geometry of the outline and of every refine line (their coordinates, wherever they
  come from), the release polygons if a ``release`` field grades the sizes, and the bytes of
  the DEM file if a ``terrain`` field does;
- the source of :mod:`fem_runout.meshing` and the versions of gmsh, NumPy and shapely.

Anything else (friction, time, outputs, another method) reuses the mesh; a change of any of
these makes a new one. The same case gives the same mesh bit for bit whether it comes from
gmsh or from the cache (tested).

The disk cache lives in ``$FEM_RUNOUT_CACHE/meshes`` (default ``~/.cache/fem_runout``, like
FFCx's ``~/.cache/fenics``; ``FEM_RUNOUT_CACHE=off`` disables it). A file is written whole
under a temporary name and renamed, so concurrent runs never read half a mesh; a file that
cannot be read or written is ignored (the mesh is made again). The folder keeps the
:data:`MAX_FILES` most recently used meshes.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import zipfile
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fem_runout.meshing.quadmesh import GROUPS, QuadMesh

if TYPE_CHECKING:
    from fem_runout.config import Case

__all__ = ["CACHE_ENV", "MAX_FILES", "Origin", "cache_dir", "cached_mesh", "clear_memory",
           "last_origin", "mesh_key"]

#: Environment variable naming the cache folder (``off`` or ``0``: no disk cache).
CACHE_ENV = "FEM_RUNOUT_CACHE"
_IN_MEMORY = 4  # meshes kept in the process (an ensemble or a comparison needs one)
#: Files kept on disk: beyond this the least recently used are deleted (a 20 000-cell mesh
#: takes about 1 MB).
MAX_FILES = 64
_memory: OrderedDict[str, QuadMesh] = OrderedDict()


@dataclass(frozen=True)
class Origin:
    """Where :func:`cached_mesh` found its last mesh.

    Attributes:
        source: ``gmsh`` (made now), ``disk`` or ``process`` (kept).
        seconds: Time to get it [s].
        folder: The disk cache's folder (None: disabled).
    """

    source: str
    seconds: float
    folder: Path | None


_last: list[Origin] = []


def last_origin() -> Origin | None:
    """Return where this process's last outline mesh came from (None: none made yet)."""
    return _last[-1] if _last else None


def cache_dir() -> Path | None:
    """Return the cached meshes' folder, or None when ``FEM_RUNOUT_CACHE`` is ``off``/``0``."""
    value = os.environ.get(CACHE_ENV, "").strip()
    if value.lower() in ("off", "0", "false", "no"):
        return None
    if value:
        return Path(value).expanduser() / "meshes"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "fem_runout" / "meshes"


@cache
def _code_digest() -> bytes:
    """Digest of the meshing package's source and the libraries that shape the mesh."""
    import gmsh
    import shapely

    h = hashlib.sha256()
    for path in sorted(Path(__file__).parent.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    h.update(f"{gmsh.__version__} {np.__version__} {shapely.__version__}".encode())
    return h.digest()


def _file_digest(path: Path) -> bytes:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.digest()


def mesh_key(case: Case) -> str:
    """Hex digest of everything an outline mesh of ``case`` depends on (module docstring)."""
    from fem_runout.meshing.shapes import case_line, case_outline, release_union

    d = case.domain
    h = hashlib.sha256(_code_digest())
    h.update(json.dumps(d.model_dump(mode="json"), sort_keys=True, default=str).encode())
    h.update(case_outline(case).geom.wkb)
    for i, item in enumerate(d.refine or ()):
        h.update(f"\0refine {i} {item.kind}".encode())
        if item.kind == "line":
            h.update(case_line(case, i).geom.wkb)
        elif item.kind == "release":
            release = release_union(case)
            h.update(b"" if release is None else release.wkb)
        else:
            assert case.terrain.dem is not None
            h.update(_file_digest(case.resolve_input(case.terrain.dem)))
            h.update(f"fill {case.terrain.fill_nodata}".encode())
    return h.hexdigest()


def _frozen(mesh: QuadMesh) -> QuadMesh:
    """``mesh`` with read-only arrays (it is shared by every run that gets it)."""
    arrays = [mesh.nodes, mesh.quads, *mesh.groups.values()]
    for a in arrays:
        a.flags.writeable = False
    return mesh


def _load(path: Path) -> QuadMesh | None:
    try:
        with np.load(path, allow_pickle=False) as f:
            groups = {g: f[f"group_{g}"] for g in GROUPS if f"group_{g}" in f.files}
            mesh = QuadMesh(f["nodes"], f["quads"], groups)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    ok = (mesh.nodes.ndim == 2 and mesh.nodes.shape[1] == 2 and mesh.quads.ndim == 2
          and mesh.quads.shape[1] == 4 and mesh.quads.size > 0
          and 0 <= mesh.quads.min() and mesh.quads.max() < len(mesh.nodes))
    return mesh if ok else None


def _store(path: Path, mesh: QuadMesh) -> None:
    groups = {f"group_{g}": e for g, e in mesh.groups.items()}
    tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(tmp, nodes=mesh.nodes, quads=mesh.quads, **groups)
        os.replace(tmp, path)
        _evict(path.parent)
    except OSError:
        tmp.unlink(missing_ok=True)


def _evict(folder: Path) -> None:
    """Delete the least recently used meshes beyond :data:`MAX_FILES`.

    By modification time, which a read from the disk renews (:func:`_touch`).
    """
    files = []
    for f in folder.glob("*.npz"):
        if ".tmp" not in f.name:
            try:
                files.append((f.stat().st_mtime_ns, f.name, f))
            except OSError:  # deleted by another run meanwhile
                continue
    for *_, f in sorted(files)[:max(0, len(files) - MAX_FILES)]:
        f.unlink(missing_ok=True)


def cached_mesh(case: Case, make: Callable[[Case], QuadMesh]) -> QuadMesh:
    """Return ``make(case)``, from the process's or the disk's cache when made before.

    Args:
        case: A resolved case whose ``domain`` is an outline.
        make: The mesher (:func:`fem_runout.meshing.outline.mesh_outline`); its errors are
            not cached.
    """
    start = time.perf_counter()
    key = mesh_key(case)
    folder = cache_dir()
    if key in _memory:
        _memory.move_to_end(key)
        _note("process", start, folder)
        return _memory[key]
    path = None if folder is None else folder / f"{key}.npz"
    mesh = None if path is None or not path.is_file() else _load(path)
    source = "disk"
    if mesh is not None:
        _touch(path)
    if mesh is None:
        mesh, source = make(case), "gmsh"
        if path is not None:
            _store(path, mesh)
    _memory[key] = _frozen(mesh)
    while len(_memory) > _IN_MEMORY:
        _memory.popitem(last=False)
    _note(source, start, folder)
    return mesh


def _touch(path: Path) -> None:
    """Mark a cached file as just used (:func:`_evict` keeps the most recently used)."""
    try:
        os.utime(path)
    except OSError:
        pass


def _note(source: str, start: float, folder: Path | None) -> None:
    _last[:] = [Origin(source, time.perf_counter() - start, folder)]


def clear_memory() -> None:
    """Forget the meshes kept in this process (the disk cache stays)."""
    _memory.clear()
