"""Numba's on-disk kernel cache, invalidated when a module a kernel calls into changes.

Numba stamps a cached kernel (``__pycache__/<module>.<function>-<line>.py313.nbi/.nbc``) with
the modification time and size of the kernel's *own* source file only. A kernel that calls
(and so compiles in) a function or a constant of another module keeps the old machine code
when only that other module is edited: ``mpm.mesh_weights`` compiles in ``mpm.mesh_clip``,
the friction kernel ``fem_runout.physics.friction.newton``. Edited physics then ran stale
code without a word (met in sessions 29–32 while profiling).

:func:`invalidate_stale` fixes this at import: every module of the packages that uses numba
gets a fingerprint, the SHA-256 of its source, of the numba-using modules it imports
(transitively, through such modules: only they define compiled functions) and of the modules
any of these import directly (their constants are compiled in); where a fingerprint differs
from the one recorded with the cache (``__pycache__/numba_dependencies.json``), that module's
cache files are removed and numba compiles it again. ``fem_runout/__init__`` runs it, for
``mpm`` too, and ``mpm/__init__`` calls it as well (a script may import an ``mpm`` module
alone). It reads about 150 small files (about 30 ms). Errors (a read-only install, a race
between MPI ranks deleting the same file) are ignored: the worst case is a recompilation.
Caches that numba keeps outside ``__pycache__`` (``NUMBA_CACHE_DIR``, or a read-only tree)
are not covered.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from pathlib import Path

__all__ = ["RECORD", "fingerprints", "invalidate_once", "invalidate_stale", "packages"]

#: File in each ``__pycache__`` holding the fingerprints of that folder's kernel modules.
RECORD = "numba_dependencies.json"

_IMPORT = re.compile(r"^[ \t]*(?:from[ \t]+([\w.]+)[ \t]+import[ \t]+(\([^)]*\)|[^\n]*)"
                     r"|import[ \t]+([\w.]+))", re.MULTILINE)

_USES_NUMBA = re.compile(r"^[ \t]*(?:import|from)[ \t]+numba\b", re.MULTILINE)


def _module_names(roots: dict[str, Path], files: list[Path]) -> dict[str, Path]:
    """Dotted module name -> source file, for the packages' files."""
    names = {}
    for name, root in roots.items():
        prefix = str(root) + os.sep
        for f in files:
            text = str(f)
            if text.startswith(prefix):
                parts = text[len(prefix):-3].split(os.sep)
                parts = parts[:-1] if parts[-1] == "__init__" else parts
                names[".".join((name, *parts))] = f
    return names


def _imports(text: str, modules: dict[str, Path]) -> set[Path]:
    """Files of the packages that ``text`` imports (``from a.b import c`` may name a module c)."""
    found: set[Path] = set()
    for frm, names, plain in _IMPORT.findall(text):
        module = frm or plain
        for candidate in (module, *(f"{module}.{n}" for n in re.findall(r"\w+", names))):
            if candidate in modules:
                found.add(modules[candidate])
    return found


def fingerprints(roots: dict[str, Path]) -> dict[Path, str]:
    """SHA-256 of each numba-using module of the packages with what its kernels can compile in.

    That is the module, the numba-using modules it imports (transitively, through such
    modules only: only they define compiled functions), and the modules any of these import
    directly (their constants become compile-time constants).

    Args:
        roots: Package name -> package folder (e.g. ``{"fem_runout": Path(...)}``).

    Returns:
        Module file -> hex digest, for the modules that import numba.
    """
    texts = {p: p.read_text(encoding="utf-8") for root in roots.values()
             for p in sorted(root.rglob("*.py"))}
    modules = _module_names(roots, list(texts))
    deps = {p: _imports(t, modules) for p, t in texts.items()}
    kernels = {p for p, t in texts.items() if _USES_NUMBA.search(t)}
    digests = {p: hashlib.sha256(t.encode()).hexdigest() for p, t in texts.items()}
    out = {}
    for path in sorted(kernels):
        seen, todo = {path}, [path]
        while todo:
            for d in deps[todo.pop()] & kernels:
                if d not in seen:
                    seen.add(d)
                    todo.append(d)
        files = seen.union(*(deps[p] for p in seen))
        digest = hashlib.sha256()
        for p in sorted(files):
            digest.update(f"{p}\0{digests[p]}\n".encode())
        out[path] = digest.hexdigest()
    return out


def invalidate_stale(roots: dict[str, Path]) -> list[Path]:
    """Remove the cached kernels of modules whose fingerprint changed; return what was removed.

    A module seen for the first time (no record) has its cache files removed too: whether
    they are current cannot be known.
    """
    removed: list[Path] = []
    try:
        prints = fingerprints(roots)
    except OSError:
        return removed
    by_folder: dict[Path, dict[str, str]] = {}
    for path, digest in prints.items():
        by_folder.setdefault(path.parent / "__pycache__", {})[path.stem] = digest
    for cache, current in by_folder.items():
        if not cache.is_dir():  # nothing cached yet: record what numba will compile
            try:
                cache.mkdir()
            except OSError:
                continue
        try:
            recorded = json.loads((cache / RECORD).read_text())
        except (OSError, ValueError):
            recorded = {}
        stale = [stem for stem, digest in current.items() if recorded.get(stem) != digest]
        for stem in stale:
            for f in list(cache.glob(f"{stem}.*.nbi")) + list(cache.glob(f"{stem}.*.nbc")):
                try:
                    f.unlink()
                    removed.append(f)
                except OSError:
                    pass
        if stale or set(recorded) != set(current):
            _write_atomic(cache / RECORD, json.dumps(current, indent=0, sort_keys=True))
    return removed


def _write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file (ranks may write it together)."""
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)


_checked = False


def invalidate_once() -> None:
    """:func:`invalidate_stale` of :func:`packages`, once per process (``fem_runout/__init__``)."""
    global _checked
    if _checked:
        return
    _checked = True
    invalidate_stale(packages())


def packages() -> dict[str, Path]:
    """``fem_runout`` and the packages of the registered methods' builders: name -> folder."""
    import importlib.util

    from fem_runout.methods import get, method_names

    names = {"fem_runout"} | {get(m).builder.split(".")[0] for m in method_names()}
    found = {}
    for name in sorted(names):
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.submodule_search_locations:
            found[name] = Path(next(iter(spec.submodule_search_locations))).resolve()
    return found
