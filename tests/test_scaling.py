"""``python -m fem_runout.bench scaling``: ABBA rounds, medians, the results' agreement."""

import argparse

import pytest

from fem_runout.bench import scaling


def _summary(wall: float, runout: float = 1500.0, area: float = 2e5, steps: int = 900) -> dict:
    return {"wall_time": wall, "runout_length": runout, "affected_area": area, "steps": steps}


def test_rounds_alternate_which_rank_count_runs_first():
    assert scaling.abba_order(4, 2) == [(1, 2), (2, 1), (1, 2), (2, 1)]
    assert scaling.abba_order(1, 3) == [(1, 3)]


def test_the_speed_up_is_the_ratio_of_the_medians():
    walls = [(14.0, 9.0), (15.0, 9.5), (13.0, 10.0), (20.0, 8.0)]
    runs = [{1: _summary(a), 2: _summary(b)} for a, b in walls]
    s = scaling.summarize(runs)
    assert s["medians"] == {1: 14.5, 2: 9.25}
    assert s["ratio"] == pytest.approx(14.5 / 9.25, rel=1e-15)
    assert s["round_ratios"] == pytest.approx([a / b for a, b in walls], rel=1e-15)
    assert s["same"] and s["result"]["steps"] == 900
    table = scaling.format_table({"mpm": s}, 2)
    assert "**1.57×**" in table and "| yes |" in table
    assert "1.30–2.50 (1.57)" in table  # the range and median of the paired ratios
    assert "| – |" in table  # summaries without an end time


def test_the_table_says_how_the_runs_ended():
    rest = _summary(14.0) | {"t_end": 232.238, "at_rest": True}
    capped = _summary(9.0) | {"t_end": 600.0, "at_rest": False}
    s = scaling.summarize([{1: rest, 2: rest}])
    assert "| 232.2 (at rest) |" in scaling.format_table({"mpm": s}, 2)
    s = scaling.summarize([{1: capped, 2: capped}])
    assert "| 600.0 (end or max) |" in scaling.format_table({"tg2": s}, 2)


def test_side_by_side_copies_give_the_machines_ceiling():
    walls = [(14.0, 9.0), (15.0, 9.5), (13.0, 10.0)]
    side = [(16.0, 17.0), (16.5, 16.5), (20.0, 18.0)]  # two 1-rank copies run at once
    runs = [{1: _summary(a), 2: _summary(b), "side": [_summary(c), _summary(d)]}
            for (a, b), (c, d) in zip(walls, side, strict=True)]
    s = scaling.summarize(runs)
    assert s["side"] == pytest.approx([16.5, 16.5, 19.0], rel=1e-15)
    assert s["ceiling"] == pytest.approx(2 * 14.0 / 16.5, rel=1e-15)
    # an even split waits for the slower core: the rounds' slowest copies 17, 16.5, 20
    assert s["side_slowest"] == [17.0, 16.5, 20.0]
    assert s["even_ceiling"] == pytest.approx(2 * 14.0 / 17.0, rel=1e-15)
    assert s["ratio"] == pytest.approx(14.0 / 9.5, rel=1e-15) and s["same"]
    table = scaling.format_table({"tg2": s}, 2)
    assert "| 2 × 1 rank at once [s], per round | ceiling (even split) |" in table
    assert "| 16.50, 16.50, 19.00 | 1.70× (1.65×) |" in table
    runs[1]["side"][0] = _summary(16.0, steps=901)  # a copy with another result is flagged
    assert not scaling.summarize(runs)["same"]


@pytest.mark.parametrize("key, value", [("steps", 901), ("runout_length", 1500.5),
                                        ("affected_area", 2e5 + 1.0)])
def test_a_result_that_depends_on_the_rank_count_is_flagged(key, value):
    other = _summary(9.0) | {key: value}
    s = scaling.summarize([{1: _summary(14.0), 2: _summary(9.0)}, {1: _summary(14.0), 2: other}])
    assert not s["same"]
    assert "| NO |" in scaling.format_table({"tg2": s}, 2)


def test_a_small_case_at_1_and_2_ranks_gives_the_same_result(tmp_path):
    """Two real runs (the command line, 1 and 2 ranks): the doc's table between its markers."""
    doc = tmp_path / "doc.md"
    doc.write_text(f"before\n{scaling.BEGIN}\nold\n{scaling.END}\nafter\n")
    args = argparse.Namespace(
        case=scaling.ROOT / "cases" / "hemisphere.yaml", methods=["tg2"], ranks=2, rounds=1,
        set=["domain.cells=[24,24]", "time.end=0.05", "output.pictures=false"],
        work=tmp_path / "runs", out=doc, side_by_side=True)
    assert scaling.main(args) == 0
    text = doc.read_text()
    assert text.startswith("before\n") and text.endswith("after\n") and "old" not in text
    row = next(line for line in text.splitlines() if line.startswith("| tg2 |"))
    assert row.endswith("| yes |")
    assert "--set time.end=0.05" in text and "--side-by-side" in text
    assert row.count("|") == 14  # the two side-by-side columns
