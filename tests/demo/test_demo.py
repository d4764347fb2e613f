"""``impact-rig demo --quick`` run as a user runs it (a subprocess on the virtual rig over its
real protocols), and the report folder it leaves: report, figures, JSON reports, recordings."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from analysis.discrepancy.candidates import candidates_for
from analysis.experiments import FORCED
from analysis.extensions import CAUSES
from analysis.hdf5_records import load_hdf5_steps
from recording.reader import open_recording
from rig.cli import main
from rig.config import load_config
from tests.browser import console_errors, external_references, headless_chromium, images
from tests.html_page import read_page
from tests.strict_json import strict_loads

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
TRUE_L_M = load_config().constants.L_m
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SECTION_6_KEYS = {"experiment", "cause", "ranking", "baseline", "extended", "gain", "localization"}
GAIN_KEYS = {
    "rms_reduction",
    "heldout_rms_baseline",
    "heldout_rms_extended",
    "information_criterion_delta",
}


def _command() -> list[str]:
    script = shutil.which("impact-rig")
    return [script] if script else [sys.executable, "-m", "rig.cli"]


def _env() -> dict[str, str]:
    """The environment with this checkout first on the path: the ``impact-rig`` script runs
    the code under test, not a copy installed beside it (``pip install .`` in CI, or an
    editable install of another tree), and loads the compiled integrator the tests' own
    processes cached instead of compiling it again for that copy."""
    paths = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": paths}


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """One quick demo into a fresh folder: (folder, completed process)."""
    folder = tmp_path_factory.mktemp("demo") / "report"
    done = subprocess.run(
        [*_command(), "demo", "--quick", "--out", str(folder)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
        env=_env(),
    )
    return folder, done


def _json(folder, name):
    """A file of the report folder, read as strict JSON (no NaN or Infinity token)."""
    return strict_loads((folder / name).read_text(encoding="utf-8"))


def _assert_estimate(estimate, *, interval=True):
    assert isinstance(estimate["value"], float)
    if interval:
        low, high = estimate["ci95"]
        assert low <= estimate["value"] <= high


def test_the_demo_succeeds_shows_progress_and_prints_where_the_report_is(demo):
    folder, done = demo
    assert done.returncode == 0, done.stderr[-3000:]
    assert str(folder / "report.md") in done.stdout
    for stage in range(1, 7):
        assert f"[{stage}/6]" in done.stderr
    assert "hidden in the virtual rig: coulomb_friction" in done.stdout


def test_every_file_of_the_demo_report_says_what_made_it(demo):
    from PIL import Image

    folder, _ = demo
    for path in folder.rglob("*.json"):
        assert _json(path.parent, path.name)["provenance"]["command_line"][:2] == [
            "impact-rig", "demo"], path
    for path in [*folder.rglob("*.md"), *folder.rglob("*.html")]:
        assert "Made by impact-rig " in path.read_text(encoding="utf-8"), path
    for path in folder.rglob("*.html"):
        assert read_page(path).meta["generator"].startswith("impact-rig "), path
    for path in folder.rglob("*.png"):
        with Image.open(path) as image:
            assert json.loads(image.text["Provenance"])["software"]["impact-rig"], path


def test_the_report_shows_figures_that_exist(demo):
    folder, _ = demo
    report = (folder / "report.md").read_text(encoding="utf-8")
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report)
    expected = {
        "figures/bifurcation.png",
        "analysis/free_decay_fit.png",
        "analysis/impact_decay_fit.png",
    }
    assert set(figures) >= expected
    for figure in figures:
        data = (folder / figure).read_bytes()
        assert data[:8] == PNG_MAGIC and len(data) > 10_000


def test_the_html_report_says_what_the_markdown_and_the_json_say(demo):
    folder, _ = demo
    report = read_page(folder / "report.html")
    markdown = (folder / "report.md").read_text(encoding="utf-8")
    assert report.title == "impact-rig demo report"
    assert [image["src"] for image in report.images] == re.findall(
        r"!\[[^\]]*\]\(([^)]+)\)", markdown)
    assert all(image["alt"] and image["width"] for image in report.images)
    # the explained model's parameters, row by row, as parameters.json holds them
    parameters = _json(folder, "parameters.json")["parameters"]
    rows = report.table_with("parameter")[1:]
    assert [row[0] for row in rows] == list(parameters)
    assert [row[3] for row in rows] == [f"{p['value']:.6g}" for p in parameters.values()]
    for name in ("free_decay", "impact_decay"):
        analysis = _json(folder, f"analysis/{name}.json")
        assert f"most probable cause: {analysis['cause']}" in report.items
        assert {"href": f"analysis/{name}.html"} in report.links
        page = read_page(folder / "analysis" / f"{name}.html")
        assert f"where the baseline fails: {analysis['localization']}" in page.items
        ranked = [row[0] for row in page.table_with("cause")[1:]]
        assert ranked == [row["cause"] for row in analysis["ranking"]]
    assert "the analysis named coulomb_friction (matches)" in " ".join(report.items)
    assert report.paragraphs[-1].startswith("Made by impact-rig ")
    assert "impact-rig demo --quick" in report.paragraphs[-1]


def test_the_html_report_opens_in_a_browser_with_every_figure(demo, tmp_path):
    from PIL import Image

    folder, _ = demo
    pages = ["report.html", "analysis/free_decay.html", "analysis/impact_decay.html"]
    with headless_chromium(tmp_path / "profile") as browser:
        for name in pages:
            browser.get((folder / name).as_uri())
            assert browser.title == read_page(folder / name).title, name
            shown = images(browser)
            assert shown, name
            for image in shown:
                assert image["complete"] and image["naturalWidth"] >= 1000, (name, image)
            assert console_errors(browser) == [], name
            assert external_references(browser) == [], name
            assert browser.execute_script("return document.scripts.length") == 0
        # the report's link to an analysis page opens that page
        browser.get((folder / "report.html").as_uri())
        browser.find_element("link text", "analysis/impact_decay").click()
        assert browser.title == "Discrepancy analysis: impact_decay.h5"
        browser.back()
        screenshot = tmp_path / "report.png"
        assert browser.save_screenshot(str(screenshot))
    with Image.open(screenshot) as image:
        pixels = np.asarray(image.convert("RGB")).reshape(-1, 3).astype(np.uint32)
    _, counts = np.unique(pixels[:, 0] << 16 | pixels[:, 1] << 8 | pixels[:, 2],
                          return_counts=True)
    assert counts.size > 20 and counts.max() < 0.97 * counts.sum()  # text, tables: not blank


def test_the_identification_reports_carry_the_section_7_keys_with_intervals(demo):
    folder, _ = demo
    free = _json(folder, "identify_free_decay.json")
    assert free["experiment"] == "free_decay"
    for key in ("L_m", "omega_rad_s", "zeta"):
        _assert_estimate(free["parameters"][key])
    impact = _json(folder, "identify_impact_decay.json")
    assert impact["experiment"] == "impact_decay"
    for key in ("K_N_per_m1.5", "E_Pa", "mu0_s_per_m"):
        _assert_estimate(impact["parameters"][key])
    combined = _json(folder, "parameters.json")
    for key in ("L_m", "zeta", "K_N_per_m1.5", "mu0_s_per_m"):
        _assert_estimate(combined["parameters"][key])
        _assert_estimate(combined["baseline_identification"][key])


def test_the_identified_length_is_the_rigs_within_a_narrow_interval(demo):
    folder, _ = demo
    estimate = _json(folder, "parameters.json")["parameters"]["L_m"]
    low, high = estimate["ci95"]
    assert low <= TRUE_L_M <= high
    assert high - low < 0.002 * TRUE_L_M  # an interval that says something


def test_the_recordings_open_complete_and_hold_the_sweep_steps(demo):
    folder, _ = demo
    experiments = {
        "free_decay.h5": "free_decay",
        "impact_decay.h5": "impact_decay",
        "sweep_10Hz.h5": "forced",
    }
    for name, experiment in experiments.items():
        with open_recording(folder / "recordings" / name) as recording:
            status = recording.status()
            assert status.closed and status.stop_reason.startswith("completed")
            assert recording.info.experiment == experiment
            assert len(recording.channel("angle")) > 1000
    steps = load_hdf5_steps(folder / "recordings" / "sweep_10Hz.h5")
    regimes = _json(folder, "sweep_regimes.json")["steps"]
    assert len(steps) == len(regimes) == 5  # three amplitudes up, two back down
    betas = [step["beta"] for step in regimes]
    assert betas == pytest.approx(betas[::-1])
    assert [step["direction"] for step in regimes] == ["up"] * 3 + ["down"] * 2
    kinds = ("periodic", "quasi_periodic", "chaotic", "undetermined", "unclassified")
    for step in regimes:
        assert step["kind"] in kinds
        assert step["poincare_points"] >= 40  # one tachometer pulse per drive period


def test_the_discrepancy_reports_follow_section_6(demo):
    # The demo's records come from the virtual rig, whose integrator and cause code the
    # analysis shares: the cause it names and the sizes it finds are tested on independent
    # records (docs/development.md, "Which test names each cause"); here, that the reports
    # are whole and agree with themselves.
    folder, _ = demo
    for name in ("analysis/free_decay.json", "analysis/impact_decay.json"):
        report = _json(folder, name)
        assert set(report) >= SECTION_6_KEYS
        assert set(report["gain"]) >= GAIN_KEYS
        adopted = [entry["cause"] for entry in report["causes"]]
        assert report["cause"] == (adopted[0] if adopted else "none"), name
        assert set(adopted) <= set(CAUSES), name
        scores = [entry["score"] for entry in report["ranking"]]
        assert scores == sorted(scores, reverse=True), name
        for entry in report["ranking"]:
            assert {"cause", "score", "parameters"} <= set(entry)


def test_a_folder_with_files_in_it_is_refused_before_anything_runs(tmp_path, capsys):
    folder = tmp_path / "taken"
    folder.mkdir()
    keep = folder / "notes.txt"
    keep.write_text("mine")
    assert main(["demo", "--quick", "--out", str(folder)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert keep.read_text() == "mine" and sorted(folder.iterdir()) == [keep]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--cause", "friction"], "unknown cause 'friction'"),
        (["--param", "Tc_N_m=5"], "coulomb_friction.Tc_N_m = 5.0"),
        (["--param", "Tc=1e-5"], "unknown parameter(s) ['Tc']"),
        (["--param", "Tc_N_m"], "expected NAME=VALUE"),
        (["--param", "Tc_N_m=abc"], "'abc' is not a number"),
        (["--cause", "none", "--param", "Tc_N_m=1e-5"], "takes no parameters"),
    ],
)
def test_a_bad_cause_is_refused_with_what_was_wrong(tmp_path, capsys, options, message):
    folder = tmp_path / "out"
    assert main(["demo", "--quick", "--out", str(folder), *options]) == 2
    assert message in capsys.readouterr().err
    assert not folder.exists()


def test_a_rig_file_with_several_hidden_causes_needs_a_choice(tmp_path, capsys):
    rig_file = tmp_path / "lab.toml"
    rig_file.write_text(
        load_config().text
        + "\n[virtual.causes]\ncoulomb_friction = { Tc_N_m = 1e-5 }\n"
        + "sensor_offset = { offset_rad = 0.002 }\n"
    )
    folder = tmp_path / "out"
    assert main(["demo", "--quick", "--config", str(rig_file), "--out", str(folder)]) == 2
    assert "choose it with --cause" in capsys.readouterr().err
    assert not folder.exists()


def test_a_rig_the_virtual_rig_cannot_emulate_is_a_clear_error_not_a_traceback(tmp_path, capsys):
    text = load_config().text
    digital_laser = re.sub(r'(?m)^unit = "V"', 'unit = "count"', text)
    assert digital_laser != text
    rig_file = tmp_path / "digital_laser.toml"
    rig_file.write_text(digital_laser)
    folder = tmp_path / "out"
    assert main(["demo", "--quick", "--config", str(rig_file), "--out", str(folder)]) == 2
    error = capsys.readouterr().err
    assert "recording on the virtual rig failed" in error and 'unit = "V"' in error


def test_the_demo_explains_its_sweep_as_one_and_says_whether_the_diagrams_agree(demo):
    folder, done = demo
    summary = _json(folder, "demo.json")
    sweep = summary["sweep"]
    # the steps are timed on the samples (tests/demo/test_sweep_timing.py): a loaded machine
    # leaves the sweep usable
    assert sweep is not None, summary["notes"]
    analysed = _json(folder / "analysis", "sweep.json")["sweep"]
    assert sweep["page"] == "analysis/sweep.md" and (folder / sweep["page"]).is_file()
    # five steps, each analysed or set aside with its reason (lost samples on a busy machine)
    assert sweep["steps"] == len(analysed["steps"]) and sweep["steps"] >= 2
    assert sweep["steps"] + sweep["set_aside"] == 5
    assert sweep["causes"] == analysed["causes"]["named"]
    diagram = analysed["diagram"]
    models = [diagram["baseline"]] + ([diagram["explained"]] if diagram["explained"] else [])
    assert [m["model"] for m in sweep["diagram"]] == [m["model"] for m in models]
    explained = models[-1]
    judged = sum(step["measured"] != "undetermined" for step in explained["steps"])
    verdict = "agrees with" if explained["agreeing_steps"] == judged else "does not agree with"
    said = f"the explained model's diagram {verdict} the measured one"
    report = (folder / "report.md").read_text(encoding="utf-8")
    assert said in done.stdout and said in report
    # the quick demo checks the sweep only for a cause the free decay showed, and says so
    found = _json(folder, "analysis/free_decay.json")["cause"]
    checked_for_it = f"quick demo: the sweep was checked for {found} only" in report
    assert checked_for_it == (found in {c.name for c in candidates_for(FORCED.name)})
    section = report.split("### The sweep explained as one")[1].split("\n## ")[0]
    for figure in sweep["figures"]:  # the sweep report's diagrams, shown in the demo's
        assert f"]({figure})" in section
        assert (folder / figure).read_bytes()[:8] == PNG_MAGIC
