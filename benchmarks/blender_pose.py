"""Run inside Blender: import a BVH file as Blender's own importer does and write, for every
frame of the scene, what Blender shows of the armature.

    blender -b --factory-startup --python benchmarks/blender_pose.py -- IN.bvh OUT.json

The import is Blender's default (File > Import > Motion Capture (.bvh): Y up, -Z forward,
scale 1) with "Update Scene FPS" and "Update Scene Duration" on, as docs/guide/exports.md
tells a user to import. OUT.json holds the scene's frame rate (``fps``: ``render.fps / fps_base``), its
first and last frame, the first and last frame the action keys (``keyed``), the bones' names, each bone's world head (``head``: frames x bones x 3,
m, Blender's Z-up world), the world matrices of the feet (``feet``: frames x 2 x 4 x 4, left
and right) and their rest matrices (``feet_rest``: 2 x 4 x 4). Only Blender's Python runs this
file (no mocaplib import).

Blender 3.4's importer opens the file in mode "rU", which Python 3.11 refuses (Debian
builds Blender on the system's Python 3.11; blender.org's 3.4 bundles 3.10, where "rU" reads
as "r"): the import runs with "U" dropped from the modes it asks for, which is what "rU" means
on 3.10.
"""

import builtins
import json
import sys

import bpy

FEET = ("foot_l", "foot_r")


def main() -> None:
    source, out = sys.argv[sys.argv.index("--") + 1:][:2]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    builtin_open = builtins.open
    builtins.open = lambda file, mode="r", *args, **kwargs: builtin_open(
        file, mode.replace("U", ""), *args, **kwargs)
    try:
        bpy.ops.import_anim.bvh(filepath=source, global_scale=1.0, axis_forward="-Z",
                                axis_up="Y", update_scene_fps=True, update_scene_duration=True)
    finally:
        builtins.open = builtin_open
    armature = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
    scene = bpy.context.scene
    world = armature.matrix_world
    bones = [b.name for b in armature.pose.bones]
    heads, feet = [], []
    for frame in range(scene.frame_start, scene.frame_end + 1):
        scene.frame_set(frame)
        heads.append([list(world @ b.head) for b in armature.pose.bones])
        feet.append([[list(row) for row in world @ armature.pose.bones[name].matrix]
                     for name in FEET])
    rest = [[list(row) for row in world @ armature.data.bones[name].matrix_local]
            for name in FEET]
    with open(out, "w") as f:
        first, last = armature.animation_data.action.frame_range
        json.dump({"fps": scene.render.fps / scene.render.fps_base,
                   "frame_start": scene.frame_start, "frame_end": scene.frame_end,
                   "keyed": [first, last],
                   "bones": bones, "head": heads, "feet": feet, "feet_rest": rest,
                   "blender": bpy.app.version_string}, f)


main()
