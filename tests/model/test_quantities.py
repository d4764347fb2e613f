"""The registry of named quantities (analysis.quantities) is the one place a parameter's key
is spelled: every runtime module names a key through it, and it holds every key the docs
and the model know."""

from __future__ import annotations

import ast
import math
import re
from dataclasses import fields
from pathlib import Path

import pytest

from analysis import quantities as q
from analysis.extensions import CAUSES
from analysis.model import Drive, Nondimensional, RigParameters
from analysis.packed import ParameterError
from analysis.quantities import QUANTITIES, quantity
from rig.config import ConfigError, parse_config

ROOT = Path(__file__).resolve().parents[2]
RUNTIME = ("analysis", "rig", "gui", "hardware_sim", "recording", "drivers")
REGISTRY = "analysis/quantities.py"
# the boundary modules that may spell a key, each for its reason
BOUNDARY = {
    # the exchange format's sidecar keys (docs/MODEL.md section 5, with "g" for g_m_s2) are
    # that file format's, fixed by its readers elsewhere, not renamed with a quantity
    "analysis/exchange.py": "the exchange format's own sidecar keys",
    # below analysis in the layers (they may not import it): the recording's sweep-step and
    # drive-log fields (docs/recording_layout.md is their contract) and the shaker drivers'
    # own setting names
    "recording/layout.py": "the recording format's drive and sweep-step fields",
    "drivers/shaker_device.py": "the shaker driver's measured settings",
    "drivers/scpi_shaker.py": "the SCPI shaker driver's setting names in its messages",
}


# The dict methods whose first argument is a key.
_KEY_METHODS = {"get", "pop", "setdefault"}


def _key_positions(tree: ast.AST) -> set[int]:
    """ids of the string constants of ``tree`` that stand where a parameter key does: a dict
    display's key, a subscript (``v["e"]``), the first argument of ``get``, ``pop`` or
    ``setdefault``, the left side of ``in`` / ``not in``, and an element of a tuple, list or
    set that also holds a registry constant (``(q.zeta, "e")``, a list of keys)."""
    found: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict):
            found.update(id(k) for k in node.keys if k is not None)
        elif isinstance(node, ast.Subscript):
            found.add(id(node.slice))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr in _KEY_METHODS and node.args):
            found.add(id(node.args[0]))
        elif (isinstance(node, ast.Compare) and len(node.ops) == 1
              and isinstance(node.ops[0], ast.In | ast.NotIn)):
            found.add(id(node.left))
        elif isinstance(node, ast.Tuple | ast.List | ast.Set) and any(
                isinstance(v, ast.Attribute) and isinstance(v.value, ast.Name)
                and v.value.id == "q" for v in node.elts):
            found.update(id(v) for v in node.elts)
    return found


def spelled_keys(source: str, keys: set[str]) -> list[tuple[int, str]]:
    """(line, key) of every string constant of ``source`` equal to one of ``keys``, less
    docstrings and the literal text of f-strings (an f-string's expressions are code).

    A one-letter key (``e``, ``n``) is also an ordinary one-letter string (a paper case's
    name, a format code), so it counts only where it stands as a key (:func:`_key_positions`);
    a longer key counts wherever it is spelled."""
    tree = ast.parse(source)
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            skip.update(id(v) for v in node.values if isinstance(v, ast.Constant))
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            first = node.body[0] if node.body else None
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                skip.add(id(first.value))
    as_key = _key_positions(tree)
    return sorted((node.lineno, node.value) for node in ast.walk(tree)
                  if isinstance(node, ast.Constant) and isinstance(node.value, str)
                  and node.value in keys and id(node) not in skip
                  and (len(node.value) > 1 or id(node) in as_key))


def test_the_scanner_finds_a_spelled_key_and_passes_docstrings_and_fstring_text():
    source = ('"""zeta"""\n'
              'def f(v):\n'
              '    """theta_b_rad"""\n'
              '    return v["zeta"], f"zeta = {v[\'theta_b_rad\']}", "zeta_other"\n')
    assert spelled_keys(source, {"zeta", "theta_b_rad"}) == [(4, "theta_b_rad"), (4, "zeta")]


def test_the_scanner_finds_a_one_letter_key_only_where_it_stands_as_a_key():
    # what spelled the coefficient of restitution before it was registered, one per line
    source = ('start = {**v, "e": e0}\n'
              'x = start["e"]\n'
              'names = (q.theta0_rad, q.zeta, "e")\n'
              'y = v.get("e", 1.0)\n'
              'z = "e" in v\n'
              'line = f"e = {rc[\'parameters\'][\'e\']:.3g}"\n'
              # a paper case's name, a format code, a plain tuple: not keys
              'cases = [("e", 10.0, high, 0.064), ("n", 2.0)]\n'
              'text = format(x, "e") + "e"\n'
              'pair = ("e", "n")\n')
    assert spelled_keys(source, {"e", "n"}) == [(i, "e") for i in range(1, 7)]


