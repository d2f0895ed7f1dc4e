"""Write the example mesh inputs of meshes/ (deterministic: rerunning gives the same files).

    .venv/bin/python meshes/generate.py            # writes the three files below
    .venv/bin/python meshes/generate.py --derive   # prints the avaKot coordinates from the DEM
    .venv/bin/python meshes/generate.py --figures  # docs/figures/mesh_*.png (needs the data)

- ``curved_channel.msh``: a 20 m wide channel with a 90° bend (inner radius 30 m): a 50 m
  straight inlet leg along +x, the bend, a 50 m outlet leg along +y; 3260 structured
  quadrilaterals of about 1 m (gmsh transfinite). Physical groups: ``wall`` on both banks and
  at the inlet end, ``open`` at the outlet end, ``domain`` (2D). Used by
  cases/curved_channel.yaml.
- ``avakot_corridor.geojson``: a polygon (EPSG:31287) around the Kontertal avalanche path:
  the release area and the gully down to the valley floor, about 600 m wide, inside the part
  of the avaKot DEM that has data. Used by cases/avakot_corridor.yaml.
- ``avakot_thalweg.geojson``: the line along the gully's floor from the release down to the
  valley floor (EPSG:31287), the refine line of cases/avakot_corridor.yaml.

The avaKot coordinates are stored below (so this script needs no data); ``--derive`` recomputes
them from ``${FEM_RUNOUT_DATA}/avaKot``: the thalweg is the steepest descent (D8) from the
release polygon's centroid to the first pit, simplified (10 m), Chaikin-smoothed three times
and simplified again (3 m); the corridor is the thalweg buffered by 300 m joined with the
release buffered by 150 m, clipped to the DEM's data footprint shrunk by 40 m and simplified
(10 m). (The stored values came from that procedure; a rerun may differ by 0.1 m.)
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CRS = "EPSG:31287"  # MGI / Austria Lambert, the CRS of the avaKot data

THALWEG = [
    [177835.5, 376735.1], [177834.9, 376937.5], [177847.4, 376965.0], [177900.9, 377041.7],
    [177921.3, 377079.6], [177927.4, 377101.0], [177931.6, 377165.4], [177944.7, 377205.9],
    [177985.6, 377260.1], [178071.9, 377341.8], [178112.2, 377372.7], [178166.0, 377398.4],
    [178192.9, 377419.9], [178212.9, 377451.6], [178246.6, 377523.0], [178317.8, 377625.9],
    [178340.9, 377716.4], [178409.6, 377871.5], [178425.3, 377921.4], [178421.5, 377941.6],
    [178406.5, 377965.9], [178345.3, 378029.5],
]
CORRIDOR = [
    [177574.3, 377089.1], [177631.9, 377180.5], [177659.3, 377298.2], [177705.2, 377386.6],
    [177865.7, 377559.7], [177967.1, 377633.7], [178040.4, 377752.3], [178090.4, 377891.6],
    [178054.1, 377957.4], [178057.1, 378112.7], [178137.3, 378245.7], [178273.2, 378320.7],
    [178428.5, 378317.7], [178561.5, 378237.5], [178676.8, 378099.2], [178720.1, 377976.9],
    [178711.5, 377831.4], [178608.5, 377551.7], [178446.6, 377259.8], [178380.2, 377185.6],
    [178225.5, 377074.1], [178185.5, 376937.4], [178135.2, 376853.1], [178135.4, 376761.6],
    [177834.4, 376435.6], [177686.3, 376474.8], [177576.1, 376584.3], [177535.5, 376734.2],
    [177534.9, 376936.6], [177574.3, 377089.1],
]

# curved channel: width, inner radius (bend centre at the origin), leg length, cell size [m]
WIDTH, RADIUS, LEG, CELL = 20.0, 30.0, 50.0, 1.0


def write_geojson(path: Path, kind: str, coords: list[list[float]], name: str) -> None:
    """Write one feature (``Polygon`` or ``LineString``) with its CRS (GDAL reads ``crs``)."""
    geometry = {"type": kind, "coordinates": [coords] if kind == "Polygon" else coords}
    data = {
        "type": "FeatureCollection",
        "name": name,
        "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::31287"}},
        "features": [{"type": "Feature", "properties": {"name": name}, "geometry": geometry}],
    }
    path.write_text(json.dumps(data, indent=1) + "\n")


def curved_channel(path: Path) -> None:
    """Write the structured quadrilateral mesh of the channel with a 90° bend."""
    import gmsh

    outer = RADIUS + WIDTH
    across = round(WIDTH / CELL)
    along_bend = round(math.pi / 2 * (RADIUS + WIDTH / 2) / CELL)
    along_leg = round(LEG / CELL)
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.add("curved_channel")
        geo = gmsh.model.geo
        xy = {"c": (0, 0), "a": (-LEG, -outer), "b": (0, -outer), "d": (0, -RADIUS),
              "e": (-LEG, -RADIUS), "f": (outer, 0), "g": (RADIUS, 0), "h": (outer, LEG),
              "i": (RADIUS, LEG)}
        p = {k: geo.addPoint(x, y, 0) for k, (x, y) in xy.items()}
        line = {k: geo.addLine(p[k[0]], p[k[1]]) for k in ("ab", "bd", "de", "ea", "fg", "fh",
                                                          "hi", "ig")}
        line["bf"] = geo.addCircleArc(p["b"], p["c"], p["f"])
        line["gd"] = geo.addCircleArc(p["g"], p["c"], p["d"])
        loops = [("ab", "bd", "de", "ea"), ("bf", "fg", "gd", "bd"), ("fh", "hi", "ig", "fg")]
        signs = [(1, 1, 1, 1), (1, 1, 1, -1), (1, 1, 1, -1)]
        surfaces = [geo.addPlaneSurface([geo.addCurveLoop([s * line[k] for k, s in
                                                           zip(loop, sign, strict=True)])])
                    for loop, sign in zip(loops, signs, strict=True)]
        counts = {"bd": across, "ea": across, "fg": across, "hi": across, "ab": along_leg,
                  "de": along_leg, "fh": along_leg, "ig": along_leg, "bf": along_bend,
                  "gd": along_bend}
        for k, n in counts.items():
            geo.mesh.setTransfiniteCurve(line[k], n + 1)
        for s in surfaces:
            geo.mesh.setTransfiniteSurface(s)
            geo.mesh.setRecombine(2, s)
        geo.synchronize()
        walls = [line[k] for k in ("ab", "de", "ea", "bf", "gd", "fh", "ig")]
        gmsh.model.addPhysicalGroup(1, walls, 2, name="wall")
        gmsh.model.addPhysicalGroup(1, [line["hi"]], 1, name="open")
        gmsh.model.addPhysicalGroup(2, surfaces, 1, name="domain")
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def derive_avakot() -> None:
    """Print the thalweg and corridor coordinates computed from the avaKot DEM and release."""
    import rasterio
    import shapely
    from rasterio import features

    from fem_runout.terrain.paths import data_folder
    from fem_runout.terrain.release import read_polygons

    folder = data_folder() / "avaKot"
    with rasterio.open(folder / "avaKot.asc") as src:
        z, t = src.read(1, masked=True).filled(np.nan), src.transform
    release = read_polygons(folder / "REL" / "relKot.shp", "release").geoms[0]
    c = release.centroid
    i, j = int((c.y - t.f) / t.e), int((c.x - t.c) / t.a)
    zz, path = np.where(np.isnan(z), np.inf, z), [(i, j)]
    steps = [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj]
    while True:
        drop, di, dj = max(((zz[i, j] - zz[i + a, j + b]) / math.hypot(a, b), a, b)
                           for a, b in steps)
        if drop <= 0:
            break
        i, j = i + di, j + dj
        path.append((i, j))
    xy = np.array([(t.c + t.a * (b + 0.5), t.f + t.e * (a + 0.5)) for a, b in path])
    p = np.asarray(shapely.LineString(xy).simplify(10).coords)
    for _ in range(3):  # Chaikin corner cutting, end points kept
        q, r = 0.75 * p[:-1] + 0.25 * p[1:], 0.25 * p[:-1] + 0.75 * p[1:]
        p = np.vstack([p[:1], np.column_stack([q, r]).reshape(-1, 2), p[-1:]])
    thalweg = shapely.LineString(p).simplify(3)
    valid = np.isfinite(z).astype(np.uint8)
    foot = max((shapely.geometry.shape(g) for g, v in features.shapes(valid, transform=t)
                if v == 1), key=lambda g: g.area)
    corridor = shapely.union(thalweg.buffer(300, quad_segs=3), release.buffer(150, quad_segs=3))
    corridor = corridor.intersection(foot.buffer(-40)).simplify(10)
    print("THALWEG =", np.round(np.asarray(thalweg.coords), 1).tolist())
    print("CORRIDOR =", np.round(np.asarray(corridor.exterior.coords), 1).tolist())


def _grid(mesh: object) -> object:
    """Return a pyvista grid of the quadrilaterals, with the mean edge length per cell."""
    import pyvista as pv

    nodes, quads = mesh.nodes, mesh.quads
    cells = np.column_stack([np.full(len(quads), 4), quads]).ravel()
    grid = pv.UnstructuredGrid(cells, np.full(len(quads), pv.CellType.QUAD),
                               np.column_stack([nodes, np.zeros(len(nodes))]))
    p = nodes[quads]
    grid.cell_data["edge length [m]"] = np.linalg.norm(np.roll(p, -1, 1) - p, axis=2).mean(1)
    return grid


def _lines(points: np.ndarray, edges: np.ndarray | None = None) -> object:
    """Return a polyline through ``points``, or the segments ``edges`` between them."""
    import pyvista as pv

    if edges is None:
        edges = np.column_stack([np.arange(len(points) - 1), np.arange(1, len(points))])
    xyz = np.column_stack([points[:, :2], np.full(len(points), 0.5)])
    return pv.PolyData(xyz, lines=np.column_stack([np.full(len(edges), 2), edges]).ravel())


def _picture(mesh: object, path: Path, title: str, extra: list[tuple[object, str]],
             zoom: tuple[float, float, float, float] | None) -> None:
    """Draw the mesh seen from above: cells coloured by size, ``open`` blue, ``wall`` red."""
    import pyvista as pv

    pv.OFF_SCREEN = True
    views = [None] if zoom is None else [None, zoom]
    plotter = pv.Plotter(off_screen=True, shape=(1, len(views)),
                         window_size=(900 * len(views), 1000), border=False)
    for k, box in enumerate(views):
        plotter.subplot(0, k)
        plotter.add_mesh(_grid(mesh), show_edges=zoom is None or box is not None,
                         edge_color="black", line_width=0.5, cmap="viridis",
                         scalar_bar_args={"title": "edge length [m]"})
        for group, color in (("open", "royalblue"), ("wall", "red")):
            if len(mesh.groups[group]):
                plotter.add_mesh(_lines(mesh.nodes, mesh.groups[group]), color=color,
                                 line_width=4)
        for shape, color in extra:
            plotter.add_mesh(shape, color=color, line_width=3)
        plotter.view_xy()
        if box is not None:
            x0, x1, y0, y1 = box
            plotter.camera.focal_point = ((x0 + x1) / 2, (y0 + y1) / 2, 0)
            plotter.camera.position = ((x0 + x1) / 2, (y0 + y1) / 2, 1)
            plotter.camera.parallel_projection = True
            plotter.camera.parallel_scale = (y1 - y0) / 2
        plotter.add_text(title if box is None else "zoom on the release area", font_size=11)
    plotter.screenshot(str(path))
    plotter.close()


def figures() -> None:
    """Draw docs/figures/mesh_curved_channel.png and mesh_avakot_corridor.png; print quality."""
    import shapely

    from fem_runout.config import load_case
    from fem_runout.meshing import case_mesh, gmsh_session, mesh_quality
    from fem_runout.terrain.release import read_polygons

    out = HERE.parent / "docs" / "figures"
    for name in ("curved_channel", "avakot_corridor"):
        case = load_case(HERE.parent / "cases" / f"{name}.yaml")
        with gmsh_session():
            mesh = case_mesh(case)
        extra, zoom = [], None
        if name == "avakot_corridor":
            release = read_polygons(case.resolve_input(case.initial.release[0].polygon), "r")
            ring = np.asarray(shapely.get_exterior_ring(release.geoms[0]).coords)
            extra = [(_lines(np.asarray(THALWEG)), "orange"), (_lines(ring), "white")]
            zoom = (177700.0, 178000.0, 376550.0, 376950.0)
        q = mesh_quality(mesh.nodes, mesh.quads)
        title = (f"{name}: {q['cells']} cells, {q['nodes']} nodes\nedges {q['min_edge']:.2f}"
                 f"-{q['max_edge']:.2f} m (mean {q['mean_edge']:.2f} m)\nangles "
                 f"{q['min_angle']:.0f}-{q['max_angle']:.0f} deg, min scaled Jacobian "
                 f"{q['min_scaled_jacobian']:.2f}")
        _picture(mesh, out / f"mesh_{name}.png", title, extra, zoom)
        print(name, {k: round(v, 3) if isinstance(v, float) else v for k, v in q.items()},
              {g: len(e) for g, e in mesh.groups.items()})


def main() -> None:
    """Write the example inputs (or, with --derive, print the avaKot coordinates)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--derive", action="store_true",
                        help="print the avaKot coordinates computed from the DEM")
    parser.add_argument("--figures", action="store_true",
                        help="draw docs/figures/mesh_*.png (needs the avaKot data)")
    args = parser.parse_args()
    if args.derive or args.figures:
        derive_avakot() if args.derive else figures()
        return
    curved_channel(HERE / "curved_channel.msh")
    write_geojson(HERE / "avakot_corridor.geojson", "Polygon", CORRIDOR, "avakot_corridor")
    write_geojson(HERE / "avakot_thalweg.geojson", "LineString", THALWEG, "avakot_thalweg")
    for name in ("curved_channel.msh", "avakot_corridor.geojson", "avakot_thalweg.geojson"):
        print(f"wrote meshes/{name}")


if __name__ == "__main__":
    main()
