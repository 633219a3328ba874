"""``mocaplib synth PLAN -o DIR``: generate a capture plan's synthetic captures."""

from __future__ import annotations


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "synth", help="generate synthetic captures (C3D + truth JSON) from a capture plan",
        description="Generate the captures of a plan (e.g. protocols/paper_plan.toml): one "
                    "<name>.c3d and <name>.truth.json per capture.")
    parser.add_argument("plan", help="capture plan (TOML)")
    parser.add_argument("-o", "--output", required=True, help="folder to write into")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="generate only these captures")
    parser.add_argument("--protocol", help="marker set for every capture (default: the plan's)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from ..synth import generate_plan, load_plan

    plan = load_plan(args.plan)
    written = generate_plan(plan, args.output, only=args.only, protocol=args.protocol,
                            progress=not args.no_progress)
    print(f"wrote {len(written) // 2} captures to {args.output}")
    return 0
