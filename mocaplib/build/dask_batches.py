"""Captures on a Dask distributed cluster, several to a task.

A Dask task costs milliseconds beyond its work (submitting it, serialising its arguments and
its result, the scheduler's bookkeeping, gathering the result through the scheduler), and a lab
walk takes a few tenths of a second to process. :func:`run_on_dask` therefore sends
*batches*: :func:`dask_batches` groups the captures, in input order, into tasks of about
:data:`TASK_FRAMES` frames each (about one to two seconds of work on one core), and into at
least :data:`TASKS_PER_WORKER` tasks per worker thread when there are captures enough, so that
the workers finish together. ``batch_size`` sets the captures per task instead.

What it guarantees
    * The same results as local jobs (:func:`mocaplib.build.workers.run_tasks`): each capture
      runs ``process(path, settings)`` with one BLAS/OpenMP thread
      (:func:`mocaplib.build.threads.pinned`), whatever the worker's thread settings.
    * A capture that raises fails alone: its exception is its outcome, the other captures of
      its batch run and their results come back.
    * A batch runs with glibc's own memory thresholds (:func:`glibc_thresholds`), not the
      trim threshold Dask's nanny starts its workers with, which costs a capture 20-45 %
      more CPU time in page faults (``benchmarks/build.py --dask-memory``).
    * A batch whose task fails as a whole (Dask gave up on it after its workers died,
      ``KilledWorker``; a result that cannot be serialised) is sent again one capture per
      task: only the captures that then fail again fail.
"""

from __future__ import annotations

import ctypes
import math
import os
import statistics
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

from ..errors import MocapError
from ..io.c3d import c3d_frames
from .threads import pinned

#: Frames of capture one Dask task holds, unless ``batch_size`` is given: 2000 frames take
#: 1-2 s on one core (the samples: about 0.6 ms a frame with a static, 1.2 ms calibrating
#: from each capture; docs/results/build.md).
TASK_FRAMES = 2000

#: Tasks per worker thread the batching keeps at least (fewer captures: one task each), so
#: that the last tasks finish close together.
TASKS_PER_WORKER = 4

#: Seconds to wait for a Dask scheduler to answer.
SCHEDULER_TIMEOUT_S = 20

#: glibc's ``mallopt`` parameters, the mmap threshold glibc's dynamic rule rises to at most
#: (64-bit) and the trim threshold that rule gives it (twice), bytes; the fixed mmap threshold
#: glibc keeps when the trim threshold is set (its default).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_DYNAMIC_MMAP_MAX, _DYNAMIC_TRIM_MAX = 32 * 2 ** 20, 64 * 2 ** 20
_FIXED_MMAP = 128 * 2 ** 10
_thresholds_lock = threading.Lock()
_batches_running = 0


def dask_batches(frames: Sequence[int | None], /, *, workers: int = 1,
                 batch_size: int | None = None,
                 task_frames: int = TASK_FRAMES) -> list[list[int]]:
    """Group captures into Dask tasks: lists of positions in ``frames``, in input order.

    Parameters
    ----------
    frames
        Each capture's frame count (None: unknown, e.g. unreadable; counted as the median of
        the known ones, or all alike when none is known).
    workers
        Worker threads of the cluster: at least ``TASKS_PER_WORKER * workers`` tasks are made
        (at most one per capture).
    batch_size
        Captures per task (the last task holds the rest); None chooses from ``frames``.
    task_frames
        Frames a task should hold about. With ``tasks = max(ceil(total / task_frames),
        TASKS_PER_WORKER * workers)`` (at most one per capture), captures are taken in input
        order into a task until it holds ``total / tasks`` frames; a capture of that many
        frames or more is a task of its own.
    """
    count = len(frames)
    if batch_size is not None:
        if batch_size < 1:
            raise MocapError(f"the batch size must be >= 1 capture per task, got {batch_size}")
        return [list(range(start, min(start + batch_size, count)))
                for start in range(0, count, batch_size)]
    known = [f for f in frames if f is not None]
    typical = statistics.median(known) if known else 1
    weights = [max(typical if f is None else f, 1) for f in frames]
    tasks = min(count, max(math.ceil(sum(weights) / task_frames),
                           TASKS_PER_WORKER * max(workers, 1)))
    share = sum(weights) / tasks
    batches: list[list[int]] = []
    current: list[int] = []
    held = 0.0
    for position, weight in enumerate(weights):
        if current and weight >= share:      # a long capture: a task of its own
            batches.append(current)
            current, held = [], 0.0
        current.append(position)
        held += weight
        if held >= share:
            batches.append(current)
            current, held = [], 0.0
    if current:
        batches.append(current)
    return batches


