"""Worker processes that survive one another and never outlive their parent.

:func:`run_tasks` runs ``function(*arguments)`` for a list of tasks, in this process
(``jobs=1``) or in ``jobs`` worker processes (new interpreters), and yields each task's outcome as it
finishes. The batch build and the report's figures use it.

What it guarantees
    * A task that raises fails alone: its exception is its outcome.
    * A worker that dies (killed, out of memory, a crash in compiled code) fails no task but
      the one it was running: that task is given to a new worker once more
      (:data:`MAX_ATTEMPTS`), and fails with :class:`WorkerDied` if that worker dies too. The
      other tasks go on.
    * A task that runs longer than ``timeout`` seconds in a worker (a hang, a worker stopped
      with SIGSTOP) fails alone with :class:`TaskTimedOut`: its worker is killed and the
      other tasks go on. Tasks run in this process (``jobs=1``) have no time limit.
    * No worker outlives the pool: they are stopped when the pool ends, also on an error or
      Ctrl-C (workers ignore SIGINT and, on POSIX, run in their own process group; the parent
      stops them), and a worker whose parent dies (``kill -9``) ends too: on Linux the kernel
      kills it (``PR_SET_PDEATHSIG``), elsewhere it notices within :data:`PARENT_POLL_S` that
      its parent changed.
    * Every task runs with one BLAS/OpenMP thread (:func:`mocaplib.build.threads.pinned`), in a
      worker or not, so its floating-point results do not depend on ``jobs`` or on the
      machine's thread settings.
"""

from __future__ import annotations

import os
import pickle
import signal
import socket
import subprocess
import sys
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Iterator

from ..errors import MocapError
from .threads import pinned, single_threaded_workers

#: How often a task whose worker died is run: once more, in a new worker.
MAX_ATTEMPTS = 2
#: Seconds between a worker's checks that its parent still runs (where the kernel cannot
#: be asked to kill it with its parent).
PARENT_POLL_S = 1.0
#: Seconds idle workers get to exit after the pool's end before they are terminated.
STOP_TIMEOUT_S = 5.0


class WorkerDied(Exception):
    """The worker process running a task died, twice (see :data:`MAX_ATTEMPTS`)."""


class TaskTimedOut(Exception):
    """A task ran longer than its time limit; its worker process was killed."""


