"""MkDocs hook: ``<!-- cli-help: NAME -->`` in a page becomes the ``--help`` text of
``mocaplib NAME`` (``mocaplib`` for the top level), as the installed parser prints it, so the
CLI reference cannot drift from the code."""

from __future__ import annotations

import os
import re

PLACEHOLDER = re.compile(r"<!-- cli-help: ([a-z]+) -->")


def on_page_markdown(markdown: str, page, config, files) -> str:
    if "<!-- cli-help:" not in markdown:
        return markdown
    os.environ["COLUMNS"] = "84"  # argparse wraps to the terminal width; fix it for the page
    from mocaplib.cli import build_parser

    parser = build_parser()
    commands = parser.get_default("parsers")

    def help_text(found: re.Match) -> str:
        name = found.group(1)
        if name != "mocaplib" and name not in commands:
            raise ValueError(f"{page.file.src_path}: no sub-command {name!r} for cli-help")
        text = (parser if name == "mocaplib" else commands[name]).format_help()
        return f"```text\n{text.rstrip()}\n```"

    return PLACEHOLDER.sub(help_text, markdown)