def run_batch(process: Callable, items: list[tuple[str, object]]) -> list[tuple]:
    """What a Dask task runs: ``process(path, settings)`` for each ``(path, settings)`` of
    ``items`` with one BLAS thread and glibc's own memory thresholds (:func:`glibc_thresholds`);
    ``[(result, None) or (None, exception)]`` in their order."""
    with glibc_thresholds():
        return pinned(_each, process, items)


def _each(process: Callable, items: list[tuple[str, object]]) -> list[tuple]:
    outcomes = []
    for path, settings in items:
        try:
            outcomes.append((process(path, settings), None))
        except Exception as exc:  # fails alone, as in a local worker
            outcomes.append((None, exc))
    return outcomes


@contextmanager
def glibc_thresholds():
    """Run the body with the memory thresholds glibc's allocator reaches by itself.

    Dask's nanny starts its workers with ``MALLOC_TRIM_THRESHOLD_=65536``, to give memory back
    to the system sooner. Setting it also fixes glibc's mmap threshold at 128 KiB, so every
    array larger than that is mapped and unmapped afresh: on the samples a batch then takes
    tens of times the page faults and 20-45 % more CPU time (``benchmarks/build.py
    --dask-memory``, docs/results/build.md). Inside the
    body, in a Linux process whose environment sets that variable, the mmap and trim thresholds
    are those glibc's dynamic rule rises to (32 and 64 MiB); when the last body running in the
    process ends, the variable's trim threshold and the fixed mmap threshold are set again and
    the free memory is given back (``malloc_trim``). Elsewhere it does nothing.
    """
    global _batches_running
    trim = os.environ.get("MALLOC_TRIM_THRESHOLD_", "")
    libc = _glibc() if trim.isdigit() else None
    if libc is None:
        yield
        return
    with _thresholds_lock:
        _batches_running += 1
        libc.mallopt(_M_MMAP_THRESHOLD, _DYNAMIC_MMAP_MAX)
        libc.mallopt(_M_TRIM_THRESHOLD, _DYNAMIC_TRIM_MAX)
    try:
        yield
    finally:
        with _thresholds_lock:
            _batches_running -= 1
            if not _batches_running:
                libc.mallopt(_M_MMAP_THRESHOLD, _FIXED_MMAP)
                libc.mallopt(_M_TRIM_THRESHOLD, int(trim))
                libc.malloc_trim(0)


def _glibc():
    """The C library when it is glibc (it has ``mallopt`` and ``malloc_trim``), else None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None)
    except OSError:
        return None
    return libc if hasattr(libc, "mallopt") and hasattr(libc, "malloc_trim") else None  # musl: no


def capture_frames(path: str | os.PathLike) -> int | None:
    """The frames of the capture ``path`` (:func:`mocaplib.io.c3d.c3d_frames`), None when its
    header cannot be read (its processing then fails and says why)."""
    try:
        return c3d_frames(path)
    except (MocapError, OSError):
        return None


def run_on_dask(process: Callable, work: list[tuple[int, object, object]], address: str, *,
                batch_size: int | None = None
                ) -> Iterator[tuple[int, object, BaseException | None]]:
    """Run ``process(path, settings)`` for each work item ``(index, path, settings)`` on the
    Dask scheduler at ``address``, in batches (:func:`dask_batches`); yield ``(index, result,
    error)`` as each batch finishes (``error`` None, or the exception the capture raised or
    its task's failure). Raises :class:`MocapError` when Dask is not installed or the
    scheduler does not answer."""
    try:
        from distributed import Client, as_completed
    except ImportError as exc:
        raise MocapError("a Dask scheduler needs the optional dask extra",
                         hint="pip install 'mocaplib[dask]'") from exc
    try:
        client = Client(address, timeout=f"{SCHEDULER_TIMEOUT_S}s")
    except (OSError, TimeoutError, ValueError) as exc:  # ValueError: not an address
        raise MocapError(f"cannot connect to the Dask scheduler at {address}: {exc}",
                         hint="start one with `dask scheduler` or check the address") from exc
    with client:
        frames = [None] * len(work) if batch_size else [capture_frames(p) for _, p, _ in work]
        batches = dask_batches(frames, workers=sum(client.nthreads().values()),
                               batch_size=batch_size)

        def submit(batch: list[int]):
            items = [(os.fspath(work[k][1]), work[k][2]) for k in batch]
            return client.submit(run_batch, process, items, pure=False)

        futures = {submit(batch): batch for batch in batches}
        running = as_completed(futures)
        for future in running:
            batch = futures.pop(future)
            try:
                outcomes = future.result()
            except Exception as exc:  # the whole task failed: its workers died, or its result
                if len(batch) > 1:    # cannot be sent; each capture is tried alone
                    for k in batch:
                        alone = submit([k])
                        futures[alone] = [k]
                        running.add(alone)
                    continue
                outcomes = [(None, exc)]
            future.release()
            for k, (result, error) in zip(batch, outcomes):
                yield work[k][0], result, error
