"""Dask builds in batches: captures grouped by frames into tasks, the libraries of local jobs,
a capture that fails alone, one BLAS thread and glibc's memory thresholds in every batch.

Through real LocalClusters (dask and distributed are in the test extra). Nothing here is
timed: ``benchmarks/build.py`` measures the throughput (docs/results/build.md).
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys

import pytest
from threadpoolctl import threadpool_info

from mocaplib.build.dask_batches import TASKS_PER_WORKER, dask_batches
from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
from mocaplib.cli import main
from mocaplib.errors import C3DError, MocapError
from mocaplib.io import find_captures
from mocaplib.io.c3d import c3d_frames, read_c3d

from test_pipeline import TRIPLES, build_bytes, calls, fake_process, write_captures

dask = pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")


@contextlib.contextmanager
def local_cluster(*, processes: bool):
    """A LocalCluster of 2 workers x 1 thread; the environment as it was afterwards (a nanny
    sets its workers' variables, MALLOC_TRIM_THRESHOLD_ among them, in this process too)."""
    saved = dict(os.environ)
    try:
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=processes,
                                      dashboard_address=None) as cluster:
            yield cluster.scheduler_address
    finally:
        os.environ.clear()
        os.environ.update(saved)


def test_captures_are_grouped_by_frames_in_input_order():
    # 42 walks of 250 frames (the unknown one counted as the median), one take of 9000:
    # 19500 frames, ceil(19500 / 2000) = 10 tasks of 1950 frames: 8 walks a task, the take alone
    frames = [250] * 40 + [9000] + [None, 250]
    batches = dask_batches(frames, workers=2, task_frames=2000)
    assert batches == [list(range(start, start + 8)) for start in range(0, 40, 8)] + [
        [40], [41, 42]]


def test_few_captures_keep_every_worker_busy():
    # 6 walks hold less than one task's frames, but TASKS_PER_WORKER x 2 workers > 6: one each
    assert TASKS_PER_WORKER * 2 >= 6
    assert dask_batches([250] * 6, workers=2, task_frames=2000) == [[k] for k in range(6)]


def test_a_batch_size_sets_the_captures_per_task():
    assert dask_batches([250] * 10, batch_size=4) == [[0, 1, 2, 3], [4, 5, 6, 7], [8, 9]]
    with pytest.raises(MocapError, match="batch size must be >= 1"):
        dask_batches([250] * 3, batch_size=0)


def test_frame_counts_come_from_the_header_as_the_reader_reads_them(sample_dir, tmp_path):
    for path in find_captures([sample_dir])[:5]:
        assert c3d_frames(path) == read_c3d(path).markers.shape[0], path
    broken = tmp_path / "broken.c3d"
    broken.write_bytes(b"\x02\x50" + bytes(100))
    with pytest.raises(C3DError, match="broken.c3d"):
        c3d_frames(broken)


def test_batches_on_a_local_cluster_give_the_libraries_of_local_jobs(sample_dir, tmp_path):
    captures = find_captures([sample_dir])[:6]
    settings = BuildSettings(static=sample_dir / "rest.c3d", static_pose="neutral")
    local = build_library(captures, settings, jobs=2, progress=False)
    with local_cluster(processes=True) as address:
        batched = build_library(captures, settings, scheduler=address, batch_size=3,
                                progress=False)
    assert local.ok and batched.ok and len(local.library) == 6
    assert build_bytes(batched, tmp_path / "dask") == build_bytes(local, tmp_path / "local")


