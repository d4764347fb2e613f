"""Maps on real Dask clusters equal the map computed in one process, bit for bit: a
LocalCluster of worker processes, and a scheduler with workers started as processes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from analysis.maps import MapRunner, MapStore, finish_map
from analysis.provenance import provenance
from rig.cli import build_parser
from rig.commands.map import plan_from_args
from tests.maps.conftest import TINY, assert_same_map, map_main


@pytest.mark.slow
def test_a_local_cluster_of_processes_computes_the_same_maps(tmp_path, reference_maps):
    with MapRunner(workers=2) as runner:  # one LocalCluster (processes) for the three maps
        assert runner.where == "local Dask cluster" and runner.workers == 2
        for kind, args in TINY.items():
            out = tmp_path / f"{kind}.h5"
            plan = plan_from_args(build_parser().parse_args(["map", *args, "--out", str(out)]))
            store = MapStore.create(out, plan, provenance())
            try:
                report = runner.run(plan, store)
            finally:
                store.close()
            assert report.tasks == len(plan.tasks) and report.trajectories == plan.trajectories
            finish_map(out, out.with_suffix(".png"), runner.map)
            assert_same_map(reference_maps[kind], out)


@pytest.fixture(scope="module")
def scheduler_address(tmp_path_factory):
    """A Dask scheduler and a worker process with two one-thread workers, on loopback."""
    folder = tmp_path_factory.mktemp("dask")
    scheduler_file = folder / "scheduler.json"
    python = [sys.executable, "-m"]
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    scheduler = subprocess.Popen(
        [*python, "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
         "--no-dashboard", "--scheduler-file", str(scheduler_file)], **quiet,
    )
    workers = subprocess.Popen(
        [*python, "distributed.cli.dask_worker", "--scheduler-file", str(scheduler_file),
         "--nworkers", "2", "--nthreads", "1", "--no-dashboard",
         "--local-directory", str(folder)], **quiet,
    )
    try:
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        yield json.loads(scheduler_file.read_text())["address"]
    finally:
        for process in (workers, scheduler):  # each started in its own session: its group
            os.killpg(process.pid, signal.SIGTERM)
        for process in (workers, scheduler):
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()


@pytest.mark.parametrize("kind", ["bifurcation", "basins"])
def test_a_scheduler_with_worker_processes_computes_the_same_map(
    tmp_path, capsys, reference_maps, scheduler_address, kind
):
    out = tmp_path / f"{kind}.h5"
    status, err = map_main(capsys, *TINY[kind], "--scheduler", scheduler_address,
                           "--out", str(out))
    assert status == 0, err
    assert f"on 2 worker(s), {scheduler_address}" in err
    assert_same_map(reference_maps[kind], out)
