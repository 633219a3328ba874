"""``mocaplib build``: captures to a validated motion library (and optionally its HTML report)."""

from __future__ import annotations

import sys
from pathlib import Path

from ._common import (UsageError, add_cutoff_option, add_force_option, add_gap_option,
                      add_protocol_option, add_static_options, add_toe_off_option, check_inputs,
                      check_output_folder, check_outputs, jobs_count, measurements, positive,
                      warn)

#: ``--capture-timeout`` default: :data:`mocaplib.build.pipeline.CAPTURE_TIMEOUT_S`, not
#: imported here so that the command line parses without loading the build (a test keeps the
#: two equal).
CAPTURE_TIMEOUT_S = 600.0


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "build", help="build a motion library from C3D captures",
        description="Process every capture (import, calibrate, fit, events, cycles, "
                    "velocities, Fourier) and write the library JSON plus its diagnostics "
                    "sidecar. A failing capture is reported and the build goes on. "
                    "Exit 0 when every capture succeeded and the library is valid, 1 when some "
                    "failed or the library is not valid (no library is written when no capture "
                    "gave an entry), 2 on usage errors.")
    parser.add_argument("inputs", nargs="+", metavar="INPUT",
                        help="C3D files or folders (searched recursively for *.c3d)")
    parser.add_argument("-o", "--output", required=True, metavar="LIBRARY.json",
                        help="library file to write")
    add_protocol_option(parser, default="detected for each capture")
    add_static_options(parser)
    parser.add_argument("--require-static", action="store_true",
                        help="a capture that no static shows fails (default: it is calibrated "
                             "from itself, with a warning); statics come from --static, a "
                             "session.toml beside the captures, and the standing files among "
                             "the inputs")
    add_cutoff_option(parser)
    add_toe_off_option(parser)
    add_gap_option(parser)
    parser.add_argument("--report", metavar="DIR", help="also write the HTML report into DIR")
    parser.add_argument("--jobs", "-j", type=jobs_count, default=1, metavar="N",
                        help="worker processes, for the captures and the report's figures "
                             "(default 1; at most the number of processors)")
    parser.add_argument("--capture-timeout", type=positive(float, unit=" s"),
                        default=CAPTURE_TIMEOUT_S, metavar="SECONDS",
                        help="seconds one capture may take in a worker process (--jobs 2 or "
                             "more): a worker still running it then (hung, or stopped) is "
                             "ended and the capture fails alone "
                             f"(default {CAPTURE_TIMEOUT_S:g})")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="Dask scheduler address, e.g. tcp://host:8786 (needs mocaplib[dask])")
    parser.add_argument("--batch-size", type=positive(int), default=None, metavar="N",
                        help="captures per Dask task, with --scheduler (default: chosen from "
                             "the captures' frame counts: one to two seconds of work a task)")
    parser.add_argument("--all-cycles", action="store_true",
                        help="keep every complete cycle, not only the one chosen per activity "
                             "segment of each capture")
    parser.add_argument("--keep-non-level", action="store_true",
                        help="keep the cycles on stairs or slopes (the pelvis rises or drops "
                             "more than 3 cm per step), flagged in the warnings and the "
                             "diagnostics, instead of leaving them out of a level-locomotion "
                             "library")
    parser.add_argument("--mirror", action="store_true",
                        help="also add each capture's left-right mirror image, cut at its right "
                             "toe-offs (fills the turns and side-steps a session made to one "
                             "side only; entries flagged 'mirrored')")
    parser.add_argument("--qc", choices=("drop", "waive"), default="drop",
                        help="cycles failing a QC threshold: leave out (default) or keep with "
                             "a recorded waiver")
    cache = parser.add_mutually_exclusive_group()
    cache.add_argument("--cache-dir", metavar="DIR",
                       help="per-capture result cache (default: .mocaplib-cache beside the "
                            "library)")
    cache.add_argument("--no-cache", action="store_true", help="process every capture afresh")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    add_force_option(parser)
    parser.set_defaults(run=_run)


