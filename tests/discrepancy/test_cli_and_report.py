"""``impact-rig analyze`` end to end on files: JSON of docs/MODEL.md section 6, Markdown and
HTML page with PNG figures, clear errors on bad input.

The records come from the independent reference simulator (``reference``: scipy
DOP853 with events), never from ``impact-rig simulate``, whose integrator and cause code the
analysis shares.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

from analysis.discrepancy import DEFAULT_POLICY
from reference.decays import FREE, draw_decay
from reference.free_decays import FS_HZ, draw_free_decay
from tests.gui.recordings import write_recording
from tests.html_page import read_page
from tests.strict_json import strict_loads

SECTION_6_KEYS = {"experiment", "cause", "ranking", "baseline", "extended", "gain", "localization"}
GAIN_KEYS = {"rms_reduction", "heldout_rms_baseline", "heldout_rms_extended",
             "information_criterion_delta"}


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "rig.cli", "analyze", *args], capture_output=True, text=True,
        timeout=300,
    )


def test_analyze_writes_section_6_json_and_report(tmp_path):
    case = draw_decay(3906, FREE)  # a clean decay: the baseline explains it
    csv = case.write(tmp_path, name="run")
    out = tmp_path / "out.json"
    result = run_cli(str(csv), "--json", str(out), "--report", str(tmp_path / "rep"),
                     "--workers", "1")
    assert result.returncode == 0, result.stderr
    report = strict_loads(out.read_text(encoding="utf-8"))
    assert set(report) >= SECTION_6_KEYS
    assert set(report["gain"]) >= GAIN_KEYS
    assert report["cause"] == "none"
    assert report["experiment"] == "free_decay"
    for key in ("L_m", "omega_rad_s", "zeta", "theta0_rad"):
        estimate = report["baseline"]["parameters"][key]
        lo, hi = estimate["ci95"]
        assert lo <= estimate["value"] <= hi
    # the true L lies in the reported interval of the extended model (the correct one)
    lo, hi = report["extended"]["parameters"]["L_m"]["ci95"]
    assert lo <= case.rig.L_m <= hi
    for row in report["ranking"]:
        assert {"cause", "score", "parameters"} <= set(row)
        # the whole candidate as fitted, that suggest simulates (docs/MODEL.md section 6)
        assert row["model"]["causes"] == [row["cause"]]
        assert {"omega_rad_s", "zeta", *row["parameters"]} <= set(row["model"]["parameters"])
    stated = json.loads(csv.with_suffix(".json").read_text(encoding="utf-8"))["rig"]
    assert {k: report["rig"][k] for k in ("m_kg", "l_m", "R_m")} == \
        {k: stated[k] for k in ("m_kg", "l_m", "R_m")}
    assert report["sample_rate_hz"] > 0
    # the rules it was decided under, as the analysis held them
    assert {k: v["value"] for k, v in report["policy"].items() if "value" in v} == \
        dataclasses.asdict(DEFAULT_POLICY)
    md = (tmp_path / "rep" / "run.md").read_text()
    assert "Rules: decided under the default rules" in md
    assert "cause: `none`" in md
    # the parameters say which data and model they come from, and why identify may differ
    story = md.split("## Parameters", 1)[1].split("|", 1)[0]
    assert f"({report['samples_fitted']} samples" in story and "`impact-rig identify`" in story
    assert "No cause was found" in story
    png = tmp_path / "rep" / "run_fit.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the HTML page beside it says what the Markdown and the JSON say
    page = read_page(tmp_path / "rep" / "run.html")
    assert page.title == "Discrepancy analysis: run.csv"
    assert "cause: none" in page.items
    assert f"where the baseline fails: {report['localization']}" in page.items
    ranked = [row[0] for row in page.table_with("cause")[1:]]
    assert ranked == [row["cause"] for row in report["ranking"]]
    keys = [row[0] for row in page.table_with("key")[1:]]
    assert keys == list(dict.fromkeys([*report["baseline"]["parameters"],
                                       *report["extended"]["parameters"]]))
    assert " ".join(story.replace("`", "").split()) in page.paragraphs
    assert page.images == [{"src": "run_fit.png", "alt": "fit and residuals", "width": "800"}]
    made_by = page.paragraphs[-1]
    assert made_by.startswith("Made by impact-rig ") and " analyze " in made_by
    # the console gets a short human summary (the report is in the files): the cause, its
    # size with an interval, the fits against the noise
    lines = result.stdout.splitlines()
    assert lines[0] == "cause: none" and len(lines) < 20
    noise_ratio = report["baseline"]["rms_residual"] / report["noise_rad"]
    assert f"baseline fit: rms residual {report['baseline']['rms_residual']:.3g} rad = " \
        f"{noise_ratio:.3g} x the noise" in lines
    assert not any(line.lstrip().startswith(("{", '"')) for line in lines)  # no JSON


def test_missing_file_is_a_clear_error(tmp_path):
    result = run_cli(str(tmp_path / "absent.csv"))
    assert result.returncode != 0
    assert "absent.csv" in result.stderr


def test_record_without_motion_is_refused_with_reason(tmp_path):
    csv = tmp_path / "flat.csv"
    csv.write_text("time_s,angle_rad\n" + "".join(f"{i / 100:.2f},0.0\n" for i in range(500)))
    (tmp_path / "flat.json").write_text(json.dumps({"experiment": "free_decay", "rig": {}}))
    result = run_cli(str(csv), "--workers", "1")
    assert result.returncode == 2
    # one line naming the file and why (no traceback)
    assert result.stderr.strip().splitlines()[-1] == (
        f"impact-rig analyze: error: {csv}: cannot analyse: no oscillation: the angle is constant"
    )
    assert "Traceback" not in result.stderr


def test_analyze_reads_hdf5_records(tmp_path, capsys):
    # a reference decay with dry friction (the decay pairs' "friction alone"), written as a
    # recording by the project's recorder
    decay = draw_free_decay(8904, ("coulomb_friction",))
    truth = decay.causes["coulomb_friction"]["Tc_N_m"]
    h5 = write_recording(tmp_path / "decay.h5", decay.angle_rad, FS_HZ, experiment="free_decay")
    result = run_cli(str(h5), "--json", "-", "--workers", "1", "--quiet")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)  # --json -: the report alone on stdout
    assert not (tmp_path / "-").exists()
    assert report["cause"] == "coulomb_friction"
    scores = [row["score"] for row in report["ranking"]]
    assert report["ranking"][0]["cause"] == "coulomb_friction" and scores == sorted(scores)[::-1]
    tc = report["extended"]["parameters"]["Tc_N_m"]
    assert tc == report["ranking"][0]["parameters"]["Tc_N_m"]
    # the drawn friction lies in the interval the extended model reports
    assert tc["ci95"][0] <= truth <= tc["ci95"][1]
    # without --json the console summary names the cause and its size with the interval
    from rig.commands.analyze import _print_summary

    capsys.readouterr()
    _print_summary(report)
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "cause: coulomb_friction"
    assert lines[1].startswith("  Tc_N_m = ") and "95% CI [" in lines[1]
    assert any(line.startswith("with coulomb_friction fit: rms residual") for line in lines)
