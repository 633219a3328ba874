"""``mocaplib validate``: schema and semantic checks of a library file, for build scripts."""

from __future__ import annotations

from ..io import printable


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "validate", help="check a library file against its schema and semantic rules",
        description="Print every problem of a motion library file (content checksum, "
                    "schema, DOF lists, coefficients, periods, ids, control space, QC). Exit 0 "
                    "valid, 1 invalid.")
    parser.add_argument("library", help="library JSON file")
    parser.add_argument("--json", action="store_true",
                        help="print {\"file\", \"valid\", \"checksum\": \"verified\", "
                             "\"mismatch\" or \"absent\", \"problems\": [{\"where\", "
                             "\"message\"}]}")
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..library.document import (NO_CHECKSUM_NOTE, checksum_status, read_document,
                                    version_note)
    from ..library.validation import validate_library
    from ._common import LIBRARY_HINT, check_inputs, print_json

    check_inputs([args.library], hint=LIBRARY_HINT)
    problems = validate_library(args.library)
    readable = not any(p.where == "file" for p in problems)
    checksum = checksum_status(args.library) if readable else None
    note = version_note(read_document(args.library)[0]) if readable else None
    if args.json:
        print_json({"file": args.library, "valid": not problems, "checksum": checksum,
                    "problems": [{"where": p.where, "message": p.message} for p in problems],
                    **({"note": note} if note else {})})
        return 1 if problems else 0
    if problems:
        print(f"{args.library}: {len(problems)} problem(s)")
        for problem in problems:
            print(f"  {printable(str(problem), keep='')}")   # entry ids come from file names
    else:
        print(f"{args.library}: valid" + (" (content checksum verified)"
                                          if checksum == "verified" else ""))
    if checksum == "absent":
        print(f"note: {NO_CHECKSUM_NOTE}")
    if note:
        print(f"note: {note}")
    return 1 if problems else 0
