"""The experiment plan file (TOML): forced steps for ``impact-rig sweep --plan FILE``.

A plan is a list of forced steps, run in order, each a drive setting held for its settle
and then dwelt on (docs/MODEL.md section 8)::

    format_version = 1
    made_by = "impact-rig suggest"            # what wrote it (with its provenance)
    source = "run.report.json"                # what it was made from
    notes = "free text"

    [[step]]
    frequency_hz = 9.0
    amplitude_m = 0.0021
    settle_s = 10.0
    dwell_s = 20.0
    why = "free text: what this step is expected to show"   # optional

``impact-rig suggest`` writes plans; anyone may write one by hand.  Any other top-level
key or table (``suggestion``: what the search found) is kept and ignored; a step with a
key other than these is refused, so that a misspelt ``dwel_s`` is never run with a
default.  The shaker's limits are not this file's business: the rig file's are checked
when the plan runs, before anything moves.
"""

from __future__ import annotations

import json
import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis import quantities as q
from analysis.output_paths import check_outputs

PLAN_FORMAT_VERSION = 1
STEP_NUMBERS = (q.frequency_hz, q.amplitude_m, "settle_s", "dwell_s")
STEP_KEYS = (*STEP_NUMBERS, "why")
TOP_KEYS = ("format_version", "made_by", "source", "notes", "provenance")


class PlanFileError(ValueError):
    """A plan file that cannot be run; the message names the file, the step and the key."""


@dataclass(frozen=True)
class PlannedStep:
    """One forced step: the drive's frequency and amplitude, held ``settle_s`` before its
    ``dwell_s`` of steady state."""

    frequency_hz: float
    amplitude_m: float
    settle_s: float
    dwell_s: float
    why: str = ""

    def __post_init__(self) -> None:
        values = {name: getattr(self, name) for name in STEP_NUMBERS}
        bad = [name for name, value in values.items()
               if isinstance(value, bool) or not isinstance(value, int | float)
               or not math.isfinite(value)]
        if bad:
            raise ValueError(f"{bad[0]} = {values[bad[0]]!r}: expected a finite number")
        if not (self.frequency_hz > 0 and self.amplitude_m >= 0 and self.settle_s >= 0
                and self.dwell_s > 0):
            raise ValueError(
                f"frequency {self.frequency_hz!r} Hz, amplitude {self.amplitude_m!r} m, settle "
                f"{self.settle_s!r} s, dwell {self.dwell_s!r} s; expected a frequency > 0, an "
                "amplitude >= 0, a settle >= 0 and a dwell > 0")


@dataclass(frozen=True)
class ExperimentPlan:
    """Forced steps run in order (the sweep procedure runs them as a sweep's steps)."""

    steps: tuple[PlannedStep, ...]
    made_by: str = ""
    source: str = ""
    notes: str = ""
    extra: Mapping[str, Any] = field(default_factory=dict)  # other keys, kept and ignored

    def __post_init__(self) -> None:
        if not self.steps:
            raise ValueError("a plan needs at least one step")

    def schedule(self) -> list[tuple[int, float, float, float, float]]:
        """(direction, frequency_hz, amplitude_m, settle_s, dwell_s) of every step in order;
        the direction is 0: a plan's steps go neither up nor down."""
        return [(0, s.frequency_hz, s.amplitude_m, s.settle_s, s.dwell_s) for s in self.steps]


