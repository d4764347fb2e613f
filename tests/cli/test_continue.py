"""``impact-rig continue``: the file and figure it writes, and its errors."""

from __future__ import annotations

import argparse
import json

import h5py
import numpy as np
import pytest

from rig.cli import CommandError, add_common_options
from rig.commands import continuation


def _run(*argv: str) -> int:
    # the command's own parser, so the test needs no reinstalled entry point
    parser = argparse.ArgumentParser(prog="impact-rig")
    continuation.register(parser.add_subparsers(dest="command"))
    for command in parser._subparsers._group_actions[0].choices.values():
        add_common_options(command)
    args = parser.parse_args(argv)
    return args.func(args)


def test_continue_writes_branches_events_and_figure(tmp_path):
    out = tmp_path / "gap.h5"
    code = _run("continue", "--f-drive-hz", "10", "--vary", "beta=0.01:0.0195",
                "--param", "theta_b_rad=0.02", "--from-state", "0,0", "--max-period", "1",
                "--out", str(out), "--quiet")
    assert code == 0
    assert out.with_suffix(".png").stat().st_size > 10_000
    with h5py.File(out) as handle:
        assert handle.attrs["parameter"] == "beta"
        assert "command_line" in json.loads(handle.attrs["provenance_json"])
        assert handle.attrs["jacobians"].startswith("forward sensitivities")
        branch = handle["branches/0"]
        assert branch.attrs["periods"] == 1
        beta = branch["parameter"][:]
        assert beta[0] == pytest.approx(0.01) and beta[-1] == pytest.approx(0.0195)
        stable = branch["stable"][:].astype(bool)
        assert stable[0] and not stable[-1]
        kinds = [k.decode() if isinstance(k, bytes) else k for k in handle["events/kind"][:]]
        assert sorted(kinds) == ["grazing", "period_doubling"]
        real, imag = handle["events/multipliers_real"][:], handle["events/multipliers_imag"][:]
        moduli = np.hypot(real, imag)
        pd = kinds.index("period_doubling")
        assert real[pd, 0] == pytest.approx(-1.0, abs=1e-6)
        assert moduli[pd, 1] < 1.0


def test_continue_refuses_existing_output_and_names_failed_newton(tmp_path):
    out = tmp_path / "x.h5"
    out.write_bytes(b"")
    with pytest.raises(Exception, match="already exists"):
        _run("continue", "--f-drive-hz", "10", "--vary", "beta=0.01:0.02", "--out", str(out))
    with pytest.raises(CommandError, match="NAME=START:STOP"):
        _run("continue", "--f-drive-hz", "10", "--vary", "beta=0.01", "--out",
             str(tmp_path / "y.h5"))
    # case (g)'s period-1 orbit from a state far off, with the pendulum nearly over the top
    with pytest.raises(CommandError, match=r"beta = 0\.022"):
        _run("continue", "--case", "g", "--vary", "beta=0.022:0.03", "--from-state", "3,40",
             "--out", str(tmp_path / "z.h5"))


def test_continue_draws_a_brute_force_diagram_under_the_branches(tmp_path):
    out = tmp_path / "g.h5"
    code = _run("continue", "--case", "g", "--vary", "beta=0.02:0.03", "--period", "2",
                "--from-state=-0.12,-0.7", "--brute-force", "3", "--brute-force-periods",
                "50", "--out", str(out), "--quiet")
    assert code == 0
    with h5py.File(out) as handle:
        overlays = json.loads(handle.attrs["overlays_json"])
        assert overlays[0]["directions"] == ["up", "down"]
        assert overlays[0]["brute_force"]["values"] == 3
        section = handle["branches/0/section_theta"][:]
        assert section.shape == (handle["branches/0/parameter"].size, 2)
    with pytest.raises(CommandError, match=r"--overlay .*no such file"):
        _run("continue", "--case", "g", "--vary", "beta=0.02:0.03", "--overlay",
             str(tmp_path / "missing.h5"), "--out", str(tmp_path / "m.h5"))