def test_no_runtime_module_spells_a_registered_key_outside_the_registry():
    keys = set(QUANTITIES) | set(q.COMMAND_LINE_NAMES)
    found = []
    for package in RUNTIME:
        for path in sorted((ROOT / package).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel == REGISTRY or rel in BOUNDARY:
                continue
            found += [f"{rel}:{line}: {key!r}"
                      for line, key in spelled_keys(path.read_text(encoding="utf-8"), keys)]
    assert not found, ("parameter keys spelled as string literals; name them through "
                       "analysis.quantities (from analysis import quantities as q; q.KEY):\n"
                       + "\n".join(found))


def test_the_boundary_modules_exist_and_still_spell_a_key():
    # an allowance that is no longer needed is removed, not left to cover a new literal
    for rel in BOUNDARY:
        assert spelled_keys((ROOT / rel).read_text(encoding="utf-8"), set(QUANTITIES)), rel


def test_the_command_line_names_stand_for_registered_quantities():
    assert set(q.COMMAND_LINE_NAMES.values()) <= set(QUANTITIES)
    assert not set(q.COMMAND_LINE_NAMES) & set(QUANTITIES)


def _section_7_keys() -> set[str]:
    text = (ROOT / "docs" / "MODEL.md").read_text(encoding="utf-8")
    section = text.split("## 7. ", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| ")]
    return {key for row in rows for key in re.findall(r"`([^`]+)`", row)}


def test_every_key_of_model_md_section_7_is_registered():
    keys = _section_7_keys()
    assert {"theta_b_rad", "K_N_per_m1.5", "tau_s"} <= keys  # the table was read
    assert keys - set(QUANTITIES) == set()


def test_the_rig_and_every_cause_name_registered_quantities():
    rig = {f.name for f in fields(RigParameters)}
    assert rig - set(QUANTITIES) == set()
    for c in CAUSES.values():
        for spec in c.parameters:
            assert spec.doc == quantity(spec.name).doc  # meaning and unit defined once


def test_a_cause_whose_fit_would_leave_the_physical_bounds_is_refused():
    from analysis.extensions import ParameterSpec

    with pytest.raises(ParameterError, match=r"tau_s = -0.1: must be >= 0"):
        ParameterSpec(q.tau_s, 0.0, -0.1, 1.0)


def test_every_quantity_knows_its_symbol_meaning_and_sane_bounds():
    for key, entry in QUANTITIES.items():
        assert entry.key == key and entry.symbol and entry.meaning, key
        assert entry.bounds is None or entry.bounds.low < entry.bounds.high, key


def test_a_value_is_checked_against_its_registered_bounds_with_one_line_naming_it():
    assert q.check(q.theta_b_rad, -0.1) == -0.1
    assert q.check(q.zeta, 0) == 0.0  # closed at 0
    with pytest.raises(ParameterError, match=r"^m_kg = 0: must be > 0 \(pendulum mass, kg\)$"):
        q.check(q.m_kg, 0)
    with pytest.raises(ParameterError, match=r"theta_b_rad = 1.6: must be in \(-1.5708, 1.5708\)"):
        q.check(q.theta_b_rad, 1.6)
    with pytest.raises(ParameterError, match="expected a finite number"):
        q.check(q.amplitude_m, math.inf)
    with pytest.raises(ParameterError, match="expected a number"):
        q.check(q.frequency_hz, True)


def test_the_model_and_the_rig_file_take_their_limits_from_the_registry():
    # the same bound, the same words, wherever a value is refused
    with pytest.raises(ParameterError, match=r"theta_b_rad = 1.6: must be in \(-1.5708, 1.5708\)"):
        RigParameters(theta_b_rad=1.6)
    with pytest.raises(ParameterError, match=r"amplitude_m = -0.001: must be >= 0"):
        Drive(amplitude_m=-0.001, frequency_hz=10.0)
    with pytest.raises(ParameterError, match=r"gamma = 0: must be > 0"):
        Nondimensional(eta=1.0, beta=0.1, mu=0.1, gamma=0)
    text = (ROOT / "rig" / "default_rig.toml").read_text(encoding="utf-8")
    assert "\nm_kg = " in text
    bad = re.sub(r"\nm_kg = [^\n]*", "\nm_kg = 0.0", text, count=1)
    with pytest.raises(ConfigError, match=r"'rig.constants.m_kg' is 0.0; expected a number > 0$"):
        parse_config(bad, "rig.toml")


def test_an_unknown_key_is_refused_by_name():
    with pytest.raises(KeyError, match="unknown quantity 'theta_B'"):
        quantity("theta_B")
