"""MkDocs hook: ``<!-- cli-help: NAME -->`` in a page becomes the ``--help`` text of
``mocaplib NAME`` (``mocaplib`` for the top level; ``protocol draft`` for a sub-command's
action), as the installed parser prints it, so the CLI reference cannot drift from the code."""

from __future__ import annotations

import os
import re

PLACEHOLDER = re.compile(r"<!-- cli-help: ([a-z]+(?: [a-z]+)?) -->")


def on_page_markdown(markdown: str, page, config, files) -> str:
    if "<!-- cli-help:" not in markdown:
        return markdown
    os.environ["COLUMNS"] = "84"  # argparse wraps to the terminal width; fix it for the page
    from mocaplib.cli import build_parser

    parser = build_parser()
    commands = parser.get_default("parsers")

    def help_text(found: re.Match) -> str:
        name, _, action = found.group(1).partition(" ")
        if name != "mocaplib" and name not in commands:
            raise ValueError(f"{page.file.src_path}: no sub-command {name!r} for cli-help")
        chosen = parser if name == "mocaplib" else commands[name]
        if action:
            actions = [a.choices for a in chosen._actions if isinstance(a.choices, dict)]
            if not actions or action not in actions[0]:
                raise ValueError(f"{page.file.src_path}: no action {action!r} of {name!r}")
            chosen = actions[0][action]
        return f"```text\n{chosen.format_help().rstrip()}\n```"

    return PLACEHOLDER.sub(help_text, markdown)
