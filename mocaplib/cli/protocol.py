"""``mocaplib protocol draft``: a draft protocol for a marker set mocaplib does not know.

Only parses options and writes the file: the work is :func:`mocaplib.markersets.draft.draft_protocol`.
"""

from __future__ import annotations

from pathlib import Path

from ._common import (add_force_option, add_protocol_folders_option, check_inputs,
                      check_outputs, warn)

#: The documentation page listing every landmark, its segment, place and aliases.
LANDMARK_CATALOGUE_PAGE = "docs/guide/landmarks.md"


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "protocol", help="work with marker-set protocols (draft one for an unknown set)",
        description="Marker-set protocols. `mocaplib protocol draft CAPTURE.c3d -o mylab.toml` "
                    "writes a draft protocol for the capture's labels.")
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    draft = sub.add_parser(
        "draft", help="draft a protocol for a capture's marker set",
        description="Match each label of a capture (and of its static trial) to a landmark of "
                    "the catalogue by its name and by where the marker sits on the body "
                    "(height, side, which markers move together as one rigid body), find "
                    "clusters (rigid groups that no landmark fits: tracking markers), and write "
                    "the draft as a protocol file in which every guess is commented with its "
                    "evidence and a confidence. Check it, then run `mocaplib inspect --protocol "
                    "OUT.toml CAPTURE.c3d`. Exit 0 written, 1 when the capture cannot be read, "
                    "2 on usage errors.")
    draft.add_argument("input", metavar="CAPTURE.c3d", help="a capture of the marker set")
    draft.add_argument("--static", metavar="STATIC.c3d",
                       help="the session's static trial: the standing body places the markers, "
                            "and markers seen only there are marked static_only")
    draft.add_argument("-o", "--output", required=True, metavar="OUT.toml",
                       help="the protocol file to write")
    draft.add_argument("--name", help="the protocol's name (default: the output file's stem)")
    add_protocol_folders_option(draft)
    add_force_option(draft)
    draft.set_defaults(run=_run)


def _run(args) -> int:
    from ..io.atomic import atomic_write_text
    from ..io.c3d import read_c3d
    from ..markersets.draft import draft_protocol

    check_inputs([args.input] + ([args.static] if args.static else []))
    check_outputs({"-o": args.output}, [args.input] + ([args.static] if args.static else []),
                  force=args.force)
    trial = read_c3d(args.input)
    static = read_c3d(args.static) if args.static else None
    draft = draft_protocol(trial, static=static, name=args.name or Path(args.output).stem)
    atomic_write_text(args.output, draft.to_toml())
    for line in draft.warnings():
        warn(line)
    matched = sum(e.landmark is not None for e in draft.entries)
    tracking = sum(e.segment is not None for e in draft.entries)
    unknown = len(draft.entries) - matched - tracking
    print(f"{args.output}: {len(draft.entries)} labels, {matched} matched to landmarks, "
          f"{tracking} tracking markers, {unknown} unmatched, {len(draft.warnings())} of low "
          f"confidence; check it, then run `mocaplib "
          f"inspect --protocol {args.output} {args.input}`; the landmark names are listed in "
          f"{LANDMARK_CATALOGUE_PAGE}")
    return 0
