"""End-to-end accuracy of v̂, ω̂, v̂_l against the synthetic truth, per locomotion type.

    /work/venv/bin/python benchmarks/velocity_accuracy.py [LIBRARY.json] [--samples sample_c3d]

Builds the library from ``--samples`` (``mocaplib build ... --jobs 2``) unless a library file
is given, then matches every entry with the truth cycle of its capture whose start time is
nearest (``*.truth.json`` beside each ``*.c3d``) and prints, per locomotion type, the number of
entries and the worst |Δv̂| (also as % of the truth), |Δω̂| and |Δv̂_l|, each against the
issue's targets: v̂ within 2 % (0.02 m/s where the truth is near 0: under 1 m/s), ω̂ within
0.02 rad/s, v̂_l within 0.02 m/s. Exit code 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mocaplib.library import load_library  # noqa: E402

#: Locomotion type of a sample capture, from its file name (first match wins).
TYPES = (("side_curve", r"^side_.*_curve_"), ("side_step", r"^side_"), ("diagonal", r"^diag_"),
         ("walk_curve", r"^walk_curve_"), ("walk_straight", r"^walk_straight_"),
         ("run", r"^run_"), ("turn_spot", r"^turn_spot_"), ("rest", r"^rest"))
V_REL, V_ABS, OMEGA_TOL, V_L_TOL = 0.02, 0.02, 0.02, 0.02


def locomotion_type(name: str) -> str:
    return next((kind for kind, pattern in TYPES if re.match(pattern, name)), "other")


def compare(library_path: Path, samples: Path) -> list[dict]:
    """One row per library entry: capture name, type, truth and estimate of v, omega, v_l."""
    entries = load_library(library_path).entries
    rows = []
    for entry in entries.itertuples():
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
        rows.append({"name": name, "type": locomotion_type(name), "start_dt": dt,
                     **{f"true_{k}": truth[k] for k in ("v", "omega", "v_l")},
                     **{k: float(getattr(entry, k)) for k in ("v", "omega", "v_l")}})
    return rows


def v_tolerance(true_v: float) -> float:
    """2 % of v̂, at least 0.02 m/s (the issue's tolerance near 0)."""
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("library", nargs="?", type=Path, help="a built library (else built now)")
    parser.add_argument("--samples", type=Path, default=ROOT / "sample_c3d")
    parser.add_argument("--static", type=Path, help="passed to mocaplib build as --static")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        library = args.library
        if library is None:
            library = Path(tmp) / "lib.json"
            command = [sys.executable, "-m", "mocaplib", "build", str(args.samples), "-o",
                       str(library), "--jobs", "2", "--no-cache"]
            if args.static:
                command += ["--static", str(args.static)]
            subprocess.run(command, check=True, cwd=ROOT, capture_output=True)
        return 0 if report(compare(library, args.samples)) else 1


if __name__ == "__main__":
    sys.exit(main())