def read_plan(path: str | Path) -> ExperimentPlan:
    """The plan in ``path`` (:class:`PlanFileError` naming the file, the step and the key)."""
    path = Path(path)
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise PlanFileError(f"{path}: no such plan file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise PlanFileError(f"{path}: cannot read the plan ({error})") from None
    except tomllib.TOMLDecodeError as error:
        raise PlanFileError(f"{path}: not a TOML plan file ({error})") from None
    version = table.get("format_version", PLAN_FORMAT_VERSION)
    if version != PLAN_FORMAT_VERSION:
        raise PlanFileError(f"{path}: format_version {version!r}; this impact-rig reads "
                            f"version {PLAN_FORMAT_VERSION}")
    listed = table.get("step")
    if not isinstance(listed, list) or not listed:
        raise PlanFileError(f"{path}: no [[step]] tables; a plan lists its forced steps as "
                            "[[step]] with " + ", ".join(STEP_NUMBERS))
    steps = [_step(path, number, entry) for number, entry in enumerate(listed, start=1)]
    texts = {}
    for key in ("made_by", "source", "notes"):
        value = table.get(key, "")
        if not isinstance(value, str):
            raise PlanFileError(f"{path}: {key} = {value!r}: expected text")
        texts[key] = value
    extra = {k: v for k, v in table.items() if k not in (*TOP_KEYS, "step")}
    return ExperimentPlan(tuple(steps), extra=extra, **texts)


def _step(path: Path, number: int, entry: Any) -> PlannedStep:
    where = f"{path}: step {number}"
    if not isinstance(entry, dict):
        raise PlanFileError(f"{where}: expected a [[step]] table")
    unknown = sorted(set(entry) - set(STEP_KEYS))
    if unknown:
        raise PlanFileError(f"{where}: unknown key(s) {unknown}; a step has "
                            + ", ".join(STEP_KEYS))
    missing = [key for key in STEP_NUMBERS if key not in entry]
    if missing:
        raise PlanFileError(f"{where}: missing {', '.join(missing)}")
    why = entry.get("why", "")
    if not isinstance(why, str):
        raise PlanFileError(f"{where}: why = {why!r}: expected text")
    try:
        return PlannedStep(*(entry[key] for key in STEP_NUMBERS), why=why)
    except ValueError as error:
        raise PlanFileError(f"{where}: {error}") from None


def write_plan(
    path: str | Path, plan: ExperimentPlan, *, provenance: Mapping[str, Any],
    inputs: Sequence[str | Path] = (), overwrite: bool = False,
) -> Path:
    """Write ``plan`` as TOML with the ``provenance`` of what made it (one line of JSON);
    ``plan.extra`` tables (plain values, lists of them and tables of them) are written
    after the steps.  An existing file is refused unless ``overwrite``, an input always."""
    path, = check_outputs([path], inputs=inputs, overwrite=overwrite)
    lines = [f"# An experiment plan for 'impact-rig sweep --plan {path.name}'",
             f"format_version = {PLAN_FORMAT_VERSION}",
             f"made_by = {_text(plan.made_by)}",
             f"source = {_text(plan.source)}",
             f"notes = {_text(plan.notes)}",
             f"provenance = {_text(json.dumps(provenance, separators=(',', ':')))}", ""]
    for step in plan.steps:
        lines.append("[[step]]")
        lines += [f"{key} = {_value(getattr(step, key))}" for key in STEP_NUMBERS]
        if step.why:
            lines.append(f"why = {_text(step.why)}")
        lines.append("")
    for name, table in plan.extra.items():
        lines += _table(name, table)
    path.write_text("\n".join(lines).rstrip("\n") + "\n", encoding="utf-8")
    return path


def _table(name: str, table: Any) -> list[str]:
    if isinstance(table, list):  # an array of tables
        out = []
        for entry in table:
            out += [f"[[{name}]]", *_pairs(entry), ""]
        return out
    return [f"[{name}]", *_pairs(table), ""]


def _pairs(table: Mapping[str, Any]) -> list[str]:
    return [f"{key} = {_value(value)}" for key, value in table.items()]


def _value(value: Any) -> str:
    if isinstance(value, str):
        return _text(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {value!r} into a plan file")


def _text(value: str) -> str:
    # a JSON string is a TOML basic string: the same quotes and escapes (json never writes
    # the one escape TOML lacks, "\/"); TOML also wants DEL escaped, which JSON leaves
    return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
