"""Benchmark: mocaplib.read_c3d vs ezc3d vs the c3d package's read_frames, in one run.

Writes a 6,000-frame, 40-marker capture (a person-like cloud walking along X, with gaps, no
analog channels: every reader decodes the same words) in float and in integer storage with
mocaplib's writer into a temporary folder, then times reading each file completely into
memory (median of --repeats runs) and checks mocaplib's coordinates against ezc3d's. When the
real files are present (the folder ``shared/data/c3d`` beside the repository, or
``$MOCAPLIB_SHARED_C3D`` as for the tests), also times them
(mocaplib vs ezc3d), twice for ezc3d: as its Python package reads (points, analogs, residuals
and rotations as numpy arrays) and like for like, the points alone (``ezc3d.ezc3d.c3d(path)
.get_points()``: its C++ reader cannot skip decoding the analog samples, but nothing else
becomes numpy). mocaplib reads the POINT words only and skips the analog samples.

``--big-gb X`` instead writes an X GB file (40 markers and 64 analog channels at 10 samples a
frame, so that the analog samples are four fifths of the file) and reads it in a fresh
process, reporting the peak resident memory and tracemalloc's peak against the marker array
and the file size. Prints Markdown tables (``--markdown PATH`` also writes them into a
results page, :mod:`markdown_results`).

    python benchmarks/read_c3d.py [--repeats 7] [--frames 6000] [--markers 40] [--big-gb X]
        [--markdown PATH]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
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

REAL_FILES = Path(os.environ.get("MOCAPLIB_SHARED_C3D",
                                 Path(__file__).resolve().parents[2] / "shared" / "data" / "c3d"))


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


def read_ezc3d_points(path: Path) -> np.ndarray:
    """ezc3d's C++ reader, then only its points as numpy (not the analogs, residuals...)."""
    import ezc3d

    return ezc3d.ezc3d.c3d(str(path)).get_points()


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
    parser.add_argument("--big-gb", type=float, default=0.0,
                        help="read a file of this many GB instead and report the memory it "
                             "takes")
    add_markdown_option(parser)
    args = parser.parse_args()
    with markdown_page(args.markdown, __file__):
        if args.big_gb:
            big_file(args.big_gb)
        else:
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
    if real:  # the c3d package refuses 2 of them, so it is left out of these rows
        ours = sum(median_time(read_c3d, path, args.repeats) for path in real)
        for what, reader in (("ezc3d: everything", read_ezc3d),
                             ("ezc3d: points only", read_ezc3d_points)):
            theirs = sum(median_time(reader, path, args.repeats) for path in real)
            print(f"| all {len(real)} real files, {what} (sum of medians) | {ours * 1e3:.1f} ms "
                  f"| {theirs * 1e3:.1f} ms | - | {theirs / ours:.1f}x | - | see tests "
                  "(<= 1e-6 m) |")


#: The big file's frame: 40 markers (4 float words each) and 64 analog channels x 10 samples.
BIG_MARKERS, BIG_ANALOG = 40, (64, 10)


def write_big(path: Path, gigabytes: float) -> int:
    """Write a float-storage C3D of about ``gigabytes`` GB: BIG_MARKERS markers walking, the
    analog channels of :data:`BIG_ANALOG`; returns the frame count. The header and parameters
    come from the ``c3d`` package's writer, the frames are written a chunk at a time."""
    import c3d

    frame_words = 4 * BIG_MARKERS + BIG_ANALOG[0] * BIG_ANALOG[1]
    frames = int(gigabytes * 1e9 // (4 * frame_words))

    class Frames:
        """What the writer reads of its frames: their count and the first one's shapes."""

        def __len__(self):
            return frames

        def __getitem__(self, index):
            return np.zeros((BIG_MARKERS, 5)), np.zeros(BIG_ANALOG)

    class Writer(c3d.Writer):
        def _write_frames(self, handle):
            cloud = walking_cloud(1000, BIG_MARKERS, 100.0) * 1000.0
            words = np.zeros((1000, frame_words), np.float32)
            words[:, 4 * BIG_MARKERS:] = 0.5
            for start in range(0, frames, 1000):
                n = min(1000, frames - start)
                points = words[:n, :4 * BIG_MARKERS].reshape(n, BIG_MARKERS, 4)
                points[..., :3] = np.nan_to_num(cloud[:n]) + [1300.0 * start / 100.0, 0, 0]
                points[..., 3] = np.where(np.isnan(cloud[:n, :, 0]), -1.0, 0.0)
                handle.write(words[:n].tobytes())

    writer = Writer(point_rate=100.0, analog_rate=1000.0, point_scale=-1.0, point_units="mm")
    writer.set_point_labels([f"M{i:02d}" for i in range(BIG_MARKERS)])
    writer.set_analog_labels([f"A{i:02d}" for i in range(BIG_ANALOG[0])])
    writer._frames = Frames()
    with open(path, "wb") as handle, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        writer.write(handle)
    return frames


#: Run in a fresh process: read the file, print the marker array's bytes, tracemalloc's peak,
#: the process's peak resident memory and the wall time.
_READ_IN_CHILD = """
import json, re, sys, time, tracemalloc
from pathlib import Path
from mocaplib.io.c3d import read_c3d
tracemalloc.start()
start = time.perf_counter()
trial = read_c3d(sys.argv[1])
seconds = time.perf_counter() - start
# the peak resident memory of this program (Linux: VmHWM; getrusage's maxrss would count
# the parent's pages shared before exec)
status = Path("/proc/self/status").read_text()
print(json.dumps({"frames": trial.n_frames, "markers": trial.markers.nbytes,
                  "peak": tracemalloc.get_traced_memory()[1], "seconds": seconds,
                  "rss": 1024 * int(re.search(r"VmHWM:\\s*(\\d+) kB", status).group(1))}))
"""


def big_file(gigabytes: float) -> None:
    """Write a ``gigabytes`` GB file and print the memory reading it takes."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "big.c3d"
        write_big(path, gigabytes)
        small = Path(folder) / "small.c3d"
        write_c3d(small, walking_cloud(10, BIG_MARKERS, 100.0), [f"M{i:02d}" for i in
                                                                 range(BIG_MARKERS)], 100.0)
        rss = {}
        for name, file in (("small", small), ("big", path)):
            done = subprocess.run([sys.executable, "-c", _READ_IN_CHILD, str(file)],
                                  capture_output=True, text=True, check=True)
            result = json.loads(done.stdout)
            rss[name] = result["rss"]
        size = path.stat().st_size
    mb = 1e-6
    print(f"\nA {size / 1e9:.2f} GB file ({result['frames']} frames, {BIG_MARKERS} markers, "
          f"{BIG_ANALOG[0]} analog channels x {BIG_ANALOG[1]} samples a frame), read in a "
          f"fresh process in {result['seconds']:.1f} s:\n")
    print("| marker array | tracemalloc peak | peak resident memory | the same process on a "
          "10-frame file | file size |\n|---|---|---|---|---|")
    print(f"| {result['markers'] * mb:.0f} MB | {result['peak'] * mb:.0f} MB | "
          f"{rss['big'] * mb:.0f} MB | {rss['small'] * mb:.0f} MB | {size * mb:.0f} MB |")


if __name__ == "__main__":
    raise SystemExit(main())
