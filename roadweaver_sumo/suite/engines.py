"""Where the scenarios of a suite are built: a local process pool, or a Ray cluster.

Both run the same module-level job function on picklable jobs and hand each result to
``on_result`` as it arrives; the caller sorts everything into place, so the order in which jobs
finish never shows in the outputs.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import re
import signal
import socket
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from .. import children
from ..errors import RoadweaverError
from ..spec import MAX_WORKERS

ENGINES = ("local", "ray")
RAY_HINT = "install it with: pip install 'roadweaver-sumo[ray]'"


def default_workers() -> int:
    return os.cpu_count() or 1


def cores_busy(engine: str, workers: int | None) -> bool:
    """Whether the suite's workers keep every core busy: then each scenario is validated
    without a second process loading its net (``pipeline.make_scenario``). Ray runs a job per
    CPU of each node."""
    return engine == "ray" or check_workers(workers) >= default_workers()


def check_workers(workers: int | None) -> int:
    workers = default_workers() if workers is None else workers
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= MAX_WORKERS:
        raise RoadweaverError(f"--workers must be 1..{MAX_WORKERS}, got {workers!r}")
    return workers


def check_engine(engine: str, workers: int | None, address: str | None) -> None:
    """Fail early, before any work, on an unknown engine, bad worker count or missing Ray."""
    if engine not in ENGINES:
        raise RoadweaverError(f"unknown engine {engine!r}; choose one of {', '.join(ENGINES)}")
    if address is not None and engine != "ray":
        raise RoadweaverError("--address needs --engine ray")
    if engine == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise RoadweaverError(f"--engine ray needs Ray; {RAY_HINT}") from None
    if engine == "local" or address is None:
        check_workers(workers)
    if address is not None:
        _check_reachable(address)


def _check_reachable(address: str) -> None:
    """A HOST:PORT (or ray://HOST:PORT) that nothing answers on is an error within seconds;
    ray.init would retry for minutes. Other forms (``auto``) are left to Ray."""
    match = re.fullmatch(r"(?:ray://)?\[?([^\[\]]+?)\]?:(\d{1,5})", address.strip())
    if not match:
        return
    try:
        socket.create_connection((match.group(1), int(match.group(2))), timeout=5).close()
    except (OSError, ValueError, OverflowError) as exc:
        raise RoadweaverError(f"cannot reach Ray at {address}: {exc}") from None


def run_jobs(
    fn: Callable,
    jobs: Sequence,
    on_result: Callable,
    *,
    engine: str = "local",
    workers: int | None = None,
    address: str | None = None,
) -> None:
    """Run ``fn(job)`` for every job on ``engine`` and call ``on_result`` with each return value."""
    check_engine(engine, workers, address)
    if engine == "ray":
        _run_ray(fn, jobs, on_result, workers, address)
    else:
        _run_local(fn, jobs, on_result, check_workers(workers))


def _run_local(fn: Callable, jobs: Sequence, on_result: Callable, workers: int) -> None:
    """A process pool; 'spawn' so workers start clean whatever threads the caller runs (a forked
    copy of a process with threads can deadlock). When this process is interrupted (Ctrl-C,
    SIGTERM) or killed, the workers die, and with them their children (:func:`_worker_start`);
    the scenarios they were building are in the caller's staging folder."""
    context = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(max_workers=min(workers, max(len(jobs), 1)), mp_context=context,
                               initializer=_worker_start, initargs=(os.getpid(),))
    try:
        pending = {pool.submit(fn, job) for job in jobs}
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in sorted(done, key=id):
                on_result(future.result())
    except BrokenProcessPool:
        raise RoadweaverError("a worker process died (out of memory?)") from None
    except BaseException:
        for worker in multiprocessing.active_children():
            worker.kill()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _worker_start(parent_pid: int) -> None:
    """In each pool worker: die with the parent, and leave a terminal's Ctrl-C to it (it kills
    the workers), so that no worker prints a traceback of its own."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    children.die_with_parent(parent_pid)


def _run_ray(fn: Callable, jobs: Sequence, on_result: Callable, workers, address) -> None:
    """Ray tasks of one CPU each. Joins a running Ray (``ray.init`` already called, or
    ``address``) or starts a local one with ``workers`` CPUs, shut down again afterwards."""
    try:
        import ray
    except ImportError:
        raise RoadweaverError(f"--engine ray needs Ray; {RAY_HINT}") from None
    started_here = not ray.is_initialized()
    if started_here:
        options = {"include_dashboard": False, "log_to_driver": False,
                   "logging_level": logging.ERROR}  # fmt: skip
        if address is None:
            options["num_cpus"] = check_workers(workers)
        try:
            ray.init(address=address, **options)
        except Exception as exc:  # noqa: BLE001 - ray raises ConnectionError, RuntimeError...
            where = f"at {address}" if address else "locally"
            raise RoadweaverError(f"cannot start Ray {where}: {_one_line(exc)}") from None
    try:
        task = ray.remote(num_cpus=1)(fn)
        pending = [task.remote(job) for job in jobs]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                try:
                    result = ray.get(ref)
                except ray.exceptions.RayError as exc:
                    raise RoadweaverError(f"a Ray task failed: {_one_line(exc)}") from None
                on_result(result)
    finally:
        if started_here:
            ray.shutdown()


def _one_line(exc: Exception) -> str:
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    return lines[-1] if lines else type(exc).__name__
