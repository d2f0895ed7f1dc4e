"""The padded DEM of ``python -m fem_runout.bench footprint`` (issue 16)."""

import numpy as np

from fem_runout.bench.footprint import pad_ascii_grid


def test_padded_dem_holds_the_original_at_its_place(tmp_path):
    rows, cols, size = 6, 8, 5.0
    data = np.arange(rows * cols, dtype=float).reshape(rows, cols)
    src = tmp_path / "dem.asc"
    head = f"ncols {cols}\nnrows {rows}\nxllcorner 1000.0\nyllcorner 2000.0\n" \
           f"cellsize {size}\nNODATA_value -9999\n"
    src.write_text(head + "\n".join(" ".join(f"{v:.1f}" for v in r) for r in data) + "\n")
    dst = tmp_path / "pad.asc"
    assert pad_ascii_grid(src, dst, 2.0) == (16, 12)  # 4x the area
    lines = dst.read_text().splitlines()
    meta = dict(line.split()[:2] for line in lines[:6])
    assert float(meta["xllcorner"]) == 1000.0 - 4 * size
    assert float(meta["yllcorner"]) == 2000.0 - 3 * size
    padded = np.loadtxt(lines[6:])
    assert np.array_equal(padded[3:9, 4:12], data)  # the original block, same coordinates
    assert np.array_equal(padded[2], padded[3]) and np.array_equal(padded[:, 3], padded[:, 4])
