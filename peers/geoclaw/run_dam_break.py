r"""GeoClaw (clawpack 5.14.0) on the inclined dry-bed dam break (cases/inclined_dam_break.yaml).

Run it with the GeoClaw venv's python (see ``peers/geoclaw/setup.sh``)::

    $PEERS_VENV/bin/python peers/geoclaw/run_dam_break.py --nx 330 --ny 33 \
        --out /tmp/geoclaw_dam_break

Case: bed ``Z = 100 - x/3`` on ``[0, xmax] x [0, 20]``, water at rest with surface 100 m behind
the dam ``x <= 20`` (``h = x/3``), dry elsewhere, g = 9.81, no friction, no Coriolis, extrapolation
(outflow) boundaries left/right, walls bottom/top, one grid level (no AMR), CFL 0.9, dry tolerance
1e-6 m.  The initial state is set by a small ``qinit.f90`` replacing GeoClaw's: cells whose centre
has ``x <= x_dam`` get ``h = max(0, eta_dam - B)``, all others are dry.

The binary ``xgeoclaw`` is compiled once per (clawpack version, gfortran, flags, sources) key under
``<venv>/share/geoclaw_build/<key>`` and reused.  The run itself is timed (``wall_time``), the time
steps are counted from ``fort.amr``, and the front (largest cell centre x with ``h > threshold``,
mean over the y rows) at 5.5 s and at ``--tfinal`` is compared with the exact tip
``x_f(t) = 20 + 2 sqrt(g 20/3) t + g t^2 / 6``.  Everything goes to ``summary.json`` in ``--out``.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.metadata
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

G = 9.81
X_DAM = 20.0
ETA_DAM = 100.0
SLOPE = 1.0 / 3.0
Y_EXTENT = 20.0
REPO_ROOT = Path(__file__).resolve().parents[2]

QINIT_F90 = """\
! Dam break initial state (fem_runout peer run): h = max(0, eta_dam - B) in the cells whose
! centre has x <= x_dam, dry elsewhere, zero momentum.  x_dam and eta_dam are read from dam.data.
subroutine qinit(meqn,mbc,mx,my,xlower,ylower,dx,dy,q,maux,aux)
    implicit none
    integer, intent(in) :: meqn,mbc,mx,my,maux
    real(kind=8), intent(in) :: xlower,ylower,dx,dy
    real(kind=8), intent(inout) :: q(meqn,1-mbc:mx+mbc,1-mbc:my+mbc)
    real(kind=8), intent(inout) :: aux(maux,1-mbc:mx+mbc,1-mbc:my+mbc)
    integer :: i, j, iunit
    real(kind=8) :: x, x_dam, eta_dam

    open(newunit=iunit, file='dam.data', status='old', action='read')
    read(iunit,*) x_dam
    read(iunit,*) eta_dam
    close(iunit)
    q = 0.d0
    do j = 1, my
        do i = 1, mx
            x = xlower + (i - 0.5d0)*dx
            if (x <= x_dam + 1.d-9*dx) q(1,i,j) = max(0.d0, eta_dam - aux(1,i,j))
        end do
    end do
end subroutine qinit
"""

MAKEFILE = """\
# xgeoclaw for the fem_runout dam-break peer run (GeoClaw's qinit.f90 replaced by ours)
CLAWMAKE = $(CLAW)/clawutil/src/Makefile.common
CLAW_PKG = geoclaw
EXE = xgeoclaw
FFLAGS = {fflags}
GEOLIB = $(CLAW)/geoclaw/src/2d/shallow
include $(GEOLIB)/Makefile.geoclaw
EXCLUDE_MODULES =
EXCLUDE_SOURCES = $(GEOLIB)/qinit.f90
MODULES =
SOURCES = qinit.f90 \\
  $(CLAW)/riemann/src/rpn2_geoclaw.f \\
  $(CLAW)/riemann/src/rpt2_geoclaw.f \\
  $(CLAW)/riemann/src/geoclaw_riemann_utils.f
