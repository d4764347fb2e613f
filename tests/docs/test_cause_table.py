"""The test guide's table of which test names each cause (docs/development.md, "Which test
names each cause") against the causes of docs/MODEL.md section 6 and the tests that exist."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "development.md"
MODEL = ROOT / "docs" / "MODEL.md"
KINDS = ("free decay", "impact decay", "forced record")
NODE = re.compile(r"^`([\w/]+\.py)::(\w+)(?:\[(.+)\])?`$")


def _rows(text: str) -> list[list[str]]:
    """The cells of the first Markdown table in ``text``."""
    rows = []
    for line in text.splitlines():
        if line.startswith("|"):
            rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
        elif rows:
            break
    return rows


def _model_causes() -> list[str]:
    section = MODEL.read_text(encoding="utf-8").split("\n## 6.", 1)[1]
    return [row[0] for row in _rows(section)[2:]]


def _table() -> dict[str, dict[str, str]]:
    rows = _rows(GUIDE.read_text(encoding="utf-8").split("<!-- cause-table -->", 1)[1])
    assert rows[0] == ["cause", *KINDS], rows[0]
    return {row[0]: dict(zip(KINDS, row[1:], strict=True)) for row in rows[2:]}


def _exists(file: str, function: str, case: str | None) -> bool:
    """The test function is defined in tests/FILE, and its case is named there (a string
    constant: a parametrize id or the key of the dict it runs over)."""
    path = ROOT / "tests" / file
    if not path.is_file():
        return False
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = {node.name for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)}
    strings = {node.value for node in ast.walk(tree)
               if isinstance(node, ast.Constant) and isinstance(node.value, str)}
    return function in names and (case is None or case in strings)


def test_every_cause_has_a_row_and_nothing_else_does():
    causes = _model_causes()
    assert "none" in causes and "coulomb_friction" in causes
    assert list(_table()) == causes


def test_every_test_listed_exists_and_every_gap_says_why():
    for cause, cells in _table().items():
        for kind, cell in cells.items():
            if cell.startswith("- "):
                assert len(cell) > 10, (cause, kind, "a gap must say why")
                for quoted in re.findall(r"`[^`]+\.py::[^`]+`", cell):  # a known miss's test
                    assert _exists(*NODE.match(quoted).groups()), (cause, kind, quoted)
                continue
            match = NODE.match(cell)
            assert match, (cause, kind, cell)
            assert _exists(*match.groups()), (cause, kind, cell)


def test_the_check_tells_a_missing_test():
    assert _exists("docs/test_cause_table.py", "test_the_check_tells_a_missing_test", None)
    assert not _exists("docs/test_cause_table.py", "test_that_is_not_here", None)
    assert not _exists("docs/test_cause_table.py", "test_the_check_tells_a_missing_test",
                       "a case " + "never named")
    assert not _exists("docs/absent.py", "test_x", None)
