"""No test of the analysis takes its data from the project's own model (issue 39).

A test that hides an effect and requires the analysis to find it, or that recovers
parameters, must draw its record from an independent generator (the :mod:`reference`
package: scipy DOP853 with events): an error shared by the project's integrator or cause
code and the fit built on the same code cancels, and the test passes with the bug.  This
scan reads every module under ``tests/`` and ``harness/`` (the tools the tests share with
the benchmarks) and fails when one both runs an analysis (imports ``analysis.discrepancy``
or ``analysis.identify``, names the ``analyze``, ``identify`` or ``demo`` command, or
drives the window's analysis tab) and takes data from the project's model (imports
``analysis.simulate``, ``hardware_sim``, the decay generator ``harness.hidden_cause``,
``gui.screenshots`` or the fit's own ``simulated_free_decay``, or names the ``simulate``
command or ``--sim``), unless the module is in :data:`ALLOWED` with the reason it asserts
nothing about a named cause or a recovered value on that data.  No module of
``reference/`` takes data from the project's model at all.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCANNED = ("tests", "harness")  # every module here is scanned for a mix
INDEPENDENT = "reference"  # no module here takes data from the project's model
ENTRY_MODULES = ("analysis.discrepancy", "analysis.identify")
ENTRY_COMMANDS = ("analyze", "identify", "demo")
ENTRY_ATTRIBUTES = ("analysis_panel",)  # the window's analysis tab runs both
SOURCE_MODULES = ("analysis.simulate", "hardware_sim", "harness.hidden_cause",
                  "gui.screenshots")
SOURCE_NAMES = {("analysis.identify.free_decay", "simulated_free_decay")}
SOURCE_COMMANDS = ("simulate", "demo", "--sim")

# module (relative to the repository) -> why it may hold both: it tests the pipeline or a
# format on the project's data and asserts nothing about the cause named or the values found
ALLOWED = {
    "tests/cli/test_cli.py": "the parser declares the commands; no record is analysed",
    "tests/demo/test_demo.py": "the demo's pipeline: its reports follow section 6 and are "
                               "consistent, not which cause the virtual rig hid",
    "tests/demo/test_virtual_causes.py": "the demo's hidden cause is the one its virtual rig "
                                         "runs; nothing is recorded or analysed",
    "tests/docs/test_commands.py": "the pages' commands run as shown (on the virtual rig, the "
                                   "demo among them): each ends well and writes what it "
                                   "names, whatever it finds",
    "tests/discrepancy/test_plausibility.py": "hidden_cause's drawn sizes must be plausible; "
                                              "no record is made",
    "tests/gui/test_live.py": "a recording made live is handed to the analysis tab, which is "
                              "not run",
    "tests/gui/test_screenshots.py": "the screenshots show each view drawn: the analysis tab "
                                     "has an explanation, whichever cause it names",
    "tests/identify/test_cli.py": "`simulate --out FILE.h5` is identified like its CSV: the "
                                  "two files agree, the truth is not asked",
    "tests/reference/test_no_common_mode.py": "this scan names the modules it looks for",
    "tests/suggest/test_cli.py": "the loop's pipeline on the virtual rig: a record, the plan "
                                 "run, both analysed as one rig, whatever cause is named",
    "tests/trust/test_boundary.py": "bad input is refused with a one-line error",
    "tests/trust/test_overwrite.py": "no file is written over",
    "tests/trust/test_provenance.py": "the outputs say what made them",
}


def _within(name: str, prefixes: tuple[str, ...]) -> bool:
    return any(name == prefix or name.startswith(prefix + ".") for prefix in prefixes)


def uses(source: str) -> tuple[set[str], set[str]]:
    """The analysis entries and the project data sources a module's text uses."""
    entries: set[str] = set()
    sources: set[str] = set()
    strings: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module:
            for alias in node.names:
                full = f"{node.module}.{alias.name}"
                if (node.module, alias.name) in SOURCE_NAMES or _within(full, SOURCE_MODULES) \
                        or _within(node.module, SOURCE_MODULES):
                    sources.add(full)
                elif _within(node.module, ENTRY_MODULES) or _within(full, ENTRY_MODULES):
                    entries.add(full)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if _within(alias.name, SOURCE_MODULES):
                    sources.add(alias.name)
                elif _within(alias.name, ENTRY_MODULES):
                    entries.add(alias.name)
        elif isinstance(node, ast.Attribute) and node.attr in ENTRY_ATTRIBUTES:
            entries.add(f"window.{node.attr}")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            strings.add(node.value)
    entries |= {f"`{c}` command" for c in ENTRY_COMMANDS if c in strings}
    sources |= {f"`{c}` command" for c in SOURCE_COMMANDS if c in strings}
    return entries, sources


def _may_use_a_source(text: str) -> bool:
    """A cheap look before parsing: the module's text names some data source at all."""
    words = [*SOURCE_MODULES, *(name for _module, name in SOURCE_NAMES),
             *(f"{quote}{command}{quote}" for command in SOURCE_COMMANDS for quote in "'\"")]
    return any(word in text for word in words)


def _modules(folder: str) -> list[tuple[str, str]]:
    """Each module under ``folder`` as its path relative to the repository and its text."""
    return [(path.relative_to(ROOT).as_posix(), path.read_text(encoding="utf-8"))
            for path in sorted((ROOT / folder).rglob("*.py"))]


def test_no_test_of_the_analysis_takes_the_projects_own_data():
    mixed = {}
    for name, text in (module for folder in SCANNED for module in _modules(folder)):
        if not _may_use_a_source(text):
            continue
        entries, sources = uses(text)
        if entries and sources and name not in ALLOWED:
            mixed[name] = (sorted(entries), sorted(sources))
    assert not mixed, ("analysed on the project's own data (use the reference package, or add "
                       f"the module to ALLOWED with the reason): {mixed}")


def test_the_reference_takes_no_data_from_the_projects_model():
    modules = _modules(INDEPENDENT)
    assert any(name == f"{INDEPENDENT}/simulator.py" for name, _text in modules)
    taken = {name: sorted(sources) for name, text in modules
             if (sources := uses(text)[1])}
    assert not taken, f"the reference generators must stay independent of the model: {taken}"


def test_every_allowed_module_exists_and_still_needs_its_place():
    for name in ALLOWED:
        path = ROOT / name
        assert path.is_file(), name
        entries, sources = uses(path.read_text(encoding="utf-8"))
        assert entries and sources, f"{name}: no longer mixes them; take it off ALLOWED"


def test_the_scan_sees_each_way_in():
    assert uses("from analysis.simulate import simulate\n"
                "from analysis.discrepancy import analyze_record\n") == (
        {"analysis.discrepancy.analyze_record"}, {"analysis.simulate.simulate"})
    entries, sources = uses("import hardware_sim.virtual_rig\n"
                            "def test(window):\n    window.analysis_panel.explain.click()\n")
    assert entries == {"window.analysis_panel"} and sources == {"hardware_sim.virtual_rig"}
    entries, sources = uses("ARGS = ['simulate', '--cause', 'coulomb_friction']\n"
                            "main(['analyze', 'x.csv'])\n")
    assert entries == {"`analyze` command"} and sources == {"`simulate` command"}
    assert uses("from analysis.identify.free_decay import simulated_free_decay\n") == (
        set(), {"analysis.identify.free_decay.simulated_free_decay"})
    assert uses("from reference.decays import draw_decay\n"
                "from analysis.discrepancy import analyze_record\n")[1] == set()
