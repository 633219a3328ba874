"""``mocaplib retarget``: a library cycle adapted to another body by IK on its poulaine."""

from __future__ import annotations

import json
from pathlib import Path

from ._common import (LIBRARY_HINT, UsageError, add_force_option, bounded, check_inputs,
                      check_outputs, positive)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "retarget", help="adapt a library cycle to another body (poulaine + IK)",
        description="Retarget the cycle of one library entry to a body of another height or "
                    "segment lengths: each ankle follows a poulaine interpolated from the "
                    "library's (step length, foot spacing and stance as requested, by default "
                    "the entry's scaled to the body), solved by inverse kinematics with "
                    "secondary tasks (joint limits, reference posture, rotational kinetic "
                    "energy). Writes the joint angles and prints the criteria C1-C3 of the "
                    "entry and of the result. See docs/poulaines.md.")
    parser.add_argument("library", help="library JSON file")
    parser.add_argument("entry", help="entry id (see `mocaplib query` or the report)")
    body = parser.add_mutually_exclusive_group(required=True)
    body.add_argument("--height", type=positive(float, unit=" m"), metavar="H",
                      help="target standing height, m (segment lengths in the nominal "
                           "proportions of mocaplib.skeleton)")
    body.add_argument("--segment-lengths", metavar="FILE",
                      help="JSON object of the target's segment lengths in metres, every "
                           "length of the skeleton (the library's skeleton.segment_lengths_m "
                           "has the names)")
    parser.add_argument("--step-length", type=positive(float, unit=" m"), metavar="L",
                        help="the ankle's fore-aft excursion relative to the pelvis, m "
                             "(default: the entry's, times the ratio of leg lengths)")
    parser.add_argument("--foot-spacing", type=bounded(5.0), metavar="W",
                        help="lateral distance between the ankles in support, m (default: the "
                             "entry's, times the ratio of hip widths)")
    parser.add_argument("--stance", type=positive(float, unit=" m"), metavar="S",
                        help="pelvis-to-ankle height in support, m (default: the entry's, "
                             "times the ratio of leg lengths)")
    parser.add_argument("--rate", type=positive(float, unit=" Hz", most=1000.0), default=100.0,
                        metavar="HZ", help="output samples per second (default 100)")
    for name, default, what in (("joint-limits", 1e-3, "distance to the joint limits"),
                                ("reference", 1.0, "distance to the entry's posture, per rad²"),
                                ("kinetic", 1e-2, "rotational kinetic energy, per J/kg")):
        parser.add_argument(f"--weight-{name}", type=float, default=default, metavar="W",
                            help=f"weight of the {what} in the IK's null space (default "
                                 f"{default:g})")
    parser.add_argument("-o", "--output", action="append", required=True, metavar="OUT",
                        help="file to write, by its suffix: .csv (rad, m), .mot (OpenSim), "
                             ".bvh, .gltf or .glb (glTF 2.0 for game engines); repeat for "
                             "several")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    add_force_option(parser)
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..errors import MocapError
    from ..export.formats import format_of
    from ..library.format import load_library
    from ..library.retarget import ANKLE_TOLERANCE_M, MIN_STEPS, Weights, lowest_rate, retarget
    from ._common import print_json

    check_inputs([args.library] + ([args.segment_lengths] if args.segment_lengths else []),
                 hint=LIBRARY_HINT)
    for out in args.output:
        try:
            format_of(out, "motion")
        except MocapError as exc:
            raise UsageError(f"-o {out}: {exc.message}; {exc.hint}") from None
    check_outputs({f"-o {out}": out for out in args.output}, [args.library],
                  force=args.force)
    skeleton = _skeleton(args)
    try:
        weights = Weights(joint_limits=args.weight_joint_limits, reference=args.weight_reference,
                          kinetic=args.weight_kinetic)
    except MocapError as exc:
        raise UsageError(str(exc)) from None
    library = load_library(args.library)
    if args.entry not in {e.id for e in library.entries}:
        raise UsageError(f"no entry {args.entry!r} in {args.library}"
                         f"{_closest(args.entry, library)}")
    period = float(library.entry(args.entry).T)
    if round(period * args.rate) < MIN_STEPS:
        raise UsageError(f"--rate {args.rate:g}: fewer than {MIN_STEPS} samples over the "
                         f"cycle of {args.entry} ({period:.3g} s): give at least "
                         f"{lowest_rate(period):.3g} Hz")
    result = retarget(library, args.entry, skeleton=skeleton, step_length=args.step_length,
                      foot_spacing=args.foot_spacing, stance=args.stance, weights=weights,
                      rate=args.rate)
    if not result.ankle_error_m <= ANKLE_TOLERANCE_M:
        raise MocapError(f"the body cannot follow the request: its ankles stay up to "
                         f"{result.ankle_error_m:.3f} m from the requested paths (step length, "
                         f"foot spacing, stance {', '.join(f'{v:.3f}' for v in result.requested)}"
                         f" m; limit {ANKLE_TOLERANCE_M:g} m); nothing written",
                         hint="ask for a step, foot spacing and stance this body can reach, "
                              "or leave them to the entry's, scaled to the body")
    written = [str(result.write(out)) for out in args.output]
    summary = result.summary() | {"outputs": written}
    if args.json:
        print_json(summary)
        return 0
    step, spacing, stance = summary["requested_m"]
    print(f"{args.entry} retargeted: step length {step:.3f} m, foot spacing {spacing:.3f} m, "
          f"stance {stance:.3f} m (poulaine x, y, z from {', '.join(summary['sources'])})")
    print(f"  {summary['frames']} frames at {summary['rate_hz']:g} Hz; the IK's ankles within "
          f"{summary['ankle_error_m'] * 1000:.1f} mm of the poulaine; "
          f"{summary['clamped_steps']} IK steps stopped by a joint limit, "
          f"{summary['limit_violations']} samples outside the limits, "
          f"{summary['hyperextended_samples']} of a hyperextended knee")
    feet, entry = summary["feet"]["output"], summary["feet"]["entry"]
    print(f"  feet planted, at worst: slide {feet['slide_m'] * 1000:.1f} mm per stance, "
          f"{feet['penetration_m'] * 1000:.1f} mm below the floor, flat-foot hover "
          f"{feet['hover_m'] * 1000:.1f} mm (the entry's {entry['hover_m'] * 1000:.1f} mm); "
          f"pelvis vertical acceleration {feet['pelvis_acceleration_m_s2']:.1f} m/s² (the "
          f"entry's {entry['pelvis_acceleration_m_s2']:.1f} m/s²)")
    print("  criterion                      entry      result")
    for key, label, digits in (("jerk_rms_rad_s3", "C1 jerk RMS (rad/s³)", 0),
                               ("cycle_closure_rad", "C2 closure (rad)", 4),
                               ("internal_power_w_kg", "C3 internal power (W/kg)", 2)):
        print(f"  {label:28s} {summary['criteria']['input'][key]:9.{digits}f}  "
              f"{summary['criteria']['output'][key]:9.{digits}f}")
    for path in written:
        print(f"  wrote {path}")
    return 0


