"""The worker pool: a dead worker fails only its task (after one more try), no worker outlives
the pool or its parent, and every task runs with one BLAS thread.

The task functions live in this module so that spawned workers can import them.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from mocaplib.build.workers import MAX_ATTEMPTS, WorkerDied, max_jobs, run_tasks

needs_two = pytest.mark.skipif(max_jobs() < 2, reason="needs two processors for two workers")


def square(x):
    return x * x


def fail(x):
    raise ValueError(f"bad {x}")


def die_first_time(marker: str, x):
    """Kill this worker (as the out-of-memory killer would) unless ``marker`` exists."""
    if not os.path.exists(marker):
        Path(marker).write_text("died once")
        os.kill(os.getpid(), signal.SIGKILL)
    return x


def die(x):
    os.kill(os.getpid(), signal.SIGKILL)


def pid_and_threads(_):
    from threadpoolctl import threadpool_info

    return os.getpid(), sorted({pool["num_threads"] for pool in threadpool_info()})


def outcomes(function, tasks, jobs):
    found = {}
    for i, value, error in run_tasks(function, tasks, jobs=jobs):
        assert i not in found, "each task has one outcome"
        found[i] = value if error is None else error
    return [found[i] for i in range(len(tasks))]


def gone(pid: int) -> bool:
    """Whether ``pid`` no longer runs (a zombie left for its parent to reap counts as gone)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(") ", 1)[1][0] == "Z"
    except FileNotFoundError:
        return True


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_raising_task_fails_alone(jobs):
    results = outcomes(fail, [(1,)], jobs) + outcomes(square, [(2,), (3,)], jobs)
    assert isinstance(results[0], ValueError) and str(results[0]) == "bad 1"
    assert results[1:] == [4, 9]


@needs_two
def test_a_task_whose_worker_dies_is_given_to_a_new_worker_once(tmp_path):
    marker = str(tmp_path / "died")
    results = outcomes(die_first_time, [(marker, "killed then done"), (marker, 7)], jobs=2)
    assert results == ["killed then done", 7]
    assert Path(marker).read_text() == "died once"


@needs_two
def test_a_task_that_kills_every_worker_fails_alone_and_the_others_finish():
    tasks = [(i,) for i in range(6)]
    results = outcomes(_square_or_die, tasks, jobs=2)
    assert [r for i, r in enumerate(results) if i != 3] == [0, 1, 4, 16, 25]
    assert isinstance(results[3], WorkerDied)
    assert f"died, {MAX_ATTEMPTS} times" in str(results[3]) and "SIGKILL" in str(results[3])


def _square_or_die(x):
    return die(x) if x == 3 else square(x)


@pytest.mark.parametrize("jobs", [1, 2])
def test_every_task_runs_with_one_blas_thread(jobs):
    # a multi-threaded BLAS sums in an order that depends on its thread count: pinned to one,
    # a task gives the same bits in this process (--jobs 1) and in a worker (--jobs 2)
    for _, threads in outcomes(pid_and_threads, [(i,) for i in range(3)], jobs):
        assert threads == [1]


@needs_two
def test_no_worker_outlives_the_pool_even_when_it_is_left_early():
    pids = {pid for pid, _ in outcomes(pid_and_threads, [(i,) for i in range(4)], jobs=2)}
    assert os.getpid() not in pids and len(pids) >= 1
    assert all(gone(pid) for pid in pids)
    tasks = run_tasks(pid_and_threads, [(i,) for i in range(4)], jobs=2)
    _, (pid, _), _ = next(tasks)
    tasks.close()  # the consumer stops: the pool ends its workers at once
    assert gone(pid)


@needs_two
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_workers_end_when_their_parent_is_killed(tmp_path):
    pids = tmp_path / "pids"
    script = textwrap.dedent(f"""
        import os, sys, time
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_workers import record_and_sleep
        from mocaplib.build.workers import run_tasks
        if __name__ == "__main__":
            list(run_tasks(record_and_sleep, [({str(pids)!r},)] * 2, jobs=2))
        """)
    parent = subprocess.Popen([sys.executable, "-c", script], start_new_session=True)
    try:
        workers = wait_for_lines(pids, 2)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        assert wait_until(lambda: not session_processes(parent.pid)), \
            f"left running after kill -9 of their parent: {session_processes(parent.pid)}"
        assert all(gone(pid) for pid in workers)
    finally:
        for pid in session_processes(parent.pid):
            os.kill(pid, signal.SIGKILL)


def record_and_sleep(path: str) -> None:
    with open(path, "a") as out:
        out.write(f"{os.getpid()}\n")
    time.sleep(600)


def wait_for_lines(path: Path, n: int, limit_s: float = 60.0) -> list[int]:
    assert wait_until(lambda: path.exists() and len(path.read_text().split()) >= n, limit_s), \
        f"the workers did not start within {limit_s} s"
    return [int(line) for line in path.read_text().split()]


def wait_until(condition, limit_s: float = 30.0) -> bool:
    """Poll ``condition`` until it holds (True) or ``limit_s`` passes (False): a generous
    bound on how long a kill takes to land, not a speed requirement."""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.1)
    return condition()


def session_processes(session: int) -> list[int]:
    """Live processes of a session (a process started with ``start_new_session`` and every
    process it started, wherever they were re-parented)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(") ", 1)[1].split()
        except (FileNotFoundError, ProcessLookupError, IndexError):
            continue
        if int(fields[3]) == session and fields[0] != "Z":
            found.append(int(entry.name))
    return found


@needs_two
def test_a_function_workers_cannot_import_fails_its_tasks(capfd):
    import types

    ghost = types.ModuleType("ghost_module")  # exists in this process only
    exec("def same(x):\n    return x\n", ghost.__dict__)
    sys.modules["ghost_module"] = ghost
    try:
        results = outcomes(ghost.same, [(1,), (2,)], jobs=2)
    finally:
        del sys.modules["ghost_module"]
    assert all(isinstance(r, ModuleNotFoundError) for r in results)
    assert "Traceback" not in capfd.readouterr().err


@needs_two
def test_a_function_defined_in_a_script_runs_in_workers(tmp_path):
    # as with multiprocessing's spawn, workers import the script's main module (its
    # `if __name__ == "__main__":` part does not run there)
    script = tmp_path / "script.py"
    script.write_text(textwrap.dedent("""
        from mocaplib.build.workers import run_tasks

        def triple(x):
            return 3 * x

        if __name__ == "__main__":
            print(sorted(value for _, value, _ in run_tasks(triple, [(1,), (2,)], jobs=2)))
        """))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0 and done.stdout == "[3, 6]\n", done.stderr


@pytest.mark.parametrize("chosen", [None, "2"])
def test_the_command_line_runs_numpy_with_one_blas_thread_unless_told(chosen):
    # the solver's batched small matrices: more threads only compete (and change the last bits)
    code = ("import sys\nfrom mocaplib.cli import main\nmain(['--version'])\n"
            "import numpy\nfrom threadpoolctl import threadpool_info\n"
            "print(sorted({i['num_threads'] for i in threadpool_info() "
            "if i['user_api'] == 'blas'}))")
    env = {k: v for k, v in os.environ.items()
           if k not in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    if chosen:
        env["OPENBLAS_NUM_THREADS"] = chosen
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    expected = [1] if chosen is None else [min(int(chosen), os.cpu_count() or 1)]
    assert done.stdout.splitlines()[-1] == str(expected)
