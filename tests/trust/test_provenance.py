"""Every recording, sidecar and report says which software made it, where, when and by whom."""

from __future__ import annotations

import json
import subprocess
import sys

from analysis.provenance import DEPENDENCIES
from recording.reader import open_recording
from tests.trust.conftest import REPO, run_cli


def _check(block, operator=None):
    assert block["software"]["impact-rig"]
    assert set(DEPENDENCIES) <= set(block["dependencies"])
    assert block["python"] and block["host"] and block["start_time_utc"]
    assert block["command_line"][0] == "impact-rig"
    if (REPO / ".git").exists():
        head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
        assert block["git"]["commit"] == head
    if operator is not None:
        assert block["operator"] == operator


def test_a_recording_its_export_and_its_log_carry_provenance(recording, tmp_path):
    with open_recording(recording) as rec:
        _check(rec.info.provenance, operator="A. Tester")
        assert rec.info.provenance["command_line"][1] == "record"
    log = recording.with_suffix(".log").read_text()
    assert "completed" in log
    _check(json.loads(log.split("provenance: ", 1)[1].splitlines()[0]), operator="A. Tester")
    out = tmp_path / "run.csv"
    assert run_cli("export", str(recording), "--out", str(out), "--operator", "B").returncode == 0
    _check(json.loads(out.with_suffix(".json").read_text())["provenance"], operator="B")


def test_an_identify_report_carries_provenance(tmp_path):
    csv = tmp_path / "decay.csv"
    run_cli("simulate", "--experiment", "free_decay", "--theta0", "0.1", "--duration", "4",
            "--fs", "200", "--out", str(csv))
    _check(json.loads(csv.with_suffix(".json").read_text())["provenance"])
    report = tmp_path / "params.json"
    done = run_cli("identify", str(csv), "--json", str(report))
    assert done.returncode == 0, done.stderr
    _check(json.loads(report.read_text())["provenance"])


def _png_provenance(path):
    from PIL import Image

    with Image.open(path) as image:
        return json.loads(image.text["Provenance"])


def test_every_file_of_an_analysis_report_carries_provenance(tmp_path):
    csv = tmp_path / "decay.csv"
    run_cli("simulate", "--experiment", "free_decay", "--theta0", "0.1", "--duration", "4",
            "--fs", "200", "--out", str(csv))
    folder, report = tmp_path / "report", tmp_path / "analysis.json"
    done = run_cli("analyze", str(csv), "--json", str(report), "--report", str(folder),
                   "--operator", "C. Analyst", "--workers", "1")
    assert done.returncode == 0, done.stderr
    _check(json.loads(report.read_text())["provenance"], operator="C. Analyst")
    written = sorted(folder.iterdir())
    assert {path.suffix for path in written} == {".md", ".html", ".json", ".png"}
    for path in written:
        if path.suffix == ".json":
            _check(json.loads(path.read_text())["provenance"], operator="C. Analyst")
        elif path.suffix == ".png":
            _check(_png_provenance(path), operator="C. Analyst")
        elif path.suffix == ".md":
            closing = path.read_text().rstrip().splitlines()[-1]
            assert closing.startswith("Made by impact-rig ") and "by C. Analyst" in closing
            assert "`impact-rig analyze " in closing
        else:  # the HTML twin: the same closing line, and the software in its head
            page = path.read_text()
            assert '<meta name="generator" content="impact-rig ' in page
            assert "Made by impact-rig " in page and "by C. Analyst" in page
            assert "<code>impact-rig analyze " in page


def test_version_is_printed():
    done = subprocess.run([sys.executable, "-m", "rig.cli", "--version"], capture_output=True,
                          text=True, check=False)
    assert done.returncode == 0 and done.stdout.startswith("impact-rig ")