def _check_usage(args):
    """The captures the inputs name (C3D files, and those found in folders), the build's
    settings and the folders that could not be listed; raise :class:`UsageError` for what would fail or do harm before any capture is
    processed: a missing input, a --static that is missing, cannot be read or is not standing
    (every capture would fail on it), a session file beside the captures that cannot be used
    (:func:`mocaplib.build.sessions.sessions_of`: its static is checked as --static), an output that would overwrite a file the build reads
    (:func:`mocaplib.build.pipeline.build_inputs`) or cannot be written, a --report folder that
    cannot take the report."""
    from ..build.pipeline import build_inputs
    from ..build.sessions import sessions_of
    from ..errors import MocapError
    from ..io import find_captures
    from ..build.settings import BuildSettings
    from ..library.format import diagnostics_path

    if args.batch_size is not None and args.scheduler is None:
        raise UsageError("--batch-size sets the captures per Dask task: give it with "
                         "--scheduler ADDRESS (local jobs run one capture per task)")
    check_inputs(args.inputs, args.static, static_pose=args.static_pose,
                 references=args.forward_reference, static_window=args.static_window)
    unlisted: list[MocapError] = []    # said by the build's summary when there are captures
    captures = find_captures(args.inputs, unlisted=unlisted)
    if not captures:
        raise UsageError(f"no C3D captures (*.c3d) in {', '.join(args.inputs)}"
                         + "".join(f"; {folder}" for folder in unlisted))
    try:
        sessions_of(captures)
    except MocapError as exc:
        raise UsageError(str(exc)) from None
    settings = BuildSettings(protocol=args.protocol, static=args.static,
                             static_pose=args.static_pose, static_window=args.static_window,
                             require_static=args.require_static,
                             forward_reference=args.forward_reference, cutoff=args.cutoff,
                             toe_off=args.toe_off, max_gap_s=args.max_gap_s,
                             all_cycles=args.all_cycles,
                             mirror=args.mirror, keep_non_level=args.keep_non_level,
                             qc_policy=args.qc,
                             measurements=measurements(args))
    inputs = build_inputs(captures, settings)
    check_outputs({"-o": args.output, "-o (its diagnostics sidecar)":
                   diagnostics_path(args.output)}, inputs, force=args.force)
    if args.report:
        from ..report import report_name

        check_output_folder("--report", args.report, report_name(args.output), inputs)
    return captures, settings, unlisted


def _run(args) -> int:
    from ..build.drafting import DRAFTS_FOLDER
    from ..build.pipeline import build_library
    from ..library.validation import control_space_warning, validate_library

    captures, settings, unlisted = _check_usage(args)
    output = Path(args.output)
    cache_dir = None if args.no_cache else Path(args.cache_dir or output.parent / ".mocaplib-cache")
    result = build_library(captures, settings, jobs=args.jobs, scheduler=args.scheduler,
                           cache_dir=cache_dir, progress=not args.quiet and sys.stderr.isatty(),
                           capture_timeout=args.capture_timeout,
                           drafts_dir=output.parent / DRAFTS_FOLDER,
                           batch_size=args.batch_size)
    result.unlisted += [str(folder) for folder in unlisted]   # the build got the files found
    print(result.summary_text())
    library_path, sidecar = result.write(output)  # LibraryError, nothing written: no entry
    print(f"wrote {library_path} ({len(result.library)} entries) and {sidecar}")
    problems = validate_library(result.library)
    for problem in problems:
        warn(f"library: {problem}")
    if not problems and control_space_warning(result.library):
        warn(f"{library_path}: {control_space_warning(result.library)}")
    if problems:
        print(f"mocaplib build: error: {library_path} was written but is not valid "
              f"({len(problems)} problem(s) above): fix what they name and build again",
              file=sys.stderr)
    if args.report:
        from ..report import write_report

        print(f"report: {write_report(library_path, args.report, jobs=args.jobs)}")
    return 0 if result.ok and not problems else 1