include $(CLAWMAKE)
"""


def exact_front(t: float) -> float:
    """Exact dry-bed front tip [m] (as ``fem_runout.references.inclined_dam_break``)."""
    return X_DAM + 2.0 * math.sqrt(G * X_DAM * SLOPE) * t + 0.5 * G * SLOPE * t * t


def clawpack_version() -> str:
    """Installed clawpack version."""
    return importlib.metadata.version("clawpack")


def claw_dir() -> Path:
    """``$CLAW`` or the sdist tree unpacked by setup.sh under the venv."""
    claw = Path(
        os.environ.get("CLAW") or Path(sys.prefix) / "src" / f"clawpack-{clawpack_version()}"
    )
    if not (claw / "geoclaw" / "src" / "2d" / "shallow" / "Makefile.geoclaw").is_file():
        sys.exit(f"GeoClaw Fortran sources not found under CLAW={claw}: run peers/geoclaw/setup.sh")
    return claw


def build(fflags: str) -> tuple[Path, str]:
    """Compile (or reuse) xgeoclaw; return its path and the make command used."""
    if shutil.which("gfortran") is None:
        sys.exit(
            "gfortran not found: install it with your package manager "
            "(e.g. apt-get install gfortran)"
        )
    claw = claw_dir()
    fc_version = subprocess.run(
        ["gfortran", "--version"], capture_output=True, text=True, check=True
    ).stdout.splitlines()[0]
    makefile = MAKEFILE.format(fflags=fflags)
    key = hashlib.sha256(
        "\n".join([clawpack_version(), str(claw), fc_version, makefile, QINIT_F90]).encode()
    ).hexdigest()[:12]
    bdir = Path(sys.prefix) / "share" / "geoclaw_build" / key
    exe = bdir / "xgeoclaw"
    cmd = f"make -C {bdir} .exe CLAW={claw} FC=gfortran CLAW_PYTHON={sys.executable}"
    if exe.is_file():
        return exe, cmd
    bdir.mkdir(parents=True, exist_ok=True)
    (bdir / "Makefile").write_text(makefile)
    (bdir / "qinit.f90").write_text(QINIT_F90)
    env = dict(os.environ, CLAW=str(claw), FC="gfortran", CLAW_PYTHON=sys.executable)
    print(f"compiling xgeoclaw in {bdir} ...", flush=True)
    t0 = time.perf_counter()
    res = subprocess.run(cmd.split(), env=env, capture_output=True, text=True)
    (bdir / "make.log").write_text(res.stdout + res.stderr)
    if res.returncode != 0 or not exe.is_file():
        sys.exit(f"compiling xgeoclaw failed, see {bdir / 'make.log'}")
    print(f"compiled in {time.perf_counter() - t0:.0f} s", flush=True)
    return exe, cmd


def write_topo(path: Path, xmax: float, spacing: float = 2.0, margin: float = 10.0) -> None:
    """Write a topotype-3 file of ``Z = 100 - x/3`` covering the domain with a margin.

    The bed is linear, hence exact under GeoClaw's bilinear cell integration.
    """
    x = np.arange(-margin, xmax + margin + 0.5 * spacing, spacing)
    y = np.arange(-margin, Y_EXTENT + margin + 0.5 * spacing, spacing)
    z = np.tile(ETA_DAM - SLOPE * x, (y.size, 1))  # rows from north to south (y-invariant)
    header = (
        f"{x.size} ncols\n{y.size} nrows\n{x[0]:.6f} xlower\n{y[0]:.6f} ylower\n"
        f"{spacing:.6f} cellsize\n-99999 nodata_value\n"
    )
    with path.open("w") as f:
        f.write(header)
        np.savetxt(f, z, fmt="%.8f")


def write_data(
    run: Path, nx: int, ny: int, xmax: float, tfinal: float, cfl: float, times: list[float]
) -> None:
    """Write GeoClaw's ``*.data`` files (the setrun), the topography and ``dam.data`` in ``run``."""
    from clawpack.clawutil import data

    rundata = data.ClawRunData("geoclaw", 2)
    cd = rundata.clawdata
    cd.lower[0], cd.upper[0], cd.lower[1], cd.upper[1] = 0.0, float(xmax), 0.0, Y_EXTENT
    cd.num_cells[0], cd.num_cells[1] = int(nx), int(ny)
    cd.num_eqn, cd.num_aux, cd.capa_index = 3, 1, 0
    cd.t0 = 0.0
    cd.output_style = 2
    cd.output_times = [float(t) for t in times]  # plain floats: numpy 2 scalars break claw.data
    cd.output_t0 = False
    cd.output_format = "ascii"
    cd.output_q_components = "all"
    cd.output_aux_components = "none"
    cd.verbosity = 0
    dx = xmax / nx
    cd.dt_variable = True
    cd.dt_initial = float(0.5 * cfl * dx / math.sqrt(G * X_DAM * SLOPE))
    cd.dt_max = 1e99
    cd.cfl_desired, cd.cfl_max = float(cfl), 1.0
    cd.steps_max = 1000000
    cd.order, cd.dimensional_split, cd.transverse_waves = 2, "unsplit", 2
    cd.num_waves, cd.limiter, cd.use_fwaves = 3, ["mc", "mc", "mc"], True
    cd.source_split = "godunov"
    cd.num_ghost = 2
    cd.bc_lower[0], cd.bc_upper[0] = "extrap", "extrap"
    cd.bc_lower[1], cd.bc_upper[1] = "wall", "wall"
    cd.checkpt_style = 0
    amr = rundata.amrdata
    amr.amr_levels_max = 1
    amr.refinement_ratios_x = amr.refinement_ratios_y = amr.refinement_ratios_t = [2]
    amr.aux_type = ["center"]
    amr.flag_richardson, amr.flag2refine = False, False
    amr.regrid_interval = 1000000
    amr.tprint = True  # one "AMRCLAW: level 1 ..." line per time step in fort.amr
    geo = rundata.geo_data
    geo.gravity, geo.coordinate_system = G, 1
    geo.coriolis_forcing = False
    geo.sea_level = 0.0  # everything dry, then qinit.f90 fills the reservoir
    geo.dry_tolerance = 1e-6
    geo.friction_forcing = False
    geo.manning_coefficient = 0.0
    geo.friction_depth = 1e6
    rundata.refinement_data.variable_dt_refinement_ratios = False
    write_topo(run / "topo.tt3", xmax)
    rundata.topo_data.topofiles = [[3, str(run / "topo.tt3")]]
    rundata.qinit_data.qinit_type = 0
    rundata.write(out_dir=str(run))
    (run / "dam.data").write_text(f"{X_DAM!r}  x_dam\n{ETA_DAM!r}  eta_dam\n")


