"""Where kinematic toe-off marks lie against the force plates and the synthetic truth.

    python benchmarks/toe_off_marks.py [--samples sample_c3d] [--real DIR] [--markdown PATH]

For every force-plate unloading of the real files under ``--real`` (default
``$MOCAPLIB_SHARED_C3D``, else ``../shared/data/c3d``; :func:`event_accuracy.plate_unloadings`,
20 N) paired with a placed default toe-off within 0.1 s, and for every toe-off of the walking
samples of ``--samples`` (their truth: the toes' tips leaving the floor; runs left out, their
toe-off is the lift), prints each candidate mark's time minus the reference's (:data:`MARKS`):
the default toe-off's two marks (:func:`mocaplib.gait.foot_events.toe_off_marks`) and the
features the literature times toe-offs on (O'Connor et al. 2007: the foot centre's upward
velocity peak; Hreljac & Marshall 2000: the toe's horizontal acceleration peak; Bruening &
Ridge 2014: the toe's speed crossing a threshold; De Witt 2010, Fellin et al. 2010: the toe's
vertical velocity, acceleration and position; the toe's horizontal speed rising to a share
of its swing's peak, a threshold relative to the stride's own swing; the foot's instantaneous
centre of rotation running ahead of the toe marker as the toes leave), and, at the reference,
the foot's pitch rate as a share of its push-off peak and the toe's horizontal speed as a
share of its swing's peak (per locomotion type on the samples). Each mark is sought from 0.15 s
before to 0.1 s after the default toe-off, on the detector's low-passed points
(:func:`mocaplib.gait.events.capture_feet`). Then every mean of two marks (weights ¼, ½,
¾) and median of three against the per-file targets (median |Δ| <= 10 ms and worst <= 30 ms
against each real file's plates and lab Foot Offs) and the samples' (within 1 frame in every
locomotion type).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from event_accuracy import plate_files, plate_unloadings
from markdown_results import add_markdown_option, markdown_page

from mocaplib.gait.events import capture_events, capture_feet
from mocaplib.gait.feet import LAB_EVENT_KINDS
from mocaplib.gait.foot_events import peak_time, toe_off_marks, toe_off_signals
from mocaplib.io.c3d import read_c3d
from mocaplib.markersets.matching import detect_protocol
from mocaplib.synth.plan import locomotion_type

#: The candidate marks, in the tables' order: (column, what it is).
MARKS = (("default", "the default toe-off (mean of (a) and (b))"),
         ("(a)", "velocity peak of the point 60 % of the way to the toe marker"),
         ("(b)", "end of the roll: the pitch rate down to half its push-off peak"),
         ("centre", "foot centre's upward-velocity peak (O'Connor 2007)"),
         ("toe vz", "toe marker's upward-velocity peak"),
         ("toe az", "toe marker's upward-acceleration peak"),
         ("toe +10 mm", "toe marker 10 mm above its stance height"),
         ("pitch 0.7", "the pitch rate down to 0.7 of its push-off peak"),
         ("toe 1 m/s", "toe marker's horizontal speed over 1 m/s"),
         ("toe ah", "toe marker's horizontal-acceleration peak (Hreljac 2000)"),
         ("toe 25 %", "toe marker's horizontal speed up to a quarter of its swing's peak"),
         ("pivot 8 cm", "the foot's instantaneous centre of rotation 8 cm ahead of the toe marker"))
#: Search window around the default toe-off (s before, s after).
BEFORE_S, AFTER_S = 0.15, 0.10
#: The toe marker's swing peak of horizontal speed is sought until this long after the
#: default toe-off (s), and its share that marks the toe-off: the median share of the real
#: feet at the plates' unloading (0.15-0.34 over the 15).
SWING_PEAK_S, TOE_SPEED_SHARE = 0.35, 0.25
#: How far ahead of the toe marker (m, along the foot) the foot's instantaneous centre of
#: rotation marks the toe-off: it sits near the toe marker while the foot rolls over its
#: forefoot and runs forwards as the foot leaves; 8 cm, about the toes' length past the
#: metatarsal heads.
PIVOT_AHEAD_M = 0.08


def pivot_ahead(foot, last: int) -> tuple[np.ndarray, np.ndarray]:
    """How far (m) the instantaneous centre of rotation of the heel-toe line (the line in the
    vertical plane through it, velocities relative to the ground) lies ahead of the marker of
    index ``last`` along the foot, and the line's angular velocity (rad/s), each (F,)."""
    velocity = foot.velocity - foot.ground
    line = foot.points[last] - foot.points[1 - last]
    along = line[:, :2] / np.linalg.norm(line[:, :2], axis=1, keepdims=True)

    def planar(v):
        return np.stack([np.sum(v[:, :2] * along, axis=1), v[:, 2]], axis=1)

    r, dv, heel = planar(line), planar(velocity[last] - velocity[1 - last]), planar(
        velocity[1 - last])
    omega = (r[:, 0] * dv[:, 1] - r[:, 1] * dv[:, 0]) / np.sum(r ** 2, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return -heel[:, 1] / omega - r[:, 0], omega


def _crossing(signal: np.ndarray, lo: int, hi: int, level: float, *, rising: bool) -> float:
    """First sub-frame time (frames) in ``[lo, hi)`` where ``signal`` crosses ``level``."""
    for i in range(max(lo, 1), hi):
        a, b = signal[i - 1], signal[i]
        if (a < level <= b) if rising else (a > level >= b):
            return i - 1 + (a - level) / (a - b)
    return np.nan


def marks_of(foot, rate: float, detected: float
             ) -> tuple[dict[str, float], np.ndarray, np.ndarray]:
    """{column of :data:`MARKS`: time (frames, NaN where not found)} around the default
    toe-off ``detected`` (frames) of the prepared ``foot``, the foot's pitch rate (F,) and the
    toe marker's horizontal speed as a share of its swing's peak (F,)."""
    lo = max(0, round(detected - BEFORE_S * rate))
    hi = min(len(foot.given), round(detected + AFTER_S * rate))
    last = int(np.argmin(foot.heights[:, min(hi - 1, round(detected + 0.05 * rate))]))
    signals = toe_off_signals(foot, last, rate)
    pitch_rate = signals[1]
    peak = lo + int(np.nanargmax(pitch_rate[lo:hi]))
    vertical = foot.velocity[:, :, 2]
    horizontal = np.linalg.norm(foot.velocity[last, :, :2] - foot.ground[:2], axis=1)
    stance = np.nanmedian(foot.heights[last, max(0, lo - 10):lo + 1])
    found = {"default": detected,
             **dict(zip(("(a)", "(b)"), toe_off_marks(signals, lo, hi))),
             "centre": peak_time(vertical.mean(axis=0), lo, hi),
             "toe vz": peak_time(vertical[last], lo, hi),
             "toe az": peak_time(np.gradient(vertical[last]), lo, hi),
             "toe +10 mm": _crossing(foot.heights[last], lo, hi, stance + 0.010, rising=True),
             "pitch 0.7": _crossing(pitch_rate, peak, hi, 0.7 * pitch_rate[peak], rising=False),
             "toe 1 m/s": _crossing(horizontal, lo, hi, 1.0, rising=True),
             "toe ah": peak_time(np.gradient(horizontal), lo, hi)}
    swing = lo + int(np.nanargmax(horizontal[lo:round(detected + SWING_PEAK_S * rate)]))
    found["toe 25 %"] = _crossing(horizontal, lo, swing, TOE_SPEED_SHARE * horizontal[swing],
                                  rising=True)
    ahead, omega = pivot_ahead(foot, last)
    rolling = np.where(omega * omega[peak] > 0, ahead, np.nan)           # turning as it rolls
    found["pivot 8 cm"] = _crossing(rolling, peak, hi, PIVOT_AHEAD_M, rising=True)
    return ({k: np.nan if v is None else float(v) for k, v in found.items()}, pitch_rate,
            horizontal / horizontal[swing])


def paired_marks(path: Path, references: list[tuple[float, str | None]]
                 ) -> list[tuple[float, dict[str, float], tuple[float, float]]]:
    """For each reference toe-off (s from the first frame, side or None for either) of the C3D
    at ``path`` with a placed default toe-off within 0.1 s: (the reference, {column: mark −
    reference (s)}, (the foot's pitch rate at the reference as a share of its push-off peak,
    the toe's horizontal speed there as a share of its swing's peak))."""
    trial = read_c3d(path)
    match = detect_protocol(trial)
    events, _ = capture_events(trial, match, force_plates=False)
    feet = {foot.side: foot for foot in capture_feet(trial, match)[0]}
    offs = [e for e in events if e.kind == "toe_off" and e.placed]
    out = []
    for reference, side in references:
        near = [e for e in offs if side in (None, e.side)]
        event = min(near, key=lambda e: abs(e.time_s - reference), default=None)
        if event is None or abs(event.time_s - reference) > 0.1:
            continue
        marks, pitch_rate, toe_speed = marks_of(feet[event.side], trial.rate,
                                                event.time_s * trial.rate)
        at = reference * trial.rate
        lo = max(0, round(at - BEFORE_S * trial.rate))
        frames = np.arange(len(pitch_rate))
        pitch = np.interp(at, frames, pitch_rate) / np.nanmax(
            pitch_rate[lo:round(at + AFTER_S * trial.rate)])
        out.append((reference, {k: v / trial.rate - reference for k, v in marks.items()},
                    (float(pitch), float(np.interp(at, frames, toe_speed)))))
    return out


def plate_table(real: Path) -> dict[str, list[dict[str, float]]]:
    """Print each mark against each plate unloading of the real files (ms) and a summary;
    {file stem: [{column: mark − unloading (s)} per paired unloading]}."""
    columns = [name for name, _ in MARKS]
    print("\nEach mark minus the plate's unloading (ms; 20 N), and the foot's pitch rate at the "
          "unloading (share of its push-off peak):\n")
    print("| file | unloading (s) | " + " | ".join(columns) + " | pitch rate |\n"
          + "|---" * (len(columns) + 3) + "|")
    by_file: dict[str, list[dict[str, float]]] = defaultdict(list)
    shares = []
    for path, unloadings in plate_files(real, plate_unloadings):
        for unloading, marks, share in paired_marks(path, [(u, None) for u in unloadings]):
            by_file[path.stem].append(marks)
            shares.append(share)
            print(f"| {path.stem} | {unloading:.3f} | "
                  + " | ".join(f"{1000 * marks[c]:+.1f}" for c in columns)
                  + f" | {share[0]:.2f} |")
    print("\n| mark | median (ms) | median \\|Δ\\| (ms) | worst \\|Δ\\| (ms) | files over 10 ms "
          "(median \\|Δ\\|) |\n|---|---|---|---|---|")
    for column, meaning in MARKS:
        every = 1000 * np.array([m[column] for ms in by_file.values() for m in ms])
        over = [name for name, ms in by_file.items()
                if np.nanmedian(np.abs([1000 * m[column] for m in ms])) > 10.0]
        print(f"| {column}: {meaning} | {np.nanmedian(every):+.1f} | "
              f"{np.nanmedian(np.abs(every)):.1f} | {np.nanmax(np.abs(every)):.1f} | "
              f"{len(over)} of {len(by_file)}{': ' + ', '.join(over) if over else ''} |")
    _print_shares(shares, "the plates' unloading")
    return by_file


def lab_marks(real: Path) -> dict[str, list[dict[str, float]]]:
    """{file stem: [{column: mark − Foot Off (s)} per lab Foot Off paired with a placed toe-off
    of its side]} for the real files under ``real`` whose EVENT group holds Foot Offs."""
    by_file = {}
    for path in sorted(real.rglob("*.c3d")):
        trial = read_c3d(path)
        references = [(e.time_s - trial.start_time, _side(e)) for e in trial.events
                      if LAB_EVENT_KINDS.get(e.label) == "toe_off" and _side(e)]
        paired = paired_marks(path, references) if references else []
        if paired:
            by_file[path.stem] = [marks for _, marks, _ in paired]
    return by_file


def _side(event) -> str | None:
    """"left" or "right" from a lab event's context, else its label (LTO); None if neither."""
    letter = next((text[:1].upper() for text in (event.context, event.label)
                   if text[:1].upper() in ("L", "R")), None)
    return {"L": "left", "R": "right"}.get(letter)


def synthetic_table(samples: Path) -> dict[str, list[dict[str, float]]]:
    """Print each mark against the walking samples' true toe-offs (frames) per locomotion type;
    {locomotion type: [{column: mark − truth (frames)} per toe-off]}."""
    by_type: dict[str, list[dict[str, float]]] = defaultdict(list)
    shares: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for path in sorted(samples.glob("*.c3d")):
        truth_file = path.with_suffix(".truth.json")
        if not truth_file.is_file() or locomotion_type(path.stem) == "run":
            continue
        truth = json.loads(truth_file.read_text())
        rate = read_c3d(path).rate
        references = [(e["time_s"], e["side"]) for e in truth["events"] if e["kind"] == "toe_off"]
        for _, marks, share in paired_marks(path, references):
            by_type[locomotion_type(path.stem)].append({k: v * rate for k, v in marks.items()})
            shares[locomotion_type(path.stem)].append(share)
    every = [m for ms in by_type.values() for m in ms]
    print(f"\nEach mark minus the true toe-off on the walking samples ({samples.name}, "
          f"{len(every)} toe-offs; frames): median, and within 1 frame overall and in the "
          "worst locomotion type:\n")
    print("| mark | median (frames) | within 1 frame | worst type |\n|---|---|---|---|")
    for column, _ in MARKS:
        within = {kind: np.mean([abs(m[column]) <= 1.0 for m in ms])
                  for kind, ms in by_type.items()}
        worst = min(within, key=within.get)
        print(f"| {column} | {np.nanmedian([m[column] for m in every]):+.2f} | "
              f"{100 * np.mean([abs(m[column]) <= 1.0 for m in every]):.0f} % | "
              f"{worst} {100 * within[worst]:.0f} % |")
    _print_shares([s for kind in shares.values() for s in kind], "the samples' true toe-offs")
    print("\nThe toe's horizontal speed at the true toe-offs, share of its swing's peak, median "
          "(range) per locomotion type: " + "; ".join(
              f"{kind} {np.median(toe):.2f} ({min(toe):.2f}–{max(toe):.2f})"
              for kind, toe in ((kind, [s[1] for s in kind_shares])
                                for kind, kind_shares in sorted(shares.items()))) + ".")
    return by_type


def _print_shares(shares: list[tuple[float, float]], where: str) -> None:
    """Print the ranges and medians of ``shares`` ((pitch rate share, toe speed share) per
    toe-off, :func:`paired_marks`) at ``where``."""
    pitch, toe = np.array(shares).T
    print(f"\nAt {where}: the foot's pitch rate {pitch.min():.2f}–{pitch.max():.2f} of its "
          f"push-off peak (median {np.median(pitch):.2f}); the toe's horizontal speed "
          f"{toe.min():.2f}–{toe.max():.2f} of its swing's peak (median {np.median(toe):.2f}).")


def combinations_table(real: dict[str, dict[str, list[dict[str, float]]]],
                       by_type: dict[str, list[dict[str, float]]], *, shown: int = 8) -> None:
    """Print how the means of two marks (weights ¼, ½, ¾) and the medians of three do against
    the per-file targets (median |Δ| <= 10 ms, worst <= 30 ms) on ``real`` ({"plates" or "lab
    Foot Off": {file: marks (s)}}) and within 1 frame on the samples ``by_type`` (frames)."""
    columns = [name for name, _ in MARKS]
    rules = {f"{w:g}·{a} + {1 - w:g}·{b}": (lambda m, a=a, b=b, w=w: w * m[a] + (1 - w) * m[b])
             for a, b in itertools.combinations(columns, 2) for w in (0.25, 0.5, 0.75)}
    rules.update({f"median({a}, {b}, {c})": (lambda m, k=(a, b, c): np.median([m[x] for x in k]))
                  for a, b, c in itertools.combinations(columns, 3)})
    rows = []
    for name, rule in rules.items():
        missed = []
        for against, by_file in real.items():
            for stem, marks in by_file.items():
                errors = np.abs([rule(m) for m in marks])
                if not (np.median(errors) <= 0.010 and errors.max() <= 0.030):
                    missed.append(f"{stem} ({against})")
        within = min(np.mean([abs(rule(m)) <= 1.0 for m in ms]) for ms in by_type.values())
        rows.append((len(missed), -within, name, missed))
    rows.sort()
    met = sum(not missed for _, _, _, missed in rows)
    print(f"\n{len(rows)} combinations of the marks (means of two weighted ¼, ½, ¾; medians of "
          f"three): {met} meet the per-file targets on every real file; those missing fewest:\n")
    print("| combination | real files missed | samples: worst type within 1 frame |\n|---|---|---|")
    for count, within, name, missed in rows[:shown]:
        print(f"| {name} | {count}: {', '.join(missed)} | {-100 * within:.0f} % |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=Path, default=ROOT / "sample_c3d")
    parser.add_argument("--real", type=Path, default=Path(os.environ.get(
        "MOCAPLIB_SHARED_C3D", ROOT.parent / "shared" / "data" / "c3d")))
    add_markdown_option(parser)
    args = parser.parse_args(argv)
    with markdown_page(args.markdown, __file__, argv):
        real = ({"plates": plate_table(args.real), "lab Foot Off": lab_marks(args.real)}
                if args.real.is_dir() else {})
        if not real:
            print(f"\nreal lab files not found under {args.real}: skipped")
        by_type = synthetic_table(args.samples)
        if real:
            combinations_table(real, by_type)
    return 0


if __name__ == "__main__":
    sys.exit(main())
