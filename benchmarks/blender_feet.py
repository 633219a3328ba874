"""mocaplib's BVH and glTF outputs as Blender shows them: joints, frame rate and planted feet,
measured in Blender itself.

    python benchmarks/blender_feet.py [LIBRARY.json] [--samples sample_c3d] [--blender blender]
                                      [--heights 1.5 1.9] [--real DIR] [--markdown PATH]

Without a library, builds the quick start's one from ``--samples``. Writes, with the CLI a user
runs, each motion as BVH and as glTF binary (.glb) by the same command: for one entry of every
locomotion type, ``mocaplib query LIBRARY V OMEGA VL --clamp --bvh --gltf --cycles 3`` at the
entry's own command; ``mocaplib retarget`` of the straight normal walk to each of
``--heights``; ``mocaplib animate`` along a path turning left. Where ``--real`` (default
``$MOCAPLIB_SHARED_C3D``, else ``../shared/data/c3d``) holds the lab walks of
tests/walking_library.py, also ``mocaplib build`` of them with ``--all-cycles`` and the same
query at every moving entry of that library (each a walk of a real person, on the library's
skeleton). Each file is imported into Blender (``blender -b``, :mod:`blender_pose`: Blender's
default BVH import with the scene's frame rate updated; its default glTF import after the
scene's frame rate is set to the file's) and measured there:

* **joints**: the largest distance over every bone head and frame between Blender's pose and
  an independent reader's forward kinematics of the same file (tests/bvh_reader.py;
  tests/gltf_reader.py, pygltflib, for the glTF; no mocaplib code); the frame counts and the
  scene's frame rate against the file's;
* **feet** as Blender poses them: each foot's toe is its bone's end site, its heel on the sole
  (tests/bvh_reader.py's :class:`Character` of the BVH, its points at the first frame moved
  with Blender's foot matrices): ``slide``, the largest horizontal travel of a heel or toe
  touching the floor (within 1 mm) in one stance; ``below``, the deepest a heel or toe goes
  under Blender's floor (z = 0); ``hover``, how far a flat foot stays above it.

Targets (as benchmarks/character.py): slide ≤ 2 mm, below ≤ 0.5 mm, hover ≤ 3 mm, joints
within 0.1 mm of the reader, the scene's frame rate the file's. Prints Markdown
(``--markdown PATH`` also writes it into a results page); exit code 1 when a target is missed,
2 when Blender is not found or its glTF importer cannot run (it needs numpy in Blender's
Python: Debian's ``python3-numpy``).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from bvh_reader import Character, parse_bvh  # noqa: E402
from character import HOVER, SLIDE, moving_entries  # noqa: E402
from control_space import quick_start_library  # noqa: E402
from gltf_reader import animated_positions  # noqa: E402
from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from mocaplib.library.format import load_library  # noqa: E402
from mocaplib.synth.plan import locomotion_type  # noqa: E402
from walking_library import REAL_WALKS  # noqa: E402

BELOW, JOINTS = 0.0005, 1e-4
HEIGHTS = (1.5, 1.9)
#: Blender's import (Y up, -Z forward): Blender's world (x, y, z) = (x, -z, y) of the file,
#: as the reader's Z-up frame.
POSE_SCRIPT = Path(__file__).resolve().parent / "blender_pose.py"
#: Blender's glTF import turns the file's Y up into Z and its +Z (the subject's front) into -Y:
#: the reader's axes (x forward, y left, z up) from Blender's world after a glTF import.
OURS_FROM_GLTF_IMPORT = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
#: The path ``animate`` follows: 4 m straight, then a quarter circle of radius 2 m to the left.
PATH_CSV = "x,y\n" + "\n".join(f"{x:.3f},{y:.3f}" for x, y in (
    [(0.5 * k, 0.0) for k in range(9)]
    + [(4.0 + 2.0 * np.sin(a), 2.0 - 2.0 * np.cos(a)) for a in np.linspace(0.2, np.pi / 2, 8)]))


class BlenderCharacter(Character):
    """A BVH file's character with its feet as Blender poses them: the reader's heel and toe
    points of each foot at the first frame, fixed to Blender's foot bone there and moved with
    Blender's foot matrices (so any rest pose and bone orientation the importer chose)."""

    def __init__(self, text: str, pose: dict, *, loop: bool = False):
        super().__init__(text, loop=loop)
        self.pose = pose

    def feet(self) -> np.ndarray:
        first = super().feet()[0]                                            # (2, 2, 3) Z up
        moved = np.asarray(self.pose["feet"])                                # (F, 2, 4, 4)
        out = []
        for side in range(2):
            local = np.linalg.solve(moved[0, side], np.c_[first[side], np.ones(2)].T)  # (4, 2)
            out.append(np.einsum("fij,jp->fpi", moved[:, side], local)[..., :3])
        return np.stack(out, axis=1)