def read_depth(run: Path, frame: int) -> tuple[float, np.ndarray, np.ndarray]:
    """Time, cell-centre x and depth ``h[ny, nx]`` of an ascii output frame (one level)."""
    from clawpack.pyclaw.solution import Solution

    sol = Solution(frame, path=str(run), file_format="ascii")
    patches = [st.patch for st in sol.states]  # one level, several grids: their union
    x0 = min(p.lower_global[0] for p in patches)
    x1 = max(p.upper_global[0] for p in patches)
    y0 = min(p.lower_global[1] for p in patches)
    y1 = max(p.upper_global[1] for p in patches)
    dx, dy = patches[0].delta
    nx, ny = int(round((x1 - x0) / dx)), int(round((y1 - y0) / dy))
    h = np.full((ny, nx), np.nan)
    for st in sol.states:
        p = st.patch
        i0 = int(round((p.lower_global[0] - x0) / dx))
        j0 = int(round((p.lower_global[1] - y0) / dy))
        mx, my = p.num_cells_global
        h[j0 : j0 + my, i0 : i0 + mx] = st.q[0].T
    if np.isnan(h).any():
        raise RuntimeError(f"frame {frame}: patches do not cover the domain")
    return float(sol.t), x0 + (np.arange(nx) + 0.5) * dx, h


