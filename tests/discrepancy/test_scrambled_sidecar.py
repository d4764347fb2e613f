"""The analysis reads only what the exchange format documents (docs/MODEL.md section 5): a
record written again with a misleading file name, notes naming a wrong cause, extra sidecar
keys carrying a false "truth", undocumented rig keys and an extra CSV column gets the same
report as the plain file.

The record comes from the independent reference simulator (``reference``: scipy
DOP853, not the project's integrator): a short free decay read through a sensor with a
linearity error, so two analyses cost seconds.
"""

from __future__ import annotations

import dataclasses
import json

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from reference.free_decays import FS_HZ, draw_free_decay

SEED = 8905
TRUE_CAUSE = "sensor_nonlinearity"
RECORD_S = 15.0  # 34 swings: the sensor's cubic shows, and the analysis takes seconds
# what a record's report echoes of its file, not what it found in it
ECHOES = ("source", "notes", "timings_s")

# everything a lab would not know, or would write down wrongly, and the format does not
# document as an input of the analysis: each says dry friction (the true cause is the
# sensor's cubic), or gives the analysis false sizes
MISLEADING_NOTES = ("dry friction at the pivot, Tc_N_m = 0.0021 (impact-rig simulate "
                    "--cause coulomb_friction); sensor calibrated, linear to 0.01 %")
MISLEADING_KEYS = {
    "cause": "coulomb_friction",
    "causes": ["coulomb_friction", "quadratic_drag"],
    "simulation": {"extensions": {"coulomb_friction": {"Tc_N_m": 0.0021}},
                   "rig": {"L_m": 0.031, "zeta": 0.05}},
    "truth": {"cause": "coulomb_friction", "k3": 0.0, "offset_rad": 0.1},
    "calibrations": {"angle": {"gain_rad_per_count": 1e-3, "k3": 0.0, "offset_rad": 0.1}},
    "source": "friction_decay.h5",
    "provenance": {"software": "impact-rig 0.1.0", "command": "impact-rig simulate --cause "
                   "coulomb_friction --out friction_decay.csv"},
    "experiment_details": {"kind": "impact_decay"},
}
# keys inside "rig" beyond m_kg, l_m, R_m, g and L_m: a false pendulum the loader must drop
UNDOCUMENTED_RIG_KEYS = {"zeta": 0.05, "Tc_N_m": 0.0021, "k3": 0.0, "omega_rad_s": 20.0}


def _scrambled_copy(plain_csv, directory):
    """The plain record's samples in ``directory/friction_decay.csv``, with an extra column
    (the format ignores unknown columns) and a sidecar written by hand, keys reordered."""
    lines = plain_csv.read_text().splitlines()
    assert lines[0] == "time_s,angle_rad"
    path = directory / "friction_decay.csv"
    rows = [f"{line},0.0021" for line in lines[1:]]
    path.write_text("\n".join(["time_s,angle_rad,Tc_N_m", *rows]) + "\n")
    plain = json.loads(plain_csv.with_suffix(".json").read_text())
    sidecar = {**MISLEADING_KEYS, "notes": MISLEADING_NOTES,
               "rig": {**UNDOCUMENTED_RIG_KEYS, **plain["rig"]},
               "experiment": plain["experiment"], "format_version": plain["format_version"]}
    path.with_suffix(".json").write_text(json.dumps(sidecar, indent=1))
    return path


def _findings(report: dict) -> str:
    """The report without its echoes, as text (NaN equals NaN there, as it should here)."""
    return json.dumps({k: v for k, v in report.items() if k not in ECHOES}, sort_keys=True,
                      default=str)


def test_notes_context_file_name_and_undocumented_fields_change_nothing(tmp_path):
    decay = draw_free_decay(SEED, (TRUE_CAUSE,))
    n = round(RECORD_S * FS_HZ)
    decay = dataclasses.replace(decay, t_s=decay.t_s[:n], angle_rad=decay.angle_rad[:n])
    (tmp_path / "plain").mkdir()
    (tmp_path / "scrambled").mkdir()
    plain_csv = decay.write(tmp_path / "plain", name="record")
    scrambled_csv = _scrambled_copy(plain_csv, tmp_path / "scrambled")

    scrambled_record = load_record(scrambled_csv)
    # the misleading words do reach the record (so the test is not vacuous) ...
    assert "dry friction" in scrambled_record.notes
    assert scrambled_record.context["cause"] == "coulomb_friction"
    plain = analyze_record(load_record(plain_csv), workers=2).as_json()
    scrambled = analyze_record(scrambled_record, workers=2).as_json()

    # ... and the plain record's report is right, so "the same" means the same right answer
    assert plain["cause"] == TRUE_CAUSE, plain["ranking"][:3]
    assert [c["cause"] for c in plain["causes"]] == [TRUE_CAUSE]
    # the same report, to the last digit: causes, ranking, values and intervals, gain
    assert scrambled["cause"] == plain["cause"]
    assert scrambled["causes"] == plain["causes"]
    assert scrambled["ranking"] == plain["ranking"]
    assert scrambled["baseline"]["parameters"] == plain["baseline"]["parameters"]
    assert scrambled["extended"]["parameters"] == plain["extended"]["parameters"]
    assert _findings(scrambled) == _findings(plain)
