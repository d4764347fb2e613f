"""Role drivers: calibrations validated at construction, laser range flags, tachometer edges
across gaps, a role nobody reads, and a stream fed by the virtual rig (both backends)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.sensors import (
    FLAG_AT_RAIL,
    FLAG_OUT_OF_RANGE,
    AnalogVoltageInput,
    LaserCalibration,
    LaserDisplacementSensor,
    PotentiometerAngleSensor,
    PotentiometerCalibration,
    Tachometer,
    TachometerCalibration,
)
from hardware_sim.daq_faults import CORRUPT_CRC
from hardware_sim.sample_source import CounterSource, expected_table_counts
from hardware_sim.virtual_rig import VirtualRig, VirtualRigSettings, compile_physics
from tests.daq.conftest import EMULATED_BACKENDS
from tests.daq.test_stream import read_past_faults, read_until

# Sources other than the counter exist only beside the Python firmware model.
python_backends_only = pytest.mark.parametrize("backend_kind", EMULATED_BACKENDS, indirect=True)


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: PotentiometerCalibration(gain_rad_per_v=0.0), "gain_rad_per_v"),
        (lambda: PotentiometerCalibration(offset_v=math.nan), "offset_v"),
        (lambda: PotentiometerCalibration(linearity=(0.1, math.inf)), r"linearity\[1\]"),
        (lambda: LaserCalibration(unit="mm"), "unit"),
        (lambda: LaserCalibration(m_per_unit=0.0), "m_per_unit"),
        (lambda: LaserCalibration(measuring_range_m=(0.05, -0.05)), "measuring_range_m"),
        (lambda: LaserCalibration(measuring_range_m=(0.0,)), "measuring_range_m"),
        (lambda: LaserCalibration(zero_m="0"), "zero_m"),
        (lambda: TachometerCalibration(line=16), "line"),
    ],
)
def test_calibration_errors_name_the_field(make, field):
    with pytest.raises(ValueError, match=field):
        make()


def test_calibrations_from_a_file_take_lists_and_numpy_numbers():
    pot = PotentiometerCalibration(offset_v=np.float32(0.5), linearity=[0.1, np.int64(0)])
    assert pot.linearity == (0.1, 0) and hash(pot)
    laser = LaserCalibration(measuring_range_m=[-0.02, 0.02])
    assert laser.measuring_range_m == (-0.02, 0.02) and hash(laser)


class PatternSource:
    """Repeats fixed table counts; angle is 0, tach low.  Enough to check per-sample flags."""

    def __init__(self, table_counts: list[int]) -> None:
        self.pattern = np.asarray(table_counts, dtype=np.int64)
        self.sample_rate_hz = 1000.0
        self.next_index = 0

    def configure(self, sample_rate_hz: float) -> None:
        self.sample_rate_hz = sample_rate_hz

    def generate(self, n: int) -> dict[str, np.ndarray]:
        index = np.arange(self.next_index, self.next_index + n)
        self.next_index += n
        return {
            "angle": np.zeros(n, dtype=np.int64),
            "table": self.pattern[index % self.pattern.size],
            "tach": np.zeros(n, dtype=bool),
        }


@python_backends_only
def test_laser_flags_rail_and_out_of_range_samples(make_board):
    # +-10 mm measuring range at 5 mm/V: +-2 V, i.e. +-6553.6 counts.
    counts = [0, 6000, 7000, -7000, 32767, -32768, 100, 40000]  # 40000: the ADC saturates
    board = make_board(PatternSource(counts))
    calibration = LaserCalibration(m_per_unit=0.005, measuring_range_m=(-0.01, 0.01))
    laser = LaserDisplacementSensor(board, 1, calibration)
    laser.start()
    blocks = read_until(laser, 800)
    raw = np.concatenate([b.raw for b in blocks])
    flags = np.concatenate([b.flags for b in blocks])
    expected_raw = np.clip(np.array(counts * 100), -32768, 32767)
    assert np.array_equal(raw[:800], expected_raw)
    oor, rail = FLAG_OUT_OF_RANGE, FLAG_AT_RAIL
    expected_flags = np.array([0, 0, oor, oor, oor | rail, oor | rail, 0, oor | rail] * 100)
    assert np.array_equal(flags[:800], expected_flags)
    values = np.concatenate([b.values for b in blocks])
    np.testing.assert_allclose(values[:800], 0.005 * expected_raw * 10.0 / 32768)


@python_backends_only
def test_laser_in_count_units_skips_the_volts(make_board):
    board = make_board(PatternSource([-1200, 0, 1200]))
    calibration = LaserCalibration(
        zero_m=0.002, m_per_unit=1e-5, unit="count", measuring_range_m=(-0.05, 0.05)
    )
    laser = LaserDisplacementSensor(board, 1, calibration)
    laser.start()
    block = read_until(laser, 300)[0]
    np.testing.assert_allclose(block.values, 0.002 + 1e-5 * block.raw.astype(float))
    assert not block.flags.any()


def test_spare_input_reads_volts(make_board):
    board = make_board(CounterSource(), analog_channels=(0, 1))
    spare = AnalogVoltageInput(board, 0)
    spare.start()
    block = read_until(spare, 500)[0]
    assert spare.channel == "ai0" and spare.unit == "V"
    np.testing.assert_allclose(block.values, block.raw * 10.0 / 32768)


def test_tach_edge_right_after_a_gap_is_not_guessed(make_board, make_faults):
    # Every edge sits on the first sample of a frame (200 samples per frame at 20 kHz).
    source = CounterSource(tach_period=400, tach_width=100, tach_phase=0)
    faults = make_faults()
    board = make_board(source, faults=faults)
    tach = Tachometer(board)
    tach.start()
    blocks = read_until(tach, 2_000)
    faults.corrupt_crc(frames=3)
    blocks = read_past_faults(tach, faults, {CORRUPT_CRC: 3}, blocks)
    assert any(b.lost_before for b in blocks)
    edges = np.concatenate([b.edge_indices for b in blocks])
    expected = []
    for block in blocks:
        # An edge needs its previous sample: the first sample after a gap cannot be one.
        start = block.first_index + (1 if block.lost_before else 0)
        expected.append(source.expected_rising_edges(max(start, 0), block.end_index))
    assert np.array_equal(edges, np.concatenate(expected))


def test_a_role_nobody_reads_loses_its_oldest_samples_and_says_how_many(make_board):
    board = make_board(CounterSource(), role_buffer_s=0.5)  # 10 000 samples at 20 kHz
    angle = PotentiometerAngleSensor(board, 0, PotentiometerCalibration())
    idle = AnalogVoltageInput(board, 1)
    board.start_roles(angle, idle)
    read_until(angle, 40_000)
    block = idle.read(1.0)
    assert block is not None
    assert block.lost_before > 0
    assert block.first_index == block.lost_before  # everything before it was dropped, counted
    assert idle.status().samples_lost == block.lost_before
    assert angle.status().samples_lost == 0
    assert np.array_equal(
        block.raw, expected_table_counts(np.arange(block.first_index, block.end_index))
    )


@python_backends_only
def test_stream_from_the_virtual_rig_matches_the_rig_itself(make_board):
    settings = VirtualRigSettings(theta0_rad=0.2, sample_rate_hz=2000.0)
    compile_physics(settings)  # before the board's clock runs
    board = make_board(VirtualRig(settings), sample_rate_hz=2000.0)
    zero_counts, rad_per_count = settings.angle_counts_to_rad()
    volts_per_count = 10.0 / 32768
    calibration = PotentiometerCalibration(
        offset_v=zero_counts * volts_per_count, gain_rad_per_v=rad_per_count / volts_per_count
    )
    angle = PotentiometerAngleSensor(board, 0, calibration)
    angle.start()
    blocks = read_until(angle, 1_000, timeout_s=30.0)
    assert all(b.lost_before == 0 for b in blocks) and blocks[0].first_index == 0
    raw = np.concatenate([b.raw for b in blocks])
    # Oracle: an identical rig asked directly, frame by frame (20 samples per frame at 2 kHz).
    twin = VirtualRig(settings)
    direct = np.concatenate([twin.generate(20)["angle"] for _ in range(raw.size // 20)])
    assert np.array_equal(raw[: direct.size], np.clip(direct, -32768, 32767))
    values = np.concatenate([b.values for b in blocks])
    assert values[0] == pytest.approx(0.2, abs=rad_per_count)  # released at 0.2 rad
