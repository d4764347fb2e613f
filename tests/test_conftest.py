"""How ``tests/conftest.py`` lays the suite out for pytest-xdist: each worker's first share
opens on slow modules and ends on short tests, no module split; a fixture's data made
once for every worker."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from tests.conftest import DONE_NAME, _chunk_sizes, _each_chunk_opens_on_slow_modules, computed_once


def _items(layout: dict[str, tuple[int, int]]) -> list:
    """Stand-ins for collected tests: module name -> (tests marked slow, other tests)."""
    items = []
    for name, (slow, fast) in layout.items():
        module = SimpleNamespace(__name__=name)
        for k in range(slow + fast):
            mark = object() if k < slow else None
            items.append(SimpleNamespace(module=module, nodeid=f"{name}::{k}",
                                         get_closest_marker=lambda _, mark=mark: mark))
    return items


def test_the_shares_are_cut_as_worksteal_cuts_them() -> None:
    assert _chunk_sizes(1260, 2) == [630, 630]
    assert _chunk_sizes(7, 3) == [2, 2, 3]
    assert _chunk_sizes(9, 2) == [4, 5]


def test_each_share_opens_on_slow_modules_and_ends_on_short_tests() -> None:
    items = _items({"slow_big": (6, 0), "fast_a": (0, 10), "slow_small": (1, 3),
                    "slow_mid": (2, 2), "fast_b": (0, 9)})
    ordered = _each_chunk_opens_on_slow_modules(items, 2)
    assert sorted(item.nodeid for item in ordered) == sorted(item.nodeid for item in items)
    first, second = ordered[:16], ordered[16:]
    # the heaviest module to the first share; the next two to the second, lighter so far
    assert [item.module.__name__ for item in first[:6]] == ["slow_big"] * 6
    assert [item.module.__name__ for item in second[:8]] == ["slow_mid"] * 4 + ["slow_small"] * 4
    for share in (first, second):
        assert share[-1].get_closest_marker("slow") is None
        assert share[-1].module.__name__.startswith("fast")
    # each module's tests together and in their order
    names = [item.module.__name__ for item in ordered]
    for name in ("slow_big", "slow_small", "slow_mid"):
        where = [k for k, n in enumerate(names) if n == name]
        assert where == list(range(where[0], where[0] + len(where)))
        assert [ordered[k].nodeid for k in where] == [f"{name}::{k}" for k in range(len(where))]


def test_a_fixture_is_made_once_for_every_worker(tmp_path, monkeypatch) -> None:
    made = []

    def make(folder: Path) -> None:
        made.append(folder)
        (folder / "data.json").write_text("[1]")

    def worker(name: str):
        return SimpleNamespace(getbasetemp=lambda: tmp_path / name)

    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw0")
    first = computed_once(worker("popen-gw0"), "shared", make)
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw1")
    second = computed_once(worker("popen-gw1"), "shared", make)
    assert first == second == tmp_path / "shared" and made == [first]
    assert (second / "data.json").read_text() == "[1]" and (second / DONE_NAME).exists()


def test_a_worker_whose_make_failed_leaves_it_to_the_next(tmp_path, monkeypatch) -> None:
    def fail(folder: Path) -> None:
        (folder / "half.json").write_text("[")
        raise RuntimeError("failed half way")

    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw0")
    factory = SimpleNamespace(getbasetemp=lambda: tmp_path / "popen-gw0")
    with pytest.raises(RuntimeError, match="half way"):
        computed_once(factory, "shared", fail)
    folder = computed_once(factory, "shared", lambda f: (f / "whole.json").write_text("[]"))
    assert sorted(p.name for p in folder.iterdir()) == [DONE_NAME, "whole.json"]
