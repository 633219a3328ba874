"""Small helpers shared by the sub-commands (output formatting, input expansion, --protocol)."""

from __future__ import annotations

import argparse
import json
import sys

from ..errors import MocapError


def print_json(obj) -> None:
    """Print ``obj`` as indented JSON on stdout (NaN written as null)."""
    print(json.dumps(_clean(obj), indent=2, ensure_ascii=False))


def _clean(obj):
    if isinstance(obj, float):
        return None if obj != obj or obj in (float("inf"), float("-inf")) else obj
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalar
        return _clean(obj.item())
    return obj


def warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


def add_protocol_option(parser, *, default: str = "the best shipped protocol") -> None:
    """``--protocol NAME|PATH|auto``; an unknown or malformed protocol is a usage error (exit 2).

    The value stays the name or path given (it is checked here, loaded again where used).
    """
    parser.add_argument("--protocol", default="auto", type=_protocol_name, metavar="NAME|PATH|auto",
                        help="marker-set protocol: a shipped name, a .toml file, or 'auto' "
                             f"(default: {default})")


def _protocol_name(value: str) -> str:
    from ..protocols import load_protocol

    if value != "auto":
        try:
            load_protocol(value)
        except MocapError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return value


def positive(kind: type):
    """argparse ``type=`` accepting numbers of ``kind`` (int or float) > 0; else exit 2."""
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
        return value
    return parse
