"""``mocaplib report``: the self-contained HTML coverage report of a library."""

from __future__ import annotations

from ._common import jobs_count


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "report", help="write the HTML coverage and quality report of a library",
        description="Write one self-contained HTML file (opens offline) with the control "
                    "space, its coverage of the target envelope, what to capture next, the "
                    "leave-one-out blending error and per-capture quality plots (from the "
                    "library's <stem>.diagnostics.json sidecar when present).")
    parser.add_argument("library", help="library JSON file")
    parser.add_argument("-o", "--output", metavar="DIR", default="reports",
                        help="folder for the report (default: reports)")
    parser.add_argument("--envelope", metavar="FILE.toml",
                        help="target envelope: a TOML file with an [envelope] table, or your "
                             "capture plan (default: the plan of mocaplib's synthetic sample "
                             "captures, shipped with it)")
    parser.add_argument("--jobs", "-j", type=jobs_count, default=None, metavar="N",
                        help="processes drawing the per-capture figures and planting the "
                             "viewer's cycles (default: one per 500 entries, a capture "
                             "counting as 60, at most the processors; the report is the same "
                             "with any number)")
    parser.add_argument("--no-opengl", action="store_true",
                        help="draw the 3-D view with matplotlib instead of pyvista/VTK")
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..report import report_name, write_report
    from ._common import LIBRARY_HINT, check_inputs, check_output_folder

    check_inputs([args.library], hint=LIBRARY_HINT)
    check_output_folder("-o", args.output, report_name(args.library), [args.library])
    _check_envelope(args.envelope)
    path = write_report(args.library, args.output, envelope=args.envelope,
                        renderer="matplotlib" if args.no_opengl else "auto",
                        jobs=args.jobs)
    print(f"report: {path}")
    return 0


def _check_envelope(envelope: str | None) -> None:
    """Raise :class:`UsageError` before any work for an ``--envelope`` file that is missing,
    malformed or holds values no envelope can have (text, NaN, infinity)."""
    from pathlib import Path

    from ..errors import MocapError
    from ..report.plan import default_envelope
    from ._common import UsageError

    if envelope is None:
        return
    try:
        default_envelope(Path(envelope))
    except MocapError as exc:
        raise UsageError(f"--envelope: {exc}") from None
