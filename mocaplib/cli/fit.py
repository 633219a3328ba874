"""``mocaplib fit``: calibrate the subject and fit joint angles to one capture.

Only parses options and writes outputs: the work is :func:`mocaplib.model.fitting.fit_capture`
(:func:`mocaplib.model.calibration.calibrate`, then :func:`mocaplib.model.ik.fit_filtered`).
"""

from __future__ import annotations

import numpy as np

from ..model.anthropometry import DEFAULT_BODY_MASS
from ._common import (add_cutoff_option, add_force_option, add_protocol_option, add_static_options,
                      check_inputs, check_outputs, heading_offsets, measurements)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "fit", help="fit the skeleton's joint angles to a C3D capture",
        description="Calibrate the subject's skeleton (from --static when given, otherwise from "
                    "the capture), fit every frame's joint angles by robust least squares and "
                    "write them as CSV: a time_s column and one column per DOF (radians; "
                    "pelvis_t* metres). Exit 0 on success, 1 when the capture cannot be fitted, "
                    "2 on usage errors (including an unknown or malformed --protocol).")
    parser.add_argument("input", metavar="FILE", help="C3D capture")
    add_protocol_option(parser, default="detected from the labels")
    add_static_options(parser)
    add_cutoff_option(parser)
    parser.add_argument("-o", "--output", required=True, metavar="OUT.csv",
                        help="joint angles as CSV")
    parser.add_argument("--mot", metavar="OUT.mot", help="also write the angles as OpenSim .mot")
    parser.add_argument("--osim", metavar="OUT.osim",
                        help="also write the calibrated model as OpenSim .osim, with de Leva's "
                             "segment masses and inertias for the subject's body mass "
                             "(--subject body_mass=KG, else the calibration file's, else "
                             f"{DEFAULT_BODY_MASS:g} kg with a warning)")
    parser.add_argument("--trc", metavar="OUT.trc",
                        help="also write the markers the fit followed (low-passed, labelling "
                             "repairs undone, outliers gapped) as OpenSim .trc, mm")
    parser.add_argument("--json", action="store_true",
                        help="print the fit as JSON: file, protocol, static, cutoff_hz and the "
                             "quality: marker_rms_mm, max_marker_error_mm, per_marker_rms_mm, "
                             "locked_dofs, held_dofs, at_limit, failed_frames, rejected_samples, "
                             "repairs (exchanged labels undone, markers left out: marker, "
                             "frames, evidence), rejected_per_marker")
    add_force_option(parser)
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..export.formats import write
    from ..io.c3d import read_c3d
    from ..markersets.matching import match_trial, missing_landmarks_error
    from ..model.fitting import fit_capture
    from ..model.ik import fit_quality
    from ..statics import static_names
    from ._common import print_json, warn

    statics = check_inputs([args.input], args.static, static_pose=args.static_pose,
                           references=args.forward_reference, static_window=args.static_window)
    check_outputs({"-o": args.output, "--mot": args.mot, "--osim": args.osim,
                   "--trc": args.trc},
                  [args.input, *(args.static or ()), *(args.forward_reference or ())],
                  force=args.force)
    trial = read_c3d(args.input)
    for note in trial.warnings:         # said before the fit, which they may explain
        warn(f"{args.input}: {note}")
    match = match_trial(trial, args.protocol)
    if match.subject_note:
        warn(f"{args.input}: {match.subject_note}")
    missing = missing_landmarks_error(match, args.input)
    if missing is not None:
        warn(str(missing))
    offsets = heading_offsets(args)
    fitted = fit_capture(trial, protocol=match, static=statics, static_pose=args.static_pose,
                         cutoff=args.cutoff, static_window=args.static_window,
                         measurements=measurements(args), heading_offsets=offsets)
    motion, model, cutoff = fitted.motion, fitted.model, fitted.cutoff
    static = None if fitted.static is None else \
        static_names([s.source for s in statics])[fitted.static]
    offset = None if offsets is None or fitted.static is None else offsets[fitted.static]
    write(motion, args.output, suffix=".csv")
    if args.mot:
        write(motion, args.mot, suffix=".mot")
    if args.osim:
        source = trial if fitted.static is None else statics[fitted.static]
        mass = {**source.measurements, **measurements(args)}.get("body_mass")
        if mass is None:
            mass = DEFAULT_BODY_MASS
            warn(f"{args.osim}: no body mass given (--subject body_mass=KG) nor stored in "
                 f"{source.source or 'the calibration file'}; the model's segment masses "
                 f"assume {mass:g} kg")
        write(model, args.osim, suffix=".osim", body_mass=mass)
    if args.trc:
        write(fitted.fitted_markers(trial), args.trc, suffix=".trc")
    quality = fit_quality(motion)
    for note in fitted.warnings:
        warn(f"{args.input}: {note}")
    if args.json:
        print_json({"file": args.input, "protocol": model.protocol.name, "static": static,
                    "heading_offset_rad": offset, "cutoff_hz": cutoff, **quality})
    else:
        print(f"{args.input}: protocol {model.protocol.name}"
              f"{f', static {static}' if static else ''}"
              f"{'' if offset is None else f' turned {np.rad2deg(offset):+.3f}°'}, "
              f"{motion.n_frames} frames, "
              f"marker RMS {quality['marker_rms_mm']:.1f} mm, "
              f"max {quality['max_marker_error_mm']:.1f} mm, markers "
              f"{'not low-passed' if cutoff is None else f'low-passed at {cutoff:g} Hz'} "
              f"-> {args.output}")
    return 0
