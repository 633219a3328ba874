"""``mocaplib events FILE``: left/right toe-offs and heel-strikes detected from the foot markers.

Parses options and formats; the work is :func:`mocaplib.gait.events.capture_events` on the heel and
toe markers the protocol names (:func:`mocaplib.gait.feet.feet_of`).
"""

from __future__ import annotations

from ._common import add_protocol_option, add_toe_off_option, check_inputs, warn


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "events", help="detect toe-offs and heel-strikes from the foot markers",
        description="Detect left/right toe-off and heel-strike from the heel and toe markers "
                    "(any direction of travel, running, treadmills); where one foot stands "
                    "alone on a force plate, its heel-strike and toe-off are timed by the "
                    "plate, and the markers' other toe-offs move by how far the plates found "
                    "them off. Times are seconds from "
                    "the file's first frame. Exit 0 on success, 1 when the file cannot be "
                    "read, has no foot markers, or shows no event in less than a second (too "
                    "short to be rest), 2 on usage errors.")
    add_common_options(parser)
    parser.add_argument("--fit", action="store_true",
                        help="fill missing foot-marker samples from the fitted skeleton "
                             "(calibrates and fits the capture first: slower)")
    parser.add_argument("--markers-only", action="store_true",
                        help="time every event from the foot markers, the force plates aside "
                             "(nor moved by them)")
    parser.add_argument("--json", action="store_true",
                        help='print {"file", "events": [{"side", "kind", "time_s", "frame", '
                             '"placed", "window_s", "plate", "spread_s", "plate_shift_s"}]}')
    parser.set_defaults(run=_run)


def add_common_options(parser) -> None:
    """FILE, --protocol and --toe-off, shared with ``mocaplib cycles``."""
    parser.add_argument("file", metavar="FILE", help="a C3D file")
    add_protocol_option(parser)
    add_toe_off_option(parser)


def load(args):
    """(trial, protocol match, missing-landmarks error or None) of ``args.file`` with
    ``args.protocol`` (:func:`mocaplib.markersets.matching.missing_landmarks_error`)."""
    from ..io.c3d import read_c3d
    from ..markersets.matching import match_trial, missing_landmarks_error

    trial = read_c3d(args.file)
    match = match_trial(trial, args.protocol)
    return trial, match, missing_landmarks_error(match, args.file)


def _run(args) -> int:
    from ..gait.cycles import check_rest_duration
    from ..gait.events import capture_events
    from ..model.fitting import fit_capture
    from ._common import print_json

    check_inputs([args.file])
    trial, match, missing = load(args)
    motion = fit_capture(trial, protocol=match).motion if args.fit else None
    events, _ = capture_events(trial, match, motion=motion, toe_off=args.toe_off,
                               force_plates=not args.markers_only)
    if missing is not None:  # events need only the foot markers, which capture_events checked
        warn(str(missing))
    if not events:
        check_rest_duration(trial.n_frames, trial.rate, source=args.file)
    if args.json:
        print_json({"file": args.file,
                    "events": [{"side": e.side, "kind": e.kind, "time_s": e.time_s,
                                "frame": e.frame, "placed": e.placed,
                                "window_s": None if e.placed else list(e.window),
                                "plate": e.plate, "spread_s": e.spread_s,
                                "plate_shift_s": e.plate_shift_s}
                               for e in events]})
        return 0
    start = (f"; times from the file's first frame, C3D frame {trial.first_frame} (lab "
             f"clock {trial.start_time:.3f} s)" if trial.first_frame != 1 and events else "")
    print(f"{args.file}: {len(events)} events ({match.protocol.name}, {trial.rate:g} Hz{start})"
          + ("; none: standing still (rest)" if not events else ""))
    for e in events:
        print(f"  {e.time_s:8.3f} s  frame {e.frame:5d}  {e.side:5s}  {e.kind:11s}"
              f"  quality {e.quality:.2f}" + ("" if e.placed else "  (not placed)")
              + ("  (uncertain)" if e.uncertain else "")
              + ("" if e.plate is None else f"  force plate {e.plate}")
              + (f"  moved {1000 * e.plate_shift_s:+.1f} ms by the plates"
                 if e.plate_shift_s else ""))
    for e in events:
        if e.warning:
            warn(f"{args.file}: {e.warning}")
    gaps = [e for e in events if not e.placed and "missing" in e.reason]
    if gaps and not args.fit:
        warn(f"{args.file}: {len(gaps)} event(s) not placed where foot markers are missing: "
             "`mocaplib events --fit` fills their gaps from the fitted skeleton, which can "
             "place them")
    return 0
