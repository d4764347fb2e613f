"""How the suite is run on several workers (pytest-xdist): the kernels compiled once, the long
tests first.

- **Compiled once.** With ``-n``, the controlling process starts ``tests/compiled_kernels.py``
  in a process of its own while the workers start and collect, and holds a lock until it
  ends; each worker waits for that lock before its first test, then loads the kernels from
  numba's cache instead of compiling them beside the other workers.
- **Long tests first.** The modules holding a test marked ``slow`` run before the others
  (each module's tests kept together, in their order), so that the run ends on short tests
  that the workers share out, not on one worker's long test while the other is idle.
"""

from __future__ import annotations

import os
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

LOCK_VARIABLE = "IMPACT_RIG_TESTS_KERNELS_LOCK"
ROOT = Path(__file__).resolve().parent.parent


def _runs_workers(config: pytest.Config) -> bool:
    """This is the controlling process of a run on pytest-xdist workers."""
    return not hasattr(config, "workerinput") and config.getoption("dist", "no") != "no"


def pytest_configure(config: pytest.Config) -> None:
    if fcntl is None or not _runs_workers(config):
        return
    handle, path = tempfile.mkstemp(prefix="impact-rig-kernels-", suffix=".lock")
    lock = os.fdopen(handle, "w")
    fcntl.flock(lock, fcntl.LOCK_EX)  # taken before any worker exists: none can pass it early
    os.environ[LOCK_VARIABLE] = path  # the workers inherit it
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    process = subprocess.Popen([sys.executable, "-m", "tests.compiled_kernels"], cwd=ROOT,
                               env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def release() -> None:
        try:
            process.wait(timeout=900)  # a failure here shows in the tests themselves
        except subprocess.TimeoutExpired:
            process.kill()
        lock.close()

    threading.Thread(target=release, daemon=True).start()
    config.add_cleanup(lambda: Path(path).unlink(missing_ok=True))


@pytest.fixture(scope="session", autouse=True)
def _kernels_compiled_once() -> None:
    """Wait until the controlling process has compiled the kernels (see the module)."""
    path = os.environ.get(LOCK_VARIABLE)
    if fcntl is None or not path or not Path(path).exists():
        return
    with open(path) as lock:
        fcntl.flock(lock, fcntl.LOCK_SH)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Modules with a test marked ``slow`` first, each module's tests kept in their order."""
    def module(item: pytest.Item) -> str:
        return getattr(getattr(item, "module", None), "__name__", "")

    slow = {module(item) for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: module(item) not in slow)
