"""``mocaplib synth PLAN -o DIR``: generate a capture plan's synthetic captures."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ._common import UsageError, add_protocol_option, check_inputs, check_outputs


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "synth", help="generate synthetic captures (C3D + truth JSON) from a capture plan",
        description="Generate the captures of a plan (e.g. protocols/paper_plan.toml): one "
                    "<name>.c3d and <name>.truth.json per capture. The whole plan is checked "
                    "before anything is written. Files in DIR are replaced only when they are "
                    "an earlier synth output of the same name (or with --overwrite). Exit 0 "
                    "when every capture was written, 1 when the plan is unusable, 2 on usage "
                    "errors (a missing plan, an unknown --only name or --protocol, an output "
                    "that cannot or must not be written).")
    parser.add_argument("plan", help="capture plan (TOML)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR", help="folder to write into")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="generate only these captures")
    add_protocol_option(parser, default="each capture's, from the plan")
    parser.add_argument("--overwrite", action="store_true",
                        help="also replace files that are not an earlier synth output of the "
                             "same name (e.g. a lab capture copied into DIR)")
    parser.add_argument("--quiet", "-q", action="store_true",
                        help="no progress bar (it is drawn only when stderr is a terminal)")
    parser.add_argument("--no-progress", dest="quiet", action="store_true",
                        help=argparse.SUPPRESS)  # the option's former name, still accepted
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..errors import SynthError
    from ..synth import check_targets, generate_plan, load_plan

    check_inputs([args.plan], hint="check the path; protocols/paper_plan.toml is a capture plan")
    plan = load_plan(args.plan)
    output = Path(args.output)
    try:
        chosen = plan.select(args.only)
        check_targets(chosen, output, overwrite=args.overwrite)
        check_outputs({"-o": output / f"{chosen[0].name}.c3d"}, [args.plan],
                      create_folders=True, force=True)  # check_targets: --overwrite
    except SynthError as exc:
        raise UsageError(str(exc)) from None
    protocol = None if args.protocol == "auto" else args.protocol
    written = generate_plan(plan, output, only=args.only, protocol=protocol, overwrite=True,
                            progress=not args.quiet and sys.stderr.isatty())  # checked above
    print(f"wrote {len(written) // 2} captures to {args.output}")
    return 0
