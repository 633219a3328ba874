"""``mocaplib validate``: schema and semantic checks of a library file, for build scripts."""

from __future__ import annotations

from ..io import printable


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "validate", help="check a library file against its schema and semantic rules",
        description="Print every problem of a motion library file (content checksum, "
                    "schema, DOF lists, coefficients, periods, ids, control space, QC). Exit 0 "
                    "valid, 1 invalid. A library whose entries span no 3-D control space "
                    "(fewer than 4) is valid, with a warning: it cannot blend commands.")
    parser.add_argument("library", help="library JSON file")
    parser.add_argument("--json", action="store_true",
                        help="print {\"file\", \"valid\", \"checksum\": \"verified\", "
                             "\"mismatch\" or \"absent\", \"problems\": [{\"where\", "
                             "\"message\"}], \"warnings\": [text]}")
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..io.fastjson import collection_paused
    from ..library.document import NO_CHECKSUM_NOTE
    from ._common import LIBRARY_HINT, check_inputs, print_json, warn

    check_inputs([args.library], hint=LIBRARY_HINT)
    # the document's values are never garbage: with the collector paused until the document
    # is released, no collection visits them (0.5 s on a 5,000-entry library)
    with collection_paused():
        problems, checksum, note, warnings = _findings(args.library)
    if args.json:
        print_json({"file": args.library, "valid": not problems, "checksum": checksum,
                    "problems": [{"where": p.where, "message": p.message} for p in problems],
                    "warnings": warnings, **({"note": note} if note else {})})
        return 1 if problems else 0
    for warning in warnings:
        warn(f"{args.library}: {warning}")
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


def _findings(path: str):
    """The problems of the library at ``path``, its checksum status (None when it cannot be
    read), the note on its version and the warnings of a valid library."""
    from ..errors import LibraryError
    from ..library.document import CHECKSUM_KEY, checksum_status, read_document, version_note
    from ..library.validation import control_space_warning, validate_library

    try:
        document, _, finite = read_document(path, file_sha256=False)
    except LibraryError:
        document, finite = None, False         # validate_library names why
    problems = validate_library(path if document is None else document, finite=finite)
    if document is None:
        checksum = None
    elif problems:
        checksum = checksum_status(document)
    else:                       # a valid library's checksum is verified or absent
        checksum = "verified" if CHECKSUM_KEY in document else "absent"
    note = None if document is None else version_note(document)
    warnings = [] if problems else [w for w in (control_space_warning(document),) if w]
    return problems, checksum, note, warnings

