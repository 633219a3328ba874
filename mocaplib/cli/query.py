"""``mocaplib query``: which entries and weights blend a velocity command; optional BVH or glTF
cycle."""

from __future__ import annotations

import argparse
import math

from ..gait.gaits import BLEND_GAITS
from ..io import printable
from ._common import (LIBRARY_HINT, UsageError, add_force_option, bounded, check_inputs,
                      check_outputs, positive)

#: Largest |V|, |OMEGA|, |VL| accepted (m/s, rad/s): far beyond any locomotion, so only
#: typing mistakes (and overflow in the geometry) are kept out.
SPEED_LIMIT = 100.0
#: Animation output limits: frames per second and cycles (a BVH is text: 100 cycles at 1 kHz is
#: already ~100 MB). Below MIN_RATE a gait cycle (about 1 s) would get fewer than 10 frames.
MIN_RATE, MAX_RATE, MAX_CYCLES = 10.0, 1000.0, 100
#: Defaults of --cycles and --rate (they are None when not given, to tell them apart).
ANIMATION_CYCLES, ANIMATION_RATE = 1, 100.0
#: The animation outputs: option -> the format written (glTF binary for a --gltf name ending
#: in .glb).
ANIMATIONS = {"--bvh": ".bvh", "--gltf": ".gltf"}


def output_suffix(option: str, path: str, formats: dict[str, str]) -> str:
    """The format an output ``option`` writes ``path`` in: ``formats[option]``, or the glTF
    binary (``.glb``) for a ``--gltf`` name ending in .glb."""
    if option == "--gltf" and path.lower().endswith(".glb"):
        return ".glb"
    return formats[option]


