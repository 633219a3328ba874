"""``mocaplib validate``: schema and semantic checks of a library file, for build scripts."""

from __future__ import annotations


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "validate", help="check a library file against its schema and semantic rules",
        description="Print every problem of a motion library file (schema, DOF lists, "
                    "coefficients, periods, ids, control space, QC). Exit 0 valid, 1 invalid.")
    parser.add_argument("library", help="library JSON file")
    parser.add_argument("--json", action="store_true",
                        help="print {\"file\", \"valid\", "
                             "\"problems\": [{\"where\", \"message\"}]}")
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..library import validate_library
    from ._common import LIBRARY_HINT, check_inputs, print_json

    check_inputs([args.library], hint=LIBRARY_HINT)
    problems = validate_library(args.library)
    if args.json:
        print_json({"file": args.library, "valid": not problems,
                    "problems": [{"where": p.where, "message": p.message} for p in problems]})
    elif problems:
        print(f"{args.library}: {len(problems)} problem(s)")
        for problem in problems:
            print(f"  {problem}")
    else:
        print(f"{args.library}: valid")
    return 1 if problems else 0
