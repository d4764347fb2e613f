"""Frozen reference draws: what an expensive draw decided, stored as data beside the code.

Drawing a forced record costs far more than simulating it: the generator tries sub-seeds
until the regime asked for is met, sizes each cause until it shows after the baseline's
refit (``visibility``), and judges the regime with a twin trajectory.  The suite draws the
same cases on every run, so :func:`frozen` keeps each decorated draw's result (the case
without its motion: sizes, sub-seed, regime truth, visibility) in ``draws.json``, keyed by
the call, and a run that finds it there only simulates the noiseless motion again, with
the reference simulator, from the stored case.  The numbers are the same as a live draw's
to the last bit (floats are stored by their shortest round-trip repr).

The store is valid only for the code that made it: its ``fingerprint`` hashes the syntax
tree (docstrings, comments and import lines left out) of every module of this package a
frozen function depends on.  When the code changes, every draw is made live again (right,
only slow) and ``tests/reference/test_frozen.py`` fails with the command that refreshes it:

    python -m reference.frozen --refresh

which draws every stored call again with the current code.  A new call (a test adds a
case) is drawn live until the store has it: run the tests that make it with
``IMPACT_RIG_RECORD_DRAWS=stop`` set (each draw the store lacks is made, recorded in
``draws.recorded/``, and stops its test there; run again until nothing new is recorded,
as a draw may come after another), then ``--merge`` adds what they recorded.
``IMPACT_RIG_LIVE_DRAWS=1`` draws everything live (``--refresh`` sets it).
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import hashlib
import importlib
import inspect
import json
import os
import sys
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

HERE = Path(__file__).resolve().parent
STORE = HERE / "draws.json"
RECORDED = HERE / "draws.recorded"  # one file per recorded call; never committed
LIVE_ENV = "IMPACT_RIG_LIVE_DRAWS"
RECORD_ENV = "IMPACT_RIG_RECORD_DRAWS"
FORMAT = "impact-rig frozen reference draws v1"

F = TypeVar("F", bound=Callable[..., Any])
_FROZEN: dict[str, Callable[..., Any]] = {}  # key prefix (module.function) -> live function


def _stripped_tree(path: Path) -> tuple[str, set[str]]:
    """The module's syntax tree without docstrings or imports, and the sibling modules it
    imports (by their file stem)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    siblings = {p.stem for p in HERE.glob("*.py")}
    uses: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            last = (node.module or "").rsplit(".", 1)[-1]
            names = [last] + [alias.name for alias in node.names]
            uses.update(name for name in names if name in siblings)
        elif isinstance(node, ast.Import):
            uses.update(a.name.rsplit(".", 1)[-1] for a in node.names
                        if a.name.rsplit(".", 1)[-1] in siblings)

    class _Strip(ast.NodeTransformer):
        def visit_Import(self, node):
            return None

        def visit_ImportFrom(self, node):
            return None

        def generic_visit(self, node):
            body = getattr(node, "body", None)
            if (isinstance(body, list) and body and isinstance(body[0], ast.Expr)
                    and isinstance(body[0].value, ast.Constant)
                    and isinstance(body[0].value.value, str)):
                node.body = body[1:] or [ast.Pass()]
            return super().generic_visit(node)

    return ast.dump(_Strip().visit(tree), include_attributes=False), uses


@functools.cache
def fingerprint(module_stem: str) -> str:
    """SHA-256 over the stripped syntax trees of ``module_stem`` and every sibling module
    it depends on, in name order (this module and the tests excluded)."""
    seen: dict[str, str] = {}
    todo = [module_stem]
    while todo:
        stem = todo.pop()
        if stem in seen or stem == "frozen" or stem.startswith("test_"):
            continue
        dump, uses = _stripped_tree(HERE / f"{stem}.py")
        seen[stem] = dump
        todo.extend(uses)
    digest = hashlib.sha256()
    for stem in sorted(seen):
        digest.update(f"{stem}\n{seen[stem]}\n".encode())
    return digest.hexdigest()


