"""Result pages: a study's stages kept side by side in its raw figures."""
import json

from twin.viz.pages import staged


def test_a_stage_takes_its_cases_rows_in_case_order_beside_the_stages_already_recorded(tmp_path):
    (tmp_path / "after").mkdir()
    raw = tmp_path / "study.json"
    raw.write_text(json.dumps({"stages": {"before": {"commit": "a", "rows": [{"v": 0}], "summary": {"n": 1}}}}))
    for name, v in (("b", 2), ("a", 1)):
        (tmp_path / "after" / f"{name}.json").write_text(json.dumps({"v": v}))
    got = staged(raw, "after", tmp_path / "after", ["a", "b", "not-run"], lambda rows: {"n": len(rows)}, "c0ffee")
    assert list(got) == ["before", "after"] and got["before"]["rows"] == [{"v": 0}]
    assert got["after"] == {"commit": "c0ffee", "rows": [{"v": 1}, {"v": 2}], "summary": {"n": 2}}
    assert staged(tmp_path / "none.json", "s", tmp_path / "after", ["a"], len, "x") == \
        {"s": {"commit": "x", "rows": [{"v": 1}], "summary": 1}}


def test_a_table_cell_with_bars_stays_one_cell():
    from twin.viz.pages import ResultTable

    text = ResultTable("c", ["band", "mean |r| (rad/s)"], [["yaw rate |r|", 0.25]]).markdown()
    lines = text.splitlines()
    # an escaped bar is text, not a cell boundary: each row has its two cells
    assert all(line.replace("\\|", "").count("|") == 3 for line in lines[2:]), lines
    assert "yaw rate \\|r\\|" in lines[-1] and "mean \\|r\\| (rad/s)" in lines[2]
