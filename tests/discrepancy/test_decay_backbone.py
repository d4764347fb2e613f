"""A free decay whose backbone no named cause gives is flagged, and says why.

The decays are drawn by the reference simulator (``tests/reference``: scipy DOP853, not the
project's integrator): a pendulum with a cubic hairspring at its pivot, an effect outside
the registry whose stiffening changes how the frequency follows the swing, and a clean
pendulum.  The analysis sees one CSV and its JSON sidecar, as a lab writes them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from analysis.discrepancy import analyze_record
from analysis.exchange import ExchangeMeta, ExchangeRecord, write_exchange
from analysis.record_loaders import load_record
from tests.reference.simulator import Pendulum, TableMotion, simulate_reference

FS_HZ = 500.0
DURATION_S = 40.0
G = 9.81


def _free_decay(seed: int, spring: int, directory: Path) -> tuple[Path, float]:
    """A seeded free decay written as CSV + JSON, with a hairspring that stiffens (``spring``
    1) or softens (-1) the pivot, or none (0); returns its path and the spring's c3."""
    rng = np.random.default_rng(seed)
    length = rng.uniform(0.040, 0.056)
    omega = math.sqrt(G / length)
    amplitude = rng.uniform(0.25, 0.40)
    # at the swing's peak the hairspring adds (or takes) 5-12 % of gravity's restoring
    # acceleration
    c3 = spring * rng.uniform(0.05, 0.12) * omega**2 / amplitude**2
    pendulum = Pendulum(m_kg=0.0326, l_m=0.050, L_m=length, zeta=rng.uniform(0.003, 0.008),
                        K_n=1.0e6, mu0_s_per_m=0.8, g_m_s2=G, barrier=False, c3_per_s2=c3)
    t = np.arange(round(DURATION_S * FS_HZ)) / FS_HZ
    run = simulate_reference(pendulum, TableMotion(), amplitude, 0.0, t)
    noise = rng.uniform(3e-4, 1e-3)
    angle = run.theta_rad + rng.normal(0.0, noise, t.size)
    path = directory / "decay.csv"
    meta = ExchangeMeta(experiment="free_decay",
                        rig={"m_kg": 0.0326, "l_m": 0.050, "R_m": 0.0095, "g": G})
    write_exchange(path, ExchangeRecord(time_s=t, angle_rad=angle, meta=meta))
    return path, c3


@pytest.mark.parametrize(("seed", "spring"), [(8801, 1), (8802, -1)],
                         ids=["stiffening", "softening"])
def test_a_hairspring_shows_as_the_decays_backbone_and_leaves_it_unexplained(
    seed, spring, tmp_path
):
    path, c3 = _free_decay(seed, spring, tmp_path)
    report = analyze_record(load_record(path), workers=2).as_json()
    backbone = [f for f in report["residual_findings"] if f["kind"] == "backbone"]
    assert report["unexplained"], report["residual_findings"]
    assert len(backbone) == 1, report["residual_findings"]
    # a stiffening spring (c3 > 0) raises the frequency at large swings, against gravity's
    # softening: the record's frequency rises less than the model's as the swing decays
    # (mismatch < 0), and the other way for a spring that softens
    assert math.copysign(1.0, backbone[0]["mismatch"]) == -math.copysign(1.0, c3)


def test_a_clean_decay_has_no_backbone_finding(tmp_path):
    path, _ = _free_decay(8803, 0, tmp_path)
    report = analyze_record(load_record(path), workers=2).as_json()
    assert report["cause"] == "none"
    assert not [f for f in report["residual_findings"] if f["kind"] == "backbone"]
