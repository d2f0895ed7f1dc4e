#!/usr/bin/env python
"""Run the peer model AvaFrame com1DFA on the avaKot avalanche path.

Must be run with the peers venv's python (see peers/com1dfa/setup.sh), never
with the project's .venv:

    $PEERS_VENV/bin/python peers/com1dfa/run_avakot.py --out /tmp/com1dfa_avakot/out

Inputs are read from $FEM_RUNOUT_DATA/avaKot (default: <repo>/../shared/data)
and copied into an AvaFrame avalanche directory under --work (outside the
repo).  Results (pft/pfv/ppr/release-thickness rasters, summary.json) go to
--out.
"""

import argparse
import configparser
import json
import os
import pathlib
import re
import shutil
import sys
import time

T_START = time.time()  # wall time of the whole command (incl. imports)

import numpy as np  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]
DEFAULT_DATA = pathlib.Path(os.environ.get("FEM_RUNOUT_DATA", REPO.parent / "shared" / "data"))
EPSG = 31287  # MGI / Austria Lambert (avaKot.asc has no .prj; relKot.prj is MGI_Austria_Lambert)

# Every com1DFA setting changed with respect to avaframe/com1DFA/com1DFACfg.ini.
# (rho=200, muvoellmy=0.155, xsivoellmy=4000, stopCritType=kinEnergy are the
# defaults already, but are written explicitly so the run does not depend on them.)
OVERRIDES = {
    "GENERAL": {
        "simTypeList": "null",  # default: available
        "frictModel": "Voellmy",  # default: samosATAuto
        "muvoellmy": "0.155",  # default: 0.155
        "xsivoellmy": "4000.",  # default: 4000.
        "rho": "200",  # default: 200
        "meshCellSize": "10",  # default: 5
        "stopCritType": "kinEnergy",  # default: kinEnergy
        "stopCrit": "0.0001",  # default: 0.01
    },
    "EXPORTS": {
        "exportRasters": "True",  # default: False (output only: writes release raster)
    },
}


def parse_args():
    """Parse the command line; ``--set`` items go into OVERRIDES."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--out", default="/tmp/com1dfa_avakot/out", help="output folder")
    p.add_argument(
        "--work",
        default="/tmp/com1dfa_avakot",
        help="work folder (AvaFrame avalanche dir is created in it)",
    )
    p.add_argument(
        "--data",
        default=str(DEFAULT_DATA),
        help="data folder containing avaKot/ (env FEM_RUNOUT_DATA)",
    )
    p.add_argument(
        "--no-report",
        action="store_true",
        help="skip AvaFrame's plots/report (FLAGS savePlot/createReport)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SECTION.key=value",
        help="extra com1DFA setting for a sensitivity run, e.g. GENERAL.viscOption=0",
    )
    args = p.parse_args()
    for item in args.set:
        key, value = item.split("=", 1)
        section, name = key.split(".", 1)
        OVERRIDES.setdefault(section, {})[name] = value
    return args


def check_outside_repo(path, what):
    """Return ``path`` resolved; exit if it lies inside this repository."""
    path = pathlib.Path(path).resolve()
    if path == REPO or REPO in path.parents:
        sys.exit(f"{what} ({path}) must be outside the repository {REPO}")
    return path


def prepare_ava_dir(data, work):
    """Copy the avaKot DEM and release into a fresh AvaFrame avalanche folder."""
    src = data / "avaKot"
    dem = src / "avaKot.asc"
    rel = sorted((src / "REL").glob("relKot.*"))
    if not dem.is_file() or not any(r.suffix == ".shp" for r in rel):
        sys.exit(f"avaKot input data not found under {src}")
    ava = work / "avaKot"
    if ava.exists():
        shutil.rmtree(ava)  # AvaFrame refuses to run if Work/ exists; start clean every time
    (ava / "Inputs" / "REL").mkdir(parents=True)
    shutil.copyfile(dem, ava / "Inputs" / dem.name)
    for r in rel:
        shutil.copyfile(r, ava / "Inputs" / "REL" / r.name)
    return ava


def write_override(work):
    """Write the com1DFA override ini of OVERRIDES; return its path."""
    cfg = configparser.ConfigParser()
    cfg.optionxform = str
    for sec, kv in OVERRIDES.items():
        cfg[sec] = kv
    path = work / "com1DFA_override.ini"
    with open(path, "w") as f:
        cfg.write(f)
    return path


def read_raster(path):
    """Return a raster's first band (nodata as NaN), transform and profile."""
    import rasterio

    with rasterio.open(path) as src:
        a = src.read(1).astype(float)
        nod = src.nodata
        if nod is not None:
            a[a == nod] = np.nan
        return a, src.transform, src.profile


