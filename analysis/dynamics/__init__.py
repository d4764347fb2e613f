"""Nonlinear-dynamics tools: spectra, Poincare sections, strobe sampling, embedding, Lyapunov
exponents, 0-1 test, regime judgement, bifurcation diagrams and basins of attraction."""

from analysis.dynamics.basins import (
    NO_ATTRACTOR,
    Attractor,
    BasinMap,
    basins_of_attraction,
    identify_attractors,
    plot_basins,
)
from analysis.dynamics.bifurcation import (
    BifurcationDiagram,
    bifurcation_from_recording,
    plot_bifurcation,
    simulate_bifurcation,
)
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
from analysis.dynamics.lyapunov import (
    LyapunovEstimate,
    LyapunovSpectrum,
    SpectrumSettings,
    flow_lyapunov,
    map_lyapunov,
    model_lyapunov_spectrum,
    rosenstein_lyapunov,
)
from analysis.dynamics.measured_regime import judge_record_regime, judge_regime
from analysis.dynamics.poincare import (
    PoincareSection,
    delayed_map,
    poincare_from_phase,
    poincare_from_pulses,
    smoothed_derivative,
)
from analysis.dynamics.regime import Regime, classify_regime, recurrence_distances
from analysis.dynamics.spectrum import SpectralPeak, Spectrum, amplitude_spectrum, harmonic_label
from analysis.dynamics.strobe import (
    StrobeClock,
    StrobeSamples,
    clock_from_drive,
    clock_from_tach,
    strobe_record,
    strobe_samples,
)
from analysis.dynamics.sweeps import (
    PoincareRuns,
    PoincareSettings,
    continue_along,
    model_at_beta,
    run_poincare,
)

__all__ = [
    "NO_ATTRACTOR",
    "Attractor",
    "BasinMap",
    "BifurcationDiagram",
    "DelayChoice",
    "DimensionChoice",
    "LyapunovEstimate",
    "LyapunovSpectrum",
    "PoincareRuns",
    "PoincareSection",
    "PoincareSettings",
    "Regime",
    "SpectralPeak",
    "Spectrum",
    "SpectrumSettings",
    "StrobeClock",
    "StrobeSamples",
    "ZeroOneResult",
    "amplitude_spectrum",
    "basins_of_attraction",
    "bifurcation_from_recording",
    "classify_regime",
    "clock_from_drive",
    "clock_from_tach",
    "continue_along",
    "delay_embed",
    "delayed_map",
    "false_nearest_neighbours",
    "flow_lyapunov",
    "fnn_dimension",
    "harmonic_label",
    "identify_attractors",
    "judge_record_regime",
    "judge_regime",
    "map_lyapunov",
    "model_at_beta",
    "model_lyapunov_spectrum",
    "mutual_information",
    "mutual_information_delay",
    "plot_basins",
    "plot_bifurcation",
    "poincare_from_phase",
    "poincare_from_pulses",
    "recurrence_distances",
    "rosenstein_lyapunov",
    "run_poincare",
    "simulate_bifurcation",
    "smoothed_derivative",
    "strobe_record",
    "strobe_samples",
    "zero_one_test",
]
