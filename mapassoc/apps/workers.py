"""Local worker processes that stop on request: what ``batch`` and ``run --segments`` share.

Workers are started with the ``spawn`` method (no inherited threads or locks), run BLAS
on one thread each (the parallelism is the processes), and never die of a Ctrl-C: in a
terminal SIGINT reaches every process of the group, and a worker only records it, so
that its task stops at the next window boundary and reports back.  They start with
SIGINT and SIGTERM blocked (the parent blocks them while it starts them, and the mask is
inherited), and unblock them once their handlers are in place: a Ctrl-C while a worker
is still importing is recorded like any other, not a traceback.  The parent asks all of
them to stop through one shared event.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import multiprocessing
import os
import signal
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from mapassoc.apps.stopping import StopFlag
from mapassoc.errors import InputError

__all__ = ["process_pool", "run_on_pool", "worker_stop_requested", "usable_cores", "check_jobs"]

_STOP: StopFlag | None = None
_EVENT: Any = None
_STOP_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def usable_cores() -> int:
    """Cores this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def check_jobs(jobs: int | None) -> int:
    """``jobs`` checked (an integer >= 1), or the usable cores when None."""
    if jobs is None:
        return usable_cores()
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"jobs must be an integer >= 1, got {jobs!r}")
    return jobs


def _init_worker(event: Any) -> None:
    """Worker start: BLAS on one thread, SIGINT/SIGTERM only ask to stop."""
    for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(variable, "1")
    global _STOP, _EVENT
    _STOP, _EVENT = StopFlag(), event

    def handler(signum: int, frame: object) -> None:
        assert _STOP is not None
        _STOP.set(signal.Signals(signum).name)

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOP_SIGNALS)  # blocked since the start


@contextlib.contextmanager
def _stop_signals_blocked() -> Iterator[None]:
    """SIGINT and SIGTERM held back in this thread (and in the processes it starts) while
    the block runs; one that came meanwhile is handled when the block ends."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def worker_stop_requested() -> bool:
    """In a worker of :func:`process_pool`: whether this worker or the parent asked to stop.

    False outside such a worker.
    """
    if _STOP is None:
        return False
    return _STOP() or bool(_EVENT is not None and _EVENT.is_set())


@contextlib.contextmanager
def process_pool(workers: int) -> Iterator[tuple[concurrent.futures.ProcessPoolExecutor, Any]]:
    """A spawn process pool of ``workers`` and the event that asks its tasks to stop."""
    context = multiprocessing.get_context("spawn")
    event = context.Event()
    with concurrent.futures.ProcessPoolExecutor(
        max_workers=workers, mp_context=context, initializer=_init_worker, initargs=(event,)
    ) as pool:
        yield pool, event


Task = tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]
"""A call for a pool worker: ``(function, args, kwargs)``, all picklable."""


def run_on_pool(
    workers: int,
    tasks: Sequence[Task],
    *,
    on_done: Callable[[int, concurrent.futures.Future[Any]], None],
    stop: Callable[[], bool],
) -> None:
    """Run ``tasks`` on a :func:`process_pool`, reporting each finished one at once.

    ``on_done(index, future)`` is called in this process as each task ends (its result or
    its exception is the future's).  When ``stop()`` turns True the workers are asked to
    stop (their tasks poll :func:`worker_stop_requested`) and the tasks not started are
    cancelled (never reported); the call returns when the running ones have ended.
    """
    with process_pool(workers) as (pool, event):
        with _stop_signals_blocked():  # the submissions start the workers
            futures = {
                pool.submit(function, *args, **kwargs): index
                for index, (function, args, kwargs) in enumerate(tasks)
            }
        pending = set(futures)
        while pending:
            done, pending = concurrent.futures.wait(
                pending, timeout=0.2, return_when=concurrent.futures.FIRST_COMPLETED
            )
            for future in done:
                if not future.cancelled():
                    on_done(futures[future], future)
            if stop() and not event.is_set():
                event.set()
                for future in pending:
                    future.cancel()
