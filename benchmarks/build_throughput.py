"""The throughput section of ``benchmarks/build.py``: captures/s against the number of captures
for local jobs and Dask clusters, the overhead per capture of each, the Dask target met/missed;
and (:func:`dask_memory`) the CPU time and page faults of one batch in a Dask worker.

Each size N (10, 30, 100, 300, 1000 captures; ``--quick`` stops at 100) is a temporary folder
of N copies of the sample captures, built uncached by every *way*, one after the other:

* ``jobs 1`` and ``jobs 2``: local worker processes (``build_library(jobs=...)``);
* ``LocalCluster``: a Dask ``LocalCluster`` of 2 worker processes x 1 thread, started afresh
  for each size (its start-up is printed apart: a cluster runs before a build is sent to it;
  its workers' warm-up is in the build's time, as a local worker's is; they import this
  script, and mocaplib with it, as they start);
* ``by hand``: ``dask scheduler --port 0 --scheduler-file F`` and two ``dask worker
  --scheduler-file F --nthreads 1 --preload mocaplib.build.workflow`` processes (as the guide
  starts them: the workers import mocaplib as they start, in the cluster's start-up), started
  for each size and stopped by the benchmark; their first build (the workers warm up in it)
  and ``by hand, warm``, a second build on the same workers (a cluster that served a build
  before);
* ``LocalCluster, 1 a task`` (sizes up to 100): the same cluster sent one capture a task, what
  batching saves.

The overhead per capture of a way is ``wall x workers / N - c``, ``c`` the compute per capture
of ``jobs 1`` (its stages' seconds summed over the captures, divided by N): what a capture
costs beyond its own stages. The target: a Dask way's seconds per capture at most 10 % above
those of ``jobs 2`` (the same two workers), i.e. its overhead per capture within 10 % of a
local job's cost per capture.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mocaplib.build.dask_batches import run_batch
from mocaplib.build.pipeline import build_library
from mocaplib.build.threads import pinned
from mocaplib.build.workflow import process_capture
from mocaplib.io.atomic import atomic_write_bytes

SIZES = (10, 30, 100, 300, 1000)
QUICK_SIZES = (10, 30, 100)
#: Sizes up to which the Dask cluster is also sent one capture a task.
UNBATCHED_UP_TO = 100
#: The module hand-started workers import as they start (``dask worker --preload``): the
#: stages a capture runs, as the guide's SLURM examples start them.
WORKER_PRELOAD = "mocaplib.build.workflow"
#: Dask ways meet the target when their seconds per capture are at most this ratio of jobs 2's.
TARGET_RATIO = 1.10
WORKERS = 2
PLOT_NAME = "build_throughput.png"
START_TIMEOUT_S = 60


def copies(captures: list[Path], count: int, folder: Path) -> Path:
    """``folder`` filled with ``count`` captures: the ``captures`` copied in turn, each round
    in its own sub-folder (names repeat across rounds)."""
    for k in range(count):
        source = captures[k % len(captures)]
        target = folder / f"round{k // len(captures)}" / source.name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(source, target)
    return folder


@contextlib.contextmanager
def kept_environment():
    """Put ``os.environ`` back as it was: a Dask nanny sets its workers' variables
    (``MALLOC_TRIM_THRESHOLD_``, thread counts) in the process that starts it, which the next
    local build's workers would inherit."""
    saved = dict(os.environ)
    try:
        yield
    finally:
        os.environ.clear()
        os.environ.update(saved)


@contextlib.contextmanager
def local_cluster(workers: int = WORKERS):
    """A Dask LocalCluster of ``workers`` worker processes x 1 thread: its address, and the
    seconds it took to start."""
    from distributed import LocalCluster

    with kept_environment():
        start = time.perf_counter()
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster:
            yield cluster.scheduler_address, time.perf_counter() - start


