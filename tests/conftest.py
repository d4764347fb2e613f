"""How the suite is run on several workers (pytest-xdist): the kernels compiled once, the long
tests first, an expensive fixture made once.

- **Compiled once.** With ``-n``, the controlling process starts ``tests/compiled_kernels.py``
  in a process of its own while the workers start and collect, and holds a lock until it
  ends; each worker waits for that lock before its first test, then loads the kernels from
  numba's cache instead of compiling them beside the other workers.  The folder holding the
  lock also holds that process's tiny map and whether it compiled the integrator
  (:func:`compiled_by_the_suite`).
- **Long tests first.** The modules holding a test marked ``slow`` run before the others
  (each module's tests kept together, in their order), so that the run ends on short tests
  that the workers share out, not on one worker's long test while the other is idle.  Under
  ``--dist worksteal``, which first hands each worker a contiguous run of the collection and
  lets an idle worker steal the end of a busy one's queue, the slow modules are dealt out
  over those runs, each opening on its share and ending on short tests: what is stolen is
  short, and a slow module is not split between workers.
- **Made once.** :func:`computed_once` gives a module-scoped fixture a folder of data
  that one worker makes and the others read, should the workers split the module.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path

import pytest

try:
    import fcntl
except ImportError:  # not POSIX: every worker compiles for itself, as without -n
    fcntl = None

from tests.compiled_kernels import MAP_NAME, VERDICT_NAME

FOLDER_VARIABLE = "IMPACT_RIG_TESTS_KERNELS"
LOCK_NAME = "compiling.lock"
ROOT = Path(__file__).resolve().parent.parent


def _runs_workers(config: pytest.Config) -> bool:
    """This is the controlling process of a run on pytest-xdist workers."""
    return not hasattr(config, "workerinput") and config.getoption("dist", "no") != "no"


def pytest_configure(config: pytest.Config) -> None:
    if fcntl is None or not _runs_workers(config):
        return
    folder = Path(tempfile.mkdtemp(prefix="impact-rig-kernels-"))
    lock = open(folder / LOCK_NAME, "w")  # noqa: SIM115 (closed by the thread below)
    fcntl.flock(lock, fcntl.LOCK_EX)  # taken before any worker exists: none can pass it early
    os.environ[FOLDER_VARIABLE] = str(folder)  # the workers inherit it
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    process = subprocess.Popen([sys.executable, "-m", "tests.compiled_kernels", str(folder)],
                               cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)

    def release() -> None:
        try:
            process.wait(timeout=900)  # a failure here shows in the tests themselves
        except subprocess.TimeoutExpired:
            process.kill()
        lock.close()

    threading.Thread(target=release, daemon=True).start()
    config.add_cleanup(lambda: shutil.rmtree(folder, ignore_errors=True))


def _kernels_folder() -> Path | None:
    folder = os.environ.get(FOLDER_VARIABLE)
    return Path(folder) if fcntl is not None and folder and Path(folder).is_dir() else None


@pytest.fixture(scope="session", autouse=True)
def _kernels_compiled_once() -> None:
    """Wait until the controlling process has compiled the kernels (see the module)."""
    folder = _kernels_folder()
    if folder is not None:
        with open(folder / LOCK_NAME) as lock:
            fcntl.flock(lock, fcntl.LOCK_SH)


def compiled_by_the_suite() -> Path | None:
    """The tiny bifurcation map (``tests/maps``) drawn by the process that compiled the
    kernels for this run, if it did compile the integrator (a fresh checkout); None when it
    loaded them from numba's cache, or when no such process ran (no ``-n``)."""
    folder = _kernels_folder()
    if folder is None or not (folder / VERDICT_NAME).exists():
        return None
    verdict = json.loads((folder / VERDICT_NAME).read_text())
    return folder / MAP_NAME if verdict["compiled"] and verdict["status"] == 0 else None


DONE_NAME = "done"


def computed_once(tmp_path_factory: pytest.TempPathFactory, name: str,
                  make: Callable[[Path], None]) -> Path:
    """A folder that ``make`` fills with data files once per run, whichever worker asks for
    it first (pytest-xdist's pattern: a lock and a folder in the run's temporary folder,
    which its workers share; the others wait on the lock, then read the files).  Without
    workers, a folder of this process's own.  A module-scoped fixture whose tests the
    workers split between them is otherwise set up on each: ``make`` writes data (JSON,
    ``.npz``, records), never pickles, so what a test reads is the same wherever it ran."""
    if fcntl is None or "PYTEST_XDIST_WORKER" not in os.environ:
        folder = tmp_path_factory.mktemp(name)
        make(folder)
        return folder
    root = tmp_path_factory.getbasetemp().parent  # the run's folder; each worker's is in it
    folder = root / name
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (folder / DONE_NAME).exists():  # first, or after a worker whose make failed
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
            make(folder)
            (folder / DONE_NAME).write_text("")
    return folder


def _module(item: pytest.Item) -> str:
    return getattr(getattr(item, "module", None), "__name__", "")


def _chunk_sizes(count: int, workers: int) -> list[int]:
    """How many tests ``--dist worksteal`` first hands each of ``workers`` idle workers, in
    order: the collection cut into contiguous runs as its scheduler cuts it."""
    sizes = []
    for remaining in range(workers, 0, -1):
        sizes.append((count - sum(sizes)) // remaining)
    return sizes


def _each_chunk_opens_on_slow_modules(items: list[pytest.Item], workers: int) -> list[pytest.Item]:
    """The order for ``workers`` workers under ``--dist worksteal``: the slow modules dealt
    out over the workers' first runs (the module with the most tests marked ``slow`` to the
    run with the fewest so far), each run opening on its slow modules and filled up with
    the others, so that every worker's queue ends on short tests, which is where an idle
    worker steals from."""
    modules: dict[str, list[pytest.Item]] = {}
    for item in items:
        modules.setdefault(_module(item), []).append(item)
    weight = {name: sum(item.get_closest_marker("slow") is not None for item in module)
              for name, module in modules.items()}
    slow = sorted((name for name in modules if weight[name]), key=lambda name: -weight[name])
    fast = [item for name, module in modules.items() if not weight[name] for item in module]
    sizes = _chunk_sizes(len(items), workers)
    dealt: list[list[pytest.Item]] = [[] for _ in sizes]
    load = [0] * len(sizes)
    for name in slow:  # stable: a module weighing as much as another keeps its place
        chunk = min(range(len(sizes)), key=lambda k: (load[k], len(dealt[k])))
        dealt[chunk].extend(modules[name])
        load[chunk] += weight[name]
    ordered: list[pytest.Item] = []
    for chunk, size in zip(dealt, sizes, strict=True):
        take = max(0, size - len(chunk))
        ordered += chunk + fast[:take]
        fast = fast[take:]
    return ordered + fast


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Modules with a test marked ``slow`` first, each module's tests kept in their order; on
    several workers under ``--dist worksteal``, first in each worker's share (see
    :func:`_each_chunk_opens_on_slow_modules`)."""
    slow = {_module(item) for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: _module(item) not in slow)
    workers = getattr(config, "workerinput", {}).get("workercount", 1)
    if workers > 1 and config.getoption("dist", "no") == "worksteal":
        items[:] = _each_chunk_opens_on_slow_modules(items, workers)
