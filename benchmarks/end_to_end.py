"""End to end against OpenSim: each shared real capture fitted in a fresh process, as users run it.

First the start-up: ``mocaplib --help`` and ``mocaplib inspect FILE`` (fastest of three runs).
Then, for every C3D file of the shared lab data (``shared/data/c3d`` beside the repository),
two commands are run in fresh processes and timed (wall clock, and the CPU time of the process
and its children):

* **mocaplib**: ``mocaplib fit FILE [--static STATIC] -o angles.csv`` — read the
  C3D, detect the protocol, low-pass the markers (Winter's automatic cutoff), calibrate (from
  the static when the capture has one in the data, :data:`STATICS`, else from the capture),
  fit every frame twice (outliers, then filtered), write the angles;
* **OpenSim 4.6** doing the same job on the same exported model
  (``benchmarks/opensim_tools.py JOB``): with a static, its ScaleTool scales the generic model
  (mocaplib's skeleton of 1.75 m with the catalogue's marker offsets, exported as .osim) by the
  distances between markers on each body in the static and places the markers on the static
  pose; without one, the model mocaplib calibrated from the capture (``mocaplib fit --osim``)
  is taken as it is, its calibration not timed. Then its InverseKinematicsTool solves every
  frame (accuracy 1e-5, each marker weighted as mocaplib's fit weights it). Its inputs (.trc
  markers in millimetres, the .osim) are written beforehand and not timed.

Then ``mocaplib build FOLDER --jobs 2 --no-cache`` over all the files (the standing files
among them serve as statics), against the sum of the OpenSim jobs. Two tables of in-process CPU time
(one thread) follow: each capture's stages (the automatic cutoff, the calibration, one
``fit()``, ``fit_filtered``), and the growth of ``fit_filtered`` with frames and rate
(Qualisys.c3d played forwards and backwards 1 to 16 times; two 100 Hz walks resampled to
250 Hz). Prints Markdown tables
(``--markdown PATH`` also writes them into a results page, :mod:`markdown_results`); one run
each (``--repeat`` takes the fastest of several). Needs the bench extra (``pip install
".[bench]"``: opensim).

    python benchmarks/end_to_end.py [--data DIR] [--repeat 1] [--markdown PATH]
"""

from __future__ import annotations

import argparse
import compileall
import dataclasses
import itertools
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# one BLAS thread, in this process (the stages' CPU times) as in the commands it starts
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from mocaplib.io.c3d import read_c3d  # noqa: E402

DATA = REPO.parent / "shared" / "data" / "c3d"
#: The static trial of each capture recorded with one (same subject and session, SOURCES.md).
#: btkdata's PiG_Calibration2-NoOption shows another subject than PiG_Motion-FlatFoot-Full
#: (calibration refuses it), so that capture calibrates from itself.
STATICS = {
    "biomechzoo/HC030A05.c3d": "biomechzoo/HC030A01.c3d",
    "biomechzoo/HC030A22.c3d": "biomechzoo/HC030A01.c3d",
    "motonms_unipd/Walking1.c3d": "motonms_unipd/Static1.c3d",
    "motonms_unipd/Walking3.c3d": "motonms_unipd/Static1.c3d",
}
#: Marker pairs closer than this (m) in the generic model do not measure a body's scale.
MIN_PAIR = 0.05
#: The command line as users start it: the console script beside this Python, else -m.
MOCAPLIB = ([str(Path(sys.executable).with_name("mocaplib"))]
            if Path(sys.executable).with_name("mocaplib").is_file()
            else [sys.executable, "-m", "mocaplib"])


def timed(command: list[str], repeat: int) -> tuple[float, float, subprocess.CompletedProcess]:
    """Fastest wall time (s) of ``repeat`` runs of ``command`` in a fresh process, the CPU
    time (s, user + system of the process and its children) of that run, and its result."""
    best = (float("inf"), 0.0, None)
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True)
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        if wall < best[0]:
            best = (wall, cpu, done)
    return best


def _last_line(text: str) -> str:
    """The last line of an error output that says what went wrong, in brackets after a
    space, or ''."""
    lines = [line.strip() for line in text.splitlines()
             if line.strip().startswith(("RuntimeError", "mocaplib", "Error", "[error]"))]
    return f" ({lines[-1][:160]})" if lines else ""


