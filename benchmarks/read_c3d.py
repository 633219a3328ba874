"""Benchmark: mocaplib.read_c3d vs ezc3d vs the c3d package's read_frames, in one run.

Writes a 6,000-frame, 40-marker capture (a person-like cloud walking along X, with gaps) in
float and in integer storage with mocaplib's writer into a temporary folder, then times reading
each file completely into memory (median of --repeats runs) and checks mocaplib's coordinates
against ezc3d's. When the real files are present (the folder ``shared/data/c3d`` beside the
repository), also times them (mocaplib vs ezc3d). Prints a Markdown table (``--markdown PATH``
also writes it into a results page, :mod:`markdown_results`).

    python benchmarks/read_c3d.py [--repeats 7] [--frames 6000] [--markers 40] [--markdown PATH]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from mocaplib.io.c3d import read_c3d  # noqa: E402
from mocaplib.io.c3d_write import write_c3d  # noqa: E402

REAL_FILES = Path(__file__).resolve().parents[2] / "shared" / "data" / "c3d"


def walking_cloud(frames: int, markers: int, rate: float) -> np.ndarray:
    """(F, M, 3) metres, Z up: a 1.7 m tall cloud moving at 1.3 m/s along X, 2 % missing."""
    rng = np.random.default_rng(0)
    body = np.column_stack([rng.normal(0, 0.1, markers), rng.normal(0, 0.15, markers),
                            rng.uniform(0.05, 1.7, markers)])
    t = np.arange(frames) / rate
    cloud = body[None] + np.column_stack([1.3 * t, np.zeros(frames), np.zeros(frames)])[:, None]
    cloud += rng.normal(0, 0.005, cloud.shape)
    cloud[rng.random(cloud.shape[:2]) < 0.02] = np.nan
    return cloud


def read_ezc3d(path: Path) -> np.ndarray:
    import ezc3d

    return ezc3d.c3d(str(path))["data"]["points"]


def read_c3d_package(path: Path) -> list:
    import c3d

    with open(path, "rb") as handle, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "No analog data found in file."
        return [points for _, points, _ in c3d.Reader(handle).read_frames()]


def median_time(function, path: Path, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function(path)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--frames", type=int, default=6000)
    parser.add_argument("--markers", type=int, default=40)
    add_markdown_option(parser)
    args = parser.parse_args()
    with markdown_page(args.markdown, __file__):
        compare(args)
    return 0


def compare(args) -> None:
    """Time the three readers as the parsed ``args`` ask and print the table."""
    rate = 100.0
    cloud = walking_cloud(args.frames, args.markers, rate)
    labels = [f"M{i:02d}" for i in range(args.markers)]
    print(f"{args.frames} frames x {args.markers} markers, median of {args.repeats} runs\n")
    print("| storage | mocaplib | ezc3d | c3d read_frames | ezc3d / mocaplib "
          "| c3d / mocaplib | max abs diff vs ezc3d |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for storage in ("float", "integer"):
            path = write_c3d(Path(folder) / f"{storage}.c3d", cloud, labels, rate,
                             integer=storage == "integer")
            ours = median_time(read_c3d, path, args.repeats)
            theirs = median_time(read_ezc3d, path, args.repeats)
            package = median_time(read_c3d_package, path, args.repeats)

            trial = read_c3d(path)
            reference = read_ezc3d(path)[:3].transpose(2, 1, 0) * 1e-3
            same_mask = np.array_equal(np.isnan(trial.markers), np.isnan(reference))
            difference = np.nanmax(np.abs(trial.markers - reference))
            print(f"| {storage} | {ours * 1e3:.1f} ms | {theirs * 1e3:.1f} ms | "
                  f"{package * 1e3:.1f} ms | {theirs / ours:.1f}x | {package / ours:.1f}x | "
                  f"{difference:.1e} m{'' if same_mask else ' (valid masks DIFFER)'} |")
    real = sorted(REAL_FILES.rglob("*.c3d")) if REAL_FILES.is_dir() else []
    if real:  # the c3d package refuses 2 of them, so it is left out of this row
        ours = sum(median_time(read_c3d, path, args.repeats) for path in real)
        theirs = sum(median_time(read_ezc3d, path, args.repeats) for path in real)
        print(f"| all {len(real)} real files (sum of medians) | {ours * 1e3:.1f} ms | "
              f"{theirs * 1e3:.1f} ms | - | {theirs / ours:.1f}x | - | see tests (<= 1e-6 m) |")


if __name__ == "__main__":
    raise SystemExit(main())