def write_tif(path, arr, transform):
    """Write ``arr`` as a GeoTIFF (NaN as nodata -9999)."""
    import rasterio

    prof = dict(
        driver="GTiff",
        height=arr.shape[0],
        width=arr.shape[1],
        count=1,
        dtype="float64",
        crs=f"EPSG:{EPSG}",
        transform=transform,
        nodata=-9999.0,
        compress="lzw",
    )
    a = np.where(np.isnan(arr), -9999.0, arr)
    with rasterio.open(path, "w", **prof) as dst:
        dst.write(a, 1)


def cell_centres(transform, shape):
    """Return the x and y of the cell centres of a raster grid."""
    rows, cols = np.indices(shape)
    x = transform.c + (cols + 0.5) * transform.a + (rows + 0.5) * transform.b
    y = transform.f + (cols + 0.5) * transform.d + (rows + 0.5) * transform.e
    return x, y


def main():
    """Run com1DFA on avaKot and write its rasters and metrics to ``--out``."""
    args = parse_args()
    data = pathlib.Path(args.data).resolve()
    work = check_outside_repo(args.work, "--work")
    out = check_outside_repo(args.out, "--out")
    work.mkdir(parents=True, exist_ok=True)
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)

    import importlib.metadata as md

    from avaframe.com1DFA import com1DFA
    from avaframe.in3Utils import cfgUtils, logUtils

    version = md.version("avaframe")
    ava = prepare_ava_dir(data, work)
    override = write_override(work)

    cfgMain = cfgUtils.getGeneralConfig()
    cfgMain["MAIN"]["avalancheDir"] = str(ava)
    main_changed = {"MAIN.avalancheDir": str(ava)}
    if args.no_report:
        cfgMain["FLAGS"]["savePlot"] = "False"
        cfgMain["FLAGS"]["createReport"] = "False"
        main_changed.update({"FLAGS.savePlot": "False", "FLAGS.createReport": "False"})

    logUtils.initiateLogger(str(ava), "runCom1DFA_avaKot")
    cfgCom = cfgUtils.getModuleConfig(com1DFA, str(ava), fileOverride=str(override), toPrint=False)

    t0 = time.time()
    dem, plotDict, reportDictList, simDF = com1DFA.com1DFAMain(cfgMain, cfgInfo=cfgCom)
    t_main = time.time() - t0
    if not reportDictList:
        sys.exit("com1DFA performed no simulation")

    simDF = simDF.iloc[[0]]
    sim = simDF["simName"].iloc[0]
    rep = reportDictList[0]
    rho = float(cfgCom["GENERAL"]["rho"])

    # --- mass balance file: time, current mass, ...
    mb = np.loadtxt(
        ava / "Outputs" / "com1DFA" / (f"mass_{sim}.txt"), delimiter=",", skiprows=1, ndmin=2
    )
    t_end = float(mb[-1, 0])
    m_ini, m_fin = float(mb[0, 1]), float(mb[-1, 1])

    # --- final particle count from the log
    n_part_final = None
    for lf in sorted(ava.glob("runCom1DFA_avaKot_*.log")):
        for m in re.finditer(r"MTot = ([0-9.eE+-]+) kg, (\d+) particles", lf.read_text()):
            n_part_final = int(m.group(2))

    # --- rasters
    peak = ava / "Outputs" / "com1DFA" / "peakFiles"
    rasters = {}
    arrays = {}
    transform = None
    for rt in ("pft", "pfv", "ppr"):
        f = sorted(peak.glob(f"{sim}*_{rt}.*"))
        if not f:
            continue
        a, tr, _ = read_raster(f[0])
        transform = tr if transform is None else transform
        dst = out / (f"{rt}.tif")
        write_tif(dst, a, tr)
        shutil.copy2(f[0], out / (f"{rt}_native{f[0].suffix}"))
        rasters[rt] = str(dst)
        arrays[rt] = a
    relf = sorted((ava / "Outputs" / "internalRasters").glob("releaseRaster.*"))
    if relf:
        a, tr, _ = read_raster(relf[0])
        write_tif(out / "relth.tif", a, tr)
        rasters["relth"] = str(out / "relth.tif")
        arrays["relth"] = a
    # computational DEM (remeshed by com1DFA to meshCellSize) for the run-out origin
    remeshed = sorted((ava / "Inputs" / "remeshedRasters").glob("*remeshedDEM*"))
    dem_file = remeshed[0] if remeshed else ava / "Inputs" / "avaKot.asc"
    demA, demTr, _ = read_raster(dem_file)
    if demA.shape == arrays["pft"].shape:
        write_tif(out / "dem.tif", demA, demTr)
        rasters["dem"] = str(out / "dem.tif")

    # --- derived metrics from pft/pfv
    pft = np.nan_to_num(arrays["pft"])
    csz = abs(transform.a)
    cell_area = abs(transform.a * transform.e)
    x, y = cell_centres(transform, pft.shape)
    metrics = {
        "cell_area_m2": cell_area,
        "area_pft_ge_0.1m_ha": float(np.count_nonzero(pft >= 0.1) * cell_area / 1e4),
        "area_pft_ge_0.01m_ha": float(np.count_nonzero(pft >= 0.01) * cell_area / 1e4),
        "max_pft_m": float(pft.max()),
        "max_pfv_ms": float(np.nanmax(arrays["pfv"])),
    }
    if "ppr" in arrays:
        metrics["max_ppr_kPa"] = float(np.nanmax(arrays["ppr"]))
    if demA.shape == pft.shape:
        if "relth" in arrays:
            relmask = np.nan_to_num(arrays["relth"]) > 0
            src = f"max DEM ({dem_file.name}) where release thickness raster > 0"
            metrics["release_raster_cells"] = int(relmask.sum())
            metrics["release_raster_sum_th_x_cellarea_m3"] = float(
                np.nansum(arrays["relth"]) * cell_area
            )
        else:  # fallback: cell centres inside the release polygon
            import shapefile
            from shapely.geometry import Point, shape

            poly = [
                shape(s.__geo_interface__)
                for s in shapefile.Reader(str(ava / "Inputs" / "REL" / "relKot.shp")).shapes()
            ]
            relmask = np.array(
                [
                    [
                        any(pg.contains(Point(xx, yy)) for pg in poly)
                        for xx, yy in zip(xr, yr, strict=False)
                    ]
                    for xr, yr in zip(x, y, strict=False)
                ]
            )
            src = f"max DEM ({dem_file.name}) of cell centres inside relKot.shp"
        z = np.where(relmask, demA, -np.inf)
        i, j = np.unravel_index(np.argmax(z), z.shape)
        metrics["release_top_cell"] = {
            "x": float(x[i, j]),
            "y": float(y[i, j]),
            "z": float(demA[i, j]),
            "source": src,
        }
        for thr in (0.01, 0.1):
            mask = pft > thr
            d = np.hypot(x - x[i, j], y - y[i, j])
            k = np.argmax(np.where(mask, d, -1.0))
            metrics[f"runout_m_pft_gt_{thr:g}"] = float(d.flat[k])
            metrics[f"runout_point_pft_gt_{thr:g}"] = {
                "x": float(x.flat[k]),
                "y": float(y.flat[k]),
                "z": float(demA.flat[k]),
            }

    def col(name):
        return float(simDF[name].iloc[0]) if name in simDF.columns else None

    rel_info = rep.get("Release Area", {})
    summary = {
        "model": "AvaFrame com1DFA",
        "avaframe_version": version,
        "python": sys.version.split()[0],
        "simulation": sim,
        "avalanche_dir": str(ava),
        "data_dir": str(data),
        "settings_changed": {"com1DFA": OVERRIDES, "avaframeCfg": main_changed},
        "settings_used_GENERAL": {
            k: cfgCom["GENERAL"][k]
            for k in (
                "simTypeList",
                "frictModel",
                "muvoellmy",
                "xsivoellmy",
                "rho",
                "meshCellSize",
                "stopCritType",
                "stopCrit",
                "relThFromFile",
                "dt",
                "tEnd",
                "sphKernelRadius",
                "massPerParticleDeterminationMethod",
                "deltaTh",
                "hmin",
                "curvAccInFriction",
                "explicitFriction",
                "seed",
                "initPartDistType",
            )
        },
        "release_thickness_note": (
            "thickness attribute of relKot.shp (1.0 m), interpreted by com1DFA as slope-normal"
        ),
        "release_area_info": rel_info,
        "released_volume_m3": float(rel_info["Model release volume [m3]"])
        if "Model release volume [m3]" in rel_info
        else m_ini / rho,
        "initial_mass_kg": m_ini,
        "final_mass_kg": m_fin,
        "final_volume_m3": m_fin / rho,
        "n_particles_initial": int(float(simDF["nPart"].iloc[0]))
        if "nPart" in simDF.columns
        else None,
        "n_particles_final": n_part_final,
        "simulation_end_time_s": t_end,
        "stop_info": {
            k: v
            for k, v in rep.get("Simulation Parameters", {}).items()
            if k in ("Stop criterion", "Process run time [s]", "Computation time [s]")
        },
        "n_iterations": col("nIter"),
        "wall_time_time_loop_s": col("timeLoop"),
        "wall_time_com1DFAMain_s": t_main,
        "rasters": rasters,
        "grid": {
            "cellsize": csz,
            "ncols": int(pft.shape[1]),
            "nrows": int(pft.shape[0]),
            "xll_corner": float(transform.c),
            "yll_corner": float(transform.f + pft.shape[0] * transform.e),
            "crs": f"EPSG:{EPSG}",
        },
        "metrics": metrics,
    }
    for f in list(ava.glob("runCom1DFA_avaKot_*.log")) + [
        ava / "Outputs" / "com1DFA" / (f"mass_{sim}.txt")
    ]:
        shutil.copyfile(f, out / f.name)
    shutil.copyfile(override, out / override.name)
    summary["wall_time_total_s"] = time.time() - T_START
    with open(out / "summary.json", "w") as f:
        json.dump(summary, f, indent=2)
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