def opensim_job(path: Path, static: Path | None, folder: Path) -> dict:
    """The inputs of OpenSim's job for the capture ``path`` (and its ``static``), written
    into ``folder``: the calibrated or the generic model, the markers as .trc."""
    from mocaplib.model.ik import model_markers
    from mocaplib.export.opensim import opensim_name, write_osim, write_trc
    from mocaplib.markersets.protocols import REFERENCE_HEIGHT
    from mocaplib.skeleton import SEGMENT_NAMES, Skeleton
    from mocaplib.model.fitting import fit_capture

    trial = read_c3d(path)
    statics = [read_c3d(static)] if static else None
    model = fit_capture(trial, static=statics).model     # as `mocaplib fit` calibrates
    job = {"labels": [opensim_name(label) for label in model.labels],
           "weights": model.marker_weights.tolist(),
           "motion": str(folder / "motion.trc"), "motion_end": trial.duration,
           "mot": str(folder / "ik.mot")}
    write_trc(dataclasses.replace(trial, markers=model_markers(trial, model),
                                  labels=model.labels), job["motion"])
    if static is None:
        job["model"] = str(write_osim(model, folder / "model.osim"))
        return job
    nominal = np.array([model.protocol.marker(label).landmark.position
                        for label in model.labels])
    generic = dataclasses.replace(model, skeleton=Skeleton.from_height(REFERENCE_HEIGHT),
                                  marker_offsets=nominal)
    pairs = {}
    for s, name in enumerate(SEGMENT_NAMES):
        on = np.flatnonzero(model.marker_segments == s)
        found = [(job["labels"][a], job["labels"][b]) for a, b in itertools.combinations(on, 2)
                 if np.linalg.norm(nominal[a] - nominal[b]) > MIN_PAIR]
        if found:
            pairs[name] = found
    write_trc(dataclasses.replace(statics[0], markers=model_markers(statics[0], model),
                                  labels=model.labels), folder / "static.trc")
    job.update(generic=str(write_osim(generic, folder / "generic.osim")),
               static=str(folder / "static.trc"), static_end=statics[0].duration,
               pairs=pairs, segments=list(SEGMENT_NAMES), height=REFERENCE_HEIGHT)
    return job


def stage_times(path: Path, static: Path | None) -> dict[str, float]:
    """CPU seconds (one thread, this process) of the stages of ``mocaplib fit`` on ``path``:
    the automatic cutoff, the calibration, one ``fit()`` of the filtered markers, and
    ``fit_filtered`` (both fits)."""
    from mocaplib.model.calibration import calibrate
    from mocaplib.model.filtering import filter_trial, residual_cutoff
    from mocaplib.model.ik import fit, fit_filtered
    from mocaplib.markersets.matching import match_trial

    trial = read_c3d(path)
    match = match_trial(trial, "auto")
    keep = match.columns                                 # the protocol's markers, as fit_capture
    seconds = {}
    start = time.process_time()
    residual_cutoff(trial.markers[:, keep], trial.rate)
    seconds["cutoff"] = time.process_time() - start
    filtered, used = filter_trial(trial, cutoff="auto", keep=keep)
    start = time.process_time()
    model = calibrate(filtered, protocol=match.protocol,
                      static=read_c3d(static) if static else None)
    seconds["calibrate"] = time.process_time() - start
    start = time.process_time()
    fit(filtered, model)
    seconds["fit"] = time.process_time() - start
    start = time.process_time()
    fit_filtered(trial, model, cutoff=used)
    seconds["fit_filtered"] = time.process_time() - start
    return seconds


