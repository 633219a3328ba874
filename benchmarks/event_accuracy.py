"""Toe-off and heel-strike accuracy of both toe-off definitions, against their targets.

    python benchmarks/event_accuracy.py [--samples sample_c3d] [--real DIR] [--markdown PATH]
    python benchmarks/event_accuracy.py --noise-sd 0     # samples without noise

Runs :func:`mocaplib.gait.events.capture_events` on every synthetic capture of ``--samples`` (their
EVENT group holds the true Foot Off / Foot Strike) and on the four real files with lab-recorded
events under ``--real`` (default ``$MOCAPLIB_SHARED_C3D``, else ``../shared/data/c3d``; skipped
when absent), for each toe-off definition, and prints:

* synthetic, per locomotion type (the name without speed and size): toe-offs, % within 1 frame
  (the target: >= 95 % for every type), % within 2 frames, worst |error| in frames;
* real, per event kind: events paired with a lab event, median difference, median |difference|
  (target for toe-off: <= 10 ms), how many within 10 ms, worst |difference|; and the left
  toe-offs alone, which bound the cycles (targets: median |difference| <= 10 ms, worst
  <= 30 ms);
* slow walks below the sample plan's speeds (generated here, straight and on a 2 m curve at
  0.3, 0.4, 0.5 and 0.6 m/s, :data:`SLOW_WALKS`), per speed: toe-offs, % within 1 frame, median
  and worst error against the generator's truth;
* the force plates of the real files (read with ezc3d): each plate's unloading (vertical
  force in newtons falling below :data:`PLATE_THRESHOLD_N` after a stance,
  :func:`plate_unloadings`; extrapolated on a plate whose recording cut the force to zero
  above the threshold, :func:`unloadings`) against the nearest placed toe-off and the
  nearest lab Foot Off,
  so the lab events a plate measured are told from those placed otherwise, and how much
  later the force falls below :data:`LOW_THRESHOLD_N` (what the threshold's choice moves);
* per real file that records them (any file under ``--real`` with lab Foot Off events or force
  plates), the toe-offs against its lab Foot Offs and against its plates' unloadings: paired
  (nearest placed toe-off of the side within 0.1 s; a plate with none), median and worst
  |difference| (targets: median <= 10 ms, worst <= 30 ms on every file), and the lab events
  and unloadings that fall in the window of a toe-off the detector reported as not placed;
* every toe-off of the real files whose two marks lie over 30 ms apart (uncertain: placed
  midway, with a warning) against its plate or lab Foot Off, and on the samples how far apart
  the two marks lie at most;
* the events the force plates time by default (:mod:`mocaplib.gait.plate_events`; every other
  table measures the markers' events, ``force_plates=False``) against the lab's events and
  the markers' own;
* each toe-off a plate times, left out in turn: the markers' toe-off there alone and moved
  by what the capture's other plates measured (step 5 of :mod:`mocaplib.gait.plate_events`),
  against that plate's unloading; and what moving the heel strikes the same way would give.

``--noise-sd SD`` regenerates the sample plan (``protocols/paper_plan.toml``) into a temporary
folder with marker noise ``SD`` metres instead of reading ``--samples`` (the plan's 0.0007):
``0`` shows what the detector does on exact marker paths.

Prints Markdown tables (``--markdown PATH`` also writes them into a results page,
:mod:`markdown_results`). Exit code 1 when the default definition misses a target.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from mocaplib.gait.events import TOE_OFF_DEFINITIONS, EventSettings, capture_events
from mocaplib.gait.feet import LAB_EVENT_KINDS, event_differences
from mocaplib.gait.foot_events import MARKS_APART_S
from mocaplib.gait.plate_events import (PLATE_MIN_PEAK_N, PLATE_THRESHOLD_N,  # noqa: F401
                                        PLATE_MATCH_S, Unloading, readable, unloadings)
from mocaplib.io.c3d import read_c3d  # noqa: E402
from mocaplib.markersets.matching import detect_protocol
from mocaplib.synth.plan import generate_plan, load_plan, locomotion_type  # noqa: E402

#: The real files whose EVENT group holds lab (force-plate or operator) Foot Off events.
LAB_FILES = ("biomechzoo/HC030A05.c3d", "biomechzoo/HC030A22.c3d",
             "btkdata/PiG_Motion-FlatFoot-Full.c3d", "ezc3d_testfiles/Qualisys.c3d")
SYNTHETIC_TARGET, REAL_TARGET_S, REAL_WORST_S = 0.95, 0.010, 0.030
#: Slow walks generated for their own table: (kind, speed m/s, radius m or None, seed).
SLOW_WALKS = tuple((kind, speed, radius, seed) for speed in (0.3, 0.4, 0.5, 0.6)
                   for kind, radius, seed in (("straight", None, 101), ("straight", None, 102),
                                              ("curve", 2.0, 103)))
#: The lower threshold (N) whose unloadings the plate table also shows, to tell how much of a
#: difference the threshold's choice makes (Tirosh & Sparrow advise 10 N or less for toe-off).
LOW_THRESHOLD_N = 10.0
#: The rows of the real table: (row name, event kind, lab event sides or None for both).
REAL_ROWS = (("toe_off", "toe_off", None), ("heel_strike", "heel_strike", None),
             ("left toe_off", "toe_off", "L"))


def differences(paths, toe_off: str
                ) -> dict[str, tuple[dict[str, np.ndarray], float, list[float]]]:
    """{file stem: ({event kind: detected - recorded times (s, NaN = none within 0.1 s)},
    frame rate, how far apart (s) each placed toe-off's two marks lie)}, each file read and its
    events detected once."""
    out = {}
    for path in paths:
        trial = read_c3d(path)
        events, _ = capture_events(trial, detect_protocol(trial), toe_off=toe_off,
                                   force_plates=False)
        out[path.stem] = ({row: event_differences(events, _of_side(trial.events, side),
                                                  kind=kind, start_time=trial.start_time)
                           for row, kind, side in REAL_ROWS}, trial.rate,
                          [e.spread_s for e in events if e.kind == "toe_off" and e.placed])
    return out


def _of_side(events, side):
    """The lab events of ``side`` ("L" or "R": the first letter of their context, else of their
    label), or all of them when ``side`` is None."""
    return [e for e in events
            if side is None or side in (e.context[:1].upper(), e.label[:1].upper())]


def synthetic_table(samples: Path, toe_off: str) -> bool:
    """Print the per-type table; True when every type meets the target."""
    paths = [p for p in sorted(samples.glob("*.c3d")) if p.with_suffix(".truth.json").is_file()]
    by_type: dict[str, list[float]] = {}
    spreads = []
    for name, (by_kind, rate, spread) in differences(paths, toe_off).items():
        spreads += spread
        diff = by_kind["toe_off"]
        frames = np.where(np.isnan(diff), np.inf, np.abs(diff) * rate)
        if frames.size:  # the standing capture has none
            by_type.setdefault(locomotion_type(name), []).extend(frames)
    print(f"\nSynthetic toe-offs ({samples.name}), `toe_off={toe_off!r}`:\n")
    print("| type | toe-offs | within 1 frame | within 2 frames | worst (frames) |\n"
          "|---|---|---|---|---|")
    met = True
    for kind, errors in sorted(by_type.items()) + [("ALL", sum(by_type.values(), []))]:
        errors = np.array(errors)
        within = np.mean(errors <= 1.0)
        met &= kind == "ALL" or within >= SYNTHETIC_TARGET
        print(f"| {kind} | {len(errors)} | {100 * within:.1f} % | "
              f"{100 * np.mean(errors <= 2.0):.1f} % | {errors.max():.1f} |")
    if max(spreads) > 0:                  # the default's two marks (the lift has one)
        print(f"\nThe two marks of a toe-off lie at most {1000 * max(spreads):.1f} ms apart; "
              f"{sum(x > MARKS_APART_S for x in spreads)} of {len(spreads)} toe-offs over "
              f"{1000 * MARKS_APART_S:.0f} ms (uncertain).")
    return met


def real_table(real: Path, toe_off: str) -> bool:
    """Print the real-file figures; True when the toe-off median |difference| meets the target
    and the left toe-offs' median and worst |difference| meet theirs."""
    paths = [real / name for name in LAB_FILES if (real / name).is_file()]
    if len(paths) < len(LAB_FILES):
        print(f"\nreal lab files not found under {real}: skipped")
        return True
    print(f"\nReal files with lab events ({len(paths)}), `toe_off={toe_off!r}`:\n")
    print("| kind | events | median (ms) | median \\|Δ\\| (ms) | within 10 ms "
          "| max \\|Δ\\| (ms) |\n|---|---|---|---|---|---|")
    met = True
    found = differences(paths, toe_off)
    for kind, _, _ in REAL_ROWS:
        diff = np.concatenate([by_kind[kind] for by_kind, _, _ in found.values()])
        diff = diff[np.isfinite(diff)] * 1000.0
        median_abs = np.median(np.abs(diff))
        if kind == "toe_off":
            met = median_abs <= 1000.0 * REAL_TARGET_S
        elif kind == "left toe_off":
            met &= (median_abs <= 1000.0 * REAL_TARGET_S
                    and np.abs(diff).max() <= 1000.0 * REAL_WORST_S)
        print(f"| {kind} | {len(diff)} | {np.median(diff):+.1f} | {median_abs:.1f} | "
              f"{np.sum(np.abs(diff) <= 10.0)}/{len(diff)} | {np.abs(diff).max():.1f} |")
    return met


def slow_walks() -> list[tuple[float, object, dict]]:
    """The :data:`SLOW_WALKS` generated: (speed m/s, Trial, truth) each, in the sample plan's
    session (marker placement seed 2010)."""
    from mocaplib.library.command import Command
    from mocaplib.synth.capture import synthesize_capture
    from mocaplib.synth.capture import min_duration

    out = []
    for kind, speed, radius, seed in SLOW_WALKS:
        command = Command.from_kind(kind, speed=speed, radius=radius)
        capture = synthesize_capture(command, duration=round(min_duration(command) + 0.3, 2),
                                     seed=seed, session_seed=2010)
        out.append((speed, capture.trial, capture.truth))
    return out


def slow_table(walks, toe_off: str) -> None:
    """Print the slow walks' toe-off errors per speed for ``walks`` (:func:`slow_walks`)."""
    by_speed: dict[float, list[float]] = {}
    for speed, trial, truth in walks:
        events, _ = capture_events(trial, detect_protocol(trial), toe_off=toe_off)
        for true in truth["events"]:
            if true["kind"] == "toe_off":
                found = [e.time_s - true["time_s"] for e in events
                         if e.side == true["side"] and e.kind == "toe_off"]
                by_speed.setdefault(speed, []).append(
                    min(found, key=abs) * trial.rate if found else np.inf)
    print(f"\nSlow synthetic walks (straight and 2 m curve), `toe_off={toe_off!r}`:\n")
    print("| speed (m/s) | toe-offs | within 1 frame | median (frames) | worst (frames) |\n"
          "|---|---|---|---|---|")
    for speed, errors in sorted(by_speed.items()):
        errors = np.array(errors)
        print(f"| {speed:.1f} | {len(errors)} | {100 * np.mean(np.abs(errors) <= 1.0):.1f} % | "
              f"{np.median(errors):+.2f} | {np.abs(errors).max():.2f} |")


def vertical_forces(path: Path) -> tuple[float, list[np.ndarray]]:
    """The analog rate (Hz) and each force plate's vertical force (N, > 0 under load, zero
    offset removed), shape (A,) per plate, of the C3D at ``path`` (read with ezc3d, which
    applies the analog channels' SCALE and OFFSET): the Fz channel of a type 1 or 2 plate, the
    sum of the four Fz channels of a type 3, the CAL_MATRIX row of Fz applied to the six
    channels of a type 4. The zero is the median of the samples under a tenth of the peak (a
    plate may read -15 N empty, as btkdata's Gait.c3d does). Analog sample ``k`` lies at
    ``k / rate`` s from the first point frame (the C3D layout: the analog samples of a frame
    start with it)."""
    import ezc3d

    c3d = ezc3d.c3d(str(path))
    plates = c3d["parameters"]["FORCE_PLATFORM"]
    used = int(plates["USED"]["value"][0])
    types = np.asarray(plates["TYPE"]["value"]).astype(int)
    channels = np.asarray(plates["CHANNEL"]["value"]).reshape(-1, used) - 1
    rate = float(c3d["parameters"]["ANALOG"]["RATE"]["value"][0])
    analogs = c3d["data"]["analogs"][0]
    out = []
    for plate in range(used):
        if types[plate] in (1, 2):
            force = analogs[channels[2, plate]]
        elif types[plate] == 3:
            force = analogs[channels[4:8, plate]].sum(axis=0)
        elif types[plate] == 4:
            calibration = np.asarray(plates["CAL_MATRIX"]["value"])[:, :, plate]
            force = calibration[2] @ analogs[channels[:6, plate]]
        else:
            continue
        force = force * np.sign(force[np.argmax(np.abs(force - np.median(force)))])
        empty = force < 0.1 * force.max()
        if empty.any():                                      # else a plate reading nothing
            out.append(force - np.median(force[empty]))
    return rate, out


def plate_unloadings(path: Path, *, threshold_n: float = PLATE_THRESHOLD_N) -> list[float]:
    """Seconds from the first frame at which a force plate of the C3D at ``path`` is unloaded
    (:func:`cut_unloadings`' times)."""
    return [u.time_s for u in cut_unloadings(path, threshold_n=threshold_n)]


def cut_unloadings(path: Path, *, threshold_n: float = PLATE_THRESHOLD_N) -> list[Unloading]:
    """Every force plate's :func:`unloadings` in the C3D at ``path`` (:func:`vertical_forces`),
    in time order, of the plates :func:`readable` says can give them."""
    rate, forces = vertical_forces(path)
    return sorted((u for force in forces if readable(force)
                   for u in unloadings(force, rate, threshold_n=threshold_n)),
                  key=lambda u: u.time_s)


def plate_files(real: Path, unloaded=cut_unloadings):
    """(path, ``unloaded(path)``) of every C3D file under ``real`` whose force plates can be
    read (:func:`cut_unloadings` by default), in path order."""
    for path in sorted(real.rglob("*.c3d")):
        try:
            found = unloaded(path)
        except (KeyError, IndexError, ValueError):                  # no usable plate
            continue
        yield path, found


def toe_off_differences(path: Path, *, threshold_n: float = PLATE_THRESHOLD_N
                        ) -> tuple[np.ndarray, np.ndarray, int]:
    """Default toe-offs of the C3D at ``path`` minus its recorded toe-offs (s): against the
    lab's Foot Offs (:func:`mocaplib.gait.feet.event_differences`) and against the plates'
    unloadings below ``threshold_n`` N (:func:`plate_unloadings`, the nearest placed toe-off
    of either side), each
    NaN where no placed toe-off lies within 0.1 s; and how many lab Foot Offs and unloadings
    fall in the window of a toe-off the detector reported as not placed."""
    trial = read_c3d(path)
    events, _ = capture_events(trial, detect_protocol(trial), force_plates=False)
    lab = event_differences(events, trial.events, kind="toe_off", start_time=trial.start_time)
    try:
        unloadings = plate_unloadings(path, threshold_n=threshold_n)
    except (KeyError, IndexError, ValueError):                      # no usable plate
        unloadings = []
    offs = [e.time_s for e in events if e.kind == "toe_off" and e.placed]
    plates = np.array([min((t - p for t in offs), key=abs, default=np.inf)
                       for p in unloadings])
    plates[np.abs(plates) > 0.1] = np.nan
    labs = [e.time_s - trial.start_time for e in trial.events
            if LAB_EVENT_KINDS.get(e.label) == "toe_off"]
    windows = [e.window for e in events if e.kind == "toe_off" and not e.placed]
    hidden = sum(w[0] <= t <= w[1] for t in labs + unloadings for w in windows)
    return lab, plates, hidden


def plate_table(real: Path) -> None:
    """Print, per plate unloading of the real files under ``real``, where the recording cut
    the force to zero, the nearest placed default toe-off (:func:`toe_off_differences`) and
    lab Foot Off relative to it (ms), and how much later the plate falls under
    :data:`LOW_THRESHOLD_N`."""
    print(f"\nForce-plate unloading (vertical force < {PLATE_THRESHOLD_N:.0f} N above the "
          f"plate's zero, `unloadings`) in the real files, default toe-off (– : none "
          "placed within 0.1 s; a plate whose recording cut the force to zero above the "
          "threshold: the force at the cut, and how far past it the falling force's tangent "
          "crosses the threshold):\n")
    print(f"| file | unloading (s) | cut to zero at (N) | unloading − cut (ms) | detected − plate "
          f"(ms) | lab Foot Off − plate (ms) | at {LOW_THRESHOLD_N:.0f} N − at "
          f"{PLATE_THRESHOLD_N:.0f} N (ms) |\n|---|---|---|---|---|---|---|")
    detected = []
    for path, plates in plate_files(real):
        _, ours, _ = toe_off_differences(path)
        if not np.isfinite(ours).any():              # no plate, or nobody walking on them
            continue
        trial = read_c3d(path)
        labs = [e.time_s - trial.start_time for e in trial.events
                if LAB_EVENT_KINDS.get(e.label) == "toe_off"]
        low = plate_unloadings(path, threshold_n=LOW_THRESHOLD_N)
        for plate, off in zip(plates, ours):
            lab = min((t - plate.time_s for t in labs), key=abs, default=np.inf)
            later = min((t - plate.time_s for t in low), key=abs, default=np.inf)
            detected.append(off)
            cut = (["–", "–"] if plate.cut_n is None else
                   [f"{plate.cut_n:.0f}", f"{1000 * (plate.time_s - plate.cut_s):+.1f}"])
            cells = cut + [f"{1000 * x:+.1f}" if abs(x) <= 0.1 else "–"
                           for x in (off, lab, later)]
            print(f"| {path.stem} | {plate.time_s:.3f} | " + " | ".join(cells) + " |")
    detected = 1000 * np.abs(np.array(detected)[np.isfinite(detected)])
    if not len(detected):
        print("\nNo force plate read with a toe-off placed near its unloading.")
        return
    print(f"\nDetected toe-off against the plates: median |Δ| {np.median(detected):.1f} ms, "
          f"worst {detected.max():.1f} ms over {len(detected)} unloadings.")


def per_file_table(real: Path) -> bool:
    """Print, per real file with lab Foot Offs or force plates, the default toe-offs against
    each (:func:`toe_off_differences`); True when every file's median and worst |difference|
    meet the targets."""
    print("\nToe-offs per real file that records lab Foot Offs or force plates, default "
          "toe-off (median / worst |Δ|, ms; paired of recorded):\n")
    print(f"| file | against lab Foot Off | against plate unloading | in a toe-off not placed "
          f"| against plate unloading at {LOW_THRESHOLD_N:.0f} N (not a target) |\n"
          "|---|---|---|---|---|")
    met, missed = True, []
    for path in sorted(real.rglob("*.c3d")):
        lab, plate, hidden = toe_off_differences(path)
        if not np.isfinite(np.concatenate([lab, plate])).any() and not hidden:
            continue                       # nothing recorded, or plates with nobody walking
        cells = []
        for name, diff in (("lab", lab), ("plates", plate)):
            paired = 1000 * np.abs(diff[np.isfinite(diff)])
            if not paired.size:
                cells.append(f"– (0 of {len(diff)})")
                continue
            ok = np.median(paired) <= 1000 * REAL_TARGET_S and paired.max() <= 1000 * REAL_WORST_S
            met &= bool(ok)
            if not ok:
                missed.append(f"{path.stem} ({name})")
            cells.append(f"{np.median(paired):.1f} / {paired.max():.1f} ({len(paired)} of "
                         f"{len(diff)}){'' if ok else ' **missed**'}")
        _, low, _ = toe_off_differences(path, threshold_n=LOW_THRESHOLD_N)
        low = 1000 * np.abs(low[np.isfinite(low)])
        print(f"| {path.stem} | {cells[0]} | {cells[1]} | {hidden} | "
              + (f"{np.median(low):.1f} / {low.max():.1f} |" if low.size else "– |"))
    print(f"\nPer-file targets (median <= {1000 * REAL_TARGET_S:.0f} ms, worst <= "
          f"{1000 * REAL_WORST_S:.0f} ms): " + ("met on every file" if met else
                                               "missed on " + ", ".join(missed)))
    return met


def uncertain_table(real: Path) -> None:
    """Print every default toe-off of the real files under ``real`` whose two marks lie over
    :data:`MARKS_APART_S` apart (:attr:`GaitEvent.uncertain`), against the plate's unloading or
    the lab's Foot Off of its side nearest it within 0.1 s."""
    print(f"\nToe-offs whose two marks lie over {1000 * MARKS_APART_S:.0f} ms apart (markers "
          "alone; each is placed midway and warns):\n")
    print("| file | side | toe-off (s) | marks apart (ms) | reference | toe-off − reference (ms) "
          "|\n|---|---|---|---|---|---|")
    placed = uncertain = 0
    for path in sorted(real.rglob("*.c3d")):
        trial = read_c3d(path)
        events, _ = capture_events(trial, detect_protocol(trial), force_plates=False)
        offs = [e for e in events if e.kind == "toe_off" and e.placed]
        placed += len(offs)
        try:
            plates = [(t, None, "plate") for t in plate_unloadings(path)]
        except (KeyError, IndexError, ValueError):                      # no usable plate
            plates = []
        labs = [(e.time_s - trial.start_time, e.context.lower(), "lab Foot Off")
                for e in trial.events if LAB_EVENT_KINDS.get(e.label) == "toe_off"]
        for event in (e for e in offs if e.uncertain):
            uncertain += 1
            near = [(time, kind) for time, side, kind in plates + labs
                    if side in (None, event.side) and abs(event.time_s - time) <= 0.1]
            time, kind = min(near, key=lambda r: abs(event.time_s - r[0]), default=(None, "–"))
            print(f"| {path.stem} | {event.side} | {event.time_s:.3f} | "
                  f"{1000 * event.spread_s:.1f} | {kind} | "
                  + ("– |" if time is None else f"{1000 * (event.time_s - time):+.1f} |"))
    print(f"\n{uncertain} of the {placed} placed toe-offs.")


def plate_timed_table(real: Path) -> None:
    """Print each event the force plates time by default (:mod:`mocaplib.gait.plate_events`)
    in the real files under ``real``, against the lab's event of its side and kind within
    0.1 s, beside the markers' own event there (``force_plates=False``)."""
    print("\nEvents the force plates time (default; `--markers-only` leaves them to the "
          "markers), minus the lab's event of the side and kind (ms; – : none within 0.1 s):\n")
    print("| file | side | kind | plate | time (s) | plate − lab | markers − lab | "
          "markers − plate |\n|---|---|---|---|---|---|---|---|")
    rows = {"plate": [], "markers": []}
    for path in sorted(real.rglob("*.c3d")):
        trial = read_c3d(path)
        if not trial.force_plates:
            continue
        match = detect_protocol(trial)
        timed = [e for e in capture_events(trial, match)[0] if e.plate is not None]
        markers, _ = capture_events(trial, match, force_plates=False)
        for event in timed:
            own = nearest_event(markers, event)
            side = _of_side(trial.events, event.side[0].upper())
            lab = [e.time_s - trial.start_time for e in side
                   if LAB_EVENT_KINDS.get(e.label) == event.kind
                   and abs(e.time_s - trial.start_time - event.time_s) <= 0.1]
            cells = ["–", "–"]
            if lab:
                for i, (key, t) in enumerate((("plate", event.time_s), ("markers", own.time_s))):
                    rows[key].append(1000 * (t - lab[0]))
                    cells[i] = f"{1000 * (t - lab[0]):+.1f}"
            print(f"| {path.stem} | {event.side} | {event.kind} | {event.plate} | "
                  f"{event.time_s:.3f} | {cells[0]} | {cells[1]} | "
                  f"{1000 * (own.time_s - event.time_s):+.1f} |")
    if rows["plate"]:
        print(f"\nAgainst the lab's {len(rows['plate'])} events there: the plates' median "
              f"|Δ| {np.median(np.abs(rows['plate'])):.1f} ms, worst "
              f"{np.max(np.abs(rows['plate'])):.1f}; the markers' "
              f"{np.median(np.abs(rows['markers'])):.1f} ms, worst "
              f"{np.max(np.abs(rows['markers'])):.1f}.")


def nearest_event(events, event, *, placed_only: bool = False):
    """The event of ``events`` of ``event``'s side and kind nearest it in time (placed ones
    only with ``placed_only``)."""
    return min((e for e in events if (e.side, e.kind) == (event.side, event.kind)
                and (e.placed or not placed_only)), key=lambda e: abs(e.time_s - event.time_s))


def left_out_plates(path: Path) -> list[tuple[str, str, int, float, float]]:
    """For each heel strike and toe-off a force plate times in the C3D at ``path`` (default
    events): its kind, side and plate, and the markers' event of that side and kind nearest it
    minus the plate's time (s), alone (``force_plates=False``) and, for a toe-off, moved as the
    capture's other plates measured the markers' toe-offs (that plate left out of the trial:
    step 5 of :mod:`mocaplib.gait.plate_events`); NaN for the moved one when the others move
    nothing, and for a heel strike (the plates move none)."""
    trial = read_c3d(path)
    if not trial.force_plates:
        return []
    match = detect_protocol(trial)
    markers, _ = capture_events(trial, match, force_plates=False)
    out = []
    for event in (e for e in capture_events(trial, match)[0] if e.plate is not None):
        own = nearest_event(markers, event, placed_only=True)
        shifted = np.nan
        if event.kind == "toe_off":
            others = [p for p in trial.force_plates if p.number != event.plate]
            moved, _ = capture_events(dataclasses.replace(trial, force_plates=others), match)
            found = nearest_event(moved, event, placed_only=True)
            shifted = found.time_s - event.time_s if found.plate_shift_s else np.nan
        out.append((event.kind, event.side, event.plate, own.time_s - event.time_s, shifted))
    return out


def left_out_table(real: Path) -> tuple[np.ndarray, np.ndarray]:
    """Print, per toe-off a force plate times in the real files under ``real``, the markers'
    toe-off there alone and moved by the capture's other plates (:func:`left_out_plates`),
    and a summary over those the other plates move, with what moving the heel strikes the same
    way would give; (alone, moved) |Δ| (ms) of those toe-offs."""
    print("\nThe markers' toe-offs off the plates, moved by what the capture's other plates "
          "measured (each plate left out in turn; – : the others move nothing), minus the "
          "left-out plate's unloading (ms):\n")
    print("| file | side | plate | markers alone | moved by the other plates |\n"
          "|---|---|---|---|---|")
    alone, moved, strikes = [], [], []
    for path in sorted(real.rglob("*.c3d")):
        found = left_out_plates(path)
        offsets = [own for kind, _, _, own, _ in found
                   if kind == "heel_strike" and abs(own) <= PLATE_MATCH_S]   # markers saw it
        strikes += [(abs(own), abs(own - np.median(offsets[:k] + offsets[k + 1:])))
                    for k, own in enumerate(offsets) if len(offsets) > 1]
        for _, side, plate, own, shifted in (f for f in found if f[0] == "toe_off"):
            print(f"| {path.stem} | {side} | {plate} | {1000 * own:+.1f} | "
                  + ("– |" if np.isnan(shifted) else f"{1000 * shifted:+.1f} |"))
            if np.isfinite(shifted):
                alone.append(abs(1000 * own))
                moved.append(abs(1000 * shifted))
    alone, moved = np.array(alone), np.array(moved)
    if moved.size:
        print(f"\nOver the {moved.size} the other plates move: median |Δ| {np.median(moved):.1f} "
              f"ms, worst {moved.max():.1f} (markers alone: {np.median(alone):.1f} ms, worst "
              f"{alone.max():.1f}).")
    if strikes:
        own, shifted = 1000 * np.array(strikes).T
        print(f"\nThe heel strikes are not moved: moved the same way, the {len(strikes)} the "
              f"plates time in captures with two or more would lie a median "
              f"{np.median(shifted):.1f} ms from the left-out plate's loading, worst "
              f"{shifted.max():.1f} (markers alone: {np.median(own):.1f} ms, worst "
              f"{own.max():.1f}).")
    return alone, moved


def regenerate(folder: Path, noise_sd: float) -> None:
    """Write the sample plan's captures into ``folder`` with marker noise ``noise_sd`` (m)."""
    plan = load_plan(ROOT / "protocols" / "paper_plan.toml")
    captures = tuple(
        dataclasses.replace(c, markers=dataclasses.replace(c.markers, noise_sd=noise_sd))
        for c in plan.captures)
    generate_plan(dataclasses.replace(plan, captures=captures), folder)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=Path, default=ROOT / "sample_c3d")
    parser.add_argument("--real", type=Path, default=Path(os.environ.get(
        "MOCAPLIB_SHARED_C3D", ROOT.parent / "shared" / "data" / "c3d")))
    parser.add_argument("--noise-sd", type=float, default=None, metavar="SD",
                        help="regenerate the sample plan with this marker noise (m) instead")
    add_markdown_option(parser)
    args = parser.parse_args(argv)
    with markdown_page(args.markdown, __file__, argv):
        verdict = tables(args)
    default = EventSettings().toe_off
    return 0 if all(verdict[default]) else 1


def tables(args) -> dict[str, tuple[bool, bool]]:
    """Print every table for the parsed ``args``; {toe-off definition: (synthetic target met,
    real target met)}."""
    with tempfile.TemporaryDirectory() as folder:
        samples = args.samples
        if args.noise_sd is not None:
            samples = Path(folder)
            regenerate(samples, args.noise_sd)
        verdict = {toe_off: (synthetic_table(samples, toe_off), real_table(args.real, toe_off))
                   for toe_off in TOE_OFF_DEFINITIONS}
    walks = slow_walks()
    for toe_off in TOE_OFF_DEFINITIONS:
        slow_table(walks, toe_off)
    if args.real.is_dir():
        plate_table(args.real)
        per_file_table(args.real)
        uncertain_table(args.real)
        plate_timed_table(args.real)
        left_out_table(args.real)
    print()
    for toe_off, (synthetic, real) in verdict.items():
        print(f"- `{toe_off}`: synthetic target {'met' if synthetic else 'MISSED'}, "
              f"real target {'met' if real else 'MISSED'}")
    return verdict


if __name__ == "__main__":
    sys.exit(main())