def max_jobs() -> int:
    """The processors this process may run on: more workers would only compete for them."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def run_tasks(function: Callable, tasks: list[tuple], *, jobs: int = 1,
              timeout: float | None = None
              ) -> Iterator[tuple[int, object, BaseException | None]]:
    """Run ``function(*tasks[i])`` for every task; yield ``(i, value, error)`` as each
    finishes (in any order): ``error`` is None, or the exception the task raised (``value``
    None), :class:`WorkerDied` or :class:`TaskTimedOut`.

    ``jobs``: worker processes (at most :func:`max_jobs` and one per task); 1 runs the tasks
    here, one after the other. ``function`` and the arguments must be picklable (a module-level
    function) when ``jobs`` > 1. ``timeout``: seconds a task may run in a worker before the
    worker is killed and the task fails (None: no limit; not applied with one job).
    """
    jobs = max(1, min(jobs, max_jobs(), len(tasks)))
    if jobs == 1:
        for index, arguments in enumerate(tasks):
            try:
                yield index, pinned(function, *arguments), None
            except Exception as exc:
                yield index, None, exc
        return
    yield from _Pool(jobs, timeout).run(function, tasks)


#: What a worker process runs (POSIX): the parent's import path, then :func:`_serve` on the
#: socket it inherited. SIGINT is ignored first: Ctrl-C is the parent's to handle.
_BOOTSTRAP = ("import signal, sys; signal.signal(signal.SIGINT, signal.SIG_IGN); "
              "sys.path[:] = {path!r}; from mocaplib.build.workers import _serve_socket; "
              "_serve_socket({fd}, {parent})")


class _Worker:
    """One worker process and the parent's end of the connection to it.

    On POSIX systems the worker is a new interpreter started with :data:`_BOOTSTRAP` in its own
    process group (a terminal's Ctrl-C reaches the parent only), talking over a socket pair:
    nothing it runs before :func:`_serve` can fail on a parent killed meanwhile. Elsewhere it
    is a ``multiprocessing`` "spawn" process.
    """

    def __init__(self):
        if os.name == "posix":
            from multiprocessing import spawn
            from multiprocessing.connection import Connection

            ours, theirs = socket.socketpair()
            with theirs:
                code = _BOOTSTRAP.format(path=sys.path, fd=theirs.fileno(), parent=os.getpid())
                self.process = subprocess.Popen([sys.executable, "-c", code],
                                                pass_fds=(theirs.fileno(),),
                                                stdin=subprocess.DEVNULL, process_group=0)
            self.connection = Connection(ours.detach())
            # as multiprocessing's spawn: the worker imports this process's main module too,
            # so that functions defined in a script can be sent
            preparation = spawn.get_preparation_data("mocaplib-worker")
            preparation.pop("authkey", None)  # multiprocessing's own secret: not needed
            self.connection.send(preparation)
        else:
            import multiprocessing

            context = multiprocessing.get_context("spawn")
            self.connection, child = context.Pipe()
            self.process = context.Process(target=_serve, args=(child, os.getpid()),
                                           daemon=True, name="mocaplib-worker")
            self.process.start()
            child.close()
        self.task: int | None = None
        self.started = 0.0      # time.monotonic() when it was given its task

    def send(self, message) -> None:
        self.connection.send(message)

    def receive(self):
        """The worker's reply, or None when it died (or closed its end) before sending one."""
        try:
            if self.connection.poll():
                return self.connection.recv()
        except (EOFError, OSError):
            pass
        return None

    def exit_code(self, timeout: float | None) -> int | None:
        """The process's exit code (negative: the signal that killed it) once it ended,
        waiting at most ``timeout`` s (None: as long as it takes); None if it still runs."""
        if isinstance(self.process, subprocess.Popen):
            try:
                return self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                return None
        self.process.join(timeout)
        return self.process.exitcode

    def end(self, timeout: float | None) -> int:
        """Wait at most ``timeout`` s for the process to end, kill it if it has not, release
        it; its exit code."""
        code = self.exit_code(timeout)
        if code is None:
            self.process.kill()
            code = self.exit_code(None)
        self.connection.close()
        if hasattr(self.process, "close"):  # multiprocessing.Process
            self.process.close()
        return code

    def bury(self) -> str:
        """Release a worker that died; how it ended, for people."""
        code = self.end(STOP_TIMEOUT_S)
        if code < 0:
            name = signal.Signals(-code).name if -code in signal.valid_signals() else -code
            kill = ", as the system's out-of-memory killer does" \
                if -code == getattr(signal, "SIGKILL", None) else ""
            return f"killed by signal {name}{kill}"
        return f"exited with code {code}"


class _Pool:
    """Workers started on demand, up to ``jobs``. New processes rather than forks of this one:
    the parent may hold threads (progress bar, BLAS) that a fork would copy mid-operation."""

    def __init__(self, jobs: int, timeout: float | None = None):
        self.jobs = jobs
        self.timeout = timeout
        self.workers: list[_Worker] = []

    def run(self, function, tasks):
        from multiprocessing.connection import wait

        pending = deque(range(len(tasks)))
        attempts: Counter = Counter()
        finished = False
        try:
            with single_threaded_workers():
                while pending or any(w.task is not None for w in self.workers):
                    self._hand_out(pending, function, tasks, attempts)
                    busy = [w for w in self.workers if w.task is not None]
                    # a worker's connection is ready with its reply, or at its end (EOF) when
                    # it died: only the worker holds the other end
                    ready = set(wait([w.connection for w in busy], self._time_left(busy)))
                    for worker in busy:
                        if worker.connection not in ready:
                            if self._overdue(worker):
                                yield self._end_overdue(worker)
                            continue
                        index, reply = worker.task, worker.receive()
                        worker.task = None
                        if reply is not None:
                            if worker.exit_code(0) is not None:  # died right after replying
                                self.workers.remove(worker)
                                worker.bury()
                            yield reply
                            continue
                        self.workers.remove(worker)
                        how = worker.bury()
                        if attempts[index] < MAX_ATTEMPTS:
                            pending.appendleft(index)
                        else:
                            yield index, None, WorkerDied(
                                f"the worker process running it died, {attempts[index]} times "
                                f"(last {how}); the other tasks went on")
            finished = True
        finally:
            self._stop(graceful=finished)

    def _time_left(self, busy: list[_Worker]) -> float | None:
        """Seconds until the first of the ``busy`` workers' tasks runs out of time (None: no
        limit)."""
        if self.timeout is None:
            return None
        return max(0.0, min(w.started for w in busy) + self.timeout - time.monotonic())

    def _overdue(self, worker: _Worker) -> bool:
        return self.timeout is not None and time.monotonic() - worker.started >= self.timeout

    def _end_overdue(self, worker: _Worker) -> tuple[int, None, TaskTimedOut]:
        """Kill the worker whose task ran out of time; the task's outcome."""
        index, worker.task = worker.task, None
        self.workers.remove(worker)
        worker.process.kill()
        worker.bury()
        return index, None, TaskTimedOut(
            f"it ran longer than its time limit of {self.timeout:g} s (a hang, or a worker "
            "stopped); its worker process was ended and the other tasks went on")

    def _hand_out(self, pending: deque, function, tasks, attempts: Counter) -> None:
        """Give pending tasks to idle workers, starting workers up to ``jobs``."""
        while pending:
            idle = next((w for w in self.workers if w.task is None), None)
            if idle is None and len(self.workers) < self.jobs:
                try:
                    idle = _Worker()
                except OSError as exc:  # no more processes or memory: go on with fewer
                    if not self.workers:
                        raise MocapError(f"cannot start a worker process: {exc}",
                                         hint="free memory or run with fewer jobs") from exc
                    self.jobs = len(self.workers)
                    return
                self.workers.append(idle)
            if idle is None:
                return
            index = pending.popleft()
            attempts[index] += 1
            idle.task, idle.started = index, time.monotonic()
            try:
                idle.send((index, pickle.dumps((function, tasks[index]))))
            except (BrokenPipeError, ConnectionError, EOFError):
                pass  # died meanwhile: its connection says so and the task is given again

    def _stop(self, *, graceful: bool) -> None:
        """End every worker: idle ones are asked to exit, others (or all, when the pool ends
        on an error or Ctrl-C) are terminated, and killed if they do not."""
        for worker in self.workers:
            if graceful and worker.task is None:
                try:
                    worker.send(None)
                except (OSError, EOFError):
                    pass
            else:
                worker.process.terminate()
        deadline = time.monotonic() + STOP_TIMEOUT_S
        for worker in self.workers:
            worker.end(max(0.0, deadline - time.monotonic()))
        self.workers = []


# --------------------------------------------------------------------------- worker side
def _serve_socket(fd: int, parent: int) -> None:
    """A POSIX worker (:data:`_BOOTSTRAP`): watch the parent, prepare as multiprocessing's
    spawn does (the parent's path, folder and main module), then :func:`_serve_tasks` on the
    socket ``fd`` it inherited. Nothing here can fail on a parent killed meanwhile: the
    connection just ends."""
    from multiprocessing import spawn
    from multiprocessing.connection import Connection

    _end_with_parent(parent)
    connection = Connection(fd)
    try:
        preparation = connection.recv()
    except (EOFError, OSError):
        return
    try:
        spawn.prepare(preparation)
    except Exception as exc:  # the parent's main module fails here: each task says so
        _serve_tasks(connection, failure=exc)
    else:
        _serve_tasks(connection)


def _serve(connection, parent: int) -> None:
    """A ``multiprocessing`` worker (not POSIX): ignore Ctrl-C, watch the parent, then
    :func:`_serve_tasks`."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    _end_with_parent(parent)
    _serve_tasks(connection)


def _serve_tasks(connection, *, failure: Exception | None = None) -> None:
    """Run each task received, send back ``(index, value, error)`` (``failure``, when given,
    is every task's error); stop at None or when the parent's end of the connection closes."""
    while True:
        try:
            task = connection.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        index, payload = task
        try:  # unpickled here, so that a function this process cannot import fails its task
            if failure is not None:
                raise failure
            function, arguments = pickle.loads(payload)
            reply = (index, pinned(function, *arguments), None)
        except Exception as exc:
            reply = (index, None, exc)
        try:
            connection.send(reply)
        except Exception as exc:  # a value or an exception that cannot be pickled
            connection.send((index, None, RuntimeError(
                f"the task's {'error' if reply[2] else 'result'} cannot be sent back: "
                f"{type(exc).__name__}: {exc}")))


def _end_with_parent(parent: int) -> None:
    """Make this process end when ``parent`` does: the kernel's parent-death signal on Linux,
    and a thread that checks the parent every :data:`PARENT_POLL_S` (everywhere: also covers
    a parent that died before the signal was set)."""
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass  # no prctl: the thread below does it
    if os.getppid() != parent:
        os._exit(1)

    def watch():
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="mocaplib-parent-watch", daemon=True).start()