def growth(data: Path, folder: Path) -> None:
    """Print ``fit_filtered``'s CPU time per second of capture as frames and rate grow."""
    from mocaplib.model.filtering import resample
    from mocaplib.io.c3d_write import write_c3d
    from mocaplib.markersets.matching import match_trial

    rows = []
    walk = read_c3d(data / "ezc3d_testfiles" / "Qualisys.c3d")
    for k in (1, 2, 4, 8, 16):             # forwards and backwards: continuous, k times longer
        markers = np.concatenate([walk.markers if i % 2 == 0 else walk.markers[::-1]
                                  for i in range(k)])
        rows.append((f"Qualisys.c3d x{k}", write_c3d(folder / f"qualisys_x{k}.c3d", markers,
                                                     walk.labels, walk.rate)))
    for name in ("biomechzoo/HC030A05.c3d", "btkdata/PiG_Motion-FlatFoot-Full.c3d"):
        trial = read_c3d(data / name)
        times = np.arange(int(trial.duration * 250.0) + 1) / 250.0
        flat = trial.markers.reshape(trial.n_frames, -1)
        gaps = ~np.isfinite(flat)[np.clip(np.rint(times * trial.rate).astype(int), 0,
                                          trial.n_frames - 1)]
        upsampled = np.where(gaps, np.nan, resample(flat, trial.rate, times))
        stem = Path(name).stem
        for rate, markers in ((trial.rate, trial.markers), (250.0, upsampled)):
            rows.append((f"{stem} at {rate:g} Hz", write_c3d(
                folder / f"{stem}_{rate:g}.c3d", markers.reshape(len(markers), -1, 3),
                trial.labels, rate)))
    print("\n| capture | frames | rate (Hz) | markers fitted | fit_filtered CPU (s) "
          "| per second of capture (s) |\n|---|---|---|---|---|---|")
    for label, path in rows:
        trial = read_c3d(path)
        seconds = stage_times(path, None)["fit_filtered"]
        fitted = sum(i >= 0 for i in match_trial(trial, "auto").indices)
        print(f"| {label} | {trial.n_frames} | {trial.rate:g} | {fitted} | {seconds:.3f} | "
              f"{seconds * trial.rate / trial.n_frames:.3f} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help="folder of the real captures")
    parser.add_argument("--repeat", type=int, default=1)
    add_markdown_option(parser)
    args = parser.parse_args()
    if not args.data.is_dir():
        print(f"no real captures at {args.data}", file=sys.stderr)
        return 1
    # the package's bytecode, as an installed package has it (pip compiles at install time; a
    # PYTHONDONTWRITEBYTECODE environment would otherwise compile every module in every run)
    compileall.compile_dir(REPO / "mocaplib", quiet=1)
    with markdown_page(args.markdown, __file__):
        compare(args)
    return 0


def compare(args) -> None:
    """Time both tools on every capture of ``args.data`` and the build; print the tables."""
    captures = sorted(args.data.rglob("*.c3d"))
    all_frames = sum(read_c3d(path).n_frames for path in captures)
    print(f"Load average at the start: {', '.join(f'{x:.2f}' for x in os.getloadavg())} "
          "(1, 5, 15 min) on this 2-core machine.\n")
    print("| start-up | wall (s) | CPU (s) |\n|---|---|---|")
    shown = captures[0].relative_to(args.data).as_posix()
    for label, command in (("`mocaplib --help`", ["--help"]),
                           (f"`mocaplib inspect {shown}`", ["inspect", str(captures[0])])):
        wall, cpu, _ = timed([*MOCAPLIB, *command], 3)
        print(f"| {label} | {wall:.2f} | {cpu:.2f} |")
    print()
    print("| capture | frames | static | mocaplib wall (s) | CPU (s) | OpenSim wall (s) "
          "| CPU (s) | OpenSim steps (s) | wall ratio | CPU ratio |\n"
          "|---|---|---|---|---|---|---|---|---|---|")
    totals = np.zeros(4)
    frames = 0
    failed = []
    walks = []                             # (wall, wall ratio) of the 200-500-frame captures
    with tempfile.TemporaryDirectory() as tmp:
        for path in captures:
            name = path.relative_to(args.data).as_posix()
            static = args.data / STATICS[name] if name in STATICS else None
            folder = Path(tmp) / path.stem
            folder.mkdir()
            try:
                job = opensim_job(path, static, folder)
            except Exception as exc:       # a capture mocaplib cannot fit: listed below
                failed.append(f"{name}: {exc}")
                continue
            command = [*MOCAPLIB, "fit", str(path), "-o", str(folder / "angles.csv")] + (
                ["--static", str(static)] if static else [])
            ours = timed(command, args.repeat)
            (folder / "job.json").write_text(json.dumps(job))
            theirs = timed([sys.executable, str(REPO / "benchmarks" / "opensim_tools.py"),
                            str(folder / "job.json")], args.repeat)
            if ours[2].returncode or theirs[2].returncode:
                failed.append(f"{name}: mocaplib exit {ours[2].returncode}"
                              f"{_last_line(ours[2].stderr)}, OpenSim exit "
                              f"{theirs[2].returncode}{_last_line(theirs[2].stderr)}")
                continue
            steps = json.loads(theirs[2].stdout.strip().splitlines()[-1])
            n = read_c3d(path).n_frames
            frames += n
            totals += [ours[0], ours[1], theirs[0], theirs[1]]
            if 200 <= n <= 500:
                walks.append((ours[0], theirs[0] / ours[0]))
            print(f"| {name} | {n} | {Path(static).name if static else '—'} | {ours[0]:.2f} | "
                  f"{ours[1]:.2f} | {theirs[0]:.2f} | {theirs[1]:.2f} | "
                  + " + ".join(f"{k} {v:.2f}" for k, v in steps.items())
                  + f" | {theirs[0] / ours[0]:.1f}× | {theirs[1] / ours[1]:.1f}× |")
        print(f"| **all {len(captures) - len(failed)} captures** | {frames} | | "
              f"{totals[0]:.2f} | {totals[1]:.2f} | {totals[2]:.2f} | {totals[3]:.2f} | | "
              f"{totals[2] / totals[0]:.1f}× | {totals[3] / totals[1]:.1f}× |")
        build = timed([*MOCAPLIB, "build", str(args.data), "-o", str(Path(tmp) / "library.json"),
                       "--jobs", "2", "--no-cache", "--quiet"], args.repeat)
    print(f"\n`mocaplib build` of all {len(captures)} files, 2 jobs, no cache (exit "
          f"{build[2].returncode}: captures that cannot become entries are listed in its "
          f"diagnostics): **{build[0]:.2f} s** wall, {build[1]:.2f} s CPU, "
          f"**{all_frames / build[0]:.0f} frames/s** ({all_frames} frames), against "
          f"{totals[2]:.2f} s wall for the OpenSim jobs one after the other "
          f"({totals[2] / build[0]:.1f}×).")
    if failed:
        print("\nNot compared: " + "; ".join(failed))
    walls, ratios = np.array(walks or [(np.nan, np.nan)]).T   # none in range: not met
    print("\n| target | measured | met |\n|---|---|---|")
    for target, measured, met in (
            ("`mocaplib fit` ≤ 1.5 s wall on every 200-500-frame capture",
             f"{walls.max():.2f} s at most ({len(walls)} captures)", walls.max() <= 1.5),
            ("`mocaplib fit` ≥ 5× faster than OpenSim on every 200-500-frame capture",
             f"{ratios.min():.1f}× to {ratios.max():.1f}× (median {np.median(ratios):.1f}×)",
             ratios.min() >= 5),
            ("`mocaplib build` of every file ≥ 1,000 frames/s on 2 jobs",
             f"{all_frames / build[0]:.0f} frames/s", all_frames / build[0] >= 1000)):
        print(f"| {target} | {measured} | {'yes' if met else '**no**'} |")
    print("\nIn-process CPU time (one thread) of the stages of `mocaplib fit`:\n")
    print("| capture | frames | automatic cutoff (ms) | calibrate (s) | one fit() (s) "
          "| calibrate / fit() | fit_filtered (s) |\n|---|---|---|---|---|---|---|")
    for path in captures:
        name = path.relative_to(args.data).as_posix()
        try:
            seconds = stage_times(path, args.data / STATICS[name] if name in STATICS else None)
        except Exception:                  # listed as not compared above
            continue
        print(f"| {name} | {read_c3d(path).n_frames} | {1000 * seconds['cutoff']:.1f} | "
              f"{seconds['calibrate']:.3f} | {seconds['fit']:.3f} | "
              f"{seconds['calibrate'] / seconds['fit']:.1f} | {seconds['fit_filtered']:.3f} |")
    with tempfile.TemporaryDirectory() as tmp:
        growth(args.data, Path(tmp))
    print(f"\nLoad average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}.")


if __name__ == "__main__":
    raise SystemExit(main())