def _animation_rate(text: str) -> float:
    """argparse ``type=`` of --rate: Hz in [MIN_RATE, MAX_RATE]; else exit 2."""
    rate = positive(float, unit=" Hz", most=MAX_RATE)(text)
    if rate < MIN_RATE:
        raise argparse.ArgumentTypeError(
            f"must be >= {MIN_RATE:g} Hz (a gait cycle needs frames to be seen), got {text}")
    return rate


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "query", help="blend weights of a velocity command (and its cycle as BVH or glTF)",
        description="Find the tetrahedron of one gait's cell enclosing (V, OMEGA, VL) and print "
                    "its four entries with their barycentric weights, the gait, and whether the "
                    "command was clamped onto the cell (between the walks and the runs); "
                    "outside the control space, print how far, the nearest point and entries, "
                    "and the options that serve it. Exit 0 when answered (inside or outside).")
    parser.add_argument("library", help="library JSON file")
    parser.add_argument("v", type=bounded(SPEED_LIMIT), metavar="V",
                        help="tangential speed v̂, m/s (v̂_f with --axes frontal)")
    parser.add_argument("omega", type=bounded(SPEED_LIMIT), metavar="OMEGA",
                        help="turn rate ω̂, rad/s (> 0 turns left)")
    parser.add_argument("v_l", type=bounded(SPEED_LIMIT), metavar="VL",
                        help="lateral speed v̂_l, m/s (> 0 moves left)")
    parser.add_argument("--axes", choices=("tangential", "frontal"), default="tangential",
                        help="control space (v, ω, v_l) or (v_f, ω, v_l) (default tangential)")
    parser.add_argument("--gait", choices=BLEND_GAITS,
                        help="blend this gait's entries only (default: the cell holding the "
                             "command, else the nearest)")
    parser.add_argument("--json", action="store_true",
                        help="print {inside, gait, clamped, entries, weights, point, nearest, "
                             "distance, nearest_entries, T_s} (and, with --bvh or --gltf, played_T_s: "
                             "the period in whole frames, and feet: the planted feet's slide, "
                             "penetration, hover)")
    parser.add_argument("--bvh", metavar="OUT.bvh",
                        help="write the blended cycle as BVH (Y up, metres; Blender opens it)")
    parser.add_argument("--gltf", metavar="OUT.gltf",
                        help="write the blended cycle as glTF 2.0 for game engines (Y up, +Z "
                             "forward, metres; .glb for the binary file)")
    parser.add_argument("--cycles", type=positive(int, most=MAX_CYCLES),
                        help=f"cycles written to the animation (default {ANIMATION_CYCLES}, at "
                             f"most {MAX_CYCLES}; only with --bvh or --gltf)")
    parser.add_argument("--rate", type=_animation_rate,
                        help=f"animation frame rate, Hz (default {ANIMATION_RATE:g}, "
                             f"{MIN_RATE:g} to {MAX_RATE:g}; only with --bvh or --gltf)")
    parser.add_argument("--clamp", action="store_true",
                        help="outside the hull, blend at the nearest point on the hull instead")
    add_force_option(parser)
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..errors import MocapError
    from ..export.formats import write
    from ..library.controlspace import ControlSpace
    from ..library.document import checksum_status
    from ..library.format import load_library
    from ..library.planting import plant_blend
    from ..model.motion import Motion
    from ._common import print_json, warn

    outputs = {option: getattr(args, option[2:]) for option in ANIMATIONS
               if getattr(args, option[2:])}
    ignored = [option for option, value in (("--cycles", args.cycles), ("--rate", args.rate))
               if value is not None]
    if ignored and not outputs:
        raise UsageError(f"{' and '.join(ignored)} only apply to the animation outputs: add "
                         f"--bvh OUT.bvh or --gltf OUT.gltf, or leave "
                         f"{'it' if len(ignored) == 1 else 'them'} out")
    check_inputs([args.library], hint=LIBRARY_HINT)
    check_outputs(outputs, [args.library], force=args.force)
    library = load_library(args.library)
    if checksum_status(library) == "mismatch":
        warn(f"{args.library}: its content does not match its checksum: it was changed after "
             "it was written (`mocaplib validate` says more)")
    cs = ControlSpace.from_library(library, axes=args.axes, source=args.library)
    res = cs.query([[args.v, args.omega, args.v_l]], gait=args.gait)
    blended = res
    if not res.inside[0] and args.clamp:
        blended = cs.query(res.nearest, gait=res.gait[0])
    clamped = bool(res.clamped[0] or (args.clamp and not res.inside[0]))
    answer = {"inside": bool(res.inside[0]), "point": res.points[0].tolist(),
              "axes": list(cs.axes), "gait": res.gait[0], "clamped": clamped,
              "entries": [], "weights": []}
    blend = cs.on_body(cs.blend(blended), blended) if blended.inside[0] else None
    if blend is not None:
        answer["entries"] = [cs.ids[k] for k in blended.entries[0]]
        answer["weights"] = blended.weights[0].tolist()
        answer["T_s"] = float(blend.T[0])
    if clamped or not res.inside[0]:
        answer["nearest"] = res.nearest[0].tolist()
        answer["distance"] = float(res.distance[0])
    if not res.inside[0]:
        answer["nearest_entries"] = cs.nearest_ids(res.points[0])
    if outputs and blend is None:
        raise MocapError(f"cannot write {' or '.join(outputs)}: "
                         + cs.outside_text(res), path=args.library,
                         hint=_serving_options(cs, args))
    if outputs:
        rate = args.rate or ANIMATION_RATE
        blend = blend.looped(rate)
        answer["played_T_s"] = float(blend.T[0])
        planted = plant_blend(blend, library.skeleton, rate=rate,
                              cycles=args.cycles or ANIMATION_CYCLES)
        answer["feet"] = planted.after.as_dict()
        motion = Motion(planted.q, library.skeleton, rate, source="blend")
        for option, path in outputs.items():
            answer[option[2:]] = str(write(motion, path,
                                           suffix=output_suffix(option, path, ANIMATIONS)))
    if args.json:
        print_json(answer)
        return 0
    names = ", ".join(cs.axes)
    where = ("OUTSIDE the control space" if not res.inside[0] else
             "inside the control space, between its gait cells" if res.clamped[0] else
             "inside the control space")
    print(f"({names}) = {_triple(res.points[0])}: {where}")
    if not res.inside[0]:
        print(f"  outside by {res.distance[0]:.3g} (normalised); nearest point of the "
              f"{res.gait[0]} cell: {_triple(res.nearest[0])}")
        print(f"  nearest entries: {', '.join(answer['nearest_entries'])}")
        why = cs.impossible_text(res.points[0])
        if why:
            print(f"  {why}")
        if args.clamp:
            print("  blending at that point (--clamp)")
        else:
            print(f"  {_serving_options(cs, args)}")
    elif res.clamped[0]:
        print(f"  between the gaits' cells: blended at the nearest point of the {res.gait[0]} "
              f"cell, {_triple(res.nearest[0])} (normalised distance {res.distance[0]:.3g}; "
              f"--gait chooses the gait)")
    print(f"  gait: {res.gait[0]}" + (" (asked with --gait)" if args.gait else ""))
    if answer["entries"]:
        entries = [printable(e, keep="") for e in answer["entries"]]  # ids from file names
        width = max(len(e) for e in entries)
        print(f"  {'entry':<{width}}  weight")
        for entry, weight in zip(entries, answer["weights"]):
            print(f"  {entry:<{width}}  {weight:.4f}")
        print(f"  blended period T_d = {answer['T_s']:.3f} s")
    if outputs:
        played = answer["played_T_s"]
        print(f"  played in whole frames: T = {played:.3f} s ({round(played * rate)} frames a "
              f"cycle at {rate:g} Hz), so the clip loops")
        feet = answer["feet"]
        print(f"  feet planted: slide {feet['slide_m'] * 1000:.1f} mm, below the floor "
              f"{feet['penetration_m'] * 1000:.1f} mm, flat-foot hover {feet['hover_m'] * 1000:.1f}"
              f" mm at worst over {feet['stances']} stances")
    for option in outputs:
        print(f"  {option[2:].upper()}: {answer[option[2:]]}")
    return 0


def _serving_options(cs, args) -> str:
    """The options that serve a command outside the control space ``cs``."""
    options = ["--clamp blends at the nearest point"]
    if cs.variant == "tangential":
        options.append("--axes frontal (v_f, omega, v_l) holds the entries that walk backwards")
    options += [f"--gait {g} blends the {g} cell" for g in cs.cells if g != args.gait
                and args.gait is not None]
    return "options: " + "; ".join(options)


def _triple(p) -> str:
    """A control point for people: m/s, rad/s with degrees per second, m/s."""
    return f"({p[0]:.3f} m/s, {p[1]:.3f} rad/s = {math.degrees(p[1]):.1f}°/s, {p[2]:.3f} m/s)"