def blender_pose(blender: str, path: Path, rate: float | None = None) -> dict:
    """What Blender shows of the BVH or glTF file ``path`` (:mod:`blender_pose`; ``rate``: the
    scene's frame rate for a glTF, Hz). Blender's output is in the error when it fails."""
    out = path.with_name(path.name + ".json")
    done = subprocess.run([blender, "-b", "--factory-startup", "--python-exit-code", "1",
                           "--python", str(POSE_SCRIPT), "--", str(path), str(out),
                           *([repr(rate)] if rate else [])],
                          capture_output=True, text=True, timeout=600)
    if done.returncode:
        raise RuntimeError(f"Blender could not pose {path.name}:\n{done.stdout[-2000:]}"
                           f"{done.stderr[-2000:]}")
    return json.loads(out.read_text())


def gltf_importer_missing(blender: str) -> str | None:
    """Why Blender's glTF importer cannot run here, or None: it needs numpy in Blender's own
    Python (blender.org's builds bundle it; Debian's Blender takes the system's:
    ``apt-get install python3-numpy``)."""
    done = subprocess.run([blender, "-b", "--factory-startup", "--python-exit-code", "1",
                           "--python-expr", "import numpy"], capture_output=True, timeout=120)
    if done.returncode == 0:
        return None
    return ("Blender's glTF importer needs numpy in Blender's Python (Debian: apt-get install "
            "python3-numpy)")


def _in_our_axes(pose: dict) -> dict:
    """A glTF import's pose turned into the reader's axes (:data:`OURS_FROM_GLTF_IMPORT`)."""
    turn = np.eye(4)
    turn[:3, :3] = OURS_FROM_GLTF_IMPORT
    return {**pose, "head": np.asarray(pose["head"]) @ OURS_FROM_GLTF_IMPORT.T,
            "feet": turn @ np.asarray(pose["feet"])}


def measure(name: str, path: Path, loop: bool, blender: str) -> dict:
    """One file's row: joints against an independent reader, frame rate, feet in Blender
    (``loop``: the file is one cycle that a player repeats, its stances across its ends whole).
    A glTF file (.gltf, .glb) has its BVH twin beside it (the same motion, written by the same
    command), whose reader gives the feet's sole; its joints are read with pygltflib."""
    text = path.with_suffix(".bvh").read_text()
    reader = Character(text)
    if path.suffix in (".gltf", ".glb"):
        pose = _in_our_axes(blender_pose(blender, path, 1.0 / reader.frame_time))
        times, positions, named = animated_positions(path)
        frames = len(times)
        theirs = positions[:, [named.index(bone) for bone in pose["bones"]]]
    else:
        pose = blender_pose(blender, path)
        frames = reader.frames
        theirs = np.stack([reader.position(bone) for bone in pose["bones"]], axis=1)
        named = [j["name"] for j in parse_bvh(text)[0] if j["name"] is not None]
    keyed = round(pose["keyed"][1] - pose["keyed"][0]) + 1
    scene = pose["frame_end"] - pose["frame_start"] + 1
    heads = np.asarray(pose["head"])                                          # (F, B, 3)
    seen = BlenderCharacter(text, pose, loop=loop)
    return {"output": name, "frames": frames, "blender_frames": keyed,
            "scene_frames": scene,
            "file_hz": 1.0 / reader.frame_time, "blender_fps": pose["fps"],
            "bones": f"{len(pose['bones'])}/{len(named)}",
            "joints_mm": 1000 * float(np.abs(heads - theirs).max()),
            "stances": len(seen.stances()), "slide_mm": 1000 * seen.slide(),
            "below_mm": 1000 * seen.penetration(), "hover_mm": 1000 * seen.hover(),
            "blender": pose["blender"]}


