"""Long takes: `mocaplib build` of one walk at several lengths, frames/s and peak memory.

Usage (from the repository root)::

    python benchmarks/long_takes.py [--frames N [N ...] | --quick] [--repeat R] [--all-cycles]
                                    [--markdown PATH] [--plot PATH]

1. Makes one synthetic walk (:mod:`mocaplib.synth`: the project's walker, fullbody38 markers
   at 100 Hz, 1.0 m/s around a circle of 3 m radius, as on a track) as long as the longest
   length asked for, and writes its first N frames as a C3D file for each length N (default
   6,000, 20,000, 60,000 and 100,000 frames, 1 to 17 minutes; ``--quick``: 3,000, 6,000 and
   12,000). The files hold no events: the build detects them, as on a lab's long take.
2. Runs ``python -m mocaplib build FILE -o LIBRARY --no-cache --jobs 1 --quiet`` on each
   in a fresh process and measures its wall time and peak resident memory (``ru_maxrss``
   of the process and what it waited for, from ``os.wait4``; the walk is made in another
   process so that this one, whose memory at the fork ``ru_maxrss`` also counts, stays
   small), and reads the time spent in
   the capture's stages from ``build_library`` run on it in another fresh process (the
   command's own time without start-up and writing).
3. Prints one row per length: frames/s of the whole command and of the stages, peak memory,
   and the ratio of each frames/s to the shortest length's, then each stage's seconds per
   10,000 frames; then the targets, met or missed: the longest take at >= 80 % of the
   shortest's frames/s (whole command, and stages alone: start-up counts for less in a long
   command), and under 1 GiB (1024 MiB) of peak memory.

``--repeat R`` keeps the fastest of R runs of each length (and the largest peak memory).
Prints Markdown; ``--markdown PATH`` also writes it into a results page
(:mod:`markdown_results`) and the plot of frames/s and peak memory against frames next to it
(``PATH`` with ``.png``; ``--plot PATH`` names another file). A one-entry library has no
control space: ``build`` writes it and exits with 1, which this script accepts when the
library holds the capture's entry.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from markdown_results import add_markdown_option, markdown_page, shown  # noqa: E402
from mocaplib.io.c3d_write import write_c3d  # noqa: E402
from mocaplib.library.command import Command  # noqa: E402
from mocaplib.synth.capture import synthesize_capture  # noqa: E402

FRAMES = (6_000, 20_000, 60_000, 100_000)
QUICK = (3_000, 6_000, 12_000)
RATE = 100.0
#: The walk: 1.0 m/s turning at 1/3 rad/s (a circle of 3 m radius), so that a take of any
#: length stays within a lab's volume.
WALK = Command(v_f=1.0, omega=1.0 / 3.0)
#: Targets of the longest take against the shortest.
MIN_SPEED_RATIO, MAX_PEAK_MIB = 0.8, 1024.0

#: Run in a fresh process: build one capture in-process and print its stage times as JSON.
STAGES_SCRIPT = """
import json, sys
from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
settings = BuildSettings(all_cycles=sys.argv[2] == "all")
result = build_library([sys.argv[1]], settings, jobs=1, cache_dir=None, progress=False)
print(json.dumps(result.captures[0].stage_times))
"""


def make_takes(lengths, folder: Path) -> dict[int, Path]:
    """One C3D file per length in ``lengths`` (frames): the first frames of one walk."""
    longest = max(lengths)
    capture = synthesize_capture(WALK, duration=(longest - 1) / RATE, seed=7,
                                 session_seed=2010, rate=RATE, name="long_walk")
    trial = capture.trial
    files = {}
    for n in sorted(lengths):
        path = folder / f"walk_{n}" / f"walk_{n}.c3d"
        path.parent.mkdir(parents=True)
        files[n] = write_c3d(path, trial.markers[:n], trial.labels, trial.rate, units="mm",
                             integer=True)
    return files


def resident_mib() -> float:
    """This process's resident memory now, MiB (Linux; NaN elsewhere)."""
    try:
        status = Path("/proc/self/status").read_text(encoding="utf-8")
    except OSError:
        return float("nan")
    return next((int(line.split()[1]) / 1024 for line in status.splitlines()
                 if line.startswith("VmRSS:")), float("nan"))


