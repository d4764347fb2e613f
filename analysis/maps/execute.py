"""Running a map's tasks: in this process (one worker), or on Dask distributed workers.

One worker runs every task here, in order, with no pool: the reference for results and
speed-ups.  More workers run on a Dask ``LocalCluster`` of worker processes (one thread
each), or on any Dask scheduler given by address (``tcp://host:8786``).  Every finished
task is written to the map file at once; the pieces of a continuation sweep go out one
after another, each as soon as the one before is written, ahead of the batches of
independent runs.  Tasks already done in the file are not run again.
"""

from __future__ import annotations

import logging
import os
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from analysis.maps.plan import MapPlan, Task
from analysis.maps.store import MapStore
from analysis.maps.tasks import TaskInput, continued_state, run_task, task_input, warm_up
from analysis.progress import MapProgress, MapProgressReport, Progress

CONNECT_TIMEOUT_S = 5.0
WORKERS_TIMEOUT_S = 30.0
CHAIN_PRIORITY = 10  # continuation pieces are the critical path: they go first
IN_FLIGHT_PER_WORKER = 2  # one running, one ready to start: no worker waits for the driver


class SchedulerError(RuntimeError):
    """The Dask scheduler or its workers cannot take the map; the message says what to do."""


@dataclass(frozen=True)
class RunReport:
    """What one run computed: tasks and trajectories, wall time, workers and where."""

    tasks: int
    trajectories: int
    seconds: float
    workers: int
    where: str

    @property
    def rate_per_s(self) -> float:
        """Trajectories per second of wall time."""
        return self.trajectories / self.seconds if self.seconds > 0 else float("nan")



def default_workers() -> int:
    """Local worker processes unless told otherwise: one per core."""
    return os.cpu_count() or 1


class MapRunner:
    """Where a map's tasks run, ready before any file is written: this process (one worker),
    a new LocalCluster of worker processes, or the scheduler at an address.

    Use as a context manager; an unreachable scheduler, or workers with other software,
    fail on entry with :class:`SchedulerError`.
    """

    def __init__(self, workers: int | None = None, scheduler: str | None = None) -> None:
        self.workers = default_workers() if workers is None else workers
        if self.workers < 1:
            raise ValueError(f"workers = {self.workers}: need at least 1")
        self.scheduler = scheduler
        self.where = scheduler or ("this process" if self.workers == 1 else "local Dask cluster")
        self._dask: _DaskClient | None = None

    def __enter__(self) -> MapRunner:
        versions = warm_up()  # compiles here first (once per machine): workers load the cache
        if self.scheduler is not None or self.workers > 1:
            self._dask = _DaskClient(self.scheduler, self.workers, versions)
            client = self._dask.__enter__()
            self.workers = len(client.scheduler_info()["workers"])
        return self

    def __exit__(self, *exc: object) -> None:
        if self._dask is not None:
            self._dask.__exit__(*exc)
            self._dask = None

    @property
    def client(self) -> Any:
        """The Dask client of the workers (None when the map runs in this process)."""
        return None if self._dask is None else self._dask.client

    def map(self, function: Callable[[Any], Any], inputs: Sequence[Any]) -> list[Any]:
        """``[function(x) for x in inputs]``, spread over the workers; results in order."""
        if self._dask is None:
            return [function(item) for item in inputs]
        client = self._dask.client  # one submission per input: no single large graph
        return client.gather([client.submit(function, item, pure=False) for item in inputs])

    def run(self, plan: MapPlan, store: MapStore,
            progress: MapProgressReport | None = None) -> RunReport:
        """Run every task of ``plan`` not yet done in ``store``, writing each as it finishes."""
        queue = _TaskQueue(plan, store)
        meter = _Meter(plan, store, progress)
        started = time.perf_counter()
        if self._dask is None:
            for task in queue.ready():  # in order: a sweep's piece finds the one before done
                store.write(task, run_task(queue.input(task)))
                meter.finished(task)
        else:
            _run_on(self._dask.client, queue, store, meter)
        seconds = time.perf_counter() - started
        return RunReport(meter.tasks_run, meter.trajectories_run, seconds, self.workers,
                         self.where)


class _TaskQueue:
    """Which pending tasks can start: every batch at once, a sweep's pieces in order."""

    def __init__(self, plan: MapPlan, store: MapStore) -> None:
        self.plan, self.store = plan, store
        self.pending = [task for task in plan.tasks if not store.done[task.index]]

    def ready(self) -> Iterator[Task]:
        """Pending tasks whose inputs are known now, in plan order (re-checked as they go)."""
        for task in list(self.pending):
            if self._startable(task):
                self.pending.remove(task)
                yield task

    def next_piece(self, task: Task) -> Task | None:
        """The pending piece that continues ``task``'s sweep, if any."""
        for candidate in self.pending:
            if candidate.chain_first == task.chain_first >= 0 and candidate.start == task.stop:
                self.pending.remove(candidate)
                return candidate
        return None

    def input(self, task: Task) -> TaskInput:
        """The task's input; a sweep's later piece starts where the piece before ended."""
        if task.chain_first < 0 or task.start == task.chain_first:
            return task_input(self.plan, task)
        final, status = self.store.state_after(task.start - 1)
        start = continued_state(final, status, self.plan.initial[task.chain_first])
        return task_input(self.plan, task, start)

    def _startable(self, task: Task) -> bool:
        if task.chain_first < 0 or task.start == task.chain_first:
            return True
        before = next(
            t for t in self.plan.tasks if t.stop == task.start and t.chain_first == task.chain_first
        )
        return bool(self.store.done[before.index])


