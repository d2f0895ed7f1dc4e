"""A cached kernel is recompiled when a module it compiles in changes (fem_runout.numba_cache).

Numba's cache stamps a kernel with its own file only. A temporary package with a cached kernel
``pkg.kernel.run`` calling ``pkg.helper.value`` (itself a kernel) shows the stale result after
``helper.py`` is edited, and the fresh one with :func:`invalidate_stale` at import.
"""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from fem_runout.numba_cache import RECORD, fingerprints, invalidate_stale

KERNEL = """
import numba
from pkg.helper import value

@numba.njit(cache=True)
def run():
    return value() + 0.5
"""
HELPER = """
import numba
from pkg.constants import BASE

@numba.njit(cache=True)
def value():
    return BASE + {}
"""
CONSTANTS = "from pkg.far import FAR\nBASE = 10.0\n"
FAR = "FAR = 1.0\n"
SCRIPT = """
import sys
sys.path.insert(0, {root!r})
from pathlib import Path
if {check}:
    from fem_runout.numba_cache import invalidate_stale
    invalidate_stale({{"pkg": Path({root!r}) / "pkg"}})
from pkg.kernel import run
print(run())
"""


def _package(root: Path, helper_value: int) -> Path:
    pkg = root / "pkg"
    pkg.mkdir(exist_ok=True)
    files = (("__init__", ""), ("kernel", KERNEL), ("helper", HELPER.format(helper_value)),
             ("constants", CONSTANTS), ("far", FAR))
    for name, text in files:
        (pkg / f"{name}.py").write_text(textwrap.dedent(text))
    return pkg


def _run(root: Path, check: bool) -> float:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    out = subprocess.run([sys.executable, "-c", SCRIPT.format(root=str(root), check=check)],
                         capture_output=True, text=True, env=env, check=True, cwd=root)
    return float(out.stdout.split()[-1])


def test_fingerprints_follow_the_kernels_imports(tmp_path: Path) -> None:
    """Kernel modules only; an edit of a compiled-in module or a constant changes them."""
    pkg = _package(tmp_path, 1)
    roots = {"pkg": pkg}
    first = fingerprints(roots)
    assert set(first) == {pkg / "kernel.py", pkg / "helper.py"}
    (pkg / "far.py").write_text("FAR = 2.0\n")  # imported by a constants module: not compiled in
    assert fingerprints(roots) == first
    (pkg / "constants.py").write_text(CONSTANTS.replace("10.0", "20.0"))
    second = fingerprints(roots)
    assert all(second[p] != first[p] for p in first)


def test_an_edited_helper_is_recompiled_into_the_cached_kernel(tmp_path: Path) -> None:
    """Without the check numba returns the stale 11.5; with it the edited 12.5."""
    pkg = _package(tmp_path, 1)
    assert _run(tmp_path, check=True) == 11.5
    assert (pkg / "__pycache__" / RECORD).is_file()
    (pkg / "helper.py").write_text(textwrap.dedent(HELPER.format(2)))  # kernel.py untouched
    assert _run(tmp_path, check=False) == 11.5  # numba's own check: stale
    assert _run(tmp_path, check=True) == 12.5
    assert _run(tmp_path, check=True) == 12.5  # and cached again: nothing more removed
    assert invalidate_stale({"pkg": pkg}) == []


def test_importing_an_mpm_module_alone_checks_the_cache() -> None:
    """``mpm``'s kernels compile in other modules (``mpm.projection`` the blend of
    ``mpm.projection_blend``): importing any mpm module runs the invalidation, which
    ``fem_runout``'s import does. Found when a script importing ``mpm.projection`` alone kept
    an edited constant's former value."""
    script = ("import sys; import mpm.projection; "
              "print('fem_runout.numba_cache' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True)
    assert out.stdout.split()[-1] == "True"
