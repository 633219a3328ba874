"""``mocaplib inspect``: what is in each C3D file (frames, rate, protocol, gaps, events, warnings).

Only parses options and formats: the per-file work is :func:`mocaplib.markersets.inspection.inspect_c3d`.
"""

from __future__ import annotations

import sys

from ._common import add_protocol_option


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "inspect", help="summarise C3D files: frames, rate, units, protocol, gaps, events",
        description="For each C3D file (folders are searched for *.c3d): frames, rate, "
                    "duration, units, vertical axis, the marker-set protocol matched and its "
                    "missing required landmarks, each marker's gap percentage and longest gap, "
                    "events, and warnings (left/right swaps, duplicate labels, model outputs). "
                    "Exit 0 when every file was read, 1 when some could not be, 2 on usage "
                    "errors (a path that does not exist, an unknown or malformed --protocol).")
    parser.add_argument("inputs", nargs="+", metavar="FILE", help="C3D files or folders")
    add_protocol_option(parser, default="the best shipped protocol for each file")
    parser.add_argument("--json", action="store_true",
                        help="print a JSON list, one object per file, instead of tables")
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..io import find_captures, printable
    from ..markersets.inspection import failed_summary, format_summary, inspect_c3d
    from ..markersets.protocols import load_protocol
    from ._common import check_inputs, print_json

    check_inputs(args.inputs)
    protocol = args.protocol if args.protocol == "auto" else load_protocol(args.protocol)
    summaries = []
    for item in args.inputs:
        unlisted: list = []
        files = find_captures([item], unlisted=unlisted)
        summaries.extend(failed_summary(folder.path, folder) for folder in unlisted)
        if not files and not unlisted:
            summaries.append(failed_summary(
                item, f"{item}: no *.c3d files in this folder or its subfolders (give C3D "
                      "files, or the folder that holds them)"))
        summaries.extend(inspect_c3d(path, protocol=protocol) for path in files)
    if args.json:
        print_json(summaries)
    else:
        print("\n\n".join(format_summary(s) for s in summaries))
    failed = [s for s in summaries if not s["ok"]]
    for s in failed:
        print(f"mocaplib inspect: {printable(s['error'], keep='')}", file=sys.stderr)
    return 1 if failed else 0
