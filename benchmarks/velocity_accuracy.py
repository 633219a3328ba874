"""End-to-end accuracy of v̂, ω̂, v̂_l against the synthetic truth, per locomotion type.

    python benchmarks/velocity_accuracy.py [LIBRARY.json] [--samples sample_c3d]
                                           [--static FILE] [--toe-off DEF] [--markdown PATH]
    python benchmarks/velocity_accuracy.py --placement-draws 20 [--capture run_3p5]

Builds the library from ``--samples`` (``mocaplib build ... --jobs 2``) unless a library file
is given, then matches every entry with the truth cycle of its capture whose start time is
nearest (``*.truth.json`` beside each ``*.c3d``) and prints, per locomotion type, the number of
entries and the worst |Δv̂| (also as % of the truth), |Δω̂| and |Δv̂_l|, each against the
targets: v̂ within 2 % (0.02 m/s where the truth is near 0: under 1 m/s), ω̂ within
0.02 rad/s, v̂_l within 0.02 m/s. Exit code 1 when a target is missed. With ``--static``
(neutral) the build also gets ``--forward-reference SAMPLES/walk_straight_normal.c3d``
(``--forward-reference NAME``, or ``none``); ``--toe-off`` is passed to the build (the quick
start's library: ``--static sample_c3d/rest.c3d``). Prints Markdown tables
(``--markdown PATH`` also writes them into a results page, :mod:`markdown_results`).

``--placement-draws N``: the static calibration's heading error against v̂_l. The capture
(``--capture``) and the session's static are regenerated from the sample plan with N other
marker placements, session seeds 1..N (everything else as shipped; the shipped session first,
for reference), calibrated from that static in the neutral pose, fitted (markers low-passed at
Winter's cutoff), and per draw it prints δ, the mean heading error of the fitted shoulder
line on the static itself, and the v̂_l error of the capture's true cycles (the pipeline's
pattern and velocity stages on the fitted shoulder centres); then the same with the heading
offset the forward reference (``--forward-reference``, regenerated with the same placement
and written as C3D) measures through
:func:`mocaplib.build.pipeline.forward_offsets`. Last, the sd of δ, its correlation with the v̂_l
error, and how many draws miss with and without the reference.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from mocaplib.model.calibration import calibrate  # noqa: E402
from mocaplib.gait.cycles import shoulder_centres  # noqa: E402
from mocaplib.gait.events import TOE_OFF_DEFINITIONS  # noqa: E402
from mocaplib.model.filtering import filter_trial  # noqa: E402
from mocaplib.model.ik import fit  # noqa: E402
from mocaplib.library.format import load_library  # noqa: E402
from mocaplib.gait.patterns import cycle_samples, path_velocities, shoulder_heading  # noqa: E402
from mocaplib.build.settings import BuildSettings
from mocaplib.build.forward import forward_offsets
from mocaplib.synth.capture import write_capture  # noqa: E402
from mocaplib.synth.plan import load_plan, locomotion_type  # noqa: E402

V_REL, V_ABS, OMEGA_TOL, V_L_TOL = 0.02, 0.02, 0.02, 0.02


def compare(library_path: Path, samples: Path) -> list[dict]:
    """One row per library entry: capture name, type, truth and estimate of v, omega, v_l."""
    entries = load_library(library_path).entries
    rows = []
    for entry in entries:
        name = Path(entry.source_file).stem
        truth_file = samples / f"{name}.truth.json"
        if not truth_file.exists():
            continue
        cycles = json.loads(truth_file.read_text())["cycles"]
        if cycles:
            truth = min(cycles, key=lambda c: abs(c["start_s"] - entry.start_s))
            dt = abs(truth["start_s"] - entry.start_s)
        else:  # rest: the truth is standing still
            truth, dt = {"v": 0.0, "omega": 0.0, "v_l": 0.0}, 0.0
        rows.append({"name": name, "type": locomotion_type(name, sided=False), "start_dt": dt,
                     **{f"true_{k}": truth[k] for k in ("v", "omega", "v_l")},
                     **{k: float(getattr(entry, k)) for k in ("v", "omega", "v_l")}})
    return rows


def v_tolerance(true_v: float) -> float:
    """2 % of v̂, at least 0.02 m/s (the tolerance near 0)."""
    return max(V_REL * abs(true_v), V_ABS)


def report(rows: list[dict]) -> bool:
    """Print the per-type table; True when every entry meets every target."""
    print("| type | entries | worst \\|Δv̂\\| m/s (% of v̂) | worst \\|Δω̂\\| rad/s | "
          "worst \\|Δv̂_l\\| m/s (capture) | misses |")
    print("|---|---|---|---|---|---|")
    ok = True
    for kind in sorted({r["type"] for r in rows}):
        group = [r for r in rows if r["type"] == kind]
        dv = [(abs(r["v"] - r["true_v"]), r) for r in group]
        dw = [abs(r["omega"] - r["true_omega"]) for r in group]
        dl = [(abs(r["v_l"] - r["true_v_l"]), r) for r in group]
        misses = sum(d > v_tolerance(r["true_v"]) for d, r in dv) + sum(
            d > OMEGA_TOL for d in dw) + sum(d > V_L_TOL for d, _ in dl)
        ok &= misses == 0
        worst_v, rv = max(dv, key=lambda x: x[0])
        pct = 100 * worst_v / rv["true_v"] if rv["true_v"] > 1e-9 else float("nan")
        worst_l, rl = max(dl, key=lambda x: x[0])
        print(f"| {kind} | {len(group)} | {worst_v:.4f} ({pct:.1f} %) | {max(dw):.4f} | "
              f"{worst_l:.4f} ({rl['name']}) | {misses} |")
    missed = [f"{r['name']} ({r['v_l'] - r['true_v_l']:+.3f})" for r in rows
              if abs(r["v_l"] - r["true_v_l"]) > V_L_TOL]
    if missed:
        print(f"\nv̂_l misses (estimate − truth, m/s): {', '.join(missed)}")
    late = [r["name"] for r in rows if r["start_dt"] > 0.05]
    if late:
        print(f"\nentries whose start is > 50 ms from every truth cycle: {', '.join(late)}")
    print(f"\ntargets: v̂ within 2 % (0.02 m/s under 1 m/s), ω̂ within {OMEGA_TOL} rad/s, "
          f"v̂_l within {V_L_TOL} m/s; {len(rows)} entries, "
          f"{'all met' if ok else 'NOT all met'}")
    return ok


def placement_draws(plan_path: Path, capture_name: str, draws: int, reference: str) -> None:
    """Per marker placement, that is per session seed: δ of the static, the v̂_l error, the forward
    reference's heading offset and the v̂_l error with it (module doc)."""
    planned = {c.name: c for c in load_plan(plan_path).captures}

    def generate(name, session_seed):
        return dataclasses.replace(planned[name], session_seed=session_seed).generate()

    def v_l_error(trial, model, capture) -> tuple[float, float]:
        """Mean v̂_l error over the capture's true cycles, and their mean v̂."""
        left, right = shoulder_centres(fit(trial, model))
        errors, speeds = [], []
        for cycle in capture.truth["cycles"]:
            times, mid, heading = cycle_samples(left, right, trial.rate, cycle["start_s"],
                                                cycle["end_s"])
            errors.append(path_velocities(times, mid, heading).v_l - cycle["v_l"])
            speeds.append(cycle["v"])
        return float(np.mean(errors)), float(np.mean(speeds))

    print(f"| session seed | δ static heading (deg) | Δv̂_l (m/s) | −v̂·δ (m/s) | "
          f"offset from {reference} (deg) | Δv̂_l with it (m/s) |")
    print("|---|---|---|---|---|---|")
    rows = []
    shipped = planned["rest"].session_seed
    with tempfile.TemporaryDirectory() as tmp:
        for seed in [shipped, *range(1, draws + 1)]:
            rest, capture = generate("rest", seed), generate(capture_name, seed)
            static_path, _ = write_capture(rest, tmp, "rest")
            reference_path, _ = write_capture(generate(reference, seed), tmp, reference)
            offset, = forward_offsets(BuildSettings(
                static=str(static_path), static_pose="neutral",
                forward_reference=str(reference_path)))
            trial, _ = filter_trial(capture.trial, cutoff="auto")
            model = calibrate(trial, static=rest.trial, static_pose="neutral")
            on_static = shoulder_heading(*shoulder_centres(fit(rest.trial, model)))
            true_static = shoulder_heading(rest.body.shoulders[:, 0], rest.body.shoulders[:, 1])
            delta = float(np.mean(np.angle(np.exp(1j * (on_static - true_static)))))
            error, speed = v_l_error(trial, model, capture)
            corrected, _ = v_l_error(trial, calibrate(trial, static=rest.trial,
                                                      static_pose="neutral",
                                                      heading_offset=offset), capture)
            rows.append((delta, error, -speed * delta, offset, corrected))
            label = f"{seed} (shipped)" if seed == shipped else str(seed)
            print(f"| {label} | {np.degrees(delta):+.3f} | {error:+.4f} | {-speed * delta:+.4f} "
                  f"| {np.degrees(offset):+.3f} | {corrected:+.4f} |")
    if draws < 2:
        return
    delta, error, _, offset, corrected = np.array(rows[1:]).T     # the N new draws
    print(f"\n{capture_name}, {draws} placements (3 mm sd per axis): sd of δ "
          f"{np.degrees(delta.std()):.3f} deg, correlation of δ with Δv̂_l "
          f"{np.corrcoef(delta, error)[0, 1]:+.3f}, |Δv̂_l| > {V_L_TOL} m/s in "
          f"{int((np.abs(error) > V_L_TOL).sum())} of {draws}")
    print(f"with the forward reference {reference}: correlation of its offset with −δ "
          f"{np.corrcoef(offset, -delta)[0, 1]:+.3f}; |Δv̂_l| median "
          f"{np.median(np.abs(corrected)):.4f} m/s (without: {np.median(np.abs(error)):.4f}), "
          f"max {np.abs(corrected).max():.4f} (without: {np.abs(error).max():.4f}), "
          f"> {V_L_TOL} m/s in {int((np.abs(corrected) > V_L_TOL).sum())} of {draws}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("library", nargs="?", type=Path, help="a built library (else built now)")
    parser.add_argument("--samples", type=Path, default=ROOT / "sample_c3d")
    parser.add_argument("--static", type=Path, help="passed to mocaplib build as --static")
    parser.add_argument("--static-pose", choices=("neutral", "free"), default="neutral",
                        help="passed with --static (the sample session's rest is neutral)")
    parser.add_argument("--placement-draws", type=int, metavar="N",
                        help="instead: the static's heading error over N marker placements")
    parser.add_argument("--capture", default="run_3p5", help="capture for --placement-draws")
    parser.add_argument("--forward-reference", default="walk_straight_normal", metavar="NAME",
                        help="the capture (by name) that is the forward reference: with "
                             "--placement-draws regenerated with each placement, otherwise "
                             "SAMPLES/NAME.c3d passed to mocaplib build with --static; 'none': "
                             "no reference (with --placement-draws it is always used)")
    parser.add_argument("--plan", type=Path, default=ROOT / "protocols" / "paper_plan.toml")
    parser.add_argument("--toe-off", choices=TOE_OFF_DEFINITIONS, default=None,
                        help="passed to mocaplib build (default: its own)")
    add_markdown_option(parser)
    args = parser.parse_args()
    if args.placement_draws and args.forward_reference == "none":
        parser.error("--placement-draws always measures with a forward reference: name one")
    with markdown_page(args.markdown, __file__):
        if args.placement_draws:
            placement_draws(args.plan, args.capture, args.placement_draws,
                            args.forward_reference)
            return 0
        return 0 if entries_table(args) else 1


def entries_table(args) -> bool:
    """Compare the library the parsed ``args`` name (or one built now from ``--samples``) with
    the truth and print the table; True when every target is met."""
    with tempfile.TemporaryDirectory() as tmp:
        library = args.library
        if library is None:
            library = Path(tmp) / "lib.json"
            command = [sys.executable, "-m", "mocaplib", "build", str(args.samples), "-o",
                       str(library), "--jobs", "2", "--no-cache"]
            if args.static:
                command += ["--static", str(args.static), "--static-pose", args.static_pose]
                if args.forward_reference != "none" and args.static_pose == "neutral":
                    command += ["--forward-reference",
                                str(args.samples / f"{args.forward_reference}.c3d")]
            if args.toe_off:
                command += ["--toe-off", args.toe_off]
            subprocess.run(command, check=True, cwd=ROOT, capture_output=True)
        return report(compare(library, args.samples))


if __name__ == "__main__":
    sys.exit(main())