def timed_command(args: list[str], env: dict) -> tuple[float, float, int]:
    """Wall time (s), peak resident memory (MiB) and exit code of ``args`` run to its end."""
    start = time.perf_counter()
    process = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - start
    process.returncode = os.waitstatus_to_exitcode(status)
    stderr = process.stderr.read().decode(errors="replace")
    process.stderr.close()
    if process.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(args)} failed ({process.returncode}):\n{stderr}")
    return wall, usage.ru_maxrss / 1024, process.returncode


def measure(path: Path, out: Path, env: dict, repeat: int, all_cycles: bool = False) -> dict:
    """The build of one take (every cycle an entry with ``all_cycles``): best wall time,
    largest peak memory, stage times, entries."""
    walls, peaks = [], []
    for _ in range(repeat):
        wall, peak, _ = timed_command([sys.executable, "-m", "mocaplib", "build", str(path),
                                       "-o", str(out), "--no-cache", "--jobs", "1", "--quiet",
                                       "--force"] + ["--all-cycles"] * all_cycles, env)
        walls.append(wall)
        peaks.append(peak)
    entries = json.loads(out.read_text(encoding="utf-8"))["entries"]
    if len(entries) != 1 and not all_cycles:
        raise SystemExit(f"{out}: expected the take's one entry, found {len(entries)}")
    stages = min((json.loads(subprocess.run(
        [sys.executable, "-c", STAGES_SCRIPT, str(path), "all" if all_cycles else "chosen"],
        env=env, check=True,
        capture_output=True, text=True).stdout) for _ in range(repeat)),
        key=lambda times: sum(times.values()))
    return {"wall": min(walls), "peak": max(peaks), "stages": stages, "entries": len(entries)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sizes = parser.add_mutually_exclusive_group()
    sizes.add_argument("--frames", type=int, nargs="+", default=None,
                       help=f"take lengths in frames (default {' '.join(map(str, FRAMES))})")
    sizes.add_argument("--quick", action="store_true",
                       help=f"shorter takes: {' '.join(map(str, QUICK))} frames")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--all-cycles", action="store_true",
                        help="build with --all-cycles: every cycle of the take an entry")
    parser.add_argument("--plot", type=Path, default=None,
                        help="PNG of frames/s and peak memory against frames (default: next "
                             "to --markdown's page)")
    add_markdown_option(parser)
    args = parser.parse_args()
    lengths = sorted(set(args.frames or (QUICK if args.quick else FRAMES)))
    if len(lengths) < 2 or lengths[0] < 1000:
        parser.error("give at least two lengths of 1000 frames or more")
    plot = args.plot or (args.markdown.with_suffix(".png") if args.markdown else None)
    with markdown_page(args.markdown, __file__):
        rows = report(lengths, args.repeat, args.all_cycles)
        if plot is not None:
            draw(rows, plot, args.markdown)
    return 0


