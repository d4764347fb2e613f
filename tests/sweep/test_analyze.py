"""``impact-rig analyze SWEEP`` on a sweep of the independent reference simulator (scipy;
never the project's integrator): a barrier 15 mrad off its nominal place, three
amplitude steps and a fourth the sweep was interrupted in.  One rig is fitted to every
step: each true parameter of the rig, the barrier among them, lies within the 99.9 %
interval the joint fit's 95 % one implies (seven parameters, one seed: a test at 95 %
would fail on honest intervals one seed in three); the forward selection across the steps
names the barrier offset, its one size for every step within its interval; the
interrupted step is set aside with its reason; the report lists every step.  A clean sweep
of the same rig names no cause."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import pytest

from analysis.json_output import json_ready, write_json
from analysis.sweep import analyze
from analysis.sweep.analyze import compare_with_measured
from reference.forced_records import RigTruth
from reference.sweeps import generate_sweep
from rig.cli import main
from tests.conftest import computed_once
from tests.tolerance import within_999

THETA_B_RAD = 0.015


@pytest.fixture(scope="module")
def analysed(tmp_path_factory) -> tuple[dict, Path, RigTruth]:
    """The analysis's JSON, the folder of its report, and the rig the sweep was drawn on:
    made once per run (``computed_once``), though the workers split this module's tests."""
    folder = computed_once(tmp_path_factory, "sweep-analysed", _analyse)
    return (json.loads((folder / "out.json").read_text()), folder,
            RigTruth(**json.loads((folder / "rig.json").read_text())))


def _analyse(folder: Path) -> None:
    path = folder / "sweep.h5"
    truth = generate_sweep(path, seed=1, theta_b_rad=THETA_B_RAD, betas=(0.02, 0.03, 0.04, 0.05),
                           interrupted_at=3)
    here = []

    def remembered(ident, causes, **kwargs):
        # what the diagrams were compared from, compared again in this process
        here.append(json_ready(compare_with_measured(ident, causes).as_json()))
        return compare_with_measured(ident, causes, **kwargs)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(analyze, "compare_with_measured", remembered)
        # --workers 2: the diagrams' simulations on a local Dask cluster of 2 processes
        assert main(["analyze", str(path), "--json", str(folder / "out.json"), "--report",
                     str(folder / "report"), "--workers", "2"]) == 0
    write_json(folder / "here.json", here)
    write_json(folder / "rig.json", asdict(truth.rig))


@pytest.mark.slow
def test_one_rig_for_every_step_holds_the_truth_in_its_intervals(analysed) -> None:
    js, _, rig = analysed
    sweep = js["sweep"]
    shared = sweep["shared"]
    for name, value in (("omega_rad_s", rig.omega_rad_s), ("zeta", rig.zeta),
                        ("K_N_per_m1.5", rig.K_N_per_m1_5), ("mu0_s_per_m", rig.mu0_s_per_m),
                        ("theta_b_rad", THETA_B_RAD), ("offset_rad", 0.0),
                        ("L_m", rig.L_m)):
        assert within_999(shared[name], value), (name, value, shared[name])
    assert [s["step"] for s in sweep["steps"]] == [0, 1, 2]
    for step in sweep["steps"]:
        assert step["rms_over_noise"] < 1.2
        assert step["drive"]["table"] is not None and "drive_phase_rad" in step["own"]
    assert sweep["set_aside"] == [
        {"step": 3, "reason": "interrupted: the sweep stopped during this step"}]
    assert sweep["diagram"]["named"] == ["barrier_offset"]
    assert js["policy"]["bic_margin"]["value"] > 0


def test_the_hidden_barrier_offset_is_named_with_one_size_for_every_step(analysed) -> None:
    sweep = analysed[0]["sweep"]
    assert sweep["cause"] == "barrier_offset" and sweep["causes"]["named"] == ["barrier_offset"]
    (entry,) = sweep["causes"]["selected"]
    assert entry["named"] and within_999(entry["parameters"]["theta_b_rad"], THETA_B_RAD)
    assert sorted(entry["per_step"]) == [f"theta_b_rad@{k}" for k in range(3)]
    assert not sweep["residual_findings"]
    assert all(step["explained_rms_over_noise"] < 1.2 for step in sweep["steps"])


@pytest.mark.slow
def test_a_clean_sweep_names_no_cause(tmp_path: Path) -> None:
    path = tmp_path / "clean.h5"
    generate_sweep(path, seed=2, betas=(0.02, 0.03, 0.04))
    assert main(["analyze", str(path), "--json", str(tmp_path / "out.json")]) == 0
    sweep = json.loads((tmp_path / "out.json").read_text())["sweep"]
    assert sweep["cause"] == "none" and sweep["causes"]["selected"] == []
    assert within_999(sweep["shared"]["theta_b_rad"], 0.0)


def test_report_page_has_a_row_per_step_and_the_step_set_aside(analysed) -> None:
    _, folder, _ = analysed
    page = (folder / "report" / "sweep.md").read_text()
    diagram, steps = page.split("\n## Steps\n")
    # the page leads with the diagrams and a row per step of their regimes
    assert diagram.split("\n## ")[1].startswith("Bifurcation diagram")
    assert "![baseline over the measured diagram](sweep_diagram_baseline.png)" in diagram
    assert (folder / "report" / "sweep_diagram_baseline.png").read_bytes()[:4] == b"\x89PNG"
    assert len([line for line in diagram.splitlines() if line.startswith("| ")
                and " up " in line]) == 3
    rows = [line for line in steps.splitlines() if line.startswith("| ") and " up " in line]
    assert len(rows) == 3
    assert "step 3: interrupted" in page
    assert (folder / "report" / "sweep.html").exists()


def test_the_diagrams_run_on_two_workers_as_here(analysed) -> None:
    """The JSON's sweep.diagram, simulated on a local cluster of 2 worker processes, holds
    the same figures as the comparison made again in the analysing process, from what the
    diagrams were compared from."""
    diagram = analysed[0]["sweep"]["diagram"]
    assert diagram["named"] == ["barrier_offset"] and not diagram["explained_is_baseline"]
    assert [s["step"] for s in diagram["explained"]["steps"]] == [0, 1, 2]
    assert diagram["summary"].startswith("baseline: ")
    assert "; explained model: " in diagram["summary"]
    here, = json.loads((analysed[1] / "here.json").read_text())
    assert here == diagram
