"""Benchmark `mocaplib build`: captures/s with 1 and 2 jobs, time per stage, growth with data,
and throughput against the number of captures for local jobs and Dask clusters.

Usage (from the repository root)::

    python benchmarks/build.py [SAMPLES] [--static FILE [--static-pose neutral]]
                               [--growth-captures N] [--repeat R] [--markdown PATH]
    python benchmarks/build.py --throughput [--quick] [--batch-size N] [SAMPLES]
                               [--static FILE [--static-pose neutral]] [--repeat R]
                               [--markdown PATH]
    python benchmarks/build.py --dask-memory [SAMPLES] [--static FILE [--static-pose neutral]]
                               [--markdown PATH]

Without ``--throughput`` or ``--dask-memory``:

1. Builds every capture in SAMPLES (default ``sample_c3d/``) with 1 job and with 2 jobs, cache
   off, and prints wall time, captures/s and the speed-up (ratio of the two wall times).
2. Prints the time spent in each stage, summed over captures (from the 1-job build).
3. Builds 1x, 2x and 4x the data — N captures (default: all of them) copied 1, 2 and 4 times
   into a temporary folder — with 2 jobs, and prints the wall time against the total number of
   frames, and the time per 1000 frames (flat means linear growth).

With ``--throughput`` (:mod:`build_throughput`): 10, 30, 100, 300 and 1000 copies of the
captures (``--quick``: up to 100) built with jobs 1, jobs 2, a Dask LocalCluster and a Dask
scheduler and workers started by hand; captures/s, the overhead per capture of each, the Dask
target (within 10 % of local jobs) printed met/missed, and with ``--markdown PATH`` the plot
``build_throughput.png`` beside the page. With ``--dask-memory``: the CPU time and page faults
of one batch of 20 captures in this process and in a Dask worker, with and without the
batch's glibc thresholds (:func:`mocaplib.build.dask_batches.glibc_thresholds`). ``--batch-size N`` sets the captures per Dask task
(default: chosen from the frame counts, as ``mocaplib build --scheduler`` does).

Timings are wall-clock seconds of one run each (``--repeat`` takes the best of R runs).
``--static`` / ``--static-pose`` calibrate as the quick start's main command does (default:
calibrate from each capture, as ``mocaplib build`` without ``--static``); cycles are cut at the
default toe-offs. Prints Markdown tables;
``--markdown PATH`` also writes them into a results page (:mod:`markdown_results`).
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from build_throughput import dask_memory, throughput  # noqa: E402
from markdown_results import add_markdown_option, markdown_page, shown  # noqa: E402
from mocaplib.build.pipeline import build_library
from mocaplib.io import find_captures
from mocaplib.build.settings import BuildSettings

STAGES = ("read", "import", "protocol", "filter", "calibrate", "fit", "events", "cycles",
          "entries")


def timed_build(inputs, settings: BuildSettings, jobs: int, repeat: int):
    """Best wall time of ``repeat`` uncached builds, and the result of the last one."""
    best, result = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        result = build_library(inputs, settings, jobs=jobs, cache_dir=None, progress=False)
        best = min(best, time.perf_counter() - start)
    return best, result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("samples", nargs="?", default=str(REPO / "sample_c3d"))
    parser.add_argument("--growth-captures", type=int, default=None,
                        help="captures used for the 1x/2x/4x growth runs (default: all)")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--static", default=None, help="static calibration capture")
    parser.add_argument("--static-pose", default="free", choices=("free", "neutral"))
    parser.add_argument("--throughput", action="store_true",
                        help="measure throughput against the number of captures, for local "
                             "jobs and Dask clusters (instead of the three tables)")
    parser.add_argument("--dask-memory", action="store_true",
                        help="measure the CPU time and page faults of one batch in a Dask "
                             "worker (instead of the three tables)")
    parser.add_argument("--quick", action="store_true",
                        help="throughput up to 100 captures (default: up to 1000)")
    parser.add_argument("--batch-size", type=int, default=None, metavar="N",
                        help="captures per Dask task in the throughput runs (default: chosen "
                             "from the frame counts)")
    add_markdown_option(parser)
    args = parser.parse_args()
    captures = find_captures([args.samples])
    if not captures:
        print(f"no captures in {args.samples}; generate the samples first", file=sys.stderr)
        return 1
    with markdown_page(args.markdown, __file__):
        if args.throughput:
            throughput(args, captures, BuildSettings(static=args.static,
                                                     static_pose=args.static_pose))
        elif args.dask_memory:
            dask_memory(captures, BuildSettings(static=args.static, static_pose=args.static_pose))
        else:
            report(args, captures)
    return 0


def report(args, captures) -> None:
    """Print the three tables for the parsed ``args`` and the ``captures`` found."""
    settings = BuildSettings(static=args.static, static_pose=args.static_pose)
    print(f"{len(captures)} captures in {shown(args.samples)}; static {args.static} "
          f"({args.static_pose})")

    one, result = timed_build([args.samples], settings, 1, args.repeat)
    two, result2 = timed_build([args.samples], settings, 2, args.repeat)
    same = result.library.to_json() == result2.library.to_json()
    n = len(captures)
    print(f"\n{sum(c.ok for c in result.captures)} captures processed, "
          f"{len(result.library)} entries\n")
    print("| jobs | wall time (s) | captures/s |\n|---|---|---|")
    print(f"| 1 | {one:.1f} | {n / one:.2f} |")
    print(f"| 2 | {two:.1f} | {n / two:.2f} |")
    print(f"\nspeed-up jobs=2 / jobs=1: {one / two:.2f}x; byte-identical libraries: {same}")

    totals = {s: sum(c.stage_times.get(s, 0.0) for c in result.captures) for s in STAGES}
    frames = sum(c.n_frames for c in result.captures)
    print(f"\nTime per stage (1 job, {frames} frames in total):\n")
    print("| stage | seconds | share |\n|---|---|---|")
    for stage, seconds in totals.items():
        print(f"| {stage} | {seconds:.2f} | {seconds / max(sum(totals.values()), 1e-9):.1%} |")

    subset = captures[:args.growth_captures] if args.growth_captures else captures
    print(f"\nGrowth (2 jobs, {len(subset)} captures copied k times):\n")
    print("| data | captures | frames | wall time (s) | s / 1000 frames |\n|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for k in (1, 2, 4):
            folder = Path(tmp) / f"x{k}"
            for copy in range(k):
                target = folder / f"copy{copy}"
                target.mkdir(parents=True)
                for path in subset:
                    shutil.copy2(path, target / path.name)
            wall, grown = timed_build([folder], settings, 2, args.repeat)
            total = sum(c.n_frames for c in grown.captures)
            print(f"| {k}x | {len(grown.captures)} | {total} | {wall:.1f} | "
                  f"{1000 * wall / total:.3f} |")


if __name__ == "__main__":
    sys.exit(main())
