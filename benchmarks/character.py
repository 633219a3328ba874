"""The character a library drives: planted feet, pelvis and knees of `mocaplib query` and
`mocaplib retarget` outputs, per locomotion type and body height.

    python benchmarks/character.py [LIBRARY.json] [--samples sample_c3d]
                                   [--heights 1.4 1.5 1.6 1.75 1.9 2.0] [--markdown PATH]

Without a library, builds the quick start's one from ``--samples`` (``mocaplib build SAMPLES
--static SAMPLES/rest.c3d --static-pose neutral --forward-reference
SAMPLES/walk_straight_normal.c3d --jobs 2``). Then, for every chosen entry that moves:

* **query**: the blend at the entry's own (v̂, ω̂, v̂_l) (``--clamp``), two cycles at 100 Hz as
  ``mocaplib query --bvh`` writes them (:func:`mocaplib.library.planting.plant_blend`), its feet
  before and after planting;
* **the report's viewer**: the entry's cycle planted and fitted again as a series
  (:func:`mocaplib.library.planting.planted_series`), posed at 100 Hz by the viewer's own
  JavaScript (node on templates/motion.js, tests/viewer_poses.py: each leg moved to its
  foot's lock), its feet; and the series alone (the legs not moved), for comparison; and
  the blends the viewer plays at the centroid of every second tetrahedron of the gait cells,
  their feet on the locks the page finds (``findLocks``) and from their series alone;
* **retarget** to each height: :func:`mocaplib.library.retarget.retarget` at 100 Hz, its feet,
  its pelvis's vertical acceleration against the entry's (its closed cycle on its own body)
  times the body's size ratio (requested stance over the entry's), its pelvis yaw range (about
  the cycle's steady turn) against the entry's, its lowest knee flexion, its rate and whether a
  looped file repeats a frame.

Feet (:func:`mocaplib.library.planting.contact_measures`, worst over the entries): ``slide``, the
largest horizontal travel of a heel or toe while it touches the floor (within 1 mm) in one
stance; ``below``, the deepest a heel or toe goes under the floor; ``hover``, how far a flat foot
stays above it (per stance, the lowest height the higher of heel and toe reaches). The tests
(tests/test_planting.py) measure the same from the written BVH with an independent reader.

Targets: slide <= 2 mm, below <= 0.5 mm, hover <= 3 mm; pelvis acceleration <= 1.3 x the entry's
x size + 0.5 m/s²; yaw range <= 1.5 x the entry's (+ 0.5°); knees >= 0; rate exact; no repeated
frame. Prints Markdown (``--markdown PATH`` also writes it into a results page,
:mod:`markdown_results`); exit code 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))      # the viewer's poses, computed by node

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from mocaplib.gait.fourier import RootDrift, synthesize  # noqa: E402
from mocaplib.library.controlspace import ControlSpace  # noqa: E402
from mocaplib.library.format import load_library  # noqa: E402
from mocaplib.library.legs import KNEES  # noqa: E402
from mocaplib.library.planting import cycle_contact, plant_blend  # noqa: E402
from mocaplib.library.retarget import retarget  # noqa: E402
from mocaplib.skeleton import JOINT_ANGLES, ROOT_HEADING, Skeleton  # noqa: E402
from mocaplib.synth.plan import locomotion_type  # noqa: E402
from viewer_poses import cell_centroids, viewer_blends, viewer_contact  # noqa: E402

SLIDE, BELOW, HOVER = 0.002, 0.0005, 0.003
JOLT_RATIO, JOLT_MARGIN, YAW_RATIO, YAW_MARGIN = 1.3, 0.5, 1.5, np.radians(0.5)
RATE = 100.0
HEIGHTS = (1.4, 1.5, 1.6, 1.75, 1.9, 2.0)


def moving_entries(library) -> list:
    """The chosen entries with a poulaine (walks, runs, side-steps, turns: not rest)."""
    return [e for e in library.entries if e.chosen and e.poulaine is not None]


def query_rows(library) -> pd.DataFrame:
    """One row per entry: its type and the planted blend's feet before and after."""
    cs = ControlSpace.from_library(library)
    shown = {entry: (feet, series) for entry, feet, series in viewer_contact(library, RATE)}
    rows = []
    for entry in moving_entries(library):
        answer = cs.query([[entry.v, entry.omega, entry.v_l]])
        if not answer.inside[0]:
            answer = cs.query(answer.nearest)
        planted = plant_blend(cs.blend(answer), library.skeleton, rate=RATE, cycles=2)
        before, after = planted.before, planted.after
        period = float(entry.T)
        drift = RootDrift(0.0, 0.0, 0.0, *entry.root_drift.velocities)
        viewer, series = shown[entry.id]
        alone = cycle_contact(library.skeleton,
                              lambda t: synthesize(series.a, series.b, period, t), drift,
                              period, RATE, round(period * RATE))
        rows.append({"entry": entry.id, "type": locomotion_type(entry.id.rsplit("_c", 1)[0], sided=False),
                     "slide_before": before.slide_m, "below_before": before.penetration_m,
                     "hover_before": before.hover_m, "slide": after.slide_m,
                     "below": after.penetration_m, "hover": after.hover_m,
                     "jolt": after.pelvis_acceleration_m_s2, "viewer_slide": viewer.slide_m,
                     "viewer_below": viewer.penetration_m, "viewer_hover": viewer.hover_m,
                     "series_slide": alone.slide_m, "series_below": alone.penetration_m,
                     "series_hover": alone.hover_m,
                     "own_jolt": before.pelvis_acceleration_m_s2})
    return pd.DataFrame(rows)


