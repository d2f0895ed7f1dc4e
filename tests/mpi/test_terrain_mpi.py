"""Real terrain under MPI: hazard rasters and the summary do not depend on the rank count."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
import shapely
from mpi4py import MPI

from fem_runout.api import run
from fem_runout.config import load_case
from fem_runout.output.hazard import MAP_NAMES
from tests.terrain_helpers import dem_case, plane, write_dem, write_polygons


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    comm = MPI.COMM_WORLD
    tmp = tmp_path_factory.mktemp("mpi") if comm.rank == 0 else None
    tmp = Path(comm.bcast(str(tmp) if tmp else None, root=0))
    if comm.rank == 0:
        write_dem(tmp / "dem.tif", plane(slope=0.6))
        write_polygons(tmp / "rel.geojson", [shapely.box(1010, 1950, 1030, 1975)])
    comm.barrier()
    return tmp


def test_two_ranks_equal_one(folder: Path) -> None:
    comm = MPI.COMM_WORLD
    results = {}
    for label, c in (("np", comm), ("self", MPI.COMM_SELF)):
        if c is MPI.COMM_SELF and comm.rank != 0:
            continue
        case = load_case(dem_case(
            folder / "dem.tif", output={"dir": str(folder / label), "pictures": False},
            material={"friction": {"law": "voellmy", "mu": 0.1, "xi": 1000}},
            time={"end": "auto", "max": 6.0}))
        results[label] = run(case, comm=c)
    s = results["np"].summary
    assert s["ranks"] == comm.size
    gone = s["outflow_volume"] + s["dried_volume"]
    assert abs(s["deposit_volume"] + gone - s["released_volume"]) <= 1e-10 * s["released_volume"]
    if comm.rank == 0:
        one = results["self"].summary
        for key in ("released_volume", "affected_area", "runout_length", "peak_depth_max"):
            assert s[key] == pytest.approx(one[key], rel=1e-9, abs=1e-12), key
        for name in MAP_NAMES:
            with rasterio.open(folder / "np" / f"{name}.tif") as a, \
                    rasterio.open(folder / "self" / f"{name}.tif") as b:
                np.testing.assert_allclose(a.read(1), b.read(1), rtol=1e-8, atol=1e-10)
