"""The continuation figure: event numbers that stay apart, and the overlay panel."""

from __future__ import annotations

import numpy as np

from analysis.dynamics.bifurcation import BifurcationDiagram
from analysis.dynamics.continuation import continue_orbits
from analysis.dynamics.continuation_output import (
    CALLOUT_SPACING,
    plot_continuation,
    spread_positions,
)
from analysis.dynamics.model_parameters import model_with
from analysis.dynamics.period_map import PeriodMap
from analysis.model import Drive, Model, RigParameters


def test_event_numbers_keep_their_order_and_spacing_and_stay_put_when_apart():
    crowded = [0.5, 0.5005, 0.501, 0.502, 0.98, 0.99, 0.995]
    positions = spread_positions(crowded)
    assert np.all(np.diff(positions) >= CALLOUT_SPACING - 1e-12)
    assert positions[0] >= 0.01 and positions[-1] <= 0.99
    apart = [0.1, 0.4, 0.7]
    np.testing.assert_allclose(spread_positions(apart), apart)


def test_overlays_add_a_panel_of_angles_at_drive_phase_zero(tmp_path):
    rig = RigParameters(zeta=0.002)
    model = Model(rig, Drive(amplitude_m=0.0016 * rig.L_m, frequency_hz=2.6), barrier=False)
    model = model_with(model, "beta", 0.0016)
    result = continue_orbits(PeriodMap(model, "f_drive_hz"), 2.6, 2.4, np.zeros(2))
    plain = plot_continuation(result)
    diagram = BifurcationDiagram(np.array([2.5]), np.array([[0.01, 0.02]]),
                                 np.full((1, 2), np.nan), "recorded up", "f_drive_hz")
    overlaid = plot_continuation(result, overlays=[diagram], path=tmp_path / "f.png")
    assert len(plain.axes) == 1 and len(overlaid.axes) == 2
    lower = overlaid.axes[1]
    assert lower.get_ylabel() == "angle at drive phase 0 [rad]"
    assert (tmp_path / "f.png").stat().st_size > 10_000
