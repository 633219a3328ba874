"""``mocaplib animate``: continuous motion following a path (a polyline or a timeline of
velocity commands), synthesised cycle after cycle from the library's control space."""

from __future__ import annotations

import math

from ..gait.gaits import BLEND_GAITS
from ._common import (LIBRARY_HINT, UsageError, add_force_option, check_inputs, check_outputs,
                      positive)
from .query import ANIMATION_RATE, _animation_rate, output_suffix

#: The outputs: option -> the format written (glTF binary for a --gltf name ending in .glb).
OUTPUTS = {"--bvh": ".bvh", "--gltf": ".gltf", "--csv": ".csv", "--mot": ".mot"}


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "animate", help="continuous motion following a path, as BVH, glTF, CSV or .mot",
        description="Follow PATH.csv — a polyline (columns x,y in metres, optionally t in "
                    "seconds) or a timeline of commands (columns t,v,omega,v_l: s, m/s, rad/s, "
                    "m/s) — cycle after cycle, each cycle blended from the control space at "
                    "the command the path asks for there, consecutive cycles joined at a left "
                    "toe-off with cross-faded angles. Prints each cycle's command, gait and "
                    "entries, and how far the root strayed from the path.")
    parser.add_argument("library", help="library JSON file")
    parser.add_argument("--path", required=True, metavar="PATH.csv", help="the path to follow")
    parser.add_argument("--speed", type=positive(float, unit=" m/s", most=10.0),
                        help="walking speed along a polyline without times, m/s")
    parser.add_argument("--gait", choices=BLEND_GAITS,
                        help="blend this gait's entries only (default: the command's cell)")
    parser.add_argument("--rate", type=_animation_rate,
                        help=f"frame rate, Hz (default {ANIMATION_RATE:g}); frames are at "
                             "exactly k/rate s")
    for option, suffix in OUTPUTS.items():
        parser.add_argument(option, metavar=f"OUT{suffix}", help=f"write the motion as {suffix}"
                            + (" (glTF 2.0 for game engines; .glb for the binary file)"
                               if option == "--gltf" else ""))
    add_force_option(parser)
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..export.formats import write
    from ..library.controlspace import ControlSpace
    from ..library.follow import follow, read_path, tracking_errors
    from ..library.format import load_library
    from ..library.planting import plant_feet
    from ..model.motion import Motion

    outputs = {option: getattr(args, option[2:]) for option in OUTPUTS
               if getattr(args, option[2:])}
    if not outputs:
        raise UsageError("nothing to write: add --bvh OUT.bvh, --gltf OUT.gltf, --csv OUT.csv "
                         "or --mot OUT.mot")
    check_inputs([args.library, args.path], hint=LIBRARY_HINT)
    check_outputs(outputs, [args.library, args.path], force=args.force)
    path = read_path(args.path)
    library = load_library(args.library)
    cs = ControlSpace.from_library(library, source=args.library)
    rate = args.rate or ANIMATION_RATE
    followed = follow(cs, path, rate=rate, speed=args.speed, gait=args.gait)
    planted = plant_feet(library.skeleton, followed.q, rate)
    motion = Motion(planted.q, library.skeleton, rate, source="animate")
    for option, out in outputs.items():
        print(f"{option[2:].upper()}: "
              f"{write(motion, out, suffix=output_suffix(option, out, OUTPUTS))}")
    for k, c in enumerate(followed.cycles):
        print(f"  cycle {k}: t = {c.start_s:.3f} s, T = {c.T:.3f} s, command "
              f"({c.command[0]:.3f} m/s, {c.command[1]:.3f} rad/s, {c.command[2]:.3f} m/s), "
              f"{c.gait}{_clamped(c)}: {', '.join(c.entries)}")
    errors = tracking_errors(path, followed)
    print(f"{len(followed.q)} frames at {rate:g} Hz; root within {100 * errors['root_m']:.1f} cm "
          f"of the path, heading within {errors['heading_deg']:.1f}°; largest frame-to-frame "
          f"joint change {errors['jump_deg']:.2f}° (the blended cycles' own: "
          f"{errors['own_jump_deg']:.2f}°)")
    feet = planted.after
    print(f"feet planted: slide {feet.slide_m * 1000:.1f} mm, below the floor "
          f"{feet.penetration_m * 1000:.1f} mm, flat-foot hover {feet.hover_m * 1000:.1f} mm at "
          f"worst over {feet.stances} stances")
    return 0


def _clamped(cycle) -> str:
    """How a cycle served clamped onto its cell is said: with its turn warp (deg/s)."""
    if not cycle.clamped:
        return ""
    return (f" (clamped; its path frame turned {math.degrees(cycle.turn_warp):+.2f} deg/s "
            "beyond the blend's)" if cycle.turn_warp else " (clamped)")