def test_a_capture_that_raises_fails_alone_in_its_batch(tmp_path):
    paths = write_captures(tmp_path / "caps")
    paths[2].write_text(json.dumps({"crash": "a bug in a stage"}))
    local = build_library([tmp_path / "caps"], progress=False, process=fake_process)
    (tmp_path / "caps" / "calls.log").unlink()
    with local_cluster(processes=False) as address:
        batched = build_library([tmp_path / "caps"], scheduler=address, batch_size=5,
                                progress=False, process=fake_process)
    assert batched.summary()["failures"] == local.summary()["failures"] == [
        {"file": str(paths[2]), "stage": "worker",
         "reason": f"{paths[2]}: worker failed: RuntimeError: a bug in a stage"}]
    assert len(batched.library) == 4                      # the batch's other captures landed
    assert sorted(calls(tmp_path / "caps")) == sorted(p.name for p in paths)  # each ran once
    assert build_bytes(batched, tmp_path / "dask") == build_bytes(local, tmp_path / "local")


def blas_threads_process(path: str, settings: BuildSettings):
    """:func:`fake_process`, with the BLAS/OpenMP libraries' thread counts while it ran as
    the result's warnings."""
    result = fake_process(path, settings)
    result.warnings = [f"threads {info['num_threads']}" for info in threadpool_info()]
    return result


def test_a_batch_runs_with_one_blas_thread(tmp_path):
    write_captures(tmp_path / "caps")
    two = {name: 2 for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    with dask.config.set({"distributed.nanny.pre-spawn-environ": two}), \
            local_cluster(processes=True) as address:    # workers started with 2 BLAS threads
        result = build_library([tmp_path / "caps"], scheduler=address, batch_size=5,
                               progress=False, process=blas_threads_process)
    counts = {w for c in result.captures for w in c.warnings}
    assert counts == {"threads 1"}, counts


#: Page faults of 200 arrays of 1 MiB made and dropped, printed; with glibc_thresholds() when
#: the first argument says so.
FAULTS = """
import resource, sys
import numpy as np
from mocaplib.build.dask_batches import glibc_thresholds
def churn():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(200):
        np.ones(2 ** 17).sum()
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
churn()
with glibc_thresholds() if sys.argv[1] == "inside" else open(__file__):
    print(churn())
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's thresholds")
def test_a_batch_under_dasks_trim_threshold_does_not_fault_every_array(tmp_path):
    script = tmp_path / "faults.py"
    script.write_text(FAULTS)
    env = os.environ | {"MALLOC_TRIM_THRESHOLD_": "65536", "PYTHONPATH": os.pathsep.join(
        sys.path)}
    faults = {where: int(subprocess.run([sys.executable, str(script), where], env=env,
                                        capture_output=True, text=True, check=True).stdout)
              for where in ("inside", "outside")}
    # outside: each 1 MiB array is mapped afresh, 256 pages faulted each time (51,200 in
    # all); inside it reuses the heap: a few hundred faults at most
    assert faults["outside"] > 200 * 200, faults
    assert faults["inside"] < faults["outside"] / 20, faults


def test_batch_size_without_a_scheduler_is_a_usage_error(tmp_path, sample_dir, capsys):
    code = main(["build", str(sample_dir / "rest.c3d"), "-o", str(tmp_path / "l.json"),
                 "--batch-size", "4"])
    assert code == 2
    assert "--batch-size sets the captures per Dask task" in capsys.readouterr().err


def test_a_capture_that_kills_its_worker_fails_alone_and_its_batch_lands(tmp_path):
    paths = write_captures(tmp_path / "caps", TRIPLES[:4])
    paths[1].write_text(json.dumps({"die": "always"}))
    # one task at a time per worker (no innocent task queued on the dying one), and Dask
    # gives a task up after its second worker died
    config = {"distributed.scheduler.allowed-failures": 1,
              "distributed.scheduler.worker-saturation": 1.0}
    with dask.config.set(config), local_cluster(processes=True) as address:
        result = build_library([tmp_path / "caps"], scheduler=address, batch_size=4,
                               progress=False, process=fake_process)
    failures = result.summary()["failures"]
    assert [(f["file"], f["stage"]) for f in failures] == [(str(paths[1]), "worker")], failures
    assert "KilledWorker" in failures[0]["reason"]
    assert len(result.library) == 3                        # the batch's other captures landed