# ----- the case as JSON, exactly ---------------------------------------------------------

def _encode(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {}
        for f in dataclasses.fields(value):
            if f.name == "motion":
                continue  # simulated again on load
            fields[f.name] = _encode(getattr(value, f.name))
        stem = type(value).__module__.rsplit(".", 1)[-1]  # a module of this package
        return {"__dataclass__": f"{stem}.{type(value).__qualname__}", "fields": fields}
    if isinstance(value, tuple):
        return {"__tuple__": [_encode(v) for v in value]}
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise TypeError(f"a dict with non-string keys cannot be frozen: {value!r}")
        return {k: _encode(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_encode(v) for v in value]
    if isinstance(value, np.ndarray):
        return {"__array__": value.tolist(), "dtype": str(value.dtype)}
    if isinstance(value, np.bool_ | bool):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if value is None or isinstance(value, int | float | str):
        return value
    raise TypeError(f"{type(value).__name__} cannot be frozen: {value!r}")


def _decode(value: Any) -> Any:
    if isinstance(value, list):
        return [_decode(v) for v in value]
    if not isinstance(value, dict):
        return value
    if "__dataclass__" in value:
        stem, name = value["__dataclass__"].split(".")[-2:]
        cls = getattr(importlib.import_module(f"{__package__}.{stem}"), name)
        if not dataclasses.is_dataclass(cls):
            raise TypeError(f"{value['__dataclass__']} is not a dataclass")
        return cls(**{k: _decode(v) for k, v in value["fields"].items()})
    if "__tuple__" in value:
        return tuple(_decode(v) for v in value["__tuple__"])
    if "__array__" in value:
        return np.asarray(value["__array__"], dtype=value["dtype"])
    return {k: _decode(v) for k, v in value.items()}


# ----- the store ---------------------------------------------------------------------------

def _call_key(function: Callable[..., Any], args: tuple, kwargs: dict) -> str:
    bound = inspect.signature(function).bind(*args, **kwargs)
    bound.apply_defaults()
    arguments = json.dumps(_encode(dict(bound.arguments)), sort_keys=True)
    return f"{function.__module__.rsplit('.', 1)[-1]}.{function.__name__}{arguments}"


@functools.cache
def _store() -> dict[str, Any]:
    if not STORE.exists():
        return {"format": FORMAT, "fingerprints": {}, "draws": {}}
    store = json.loads(STORE.read_text(encoding="utf-8"))
    if store.get("format") != FORMAT:
        raise ValueError(f"{STORE.name}: format {store.get('format')!r}, expected {FORMAT!r}")
    return store


def stale_modules() -> list[str]:
    """Modules whose stored fingerprint no longer matches their code."""
    stored = _store()["fingerprints"]
    return sorted(stem for stem, digest in stored.items() if fingerprint(stem) != digest)


def frozen(restore: Callable[[Any], Any]) -> Callable[[F], F]:
    """Serve the decorated draw's result from the store when the store holds this call and
    its module's fingerprint is current (``restore`` then simulates what the store leaves
    out: the motion); otherwise make the draw."""

    def decorate(function: F) -> F:
        stem = function.__module__.rsplit(".", 1)[-1]
        _FROZEN[f"{stem}.{function.__name__}"] = function

        @functools.wraps(function)
        def wrapper(*args, **kwargs):
            if os.environ.get(LIVE_ENV):
                return function(*args, **kwargs)
            key = _call_key(function, args, kwargs)
            store = _store()
            entry = store["draws"].get(key)
            if entry is not None and store["fingerprints"].get(stem) == fingerprint(stem):
                return restore(_decode(entry))
            result = function(*args, **kwargs)
            mode = os.environ.get(RECORD_ENV)
            if mode:
                _record(key, result)
                if mode == "stop":
                    raise DrawRecordedError(key)
            return result

        wrapper.live = function  # type: ignore[attr-defined]
        return wrapper  # type: ignore[return-value]

    return decorate


class DrawRecordedError(Exception):
    """Raised after a draw is recorded when ``IMPACT_RIG_RECORD_DRAWS=stop``: the test
    that asked for it stops there (a recording pass runs the draws, not the analyses)."""


def _record(key: str, result: Any) -> None:
    RECORDED.mkdir(exist_ok=True)
    name = hashlib.sha256(key.encode()).hexdigest()[:24]
    text = json.dumps({"key": key, "draw": _encode(result)})
    (RECORDED / f"{name}.json").write_text(text, encoding="utf-8")


def _split_key(key: str) -> tuple[str, dict]:
    name, _, arguments = key.partition("{")
    return name, _decode(json.loads("{" + arguments))


def draw_live(key: str) -> tuple[str, Any]:
    """The stored call ``key`` made again with the current code, encoded for the store."""
    name, arguments = _split_key(key)
    stem = name.split(".")[0]
    importlib.import_module(f"{__package__}.{stem}")
    result = _FROZEN[name](**arguments)
    return key, _encode(result)


def refresh(workers: int = 2, *, redraw: bool = True) -> int:
    """Write the store: the recorded draws merged in, and (``redraw``) every stored call
    not recorded drawn again with the current code.  Returns the number of draws."""
    draws: dict[str, Any] = {}
    recorded = sorted(RECORDED.glob("*.json")) if RECORDED.exists() else []
    for path in recorded:
        entry = json.loads(path.read_text(encoding="utf-8"))
        draws[entry["key"]] = _encode(_decode(entry["draw"]))  # the names of this layout
    stored = _store()["draws"]
    if redraw:
        todo = sorted(set(stored) - set(draws))
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for done, (key, encoded) in enumerate(pool.map(draw_live, todo), 1):
                draws[key] = encoded
                print(f"[{done}/{len(todo)}] {key[:100]}", file=sys.stderr, flush=True)
    else:
        if stale_modules():
            raise SystemExit(f"{STORE.name} is stale ({', '.join(stale_modules())}): "
                             "use --refresh, not --merge")
        draws = {**{k: _encode(_decode(v)) for k, v in stored.items()}, **draws}
    stems = sorted({key.split(".")[0] for key in draws})
    store = {
        "format": FORMAT,
        "made_by": "python -m reference.frozen (impact-rig's test suite)",
        "fingerprints": {stem: fingerprint(stem) for stem in stems},
        "draws": dict(sorted(draws.items())),
    }
    STORE.write_text(json.dumps(store, indent=1) + "\n", encoding="utf-8")
    for path in recorded:
        path.unlink()
    return len(draws)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m reference.frozen",
        description="Check or refresh the frozen reference draws (reference/draws.json).")
    parser.add_argument("--refresh", action="store_true",
                        help="draw every stored call again with the current code, merge "
                             "the recorded draws, and rewrite the store")
    parser.add_argument("--merge", action="store_true",
                        help="merge the draws recorded by IMPACT_RIG_RECORD_DRAWS into a "
                             "current store")
    parser.add_argument("--workers", type=int, default=2, help="processes for --refresh")
    args = parser.parse_args(argv)
    if args.refresh or args.merge:
        os.environ[LIVE_ENV] = "1"  # the draws inside a draw are made live too
        count = refresh(args.workers, redraw=args.refresh)
        print(f"{STORE.name}: {count} draws written")
        return 0
    stale = stale_modules()
    print(f"{STORE.name}: {len(_store()['draws'])} draws; "
          + (f"stale for {', '.join(stale)}" if stale else "current"))
    return 1 if stale else 0


if __name__ == "__main__":
    # run as the package's module, not as __main__: the generators register their draws in
    # reference.frozen, which would otherwise be a second copy of this module
    from reference import frozen as _package_module

    raise SystemExit(_package_module.main())
