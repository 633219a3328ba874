"""Run inside Blender: import a BVH or glTF file as Blender's own importers do and write, for
every keyed frame, what Blender shows of the armature.

    blender -b --factory-startup --python benchmarks/blender_pose.py -- IN.bvh OUT.json
    blender -b --factory-startup --python benchmarks/blender_pose.py -- IN.glb OUT.json RATE

A BVH is imported with Blender's defaults (File > Import > Motion Capture (.bvh): Y up, -Z
forward, scale 1) and "Update Scene FPS" and "Update Scene Duration" on, as
docs/guide/exports.md tells a user to import. A glTF (.gltf, .glb), whose keys are in seconds,
is imported with File > Import > glTF 2.0's defaults after the scene's frame rate is set to
RATE (Hz), as a user sets it to the rate the file was written at: its key at t s lands on frame
t · RATE. OUT.json holds the scene's frame rate (``fps``: ``render.fps / fps_base``), its first
and last frame, the first and last frame the action keys (``keyed``), the bones' names, and for
every keyed frame each bone's world head (``head``: frames x bones x 3, m, Blender's Z-up
world) and the world matrices of the feet (``feet``: frames x 2 x 4 x 4, left and right).
Only Blender's Python runs this file (no mocaplib import).

Blender 3.4's BVH importer opens the file in mode "rU", which Python 3.11 refuses (Debian
builds Blender on the system's Python 3.11; blender.org's 3.4 bundles 3.10, where "rU" reads
as "r"): the import runs with "U" dropped from the modes it asks for, which is what "rU" means
on 3.10.
"""

import builtins
import json
import sys

import bpy

FEET = ("foot_l", "foot_r")


def import_bvh(source: str) -> None:
    """Blender's BVH import with its default options, the scene's rate and duration updated."""
    builtin_open = builtins.open
    builtins.open = lambda file, mode="r", *args, **kwargs: builtin_open(
        file, mode.replace("U", ""), *args, **kwargs)
    try:
        bpy.ops.import_anim.bvh(filepath=source, global_scale=1.0, axis_forward="-Z",
                                axis_up="Y", update_scene_fps=True, update_scene_duration=True)
    finally:
        builtins.open = builtin_open


def import_gltf(source: str, rate: float) -> None:
    """Blender's glTF 2.0 import with its default options, the scene at ``rate`` frames/s."""
    bpy.context.scene.render.fps = round(rate)
    bpy.context.scene.render.fps_base = round(rate) / rate
    bpy.ops.import_scene.gltf(filepath=source)


def main() -> None:
    args = sys.argv[sys.argv.index("--") + 1:]
    source, out = args[:2]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if source.lower().endswith((".gltf", ".glb")):
        import_gltf(source, float(args[2]))
    else:
        import_bvh(source)
    armature = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
    scene = bpy.context.scene
    world = armature.matrix_world
    bones = [b.name for b in armature.pose.bones]
    first, last = armature.animation_data.action.frame_range
    heads, feet = [], []
    for frame in range(round(first), round(last) + 1):
        scene.frame_set(frame)
        heads.append([list(world @ b.head) for b in armature.pose.bones])
        feet.append([[list(row) for row in world @ armature.pose.bones[name].matrix]
                     for name in FEET])
    with open(out, "w") as f:
        json.dump({"fps": scene.render.fps / scene.render.fps_base,
                   "frame_start": scene.frame_start, "frame_end": scene.frame_end,
                   "keyed": [first, last],
                   "bones": bones, "head": heads, "feet": feet,
                   "blender": bpy.app.version_string}, f)


main()
