"""Nonlinear-dynamics tools: spectra, Poincare sections, embedding, Lyapunov exponents, 0-1 test,
regime classification, bifurcation diagrams and basins of attraction."""

from analysis.dynamics.chaos01 import ZeroOneResult, zero_one_test
from analysis.dynamics.embedding import (
    DelayChoice,
    DimensionChoice,
    delay_embed,
    false_nearest_neighbours,
    fnn_dimension,
    mutual_information,
    mutual_information_delay,
)
from analysis.dynamics.integrators import iterate_map, rk4_trajectory
from analysis.dynamics.lyapunov import (
    LyapunovEstimate,
    flow_lyapunov,
    map_lyapunov,
    model_lyapunov,
    rosenstein_lyapunov,
)
from analysis.dynamics.poincare import (
    PoincareSection,
    delayed_map,
    poincare_from_phase,
    poincare_from_pulses,
    smoothed_derivative,
)
from analysis.dynamics.regime import Regime, classify_motion, classify_regime
from analysis.dynamics.spectrum import SpectralPeak, Spectrum, amplitude_spectrum, harmonic_label

__all__ = [
    "DelayChoice",
    "DimensionChoice",
    "LyapunovEstimate",
    "PoincareSection",
    "Regime",
    "SpectralPeak",
    "Spectrum",
    "ZeroOneResult",
    "amplitude_spectrum",
    "classify_motion",
    "classify_regime",
    "delay_embed",
    "delayed_map",
    "false_nearest_neighbours",
    "flow_lyapunov",
    "fnn_dimension",
    "harmonic_label",
    "iterate_map",
    "map_lyapunov",
    "model_lyapunov",
    "mutual_information",
    "mutual_information_delay",
    "poincare_from_phase",
    "poincare_from_pulses",
    "rk4_trajectory",
    "rosenstein_lyapunov",
    "smoothed_derivative",
    "zero_one_test",
]