def report(lengths: list[int], repeat: int, all_cycles: bool = False) -> list[dict]:
    """Build each length (every cycle an entry with ``all_cycles``), print the tables and
    the targets; returns the rows."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        # made in another process: a build's ru_maxrss starts from this process's memory
        # when it forks, which must stay small
        with multiprocessing.get_context("spawn").Pool(1) as pool:
            files = pool.apply(make_takes, (lengths, Path(tmp)))
        floor = resident_mib()
        print(f"One synthetic walk ({WALK.v_f:g} m/s on a circle of "
              f"{WALK.v_f / WALK.omega:g} m radius, fullbody38, {RATE:g} Hz, no events in "
              f"the files), cut at {', '.join(f'{n:,}' for n in lengths)} frames "
              f"(made in {time.perf_counter() - start:.0f} s, not timed). `mocaplib build "
              f"FILE --no-cache --jobs 1{' --all-cycles' * all_cycles}`, "
              f"{'best' if repeat > 1 else 'one run'}"
              f"{f' of {repeat}' if repeat > 1 else ''} each, in a fresh process (this "
              f"script held {floor:.0f} MiB when it started them, which a build's peak "
              "counts at least):\n")
        for n in lengths:
            result = measure(files[n], Path(tmp) / f"library_{n}.json", env, repeat,
                             all_cycles)
            rows.append({"frames": n, **result})
            print(f"built {n} frames: {result['wall']:.1f} s", file=sys.stderr)
    first = rows[0]
    print("| frames | minutes | entries | wall (s) | frames/s | ratio | stages (s) | "
          "stage frames/s | ratio | peak MiB |\n|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        stages = sum(row["stages"].values())
        row["fps"], row["stage_fps"] = row["frames"] / row["wall"], row["frames"] / stages
        print(f"| {row['frames']:,} | {row['frames'] / RATE / 60:.1f} | {row['entries']} | "
              f"{row['wall']:.1f} | "
              f"{row['fps']:.0f} | {row['fps'] / first['fps']:.2f} | {stages:.1f} | "
              f"{row['stage_fps']:.0f} | {row['stage_fps'] / first['stage_fps']:.2f} | "
              f"{row['peak']:.0f} |")
    names = list(rows[-1]["stages"])
    print("\nSeconds per 10,000 frames in each stage (flat across a row: linear in frames):\n")
    print("| stage | " + " | ".join(f"{r['frames']:,}" for r in rows) + " |\n|---|"
          + "---|" * len(rows))
    for name in names:
        print(f"| {name} | " + " | ".join(
            f"{1e4 * r['stages'].get(name, 0.0) / r['frames']:.2f}" for r in rows) + " |")
    last = rows[-1]
    print(f"\nTargets, {last['frames']:,} frames against {first['frames']:,}:\n")
    for what, key in (("whole command", "fps"), ("stages alone", "stage_fps")):
        ratio = last[key] / first[key]
        print(f"- frames/s ({what}) at >= {MIN_SPEED_RATIO:.0%} of the shortest take's: "
              f"{ratio:.0%} ({last[key]:.0f} against {first[key]:.0f} frames/s): "
              f"**{'met' if ratio >= MIN_SPEED_RATIO else 'missed'}**")
    print(f"- peak memory under {MAX_PEAK_MIB:.0f} MiB: {last['peak']:.0f} MiB: "
          f"**{'met' if last['peak'] < MAX_PEAK_MIB else 'missed'}**")
    return rows


def draw(rows: list[dict], path: Path, page: Path | None) -> None:
    """Frames/s (whole command and stages) and peak memory against frames, as a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frames = [r["frames"] for r in rows]
    figure, (speed, memory) = plt.subplots(1, 2, figsize=(10, 4))
    speed.plot(frames, [r["fps"] for r in rows], "o-", label="whole command")
    speed.plot(frames, [r["stage_fps"] for r in rows], "s--", label="its stages")
    for key, colour in (("fps", "C0"), ("stage_fps", "C1")):
        speed.axhline(MIN_SPEED_RATIO * rows[0][key], color=colour, linestyle=":",
                      label=f"target: {MIN_SPEED_RATIO:.0%} of the shortest")
    speed.set(xlabel="frames in the take", ylabel="frames / s", ylim=(0, None),
              title="build speed")
    speed.legend()
    memory.plot(frames, [r["peak"] for r in rows], "o-")
    memory.axhline(MAX_PEAK_MIB, color="grey", linestyle=":", label="target: 1 GiB")
    memory.set(xlabel="frames in the take", ylabel="peak resident memory (MiB)",
               ylim=(0, None), title="build memory")
    memory.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    if page is not None:
        print(f"\n![frames/s and peak memory against frames]({os.path.relpath(path, page.parent)})")
    print(f"plot written to {shown(path)}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
