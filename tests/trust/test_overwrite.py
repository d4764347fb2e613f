"""No command writes over an existing file without --overwrite, and none over its own input."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

from rig.cli import main
from tests.trust.conftest import run_cli


def _decay_csv(folder):
    out = folder / "decay.csv"
    done = run_cli("simulate", "--experiment", "free_decay", "--theta0", "0.1", "--duration",
                   "2", "--fs", "200", "--out", str(out))
    assert done.returncode == 0, done.stderr
    return out


def _refused(done, path, why):
    assert done.returncode == 2, done.stdout
    assert "Traceback" not in done.stderr and str(path) in done.stderr and why in done.stderr


def _in_process(capsys, *args: str) -> subprocess.CompletedProcess[str]:
    """``impact-rig ARGS`` run by this process (as fast as a refusal should be)."""
    capsys.readouterr()
    status = main(list(args))
    captured = capsys.readouterr()
    return subprocess.CompletedProcess(args, status, captured.out, captured.err)


def test_analyze_never_writes_its_report_over_its_input(tmp_path, capsys):
    csv = _decay_csv(tmp_path)
    before = csv.read_bytes()
    for flags in ([], ["--overwrite"]):
        done = _in_process(capsys, "analyze", str(csv), "--json", str(csv), *flags)
        _refused(done, csv, "is an input of this command")
        done = _in_process(capsys, "analyze", str(csv), "--report", str(tmp_path), *flags)
        _refused(done, tmp_path / "decay.json", "is an input of this command")  # the sidecar
    assert csv.read_bytes() == before


def test_analyze_refuses_an_existing_page_of_its_report_before_analysing(tmp_path, capsys):
    record = tmp_path / "decay.h5"
    record.write_bytes(b"read only after the outputs were checked")
    folder = tmp_path / "report"
    folder.mkdir()
    page = folder / "decay.html"
    page.write_text("an earlier page")
    done = _in_process(capsys, "analyze", str(record), "--report", str(folder))
    _refused(done, page, "already exists")
    assert page.read_text() == "an earlier page"
    assert sorted(folder.iterdir()) == [page]


def test_identify_never_writes_over_the_sidecar_it_reads(tmp_path):
    csv = _decay_csv(tmp_path)
    sidecar = csv.with_suffix(".json")
    before = sidecar.read_bytes()
    done = run_cli("identify", str(csv), "--json", str(sidecar), "--overwrite")
    _refused(done, sidecar, "is an input of this command")
    assert sidecar.read_bytes() == before
    existing = tmp_path / "params.json"
    existing.write_text("{}")
    _refused(run_cli("identify", str(csv), "--json", str(existing)), existing, "already exists")
    assert existing.read_text() == "{}"


def test_simulate_and_export_refuse_an_existing_output(recording, tmp_path):
    h5 = tmp_path / "existing.h5"
    shutil.copy(recording, h5)
    before = h5.read_bytes()
    _refused(run_cli("simulate", "--out", str(h5)), h5, "already exists")
    assert h5.read_bytes() == before
    csv = tmp_path / "run.csv"
    csv.write_text("keep me")
    _refused(run_cli("export", str(recording), "--out", str(csv)), csv, "already exists")
    assert csv.read_text() == "keep me"


def test_replay_and_repair_never_write_over_the_recording_they_read(recording, tmp_path):
    h5 = tmp_path / "run.h5"
    shutil.copy(recording, h5)
    before = h5.read_bytes()
    for command in (["replay", str(h5), "--fast", "--record", str(h5)],
                    ["repair", str(h5), "--out", str(h5)]):
        _refused(run_cli(*command, "--overwrite"), h5, "is an input of this command")
    assert h5.read_bytes() == before


def test_record_refuses_an_existing_log_beside_the_recording(tmp_path):
    log = tmp_path / "run.log"
    log.write_text("an earlier run's log")
    done = run_cli("record", "--sim", "--duration", "1", "--out", str(tmp_path / "run.h5"))
    _refused(done, log, "already exists")
    assert not (tmp_path / "run.h5").exists()


def test_a_file_is_never_written_under_another_formats_extension(recording, tmp_path, capsys):
    """A recording (HDF5) saved as run.csv would be read by the next program as a table:
    every command that writes one refuses the name, before anything runs."""
    csv = tmp_path / "run.csv"
    refusals = [
        ("record", "--sim", "--duration", "1", "--out", str(csv)),
        ("replay", str(recording), "--fast", "--record", str(csv)),
        ("repair", str(recording), "--out", str(csv)),
        ("export", str(recording), "--out", str(tmp_path / "run.h5")),
        ("map", "basins", "--f-drive-hz", "10", "--beta", "0.05", "--vary", "theta0=0:0.1:2",
         "--vary", "omega0=0:0.1:2", "--out", str(csv)),
        ("simulate", "--out", str(tmp_path / "run.txt")),
    ]
    for args in refusals:
        _refused(_in_process(capsys, *args), Path(args[-1]), "is written as")
    assert not csv.exists() and not (tmp_path / "run.h5").exists()
