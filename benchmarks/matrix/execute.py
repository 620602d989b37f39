"""Run the cells: skip what the store has, run the rest in local processes or on Dask.

Every finished cell is written to the store the moment it arrives, and
matrix.csv is rewritten (atomically) after each, so an interrupted run loses
nothing that finished. Worker processes run numba single-threaded: the
parallelism is across cells. On SIGINT the workers are killed at once (a running
cell is recomputed by the next run); a worker whose parent dies exits with it.
"""

from __future__ import annotations

import ctypes
import math
import os
import signal
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from multiprocessing import get_context
from typing import Callable, Mapping

from hysbench.models.errors import HysbenchError

from .cells import Cell, run_cell
from .store import KEPT, CellStore


PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _worker_init(parent_pid: int) -> None:
    """Each worker: numba single-threaded, SIGINT left to the parent (which stops the workers itself: a
    Ctrl-C reaches the whole process group), and dying with its parent (``_die_with_parent``)."""
    import numba

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent_pid)
    numba.set_num_threads(1)


def _die_with_parent(parent_pid: int) -> None:
    """A worker whose parent is gone (even killed with SIGKILL) exits at once: on Linux the kernel sends it
    SIGKILL (prctl PR_SET_PDEATHSIG); elsewhere a daemon thread checks the parent's pid every second."""
    armed = False
    if sys.platform.startswith("linux"):
        try:
            armed = ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)
    if not armed:
        def watch():
            while os.getppid() == parent_pid:
                time.sleep(1.0)
            os._exit(1)

        threading.Thread(target=watch, name="hysbench-parent-watch", daemon=True).start()


def _abandon(pool: ProcessPoolExecutor, timeout: float = 1.0) -> None:
    """Stop the pool now: its worker processes are killed (a running cell is not waited for: the cells that
    finished are already in the store), its queued calls cancelled, and its manager thread, which then finds
    the workers dead, given ``timeout`` seconds to close its pipes. Python's exit joins that thread anyway;
    joined here, its closing of its wake-up pipe cannot overlap the exit's write to that pipe (which CPython
    before 3.12 does not lock: "Exception ignored ... Bad file descriptor" after the run's last line)."""
    manager = getattr(pool, "_executor_manager_thread", None)
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            proc.kill()
        except (OSError, ValueError):
            pass
    pool.shutdown(wait=False, cancel_futures=True)
    if manager is not None:
        manager.join(timeout)


def _progress(total: int, quiet: bool):
    from tqdm import tqdm

    return tqdm(total=total, unit="cell", disable=quiet or not sys.stderr.isatty(), file=sys.stderr,
                dynamic_ncols=True)


def run_matrix(cells: list[Cell], store: CellStore, *, jobs: int | None = None, dask_address: str | None = None,
               force: bool = False, on_result: Callable[[dict], None] | None = None, quiet: bool = False,
               expected_seconds: Mapping[str, float] | None = None) -> dict:
    """Run cells not already in the store; return {key: result dict} for all cells. ``expected_seconds``
    (by ``Cell.name``, e.g. an earlier run's times: ``report.seconds_per_cell``) starts the longest cells
    first, so that no worker is left with a long cell at the end; cells without a figure start before them."""
    results: dict[str, dict] = {}
    todo = []
    for cell in cells:
        cached = None if force else store.get(cell.key)
        if cached is not None:
            results[cell.key] = cached
        else:
            todo.append(cell)
    if expected_seconds:
        todo.sort(key=lambda c: -expected_seconds.get(c.name, math.inf))
    bar = _progress(len(cells), quiet)
    bar.update(len(cells) - len(todo))

    def finished(result: dict):
        if result["status"] in KEPT:
            store.put(result)
        results[result["key"]] = result
        bar.update(1)
        if on_result:
            on_result(result)

    try:
        if not todo:
            pass
        elif dask_address:
            _run_dask(todo, dask_address, finished, bar)
        else:
            jobs = jobs or os.cpu_count() or 1
            if jobs == 1 or len(todo) == 1:
                for cell in todo:
                    bar.set_description(cell.name)
                    finished(run_cell(cell))
            else:
                _run_processes(todo, jobs, finished, bar)
    finally:
        bar.close()
    return results


def _run_processes(todo: list[Cell], jobs: int, finished, bar) -> None:
    ctx = get_context("spawn")  # numba's threads do not survive fork
    pool = ProcessPoolExecutor(max_workers=min(jobs, len(todo)), mp_context=ctx, initializer=_worker_init,
                               initargs=(os.getpid(),))
    pending = {}
    try:
        pending = {pool.submit(run_cell, c): c for c in todo}
        while pending:
            running = ", ".join(c.name for c in list(pending.values())[:jobs])
            bar.set_description(running)
            # a timeout: a SIGINT the kernel hands to a helper thread runs its handler only when the main thread
            # next runs Python code, which a wait without one would put off until the next cell finishes
            done, _ = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            for fut in done:
                pending.pop(fut)
                finished(fut.result())
    except BaseException:  # e.g. SIGINT: stop within a second, keeping what finished
        for fut in pending:
            fut.cancel()
        _abandon(pool)
        raise
    pool.shutdown(wait=True)


def _run_dask(todo: list[Cell], address: str, finished, bar) -> None:
    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise HysbenchError("--dask needs the optional extra: pip install 'hysbench[dask]'") from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise HysbenchError(f"cannot connect to the Dask scheduler at {address}: {exc}") from None
    try:
        futures = [client.submit(run_cell, c, pure=False, key=f"hysbench-{c.key}") for c in todo]
        names = {f.key: c.name for f, c in zip(futures, todo)}
        for fut in as_completed(futures):
            bar.set_description(names.get(fut.key, ""))
            finished(fut.result())
    finally:
        client.close()
