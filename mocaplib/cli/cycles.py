"""``mocaplib cycles FILE``: every cycle (left toe-off to left toe-off) with its pattern,
velocities and Fourier order, and the one chosen for the library.

Parses options and formats; the work is :func:`mocaplib.build.capture.process`, the same stages
``mocaplib build`` runs: import, protocol, calibration, fit, events (missing foot-marker samples
taken from the fitted skeleton), cycles on the fitted shoulder joint centres, QC and the choice.
"""

from __future__ import annotations

import numpy as np

from ._common import (add_cutoff_option, add_gap_option, add_static_options, check_inputs,
                      heading_offsets, measurements)
from .events import add_common_options


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "cycles", help="cut a capture into cycles: pattern, v, omega, v_l, Fourier order",
        description="Cut a capture at consecutive left toe-offs; for every cycle fit a line or "
                    "arc to the path of the midpoint of the fitted shoulder joint centres, "
                    "measure v, omega, v_l, v_f, encode the fitted joint angles as Fourier "
                    "series, and mark the steadiest cycle that passes the library's QC as "
                    "chosen. A standing capture gives one rest entry. Exit 0 on success, 1 "
                    "when the capture cannot be processed, 2 on usage errors.")
    add_common_options(parser)
    add_static_options(parser)
    add_cutoff_option(parser)
    add_gap_option(parser)
    parser.add_argument("--json", action="store_true",
                        help='print {"file", "cycles": [...]} (SI units, angles in radians; '
                             '"fourier_rms_deg" in degrees)')
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..build.capture import process
    from ..gait.cycles import LEFT_TOE_OFF
    from ..gait.qc import DEFAULT_QC_THRESHOLDS, named_failures
    from ._common import print_json

    statics = check_inputs([args.file], args.static, static_pose=args.static_pose,
                           references=args.forward_reference, static_window=args.static_window)
    done = process(args.file, protocol=args.protocol, static=statics,
                   static_pose=args.static_pose, cutoff=args.cutoff,
                   static_window=args.static_window, measurements=measurements(args),
                   heading_offsets=heading_offsets(args), toe_off=args.toe_off,
                   max_gap_s=args.max_gap_s)
    match, motion = done.match, done.motion
    rows = [{**c.to_dict(), "qc_failures": named_failures(c, motion, done.qc[c.index],
                                                          DEFAULT_QC_THRESHOLDS)}
            for c in done.cycles]
    if args.json:
        print_json({"file": args.file, "cycles": rows})
        return 0
    print(f"{args.file}: {len(rows)} cycle(s), protocol {match.protocol.name}")
    print("  #   start     T    pattern  arc°    v m/s  ω °/s   v_l m/s  v_f m/s  N  rms°  worst")
    for r in rows:
        print(f"{'*' if r['chosen'] else ' '} {r['index']:<2d} {r['start_s']:6.2f} "
              f"{r['T']:5.2f}  {r['pattern']['type']:6s} "
              f"{np.rad2deg(r['pattern']['arc_angle_rad']):6.1f}"
              f"  {r['v']:6.3f} {np.rad2deg(r['omega']):6.1f}  {r['v_l']:7.3f}  {r['v_f']:7.3f}"
              f"  {r['fourier_n']:2d} {r['fourier_rms_deg']:5.2f}  {r['fourier_worst_dof']}")
    for r in rows:
        if r["start_event"] != LEFT_TOE_OFF:
            print(f"  cycle {r['index']} starts at a {r['start_event'].replace('_', ' ')} (the "
                  f"protocol's fallback); its left toe-off is {r['left_toe_off_s']:.3f} s in")
        if r["qc_failures"]:
            print(f"  cycle {r['index']} fails QC: {'; '.join(r['qc_failures'])}")
        for sentence in r["unplaced_events"] + r["uncertain_events"]:
            print(f"  cycle {r['index']}: {sentence}")
        for bound, plate, shift in zip(("start", "end"), r["bound_plates"],
                                       r["bound_plate_shifts_s"]):
            event = f"  cycle {r['index']}: its {bound} ({r['start_event'].replace('_', ' ')})"
            if plate is not None:
                print(f"{event} timed by force plate {plate}")
            elif shift:
                print(f"{event} moved {1000 * shift:+.1f} ms by the force plates")
    print("  (* = chosen for the library: the steadiest cycle that passes QC, if any does)")
    return 0