@contextlib.contextmanager
def cluster_by_hand(folder: Path):
    """``dask scheduler`` and :data:`WORKERS` ``dask worker`` processes started here (this
    checkout on their import path, :data:`WORKER_PRELOAD` imported as they start), stopped at the end: the scheduler's address, and the
    seconds until every worker had joined."""
    from distributed import Client

    dask = str(Path(sys.executable).with_name("dask"))
    address_file = folder / "scheduler.json"
    env = os.environ | {"PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[1]),
                                                       os.environ.get("PYTHONPATH", "")])}
    quiet = {"env": env, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    start = time.perf_counter()
    processes = [subprocess.Popen([dask, "scheduler", "--port", "0", "--no-dashboard",
                                   "--scheduler-file", str(address_file)], **quiet)]
    try:
        while not address_file.exists():
            if time.perf_counter() - start > START_TIMEOUT_S:
                raise RuntimeError("the Dask scheduler did not start")
            time.sleep(0.1)
        processes += [subprocess.Popen([dask, "worker", "--scheduler-file", str(address_file),
                                        "--nthreads", "1", "--no-dashboard",
                                        "--preload", WORKER_PRELOAD], **quiet)
                      for _ in range(WORKERS)]
        with Client(scheduler_file=str(address_file)) as client:
            client.wait_for_workers(WORKERS, timeout=START_TIMEOUT_S)
            address = client.scheduler.address
        yield address, time.perf_counter() - start
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            try:
                process.wait(START_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def timed(folder: Path, settings, repeat: int, **how) -> tuple[float, object]:
    """Best wall time of ``repeat`` uncached builds of ``folder``, and the last result."""
    best, result = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        result = build_library([folder], settings, cache_dir=None, progress=False, **how)
        best = min(best, time.perf_counter() - start)
    return best, result


def measure(folder: Path, settings, repeat: int, batch_size: int | None,
            unbatched: bool) -> tuple[dict, dict, float]:
    """Every way's ``(wall s, workers, same library as jobs 1)`` on ``folder``, each cluster's
    start-up seconds, and jobs 1's compute seconds (its stages summed)."""
    rows, startups = {}, {}
    wall, reference = timed(folder, settings, repeat, jobs=1)
    compute = sum(sum(c.stage_times.values()) for c in reference.captures)
    library = reference.library.to_json()
    rows["jobs 1"] = (wall, 1, True)
    wall, result = timed(folder, settings, repeat, jobs=WORKERS)
    rows[f"jobs {WORKERS}"] = (wall, WORKERS, result.library.to_json() == library)
    with local_cluster() as (address, startups["LocalCluster"]):
        wall, result = timed(folder, settings, repeat, scheduler=address, batch_size=batch_size)
        rows["LocalCluster"] = (wall, WORKERS, result.library.to_json() == library)
    if unbatched:
        with local_cluster() as (address, _):
            wall, result = timed(folder, settings, repeat, scheduler=address, batch_size=1)
            rows["LocalCluster, 1 a task"] = (wall, WORKERS, result.library.to_json() == library)
    with tempfile.TemporaryDirectory() as scratch, \
            cluster_by_hand(Path(scratch)) as (address, startups["by hand"]):
        for way in ("by hand", "by hand, warm"):
            wall, result = timed(folder, settings, repeat, scheduler=address,
                                 batch_size=batch_size)
            rows[way] = (wall, WORKERS, result.library.to_json() == library)
    return rows, startups, compute


def throughput(args, captures: list[Path], settings) -> None:
    """Print the throughput tables and the target's verdict; draw the plot beside
    ``args.markdown`` (when given)."""
    sizes = QUICK_SIZES if args.quick else SIZES
    print(f"Throughput against the number of captures (copies of the {len(captures)} "
          f"captures, cache off, {WORKERS} workers for jobs {WORKERS} and Dask; best of "
          f"{args.repeat}; Dask batch size "
          f"{args.batch_size or 'chosen from the frame counts'}):\n")
    print("| captures | way | wall (s) | captures/s | s / capture / worker | overhead / capture "
          "(ms) | overhead / compute | same library |\n|---|---|---|---|---|---|---|---|")
    curves: dict[str, list[tuple[int, float]]] = {}
    verdicts, startup_lines = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for size in sizes:
            folder = copies(captures, size, Path(tmp) / f"n{size}")
            rows, startups, compute = measure(folder, settings, args.repeat, args.batch_size,
                                              size <= UNBATCHED_UP_TO)
            shutil.rmtree(folder)
            per_capture = compute / size
            for way, (wall, workers, same) in rows.items():
                cost = wall * workers / size
                print(f"| {size} | {way} | {wall:.1f} | {size / wall:.2f} | {cost:.3f} | "
                      f"{1000 * (cost - per_capture):.0f} | "
                      f"{(cost - per_capture) / per_capture:+.0%} | {same} |", flush=True)
                curves.setdefault(way, []).append((size, size / wall))
            local = rows[f"jobs {WORKERS}"][0]
            for way in ("LocalCluster", "by hand", "by hand, warm"):
                ratio = rows[way][0] / local
                verdicts.append((size, way, ratio))
            startup_lines.append(f"{size}: " + ", ".join(f"{way} {seconds:.1f} s"
                                                         for way, seconds in startups.items()))
    print("\nCluster start-up, seconds (not in the walls above):",
          "; ".join(startup_lines) + ".")
    print(f"\nTarget: a Dask way's seconds per capture at most {TARGET_RATIO - 1:.0%} above "
          f"jobs {WORKERS}'s (the same {WORKERS} workers):\n")
    print("| captures | way | wall / jobs 2 wall | target |\n|---|---|---|---|")
    for size, way, ratio in verdicts:
        print(f"| {size} | {way} | {ratio:.2f} | "
              f"{'met' if ratio <= TARGET_RATIO else 'missed'} |")
    missed = [(size, way) for size, way, ratio in verdicts if ratio > TARGET_RATIO]
    print(f"\nDask overhead within {TARGET_RATIO - 1:.0%} of local jobs: "
          + ("met at every size" if not missed else "missed at " + ", ".join(
              f"{size} ({way})" for size, way in missed)))
    if args.markdown is not None:
        plot = draw(curves, Path(args.markdown).with_name(PLOT_NAME))
        print(f"\n![Captures per second against the number of captures]({plot.name})")


def draw(curves: dict[str, list[tuple[int, float]]], path: Path) -> Path:
    """Captures/s against captures (log x), one line per way, written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot

    figure, axes = pyplot.subplots(figsize=(6.4, 4.0), dpi=100)
    for way, points in curves.items():
        sizes, rates = zip(*points)
        axes.plot(sizes, rates, marker="o", label=way)
    axes.set_xscale("log")
    axes.set_xlabel("captures in the build")
    axes.set_ylabel("captures per second")
    axes.set_ylim(bottom=0)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    figure.tight_layout()
    image = io.BytesIO()
    figure.savefig(image, format="png", metadata={"Software": None})
    pyplot.close(figure)
    return atomic_write_bytes(path, image.getvalue())


def task_cost(function, process, items) -> tuple[float, int]:
    """CPU seconds and minor page faults of this thread while ``function(process, items)``
    runs (what a Dask task runs, measured in the worker)."""
    import resource

    before, faults = time.thread_time(), resource.getrusage(resource.RUSAGE_THREAD).ru_minflt
    function(process, items)
    return (time.thread_time() - before,
            resource.getrusage(resource.RUSAGE_THREAD).ru_minflt - faults)


def unthresholded_batch(process, items) -> list:
    """:func:`mocaplib.build.dask_batches.run_batch` without its glibc thresholds: one BLAS
    thread only."""
    return pinned(lambda: [process(path, settings) for path, settings in items])


def dask_memory(captures: list[Path], settings, count: int = 20) -> None:
    """Print the CPU time and page faults of one batch of ``count`` captures in a Dask worker
    started as Dask starts them (its nanny's ``MALLOC_TRIM_THRESHOLD_``), with and without
    the batch's glibc thresholds, beside the same batch run in this process."""
    from distributed import Client

    items = [(str(path), settings) for path in captures[:count]]
    print(f"One batch of {len(items)} captures, CPU seconds and minor page faults of the "
          "task's thread (a warm-up batch of 2 first; CPU time, unlike wall time, hardly "
          "depends on the machine's other work):\n")
    print("| where | CPU s | page faults |\n|---|---|---|")
    task_cost(run_batch, process_capture, items[:2])
    cpu, faults = task_cost(run_batch, process_capture, items)
    print(f"| this process | {cpu:.2f} | {faults} |")
    with local_cluster(workers=1) as (address, _), Client(address) as client:
        client.submit(task_cost, run_batch, process_capture, items[:2], pure=False).result()
        for name, function in (("Dask worker, glibc thresholds (run_batch)", run_batch),
                               ("Dask worker, Dask's trim threshold", unthresholded_batch)):
            cpu, faults = client.submit(task_cost, function, process_capture, items,
                                        pure=False).result()
            print(f"| {name} | {cpu:.2f} | {faults} |")
