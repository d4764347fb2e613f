"""The limits dataclass refuses bad configuration with messages that name the key."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.limits import LimitsConfigError, ShakerLimits


def test_limits_from_a_config_table() -> None:
    limits = ShakerLimits.from_mapping({"max_amplitude_m": 0.004, "max_frequency_hz": 30})
    assert limits.max_amplitude_m == 0.004 and limits.max_frequency_hz == 30


@pytest.mark.parametrize(
    ("values", "words"),
    [
        ({"max_amplitud_m": 0.004}, "unknown shaker limit"),
        ({"max_amplitude_m": "big"}, "max_amplitude_m"),
        ({"max_amplitude_m": -0.001}, "max_amplitude_m"),
        ({"max_frequency_hz": 500.0}, "amplifier's own range"),
        ({"min_frequency_hz": 20.0, "max_frequency_hz": 10.0}, "min_frequency_hz"),
        ({"min_ramp_rate_m_s": 0.0}, "min_ramp_rate_m_s"),
        ({"min_ramp_rate_m_s": 4e-7}, "resolution"),  # would be sent as 0 um/s
    ],
)
def test_bad_limits_are_refused_by_name(values: dict, words: str) -> None:
    with pytest.raises(LimitsConfigError, match=words) as error:
        ShakerLimits.from_mapping(values, source="lab.toml [shaker.limits]")
    assert "lab.toml" in str(error.value)


def test_numpy_numbers_are_numbers() -> None:
    limits = ShakerLimits(max_frequency_hz=np.int64(40))
    assert limits.check("frequency_hz", np.int64(12), 0.0, 40.0, "Hz") == 12.0
    assert limits.check("frequency_hz", np.float32(12.5), 0.0, 40.0, "Hz") == 12.5