def yaw_range(heading: np.ndarray) -> float:
    """Peak-to-peak (rad) of a heading (n,) about its straight-line trend over the cycle."""
    frames = np.arange(len(heading))
    return float(np.ptp(heading - np.polyval(np.polyfit(frames, heading, 1), frames)))


def retarget_rows(library, heights) -> pd.DataFrame:
    """One row per entry and height (module docstring)."""
    rows = []
    for entry in moving_entries(library):
        period = float(entry.T)
        t = np.arange(round(period * RATE) + 1) / round(period * RATE) * period
        own = synthesize(entry.fourier.a, entry.fourier.b, period, t)
        for height in heights:
            result = retarget(library, entry.id, skeleton=Skeleton.from_height(height),
                              rate=RATE)
            feet, source = result.feet["output"], result.feet["entry"]
            size = result.requested[2] / library.poulaine(entry.id).parameters[2]
            heading = np.unwrap(result.q[:, ROOT_HEADING])
            rows.append({
                "entry": entry.id, "type": locomotion_type(entry.id.rsplit("_c", 1)[0], sided=False),
                "height": height, "slide": feet.slide_m, "below": feet.penetration_m,
                "hover": feet.hover_m, "jolt_ratio": feet.pelvis_acceleration_m_s2
                / (source.pelvis_acceleration_m_s2 * size),
                "jolt_ok": feet.pelvis_acceleration_m_s2
                <= JOLT_RATIO * source.pelvis_acceleration_m_s2 * size + JOLT_MARGIN,
                "yaw_ratio": yaw_range(heading[:-1]) / max(yaw_range(own[:-1, ROOT_HEADING]),
                                                            1e-9),
                "yaw_ok": yaw_range(heading[:-1])
                <= YAW_RATIO * yaw_range(own[:-1, ROOT_HEADING]) + YAW_MARGIN,
                "knee_min_deg": np.degrees(result.q[:, list(KNEES)].min()),
                "ankle_error_mm": result.ankle_error_m * 1000, "rate": result.rate,
                "repeats": bool(np.allclose(result.q[0, JOINT_ANGLES], result.q[-2, JOINT_ANGLES],
                                            atol=1e-9))})
    return pd.DataFrame(rows)


def _mm(x: float) -> str:
    return f"{x * 1000:.2f}"


def query_table(df: pd.DataFrame) -> list[str]:
    lines = [("| type | entries | slide before → after (mm) | below floor before → after (mm) "
              "| flat-foot hover before → after (mm) | pelvis acceleration: entry → output "
              "(m/s²) |"), "|---|---|---|---|---|---|"]
    for kind, group in df.groupby("type"):
        lines.append(f"| {kind} | {len(group)} | {_mm(group.slide_before.max())} → "
                     f"{_mm(group.slide.max())} | {_mm(group.below_before.max())} → "
                     f"{_mm(group.below.max())} | {_mm(group.hover_before.max())} → "
                     f"{_mm(group.hover.max())} | {group.own_jolt.max():.2f} → "
                     f"{group.jolt.max():.2f} |")
    return lines


