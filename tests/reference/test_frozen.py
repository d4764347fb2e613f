"""The frozen reference draws (``reference/frozen.py``): current for the code, exact
on the way back, and the same record whether drawn live or restored."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from reference import frozen
from reference.forced_records import (
    ForcedCase,
    draw_forced_case,
    generate,
    true_pendulum,
    true_table,
)
from reference.unregistered import EFFECTS


def test_the_store_is_current_for_the_code_that_draws():
    """Fails after a change to the reference generator: the suite then draws every case
    live (right, but slow) until the store is refreshed."""
    stale = frozen.stale_modules()
    assert not stale, (f"reference/draws.json is stale for {', '.join(stale)}: run "
                       "`python -m reference.frozen --refresh` and commit the store")
    store = json.loads(frozen.STORE.read_text(encoding="utf-8"))
    assert store["draws"], "the store holds no draw"
    for key in store["draws"]:
        assert key.split(".")[0] in store["fingerprints"], key


def _cheapest_stored_forced_key() -> str:
    store = json.loads(frozen.STORE.read_text(encoding="utf-8"))
    keys = [k for k in store["draws"] if k.startswith("forced_records.draw_forced_case")]
    def cost(key: str) -> tuple:  # a clean record asks no sizing; no regime, no sub-seeds
        arguments = frozen._split_key(key)[1]
        return (arguments["cause"] != "none", arguments["regime"] is not None,
                arguments["duration_s"], key)

    return min(keys, key=cost)


def test_a_stored_draw_is_what_the_code_draws_live_to_the_last_bit():
    key = _cheapest_stored_forced_key()
    _, arguments = frozen._split_key(key)
    live = draw_forced_case.live(**arguments)
    restored = draw_forced_case(**arguments)
    assert frozen._encode(live) == frozen._encode(restored) == frozen._store()["draws"][key]
    a, b = generate(live), generate(restored)
    np.testing.assert_array_equal(a.angle_rad, b.angle_rad)
    np.testing.assert_array_equal(a.time_s, b.time_s)


def test_floats_arrays_tuples_and_none_come_back_exactly():
    value = {"x": (0.1, 1e-300, -np.float64(2.0) / 3.0, None, True),
             "a": np.array([1.0 / 3.0, np.nextafter(1.0, 2.0)])}
    back = frozen._decode(json.loads(json.dumps(frozen._encode(value))))
    assert back["x"] == (0.1, 1e-300, -2.0 / 3.0, None, True)
    np.testing.assert_array_equal(back["a"], value["a"])
    assert back["a"].dtype == np.float64
    with pytest.raises(TypeError, match="cannot be frozen"):
        frozen._encode({"f": object()})


@pytest.mark.parametrize("effect", [e for e, spec in EFFECTS.items()
                                    if not spec.moves_the_pendulum])
def test_an_effect_that_does_not_move_the_pendulum_leaves_its_motion_as_restored(effect):
    """A restored case gets its motion simulated with its effects; an effect of the sensor,
    the tach or the noise must leave the pendulum and the table as without it, or the
    restored motion would differ from the drawn one (which is the clean case's)."""
    key = _cheapest_stored_forced_key()
    case: ForcedCase = frozen._decode(frozen._store()["draws"][key])
    values = {"gain_change": 0.01, "offset_change_rad": 1e-3, "amplitude_rad": 1e-3,
              "frequency_hz": 50.0, "phase_rad": 0.0, "delay_s": 1e-3, "dof": 2.0}
    with_effect = replace(case, effects={effect: values})
    assert true_pendulum(case.rig, case.causes, with_effect.effects) == true_pendulum(
        case.rig, case.causes)
    assert true_table(case.drive, case.causes, with_effect.effects) == true_table(
        case.drive, case.causes)
