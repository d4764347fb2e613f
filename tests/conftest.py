"""How the suite is run on several workers (pytest-xdist): the kernels compiled once, the long
tests first.

- **Compiled once.** With ``-n``, the controlling process starts ``tests/compiled_kernels.py``
  in a process of its own while the workers start and collect, and holds a lock until it
  ends; each worker waits for that lock before its first test, then loads the kernels from
  numba's cache instead of compiling them beside the other workers.  The folder holding the
  lock also holds that process's tiny map and whether it compiled the integrator
  (:func:`compiled_by_the_suite`).
- **Long tests first.** The modules holding a test marked ``slow`` run before the others
  (each module's tests kept together, in their order), so that the run ends on short tests
  that the workers share out, not on one worker's long test while the other is idle.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
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


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Modules with a test marked ``slow`` first, each module's tests kept in their order."""
    def module(item: pytest.Item) -> str:
        return getattr(getattr(item, "module", None), "__name__", "")

    slow = {module(item) for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: module(item) not in slow)