def retarget_table(df: pd.DataFrame, by: str) -> list[str]:
    lines = [(f"| {by} | cycles | slide (mm) | below floor (mm) | hover (mm) | pelvis "
              "acceleration / entry's × size | yaw range / entry's | lowest knee (deg) | IK "
              "ankle error (mm) | rate (Hz) | repeated frames |"),
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, group in df.groupby(by):
        rates = sorted(set(group.rate))
        lines.append(f"| {key} | {len(group)} | {_mm(group.slide.max())} | "
                     f"{_mm(group.below.max())} | {_mm(group.hover.max())} | "
                     f"{group.jolt_ratio.max():.2f} | {group.yaw_ratio.max():.2f} | "
                     f"{group.knee_min_deg.min():.1f} | {group.ankle_error_mm.max():.2f} | "
                     f"{', '.join(f'{r:g}' for r in rates)} | {int(group.repeats.sum())} |")
    return lines


def blend_rows(library) -> pd.DataFrame:
    """One row per blend the report's viewer plays at the centroid of every second
    tetrahedron of the gait cells (tests/viewer_poses.py): its feet posed on the locks its
    JavaScript finds, and posed from its series alone."""
    rows = []
    for blend in viewer_blends(library, cell_centroids(library), RATE):
        if blend is not None:
            shown, alone = blend["contact"], blend["alone"]
            rows.append({"slide": shown.slide_m, "below": shown.penetration_m,
                         "hover": shown.hover_m, "alone_slide": alone.slide_m,
                         "alone_below": alone.penetration_m, "alone_hover": alone.hover_m})
    return pd.DataFrame(rows)


def missed_targets(queries: pd.DataFrame, retargets: pd.DataFrame,
                   blends: pd.DataFrame) -> list[str]:
    missed = []
    for name, df in (("query", queries), ("retarget", retargets)):
        for column, limit in (("slide", SLIDE), ("below", BELOW), ("hover", HOVER)):
            worst = df[column].max()
            if worst > limit:
                missed.append(f"{name} {column} {_mm(worst)} mm ({df.entry[df[column].idxmax()]})")
    for column, limit in (("viewer_slide", SLIDE), ("viewer_below", BELOW),
                          ("viewer_hover", HOVER)):
        if queries[column].max() > limit:
            missed.append(f"the report's viewer: {column[7:]} {_mm(queries[column].max())} mm")
    for column, limit in (("slide", SLIDE), ("below", BELOW), ("hover", HOVER)):
        if blends[column].max() > limit:
            missed.append(f"the report viewer's blends: {column} {_mm(blends[column].max())} mm")
    jolts = queries.jolt > JOLT_RATIO * queries.own_jolt + JOLT_MARGIN
    missed += [f"query pelvis acceleration of {e}" for e in queries.entry[jolts]]
    bad = retargets[~(retargets.jolt_ok & retargets.yaw_ok) | (retargets.knee_min_deg < 0)
                    | (retargets.rate != RATE) | retargets.repeats]
    missed += [f"retarget {row.entry} at {row.height} m" for row in bad.itertuples()]
    return missed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("library", nargs="?", type=Path, help="a built library (else built now)")
    parser.add_argument("--samples", type=Path, default=ROOT / "sample_c3d")
    parser.add_argument("--heights", type=float, nargs="+", default=HEIGHTS, metavar="M")
    add_markdown_option(parser)
    args = parser.parse_args()
    with markdown_page(args.markdown, __file__), tempfile.TemporaryDirectory() as tmp:
        library = args.library
        if library is None:
            library = Path(tmp) / "lib.json"
            subprocess.run([sys.executable, "-m", "mocaplib", "build", str(args.samples),
                            "--static", str(args.samples / "rest.c3d"), "--static-pose",
                            "neutral", "--forward-reference",
                            str(args.samples / "walk_straight_normal.c3d"), "-o", str(library),
                            "--jobs", "2"], check=True, capture_output=True)
        lib = load_library(library)
        started = time.perf_counter()
        queries = query_rows(lib)
        retargets = retarget_rows(lib, args.heights)
        blends = blend_rows(lib)
        missed = missed_targets(queries, retargets, blends)
        print(f"{len(queries)} entries that move, {len(retargets)} retargeted cycles, measured "
              f"in {time.perf_counter() - started:.0f} s.\n")
        print("### `mocaplib query` outputs, by locomotion type\n")
        print("\n".join(query_table(queries)) + "\n")
        print("Before: the blend as synthesised (the fitted ankle centre sits higher above the "
              "floor than the skeleton's ankle height); after: planted, as written.\n")
        print("The report's viewer poses each entry from its planted cycle fitted again as a "
              "Fourier series (`planted_series`), each leg then moved to its foot's lock: at "
              f"worst slide {_mm(queries.viewer_slide.max())} mm, below the floor "
              f"{_mm(queries.viewer_below.max())} mm, hover {_mm(queries.viewer_hover.max())} "
              f"mm (the series alone: {_mm(queries.series_slide.max())}, "
              f"{_mm(queries.series_below.max())}, {_mm(queries.series_hover.max())} mm).\n")
        print(f"A blend picked in the viewer ({len(blends)} blends at the centroids of every "
              "second tetrahedron of the gait cells) is posed on the locks the page finds on "
              f"it (`findLocks`): at worst slide {_mm(blends.slide.max())} mm, below the floor "
              f"{_mm(blends.below.max())} mm, hover {_mm(blends.hover.max())} mm (its series "
              f"alone: {_mm(blends.alone_slide.max())}, {_mm(blends.alone_below.max())}, "
              f"{_mm(blends.alone_hover.max())} mm).\n")
        print("### `mocaplib retarget` outputs, by body height\n")
        print("\n".join(retarget_table(retargets, "height")) + "\n")
        print("### `mocaplib retarget` outputs, by locomotion type (every height)\n")
        print("\n".join(retarget_table(retargets, "type")) + "\n")
        print("Targets: slide ≤ 2 mm, below the floor ≤ 0.5 mm, flat-foot hover ≤ 3 mm; pelvis "
              f"acceleration ≤ {JOLT_RATIO} × the entry's × size + {JOLT_MARGIN} m/s²; yaw range "
              f"≤ {YAW_RATIO} × the entry's + 0.5°; knees ≥ 0; {RATE:g} Hz exactly; no repeated "
              "frame. Missed: " + ("; ".join(missed) if missed else "none") + ".")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