def _twins(label: str, bvh: Path, loop: bool) -> list[tuple[str, Path, bool]]:
    """The rows of one output written as BVH and as glTF binary beside it."""
    return [(label, bvh, loop), (f"{label}, glTF", bvh.with_suffix(".glb"), loop)]


def outputs(library: Path, folder: Path, heights) -> list[tuple[str, Path, bool]]:
    """Write the files measured (module docstring) with the CLI, each as BVH and as glTF;
    (label, path, whether it is one looping cycle) each."""
    lib = load_library(library)
    cli = [sys.executable, "-m", "mocaplib"]
    written, seen = [], set()
    for entry in moving_entries(lib):
        kind = locomotion_type(entry.id.rsplit("_c", 1)[0], sided=False)
        if kind in seen:
            continue
        seen.add(kind)
        out = folder / f"query_{kind}.bvh"
        subprocess.run([*cli, "query", str(library), repr(entry.v), repr(entry.omega),
                        repr(entry.v_l), "--clamp", "--bvh", str(out), "--gltf",
                        str(out.with_suffix(".glb")), "--cycles", "3"],
                       check=True, capture_output=True, cwd=ROOT)
        written += _twins(f"query, {kind} ({entry.id})", out, False)
    walk = next(e.id for e in moving_entries(lib) if e.id.startswith("walk_straight_normal"))
    for height in heights:
        out = folder / f"retarget_{height}.bvh"
        subprocess.run([*cli, "retarget", str(library), walk, "--height", str(height), "-o",
                        str(out), "-o", str(out.with_suffix(".glb"))],
                       check=True, capture_output=True, cwd=ROOT)
        written += _twins(f"retarget, {walk} to {height} m (one cycle, looped)", out, True)
    path = folder / "path.csv"
    path.write_text(PATH_CSV)
    out = folder / "animate.bvh"
    subprocess.run([*cli, "animate", str(library), "--path", str(path), "--speed", "1.1",
                    "--bvh", str(out), "--gltf", str(out.with_suffix(".glb"))],
                   check=True, capture_output=True, cwd=ROOT)
    written += _twins("animate, 4 m then a left quarter circle of 2 m at 1.1 m/s", out, False)
    return written


def real_outputs(real: Path, folder: Path) -> list[tuple[str, Path, bool]]:
    """Build the library of the lab walks under ``real`` (every complete cycle) and write the
    query at every moving entry's own command, as :func:`outputs` does for the samples."""
    library = folder / "real.json"
    subprocess.run([sys.executable, "-m", "mocaplib", "build",
                    *(str(real / name) for name in REAL_WALKS), "--all-cycles", "-o",
                    str(library)], check=True, capture_output=True, cwd=ROOT)
    written = []
    for entry in load_library(library).entries:
        if entry.poulaine is None or not np.isfinite(entry.root_drift.velocities).all():
            continue
        out = folder / f"real_{entry.id}.bvh"
        command = [f"{x:.9f}" for x in (entry.v, entry.omega, entry.v_l)]   # no exponent
        subprocess.run([sys.executable, "-m", "mocaplib", "query", str(library), *command,
                        "--clamp", "--bvh", str(out), "--gltf", str(out.with_suffix(".glb")),
                        "--cycles", "3"], check=True, capture_output=True, cwd=ROOT)
        written += _twins(f"query, real walk {entry.id}", out, False)
    return written