def _skeleton(args):
    """The target skeleton of ``--height`` or ``--segment-lengths`` (UsageError when the file
    is not a JSON object of every length, in metres)."""
    from ..errors import MocapError
    from ..skeleton import Skeleton

    try:
        if args.height is not None:
            return Skeleton.from_height(args.height)
        try:
            lengths = json.loads(Path(args.segment_lengths).read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise MocapError(f"cannot read it as JSON ({exc})") from None
        if not isinstance(lengths, dict) or not all(isinstance(v, (int, float))
                                                    and not isinstance(v, bool)
                                                    for v in lengths.values()):
            raise MocapError("must be a JSON object of segment name -> metres")
        return Skeleton(lengths)
    except MocapError as exc:
        option = ("--height" if args.height is not None
                  else f"--segment-lengths {args.segment_lengths}")
        raise UsageError(f"{option}: {exc.message}") from None


def _closest(entry: str, library) -> str:
    """' (did you mean ...?)' with the library's ids closest to ``entry``, or a few of its
    ids."""
    import difflib

    ids = [e.id for e in library.entries]
    close = difflib.get_close_matches(entry, ids, n=3)
    if close:
        return f" (did you mean {', '.join(close)}?)"
    return f" (ids are {', '.join(ids[:5])}{', ...' if len(ids) > 5 else ''})"
