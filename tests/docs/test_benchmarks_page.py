"""The benchmarks page is generated from the benchmarks' results (benchmarks/results/*.json,
written by ``--save``): its tables are what ``benchmarks/page.py`` makes of those files, every
result is on the page, one figure per cell, and each file says what made it."""

from __future__ import annotations

import json

import pytest

from harness.results import END, PAGE, RESULTS, figure, generated, load_results, result, save, table


def test_the_page_is_what_the_results_make():
    page = PAGE.read_text(encoding="utf-8")
    assert generated(page, load_results()) == page, (
        "docs/benchmarks.md is out of date with benchmarks/results/: run python benchmarks/page.py"
    )


def test_every_result_says_what_made_it_and_holds_one_figure_per_row():
    results = load_results()
    assert len(results) >= 15
    for key, outcome in results.items():
        assert outcome["command"] and outcome["written_by"], key
        assert outcome["figures"], key
        for shown in outcome["figures"]:
            assert set(shown) <= {"figure", "now", "goal", "measured"}, key
            cells = [shown[cell] for cell in ("figure", "now", "goal")]
            assert all(isinstance(cell, str) and cell for cell in cells), key
            assert "\n" not in shown["now"] and len(shown["now"]) < 400, (key, shown["figure"])
            if "measured" not in shown:  # measured in the file's own run
                assert outcome["date"] and outcome["load"] and outcome["commit"], key


def _page(keys: str) -> str:
    return f"# B\n\n<!-- benchmarks: {keys} -->\n| old |\n{END}\n\ntext\n"


def test_a_saved_run_becomes_its_rows_on_the_page(tmp_path):
    outcome = result("demo-bench", [figure("speed", "3.1x", ">= 2x"), figure("lost", "0 | none")],
                     about="a trial", load_at_start=1.0)
    assert outcome["date"] and outcome["machine"] and outcome["load"]
    path = save(outcome, tmp_path)
    assert json.loads(path.read_text(encoding="utf-8"))["figures"][0]["now"] == "3.1x"
    results = load_results(tmp_path)
    page = generated(_page("demo-bench"), results)
    commit = outcome["commit"]
    measured = f"{outcome['date']}, load {outcome['load']}, {commit[:10]}{commit[40:]}"
    rows = table(results, ["demo-bench"])
    run = f"`{outcome['command']}` (a trial)"
    assert rows[2] == f"| {run} | speed | 3.1x | >= 2x | {measured} |"
    assert rows[3] == f"| | lost | 0 \\| none | - | {measured} |"
    assert page == _page("demo-bench").replace("| old |", "\n".join(rows))
    assert generated(page, results) == page


def test_a_result_left_off_the_page_or_a_key_without_result_is_an_error(tmp_path):
    save(result("one", [figure("a", "1")]), tmp_path)
    save(result("two", [figure("b", "2")]), tmp_path)
    results = load_results(tmp_path)
    with pytest.raises(ValueError, match=r"\['two'\] are in no table"):
        generated(_page("one"), results)
    with pytest.raises(ValueError, match=r"no result for \['three'\]"):
        generated(_page("one two three"), results)
    (tmp_path / "four.json").write_text('{"format": 1, "benchmark": "five"}', encoding="utf-8")
    with pytest.raises(ValueError, match=r"four\.json: not a benchmark result"):
        load_results(tmp_path)


def test_the_results_live_beside_the_benchmarks():
    assert RESULTS.parent.name == "benchmarks" and any(RESULTS.glob("*.json"))
