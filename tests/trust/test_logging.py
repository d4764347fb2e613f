"""Progress goes through the standard logging: shown by default, silenced by --quiet, kept
in the log file beside a recording; --verbose shows the debug records too."""

from __future__ import annotations

import logging

import pytest

from rig.cli import main


def _simulate(tmp_path, *flags):
    out = tmp_path / f"decay{len(list(tmp_path.iterdir()))}.csv"
    return main(["simulate", "--experiment", "free_decay", "--theta0", "0.1", "--duration", "1",
                 "--fs", "100", "--out", str(out), *flags])  # fmt: skip


@pytest.mark.parametrize(
    ("flags", "progress_shown", "debug_shown"),
    [([], True, False), (["--quiet"], False, False), (["--verbose"], True, True)],
)
def test_quiet_silences_progress_and_verbose_adds_debug(
    tmp_path, capsys, flags, progress_shown, debug_shown
):
    capsys.readouterr()
    assert _simulate(tmp_path, *flags) == 0
    logging.getLogger("impact_rig.test").debug("a debug record")
    logging.getLogger("impact_rig.test").info("an info record")
    error = capsys.readouterr().err
    assert ("simulating free_decay" in error) is progress_shown
    assert ("a debug record" in error) is debug_shown
    assert ("an info record" in error) is debug_shown  # only progress is INFO by default
    if "--quiet" in flags:
        assert error == ""


def test_the_log_beside_a_recording_keeps_its_progress(recording):
    log = recording.with_suffix(".log").read_text()
    assert "opening the devices of the virtual rig" in log  # recorded with --quiet
    assert "recording: 1/2 s" in log and log.rstrip().endswith("completed")
