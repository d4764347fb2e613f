"""Values at the boundary: a NaN in a CSV is refused with its line, not dropped; lost samples
are counted per stream, the tach's lost indices apart."""

from __future__ import annotations

import time

import pytest

from rig.cli import main
from rig.engine import AcquisitionEngine
from tests.rig.streams import CounterStream, TachStream


@pytest.fixture(scope="module")
def decay_csv(tmp_path_factory):
    """A simulated free decay in the exchange format (CSV and its JSON sidecar)."""
    out = tmp_path_factory.mktemp("decay") / "decay.csv"
    assert main(["simulate", "--experiment", "free_decay", "--theta0", "0.1", "--duration",
                 "2", "--fs", "200", "--out", str(out), "--quiet"]) == 0  # fmt: skip
    return out


@pytest.mark.parametrize(
    ("column", "text", "said"),
    [(1, "NaN", "angle_rad is nan"), (1, "-inf", "angle_rad is -inf"),
     (0, "nan", "time_s is not a finite number")],
)
def test_analyze_refuses_a_csv_with_a_non_finite_value_naming_the_line(
    decay_csv, tmp_path, capsys, column, text, said
):
    lines = decay_csv.read_text().splitlines()
    fields = lines[10].split(",")
    fields[column] = text
    lines[10] = ",".join(fields)
    damaged = tmp_path / "decay.csv"
    damaged.write_text("\n".join(lines) + "\n")
    damaged.with_suffix(".json").write_text(decay_csv.with_suffix(".json").read_text())
    capsys.readouterr()
    assert main(["analyze", str(damaged), "--workers", "1", "--quiet"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("impact-rig analyze: error: ") and len(error.splitlines()) == 1
    assert f"{damaged}: line 11: {said}" in error
    assert not list(tmp_path.glob("*report*")) and not (tmp_path / "decay.md").exists()


class LossyTach(TachStream):
    """A tach stream whose blocks skip ``lost`` covered indices at ``at``."""

    def __init__(self, at: int, lost: int, **kwargs) -> None:
        super().__init__(**kwargs)
        self.at, self.lost = at, lost

    def read(self, timeout_s: float = 0.1):
        if self.next_index == self.at:
            self.next_index += self.lost
        return super().read(timeout_s)


def test_lost_samples_are_counted_per_stream_and_the_tach_apart():
    angle = CounterStream("angle", total=6_000, gaps={1_000: 40}, block=250)
    table = CounterStream("table", total=6_000, gaps={3_000: 7}, block=250, gain=2e-3)
    tach = LossyTach(2_000, 500, total=6_000, block=250)
    engine = AcquisitionEngine([angle, table, tach])
    engine.start()
    # the engine's own state, not a delay after the streams: every stream taken in to its end
    deadline = time.monotonic() + 20
    while any(c.end_index != 6_000 for c in engine.stats().channels.values()):
        assert time.monotonic() < deadline, "the engine did not take in every stream"
        time.sleep(0.02)
    engine.stop()
    stats = engine.stats()
    assert stats.lost_per_stream == {"angle": 40, "table": 7, "tach": 500}
    assert stats.samples_lost == 47  # the tach's 500 are the same board samples again