def missed(df: pd.DataFrame) -> list[str]:
    """The targets the rows miss, in words."""
    out = []
    for row in df.itertuples(index=False):
        checks = {"slide": row.slide_mm <= 1000 * SLIDE, "below": row.below_mm <= 1000 * BELOW,
                  "hover": row.hover_mm <= 1000 * HOVER, "joints": row.joints_mm <= 1000 * JOINTS,
                  "frame rate": abs(row.blender_fps - row.file_hz) < 1e-6 * row.file_hz,
                  "frames": row.frames == row.blender_frames, "stances": row.stances >= 2}
        out += [f"{row.output}: {name}" for name, ok in checks.items() if not ok]
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("library", nargs="?", type=Path, help="a built library (else built now)")
    parser.add_argument("--samples", type=Path, default=ROOT / "sample_c3d")
    parser.add_argument("--blender", default="blender", help="the Blender executable")
    parser.add_argument("--heights", type=float, nargs="+", default=HEIGHTS, metavar="M")
    parser.add_argument("--real", type=Path, default=Path(os.environ.get(
        "MOCAPLIB_SHARED_C3D", ROOT.parent / "shared" / "data" / "c3d")),
                        help="folder of the lab walks (skipped when absent)")
    add_markdown_option(parser)
    args = parser.parse_args()
    blender = shutil.which(args.blender)
    if blender is None:
        print(f"Blender not found ({args.blender}): install it (Debian: apt-get install "
              "blender) or give --blender PATH", file=sys.stderr)
        return 2
    missing = gltf_importer_missing(blender)
    if missing:
        print(missing, file=sys.stderr)
        return 2
    with markdown_page(args.markdown, __file__), tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        library = args.library or quick_start_library(args.samples, folder / "lib.json")
        written = outputs(library, folder, args.heights)
        if all((args.real / name).is_file() for name in REAL_WALKS):
            written += real_outputs(args.real, folder)
        df = pd.DataFrame([measure(*output, blender) for output in written])
        print(f"Blender {df.blender.iloc[0]}, each file imported with its default options: a "
              "BVH with the scene's frame rate updated, a glTF (the same motion, written by the "
              "same command, `.glb`) after the scene's frame rate was set to the file's.\n")
        print("| output | frames (file / keyed / scene) | rate (file Hz / scene fps) | bones | "
              "joints vs reader (mm) | stances | slide (mm) | below (mm) | hover (mm) |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in df.itertuples(index=False):
            print(f"| {r.output} | {r.frames} / {r.blender_frames} / {r.scene_frames} | "
                  f"{r.file_hz:g} / "
                  f"{r.blender_fps:g} | {r.bones} | {r.joints_mm:.4f} | {r.stances} | "
                  f"{r.slide_mm:.2f} | {r.below_mm:.2f} | {r.hover_mm:.2f} |")
        print("\nThe BVH importer keys one frame per file frame from the scene's first; "
              "updating the scene's duration, it moves the scene's end to one frame after the "
              "last keyed one where the scene was shorter (never shortening it: 250 frames by "
              "default), hence the guide's note to set the end frame to the file's frame count "
              "for a loop. The glTF importer keys the file's key at t s on frame t · fps from "
              "frame 0 and leaves the scene's range as it was; its armature has a bone per "
              "node, the end points (`head_end`, `foot_l_end`...) included. Joints are measured "
              "against an independent reader of each file (tests/bvh_reader.py; pygltflib for "
              "the glTF), the feet on the keyed frames.")
        misses = missed(df)
        print(f"\nTargets: slide ≤ {1000 * SLIDE:g} mm, below ≤ {1000 * BELOW:g} mm, hover ≤ "
              f"{1000 * HOVER:g} mm, joints within {1000 * JOINTS:g} mm of the reader, the "
              "file's frame rate and frame count: "
              + ("all met." if not misses else "MISSED: " + "; ".join(misses) + "."))
    return 1 if misses else 0


if __name__ == "__main__":
    sys.exit(main())
