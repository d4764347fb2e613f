"""A forced record's analysis report with two competing explanations whose difference is
known analytically: both put the barrier 0.1 rad from the hanging position, one with the
paper's Hertz contact (``barrier_offset``), one with a soft delta^2.5 law
(``contact_exponent``).  Their equations are the same wherever the pendulum stays clear of
the barrier, so they predict the same record at a drive too weak to reach it, and
different ones where it impacts.

A drive of table amplitude A at frequency f gives the linearised pendulum (from rest) a
steady swing ``theta_ss = beta r^2 / sqrt((1 - r^2)^2 + (2 zeta r)^2)`` (beta = A / L, r =
f / f_n), and a transient whose free part is no larger for r < 1, so the swing stays under
``2 theta_ss`` throughout: :func:`reaches_barrier` tells the settings apart before any
simulation.

A report that names nothing (:func:`nothing_named_report`) keeps the baseline, here the
rig's Hertz barrier at the same gap, held there: against the soft law it ranks best, the
same oracle tells where they differ.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from analysis.model import RigParameters

GAP_RAD = 0.1
NOISE_RAD = 1e-3
FS_HZ = 500.0
ZETA = 0.05  # damped enough that a step settles in 10 s
RIG = RigParameters(zeta=ZETA)
OMEGA = math.sqrt(RIG.g_m_s2 / RIG.L_m)


def _estimate(value: float, relative_ci: float | None = None) -> dict[str, Any]:
    out: dict[str, Any] = {"value": value}
    if relative_ci is not None:
        out["ci95"] = [value * (1 - relative_ci), value * (1 + relative_ci)]
    return out


BIC_MARGIN = 10.0  # the report's policy.bic_margin
BASELINE_RMS_RAD = 1.02 * NOISE_RAD


def contact_pair_report(*, named: str = "barrier_offset", indistinct: bool = True,
                        ranked: bool = True) -> dict[str, Any]:
    """The report (the keys suggest reads, as ``impact-rig analyze --json`` writes them);
    ``ranked=False``: no candidate ranked at all."""
    rig_values = {"omega_rad_s": _estimate(OMEGA, 1e-3), "zeta": _estimate(ZETA, 0.02),
                  "K_N_per_m1.5": _estimate(RIG.K_N_per_m1_5, 0.05),
                  "mu0_s_per_m": _estimate(RIG.mu0_s_per_m, 0.1)}
    hertz = {**rig_values, "theta_b_rad": _estimate(GAP_RAD, 0.01)}
    soft = {**rig_values, "theta_b_rad": _estimate(GAP_RAD), "n": _estimate(2.5, 0.02),
            "K_n": _estimate(1e7)}
    baseline = {**rig_values, "theta_b_rad": {"value": GAP_RAD, "held": True}}
    return {
        "experiment": "forced",
        "rig": RIG.as_dict(),
        "sample_rate_hz": FS_HZ,
        "noise_rad": NOISE_RAD,
        "drive": {"stated": {"frequency_hz": 2.0, "amplitude_m": 1e-3},
                  "frequency_hz": 2.0},
        "cause": named,
        "indistinct": [{"causes": ["barrier_offset", "contact_exponent"],
                        "correlation": 0.97, "why": "they change the model's curve alike"}]
        if indistinct else [],
        "ranking": [
            {"cause": "barrier_offset", "score": 120.0, "implausible": None,
             "model": {"causes": ["barrier_offset"], "parameters": hertz}},
            {"cause": "contact_exponent", "score": 118.0, "implausible": None,
             "model": {"causes": ["contact_exponent"], "parameters": soft}},
        ] if ranked else [],
        "baseline": {"parameters": baseline, "rms_residual": BASELINE_RMS_RAD},
        "policy": {"bic_margin": {"value": BIC_MARGIN, "why": "as analyze's default"}},
    }


def nothing_named_report(*, second_score: float = -20.0) -> dict[str, Any]:
    """The report of a record that named no cause: the soft contact law ranked best (score
    5, under the BIC margin), the barrier offset second at ``second_score``."""
    report = contact_pair_report(named="none", indistinct=False)
    soft, hertz = report["ranking"][1], report["ranking"][0]
    report["ranking"] = [soft | {"score": 5.0}, hertz | {"score": second_score}]
    return report


def write_report(path: Path, report: dict[str, Any] | None = None, **kwargs: Any) -> Path:
    """``report`` (default: :func:`contact_pair_report` of ``kwargs``) as a JSON file."""
    content = report if report is not None else contact_pair_report(**kwargs)
    path.write_text(json.dumps(content, indent=2), encoding="utf-8")
    return path


def steady_swing_rad(frequency_hz: float, amplitude_m: float) -> float:
    """The linearised steady swing at a drive (the module's docstring)."""
    r = 2 * math.pi * frequency_hz / OMEGA
    beta = amplitude_m / RIG.L_m
    return beta * r * r / math.sqrt((1 - r * r) ** 2 + (2 * ZETA * r) ** 2)


def reaches_barrier(frequency_hz: float, amplitude_m: float) -> bool | None:
    """True when the steady swing passes the barrier, False when even the transient from
    rest (under twice the steady swing, for a drive below resonance) stays clear of it,
    None in between."""
    assert 2 * math.pi * frequency_hz < OMEGA, "the bound holds below resonance"
    swing = steady_swing_rad(frequency_hz, amplitude_m)
    if swing > GAP_RAD:
        return True
    if 2 * swing < GAP_RAD:
        return False
    return None
