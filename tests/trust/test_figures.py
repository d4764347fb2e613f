"""Figures we write: legends beside the data, never over it, at a resolution that prints, and
the software that made them in their metadata."""

from __future__ import annotations

import numpy as np
from PIL import Image

from analysis.dynamics.bifurcation import BifurcationDiagram, plot_bifurcation
from analysis.figure_style import PRINT_DPI


def test_a_diagram_keeps_its_legend_off_the_data_and_prints_sharp(tmp_path):
    beta = np.linspace(0.01, 0.3, 40)
    theta = -0.2 + 0.1 * np.sin(8 * beta)[:, None] + np.zeros((1, 5))  # a band of points
    up = BifurcationDiagram(beta, theta, np.zeros_like(theta), "up", "beta")
    down = BifurcationDiagram(beta[::-1], theta[::-1] + 0.01, np.zeros_like(theta), "down",
                              "beta")
    path = tmp_path / "diagram.png"
    figure = plot_bifurcation(up, down, title="test", path=path)
    axes = figure.axes[0]
    renderer = figure.canvas.get_renderer()
    legend = axes.get_legend().get_window_extent(renderer)
    data_area = axes.get_window_extent(renderer)
    assert legend.x0 >= data_area.x1  # beside the axes, not on the points
    width_in = figure.get_size_inches()[0]
    with Image.open(path) as image:
        assert image.width >= 0.95 * width_in * PRINT_DPI  # cropped, never reduced
        assert image.info["Software"].startswith("impact-rig")
