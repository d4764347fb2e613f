"""The Analysis tab explains a sweep recording as a sweep (``analyze_sweep`` on the analysis
thread, its stages shown as it goes): the measured diagram step by step, the per-step table,
the report's figures; a bad sweep file gets its one-line error."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from analysis.sweep.load import load_sweep
from gui.units import DISPLAY
from reference.sweeps import draw_sweep, write_marked_recording, write_sweep_recording
from tests.gui.conftest import wait_until
from tests.sweep.recordings import sine_sweep


@pytest.fixture
def window(open_window):
    return open_window(900, 600)


def test_a_sweep_recording_is_explained_with_its_diagram_and_step_table(qapp, window, tmp_path):
    generated = draw_sweep(3, None, parameter="amplitude", up_steps=2, settle_s=2.0, dwell_s=2.5)
    path = write_sweep_recording(generated, tmp_path / "sweep.h5")
    window.show_view("analysis")
    panel = window.analysis_panel
    panel.path.setText(str(path))
    panel.explain.click()
    assert not panel.explain.isEnabled()  # busy: the analysis runs on the analysis thread
    wait_until(qapp, lambda: panel.explain.isEnabled(), 240, "the sweep's analysis")
    assert panel.explained is not None, panel.state.text()
    assert panel.explained["kind"] == "sweep"
    assert panel.stages[0] == "sweep of 3 steps over the drive's amplitude"  # progress shown
    assert panel.state.text().startswith("sweep of 3 steps over the drive's amplitude: ")
    # the per-step table: one row per step, up, up, down, at the recorded settings
    rows = panel.report.toPlainText().splitlines()[1:]
    sweep = load_sweep([path])
    assert [row.split()[:2] for row in rows] == [["0", "up"], ["1", "up"], ["2", "down"]]
    for row, step in zip(rows, sweep.steps, strict=True):
        assert float(row.split()[2]) == pytest.approx(step.amplitude_m, rel=1e-3)
    # the measured diagram: points at each step's amplitude (the way down beside the way up)
    x, y = panel.diagram_points.getData()
    shown = {round(v, 6) for v in x}
    up = {round(DISPLAY["displacement"].show(s.amplitude_m), 6) for s in sweep.steps[:2]}
    assert up <= shown and len(shown) == 3 and np.all(np.isfinite(y))
    # each model's diagram over the measured one, and its regimes in the table, as the
    # analysis compared them step by step
    diagram = panel.explained["sweep"]["diagram"]
    models = [diagram["baseline"]] + ([diagram["explained"]] if diagram["explained"] else [])
    assert panel.key == ["measured", *(model["model"] for model in models)]
    for column, (model, item) in enumerate(zip(models, panel.model_points, strict=False)):
        for row, step in zip(rows, model["steps"], strict=True):
            assert row.split()[3] == step["measured"]
            assert row.split()[4 + column] == step["simulated"]
        model_x, model_y = item.getData()
        assert model_x.size and np.all(np.isfinite(model_y))
        assert np.all(np.min(np.abs(model_x[:, None] - np.array(sorted(shown))), axis=1) > 0)
    assert diagram["summary"] in panel.explanation.toPlainText()
    # the sweep report's figures (its diagrams over the measured points) shown as pictures
    assert "sweep_diagram_baseline.png" in [label.toolTip() for label in panel.figure_labels]
    assert all(not label.pixmap().isNull() for label in panel.figure_labels)


def test_a_bad_sweep_file_gets_its_one_line_error(qapp, window, tmp_path):
    angle, edges, marks = sine_sweep((1e-3, 2e-3, 3e-3))
    marks[2] = replace(marks[2], settle_start_index=marks[1].dwell_end_index - 50)
    path = write_marked_recording(tmp_path / "overlap.h5", angle, 500.0, edges, marks)
    panel = window.analysis_panel
    panel.path.setText(str(path))
    panel.explain.click()
    wait_until(qapp, lambda: panel.explain.isEnabled(), 60, "the sweep to be refused")
    text = panel.state.text()
    assert text.startswith(f"cannot explain: {path}: sweep step 2 overlaps step 1")
    assert "\n" not in text and "Traceback" not in text