class _Meter:
    """Counts finished tasks and reports progress."""

    def __init__(self, plan: MapPlan, store: MapStore,
                 progress: MapProgressReport | None) -> None:
        self.plan, self.progress = plan, progress
        self.started = time.perf_counter()
        self.tasks_run = self.trajectories_run = 0
        done = [task for task in plan.tasks if store.done[task.index]]
        self.tasks_done = len(done)
        self.trajectories_done = sum(task.size for task in done)
        self.report()

    def finished(self, task: Task) -> None:
        self.tasks_run += 1
        self.trajectories_run += task.size
        self.tasks_done += 1
        self.trajectories_done += task.size
        self.report()

    def report(self) -> None:
        if self.progress is None:
            return
        elapsed = time.perf_counter() - self.started
        rate = self.trajectories_run / elapsed if self.trajectories_run else float("nan")
        left = self.plan.trajectories - self.trajectories_done
        eta = left / rate if self.trajectories_run else float("nan")
        self.progress(
            MapProgress(
                Progress(self.tasks_done, len(self.plan.tasks)),
                Progress(self.trajectories_done, self.plan.trajectories), elapsed, rate, eta,
            )
        )


def _run_on(client: Any, queue: _TaskQueue, store: MapStore, meter: _Meter) -> None:
    """Keep every worker busy with about IN_FLIGHT_PER_WORKER tasks, write results as they
    come, and send each sweep's next piece at once, ahead of the batches still waiting."""
    from distributed import as_completed

    running: dict[str, Task] = {}
    run_id = uuid.uuid4().hex  # task keys unique on a scheduler shared by several maps
    waiting = list(queue.ready())
    limit = IN_FLIGHT_PER_WORKER * max(1, len(client.scheduler_info()["workers"]))

    def submit(task: Task) -> Any:
        future = client.submit(
            run_task,
            queue.input(task),
            key=f"impact-rig-map-{run_id}-{task.index}",
            priority=CHAIN_PRIORITY if task.chain_first >= 0 else 0,
            pure=False,
        )
        running[future.key] = task
        return future

    futures = as_completed()
    while waiting and len(running) < limit:
        futures.add(submit(waiting.pop(0)))
    for future in futures:
        task = running.pop(future.key)
        store.write(task, future.result())
        future.release()
        meter.finished(task)
        following = queue.next_piece(task) if task.chain_first >= 0 else None
        if following is not None:
            futures.add(submit(following))
        while waiting and len(running) < limit:
            futures.add(submit(waiting.pop(0)))


class _DaskClient:
    """A Dask client on the scheduler at ``address``, or on a new LocalCluster of ``workers``
    processes (closed on exit); every worker loads the integrator and must compute with the
    same software as this process (``local``: what :func:`analysis.maps.tasks.warm_up` says
    here), or the map would not be the same bit for bit."""

    def __init__(self, address: str | None, workers: int, local: dict[str, str]) -> None:
        self.address, self.workers, self.local = address, workers, local
        self.cluster: Any = None
        self.client: Any = None

    def __enter__(self) -> Any:
        from distributed import Client, LocalCluster

        try:
            if self.address is None:
                self.cluster = LocalCluster(
                    n_workers=self.workers, threads_per_worker=1, processes=True,
                    dashboard_address=":0", silence_logs=logging.ERROR,
                )
                self.client = Client(self.cluster)
                # a busy machine may still be registering the processes: count (and check)
                # them all, not the ones that happened to be up
                try:
                    self.client.wait_for_workers(self.workers, timeout=WORKERS_TIMEOUT_S)
                except TimeoutError:
                    raise SchedulerError(
                        f"{len(self.client.nthreads())} of the {self.workers} local worker "
                        f"processes started within {WORKERS_TIMEOUT_S:g} s; ask for fewer "
                        "with --workers, or free the machine"
                    ) from None
            else:
                self.client = _connect(self.address)
            _check_workers(self.client, self.local)
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self.client

    def __exit__(self, *exc: object) -> None:
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def _connect(address: str) -> Any:
    from distributed import Client

    try:
        client = Client(address, timeout=CONNECT_TIMEOUT_S)
    except (OSError, TimeoutError, ValueError) as error:
        reason = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise SchedulerError(
            f"cannot reach the Dask scheduler at {address} within {CONNECT_TIMEOUT_S:g} s "
            f"({reason}); start one with 'dask scheduler' and workers with 'dask worker "
            f"{address}', or leave out --scheduler to run on this machine"
        ) from None
    try:
        client.wait_for_workers(1, timeout=WORKERS_TIMEOUT_S)
    except TimeoutError:
        client.close()
        raise SchedulerError(
            f"the Dask scheduler at {address} has had no workers for {WORKERS_TIMEOUT_S:g} s; "
            f"start some with 'dask worker {address} --nthreads 1'"
        ) from None
    return client


def _check_workers(client: Any, local: dict[str, str]) -> None:
    """Warm every worker up and refuse one that computes with other software."""
    for worker, versions in client.run(warm_up).items():
        for name, version in versions.items():
            if version != local.get(name):
                raise SchedulerError(
                    f"worker {worker} has {name} {version}, this machine {local.get(name)}: "
                    "install the same versions everywhere, or the map would not be the "
                    "same bit for bit"
                )
