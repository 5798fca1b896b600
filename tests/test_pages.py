"""Result pages: a study's stages kept side by side in its raw figures."""
import json

import numpy as np

from twin.viz.pages import given_cell, given_record, staged, write_index


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


def test_a_truth_judged_as_given_reads_as_the_diagnosis_judged_it():
    """given_record keeps the Evidence's verdict, z and votes; given_cell says provable or not, a
    judgement that failed, a truth that changes no window, and nothing for a case not judged."""
    from twin.diagnose.search import Evidence

    def evidence(z, rel, votes, affected=12):
        return Evidence(z, rel, rel, {}, int(sum(v > 0 for v in votes)), int(sum(v < 0 for v in votes)), affected,
                        np.asarray(votes))

    strong = given_record("current=0.1,90", evidence(4.76, 0.2, [0.1] * 20), "c0ffee")
    assert strong["earns_its_place"] and strong["blocks_for"] == 20 and strong["commit"] == "c0ffee"
    assert given_cell(strong) == "provable (z 4.76, blocks 20 for / 0 against)"
    weak = given_record("dead_zone_left=0.2,0.2", evidence(2.15, 0.01, [0.1] * 6), "c0ffee")
    assert not weak["earns_its_place"] and given_cell(weak) == "not provable (z 2.15, blocks 6 for / 0 against)"
    assert given_cell({**weak, "affected_windows": 0}) == "changes no window"
    assert given_cell({"failed": True}) == "judgement failed" and given_cell(None) == "-"


def test_the_results_index_lists_a_series_by_its_latest_set_and_every_page_once(tmp_path):
    for stem, title in [("concealed_effects", "Concealed"), ("concealed_effects_second", "Concealed (second)"),
                        ("concealed_effects_tenth", "Concealed (tenth)"), ("bench_engine", "Engine"),
                        ("a_study_of_its_own", "Own")]:
        (tmp_path / f"{stem}.md").write_text(f"# {title}\n\ntext\n")
    text = write_index(tmp_path).read_text()
    line = next(ln for ln in text.splitlines() if "Concealed" in ln)
    # the tenth after the second (ordinal, not name order), the latest first
    assert line.startswith("- [Concealed (tenth)](concealed_effects_tenth.md)")
    assert line.index("[first](concealed_effects.md)") < line.index("[second](concealed_effects_second.md)")
    assert text.index("## Benchmarks") < text.index("[Engine](bench_engine.md)") < text.index("## Other studies")
    assert text.index("## Other studies") < text.index("[Own](a_study_of_its_own.md)")
    assert sum(text.count(f"({p.name})") for p in tmp_path.glob("*.md") if p.name != "index.md") == 5
