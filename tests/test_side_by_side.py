"""The peers' side-by-side report: medians, ratios of medians, and a clear error without peers."""

import json

import pytest

from fem_runout.bench import side_by_side
from fem_runout.bench.__main__ import build_parser
from fem_runout.bench.peers_doc import avakot_table, dam_table, median_row, write_doc


def _dam(wall, steps, front=350.0):
    return {"wall": wall, "steps": steps, "work": 100 * steps, "front": front, "error": 0.1}


def _ava(wall, cell, particles=None):
    return {"wall": wall, "steps": 1000, "work": (particles or 5000) * 1000, "cell": cell,
            "particles": particles, "released_volume": 2.0e4, "runout_0.01": 1600.0,
            "area_0.01": 2.0e5, "area_0.1": 1.5e5, "peak_depth": 4.0, "peak_speed": 50.0}


def test_median_over_rounds_and_range():
    row = median_row([_dam(3.0, 100), _dam(1.0, 100), _dam(2.0, 102)])
    assert (row["wall"], row["wall_min"], row["wall_max"], row["rounds"]) == (2.0, 1.0, 3.0, 3)
    assert row["steps"] == 100.0


def test_dam_table_ratios_against_geoclaw():
    rows = {"GeoClaw": median_row([_dam(2.0, 100)]), "TG2-PC": median_row([_dam(6.0, 250)])}
    lines = dam_table(rows, (10, 10))
    ours = lines[-1].split("|")[1:-1]
    # µs per cell-step = 6 s / (100 cells x 250 steps); wall 3x, steps 2.5x, per step 1.2x
    assert ours[3].strip() == "240.00"
    assert [c.strip() for c in ours[-3:]] == ["3.00", "2.50", "1.20"]


def test_avakot_ratio_only_against_the_same_cell_size():
    rows = {"com1DFA 10 m": median_row([_ava(4.0, 10.0, 800)]),
            "com1DFA 5 m": median_row([_ava(16.0, 5.0, 3000)]),
            "DAMPM": median_row([_ava(18.0, 10.0, 70000)])}
    last = avakot_table(rows)[-1].split("|")[1:-1]
    assert last[-2].strip() == "4.50"  # 18 / 4, not 18 / 16
    assert last[-1].strip() == "1.12"  # and against com1DFA's default 5 m: 18 / 16
    assert last[6].strip() == f"{1e6 * 18.0 / (70000 * 1000):.2f}"


def test_doc_and_raw_runs_written(tmp_path):
    runs = {"dam:GeoClaw": [_dam(2.0, 100)], "dam:TG2-PC": [_dam(6.0, 250), _dam(7.0, 250)]}
    out = tmp_path / "peers.md"
    write_doc(out, runs, {"grid": (10, 10)})
    text = out.read_text()
    assert "## Inclined dam break against GeoClaw (10 × 10 cells)" in text
    assert "| TG2-PC | 250 | 6.50 (6.00–7.00) |" in text
    assert json.loads(out.with_suffix(".json").read_text()) == runs


def test_missing_peer_is_a_clear_error(tmp_path, capsys):
    args = build_parser().parse_args(["side-by-side", "--geoclaw-venv", str(tmp_path / "no"),
                                      "--work", str(tmp_path / "work")])
    assert side_by_side.main(args) == 2
    err = capsys.readouterr().err
    assert "geoclaw: no virtualenv at" in err and "peers/geoclaw/setup.sh" in err
    assert not (tmp_path / "work").exists()


@pytest.mark.parametrize("skip", ["dam", "avakot"])
def test_skipped_scene_needs_no_peer(tmp_path, skip):
    args = build_parser().parse_args(["side-by-side", "--skip", skip, "--geoclaw-venv",
                                      str(tmp_path / "g"), "--avaframe-venv", str(tmp_path / "a")])
    with pytest.raises(FileNotFoundError, match="avaframe" if skip == "dam" else "geoclaw"):
        side_by_side.peer_pythons(args)


def test_ladder_grids_keep_the_aspect_and_order():
    from fem_runout.bench.peers_ladder import ladder_grids

    assert ladder_grids((495, 33), (2.0, 0.25, 1.0, 0.5)) == [(124, 8), (248, 16), (495, 33),
                                                               (990, 66)]


def test_wall_at_error_interpolates_and_only_bounds_outside():
    from fem_runout.bench.peers_ladder import wall_at_error

    # wall = 10 e^-3 on a ladder e = 0.4, 0.2, 0.1: exact inside (a power law)
    errors = [0.4, 0.2, 0.1]
    walls = [10.0 * e**-3 for e in errors]
    inside, bound = wall_at_error(errors, walls, 0.15)
    assert bound == "" and inside == pytest.approx(10.0 * 0.15**-3, rel=1e-12)
    # a level read at its own error gives its own wall
    assert wall_at_error(errors, walls, 0.2)[0] == pytest.approx(walls[1], rel=1e-12)
    # beyond the ladder: the finest (or cheapest) level's wall as a bound, no extrapolation
    assert wall_at_error(errors, walls, 0.05) == (pytest.approx(walls[2], rel=1e-12), ">")
    assert wall_at_error(errors, walls, 0.8) == (pytest.approx(walls[0], rel=1e-12), "<")


def test_ladder_section_in_the_doc(tmp_path):
    def level(wall, error, nx):
        return [{"wall": wall, "steps": 10 * nx, "error": error, "nx": nx, "ny": nx // 10,
                 "work": 1, "front": 1.0}]

    runs = {"dam:GeoClaw": level(2.0, 0.16, 100), "dam:TG2-PC": level(4.0, 0.05, 100),
            "ladder:GeoClaw 50x5": level(0.25, 0.32, 50),
            "ladder:GeoClaw 100x10": level(2.0, 0.16, 100),
            "ladder:GeoClaw 200x20": level(16.0, 0.08, 200),
            "ladder:TG2-PC 50x5": level(0.5, 0.1, 50),
            "ladder:TG2-PC 100x10": level(4.0, 0.05, 100)}
    out = tmp_path / "peers.md"
    write_doc(out, runs, {"grid": (100, 10), "ladder": (0.5, 1.0, 2.0)})
    text = out.read_text()
    assert "### Cost at equal accuracy" in text
    # GeoClaw's wall is 2 (0.16/e)^3: at TG2-PC's 0.1 (inside its ladder) 8.19 s
    assert "| TG2-PC 50 × 5 | 0.1000 | 0.50 | 8.19 | 0.061 |" in text
    # 0.05 is beyond GeoClaw's finest level (0.08, 16 s): at least 16 s, ratio at most 0.25
    assert "| TG2-PC 100 × 10 | 0.0500 | 4.00 | > 16.00 | < 0.250 |" in text
    # GeoClaw's 0.32 is above TG2-PC's coarsest error: TG2-PC needs less than 0.5 s there
    assert "| GeoClaw 50 × 5 | 0.3200 | < 0.50 | 0.25 | < 2.000 |" in text