def front(x: np.ndarray, h: np.ndarray, threshold: float) -> tuple[float, float]:
    """Front (largest cell-centre x with ``h > threshold``): mean over rows, and mid row."""
    rows = [
        float(x[np.nonzero(r > threshold)[0][-1]]) if (r > threshold).any() else float("nan")
        for r in h
    ]
    return float(np.mean(rows)), rows[len(rows) // 2]


def count_steps(fort_amr: Path) -> int:
    """Count the level-1 time steps taken (one ``AMRCLAW: level 1`` line each)."""
    return len(re.findall(r"AMRCLAW: level\s+1\s+CFL", fort_amr.read_text()))


def parse_args() -> argparse.Namespace:
    """Command line."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nx", type=int, default=330)
    ap.add_argument("--ny", type=int, default=33, help="cells across the 20 m width")
    ap.add_argument(
        "--xmax",
        type=float,
        default=300.0,
        help="domain length [m] (450 keeps the 11 s front inside)",
    )
    ap.add_argument("--out", type=Path, default=Path("/tmp/geoclaw_dam_break"))
    ap.add_argument("--tfinal", type=float, default=11.0)
    ap.add_argument("--cfl", type=float, default=0.9)
    ap.add_argument("--threshold", type=float, default=1e-3, help="front depth threshold [m]")
    ap.add_argument("--fflags", default="-O2", help="gfortran flags for xgeoclaw")
    ap.add_argument("--build-only", action="store_true", help="only compile (cache) xgeoclaw")
    return ap.parse_args()


def main() -> None:
    """Build, write the data, run xgeoclaw, measure, write summary.json."""
    args = parse_args()
    exe, make_cmd = build(args.fflags)
    if args.build_only:
        print(f"xgeoclaw OK: {exe}")
        return
    out = args.out.resolve()
    if out == REPO_ROOT or REPO_ROOT in out.parents:
        sys.exit(f"refusing: --out {out} must be outside the repository {REPO_ROOT}")
    dx = args.xmax / args.nx
    if abs(X_DAM / dx - round(X_DAM / dx)) > 1e-9:
        print(f"warning: dam x = {X_DAM} is not on a cell edge (dx = {dx:.6g})", file=sys.stderr)
    run = out / "_output"
    shutil.rmtree(run, ignore_errors=True)
    run.mkdir(parents=True)
    os.chdir(out)  # clawpack writes pyclaw.log into the current folder when imported
    times = sorted({5.5, float(args.tfinal)} if args.tfinal > 5.5 else {float(args.tfinal)})
    write_data(run, args.nx, args.ny, args.xmax, args.tfinal, args.cfl, times)

    env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
    t0 = time.perf_counter()
    res = subprocess.run([str(exe)], cwd=run, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    (run / "xgeoclaw.log").write_text(res.stdout + res.stderr)
    if res.returncode != 0:
        sys.exit(f"xgeoclaw failed ({res.returncode}), see {run / 'xgeoclaw.log'}")
    steps = count_steps(run / "fort.amr")

    fronts: dict[float, tuple[float, float, float]] = {}
    for frame, t_req in enumerate(times, start=1):
        t, x, h = read_depth(run, frame)
        if abs(t - t_req) > 1e-6:
            raise RuntimeError(f"frame {frame} is at t = {t}, expected {t_req}")
        mean_f, mid_f = front(x, h, args.threshold)
        fronts[t_req] = (mean_f, mid_f, exact_front(t_req))

    def pick(t: float, i: int) -> float | None:
        return fronts[t][i] if t in fronts else None

    f55, f11 = pick(5.5, 0), pick(float(args.tfinal), 0)
    e55, e11 = exact_front(5.5), exact_front(float(args.tfinal))
    summary = {
        "nx": args.nx,
        "ny": args.ny,
        "dx": dx,
        "dy": Y_EXTENT / args.ny,
        "xmax": args.xmax,
        "tfinal": args.tfinal,
        "cfl": args.cfl,
        "threshold": args.threshold,
        "steps": steps,
        "wall_time": wall,
        "us_per_cell_step": wall / (args.nx * args.ny * steps) * 1e6,
        "front_5_5": f55,
        "front_11": f11,
        "front_5_5_mid_y": pick(5.5, 1),
        "front_11_mid_y": pick(float(args.tfinal), 1),
        "exact_5_5": e55,
        "exact_11": e11,
        "rel_5_5": abs(f55 / e55 - 1.0) if f55 is not None else None,
        "rel_11": abs(f11 / e11 - 1.0) if f11 is not None else None,
        "front_11_outside_domain": e11 > args.xmax,
        "clawpack_version": clawpack_version(),
        "omp_num_threads": env["OMP_NUM_THREADS"],
        "fflags": args.fflags,
        "settings": {
            "order": 2,
            "transverse_waves": 2,
            "limiter": "mc",
            "fwaves": True,
            "bc_x": "extrap",
            "bc_y": "wall",
            "amr_levels_max": 1,
            "dry_tolerance": 1e-6,
            "friction": None,
            "coriolis": False,
            "front": "largest cell-centre x with h > threshold, mean over y rows",
        },
        "commands": {
            "run": " ".join([sys.executable, *sys.argv]),
            "build": make_cmd,
            "xgeoclaw": f"cd {run} && OMP_NUM_THREADS={env['OMP_NUM_THREADS']} {exe}",
        },
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(
        json.dumps(
            {
                k: summary[k]
                for k in (
                    "nx",
                    "ny",
                    "dx",
                    "steps",
                    "wall_time",
                    "us_per_cell_step",
                    "front_5_5",
                    "front_11",
                    "rel_5_5",
                    "rel_11",
                    "exact_5_5",
                    "exact_11",
                    "clawpack_version",
                )
            },
            indent=2,
        )
    )
    if summary["front_11_outside_domain"]:
        print(
            f"note: the exact front at t = {args.tfinal} s ({e11:.1f} m) lies beyond xmax = "
            f"{args.xmax} m; use --xmax 450 for a meaningful 11 s error",
            file=sys.stderr,
        )
    print(f"summary: {out / 'summary.json'}")


if __name__ == "__main__":
    main()
