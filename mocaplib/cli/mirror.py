"""``mocaplib mirror``: add the left-right mirror image of every entry of a library file."""

from __future__ import annotations

from ..io import printable
from ._common import add_force_option


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "mirror", help="add every entry's left-right mirror image to a library",
        description="Write a copy of a library with the mirror image of each entry added "
                    "(flagged 'mirrored', made from the entry's stored series shifted to its "
                    "right toe-off; docs/mirroring.md). Entries that are their own mirror "
                    "image (straight walks, runs, rest) and entries that have one are left "
                    "as they are. `mocaplib build --mirror` makes better images, from the "
                    "captures. Exit 0 when the written library is valid, 1 otherwise or when "
                    "nothing can be mirrored, 2 on usage errors.")
    parser.add_argument("library", help="library JSON file")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.json",
                        help="library file to write (with its diagnostics sidecar when the "
                             "input has one)")
    add_force_option(parser)
    parser.set_defaults(run=_run)


def _run(args) -> int:
    import sys

    from ..library.format import diagnostics_path, load_library
    from ..library.validation import validate_library
    from ..library.mirror import mirror_library, write_mirrored
    from ._common import LIBRARY_HINT, check_inputs, check_outputs, warn

    check_inputs([args.library], hint=LIBRARY_HINT)
    check_outputs({"-o": args.output, "-o (its diagnostics sidecar)":
                   diagnostics_path(args.output)},
                  [args.library, diagnostics_path(args.library)], force=args.force)
    library = load_library(args.library)
    mirrored, notes = mirror_library(library)
    for note in notes:
        print(f"note: {printable(note, keep='')}")
    sidecar, note = write_mirrored(mirrored, args.library, args.output)
    if note:
        warn(note)
    added = len(mirrored) - len(library)
    print(f"wrote {args.output} ({len(mirrored)} entries, {added} mirror images added)"
          + (f" and {sidecar}" if sidecar else ""))
    problems = validate_library(mirrored)
    for problem in problems:
        warn(f"library: {problem}")
    if problems:
        print(f"mocaplib mirror: error: {args.output} was written but is not valid "
              f"({len(problems)} problem(s) above)", file=sys.stderr)
    return 1 if problems else 0
