"""Write a benchmark's printed Markdown into a results page of the documentation.

Every script in ``benchmarks/`` prints Markdown (tables and short paragraphs). Given
``--markdown PATH``, it also writes that output into ``PATH`` as one *block*:

    <!-- benchmark: python benchmarks/NAME.py ARGS -->

    > `python benchmarks/NAME.py ARGS` · commit `abc1234` · CPU, N cores · Python X, numpy Y

    ...what the script printed...

    <!-- end benchmark -->

A page (``docs/results/NAME.md``) holds the blocks of one or more commands among text written by
hand: running a command again replaces its own block (the one whose command line is the same)
and leaves the rest of the page as it is; a command not yet on the page is appended. The
commit is ``git rev-parse --short HEAD``, with ``-dirty`` when the work tree has changes
outside ``docs/results``.
"""

from __future__ import annotations

import contextlib
import io
import os
import platform
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from mocaplib.io.atomic import atomic_write_bytes  # noqa: E402

END = "<!-- end benchmark -->"


def add_markdown_option(parser) -> None:
    """Add ``--markdown PATH`` to a script's argparse ``parser``."""
    parser.add_argument("--markdown", type=Path, metavar="PATH", default=None,
                        help="also write the printed tables into this results page "
                             "(docs/results/NAME.md), stamped with the commit and the machine")


def command_line(script: str | os.PathLike, args: list[str]) -> str:
    """``python benchmarks/NAME.py ARGS`` for the ``script`` file run with ``args``, without
    their ``--markdown PATH``."""
    kept, skip = [], False
    for arg in args:
        if skip:
            skip = False
        elif arg == "--markdown":
            skip = True
        elif not arg.startswith("--markdown="):
            kept.append(arg)
    return " ".join(["python", shown(script), *(shlex.quote(a) for a in kept)])


def shown(path: str | os.PathLike) -> str:
    """``path`` relative to the repository when it lies inside it (pages name no home folder)."""
    path = Path(path).resolve()
    with contextlib.suppress(ValueError):
        return path.relative_to(REPO).as_posix()
    return path.as_posix()


def commit() -> str:
    """Short hash of HEAD, with ``-dirty`` when the work tree differs from it outside
    ``docs/results`` (the pages benchmarks write: one run after another leaves the code
    measured as it was); ``unknown`` outside a git checkout."""
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True,
                              check=True).stdout.strip()
    try:
        head = git("rev-parse", "--short", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no", "--", ".",
                    ":(exclude)docs/results")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("-dirty" if dirty else "")


def machine() -> str:
    """CPU model, core count and load average (other jobs on the machine skew timings),
    Python and numpy versions, in one line."""
    model = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace")
        found = re.search(r"^model name\s*:\s*(.+)$", text, flags=re.MULTILINE)
        if found:
            model = found.group(1).strip()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return (f"{model}, {os.cpu_count()} cores, load average {load} (1, 5, 15 min) when "
            f"written · Python {platform.python_version()}, numpy {np.__version__}")


def block(command: str, body: str) -> str:
    """One page block: the marker, the stamp line and ``body``."""
    return (f"<!-- benchmark: {command} -->\n\n> `{command}` · commit `{commit()}` · "
            f"{machine()}\n\n{body.strip()}\n\n{END}\n")


def write_block(path: str | os.PathLike, command: str, body: str) -> Path:
    """Put ``body`` into the page ``path`` as the block of ``command`` (see the module)."""
    path = Path(path)
    page = path.read_text(encoding="utf-8") if path.exists() else ""
    new = block(command, body)
    start = page.find(f"<!-- benchmark: {command} -->\n")
    if start >= 0:
        end = page.index(END, start) + len(END) + 1
        page = page[:start] + new + page[end:]
    else:
        page = (page.rstrip("\n") + "\n\n" if page else "") + new
    return atomic_write_bytes(path, page.encode("utf-8"))


class _Tee(io.TextIOBase):
    """Text written to it goes to ``stream`` and is kept."""

    def __init__(self, stream):
        self.stream, self.kept = stream, io.StringIO()

    def write(self, text: str) -> int:
        self.kept.write(text)
        return self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()


@contextlib.contextmanager
def markdown_page(path: str | os.PathLike | None, script: str | os.PathLike,
                  args: list[str] | None = None):
    """Run the body with its printed output also written to the page ``path`` (no-op when
    None), as the block of ``script`` run with ``args`` (default: this process's arguments).
    The page is written only when the body ends without an exception."""
    if path is None:
        yield
        return
    tee = _Tee(sys.stdout)
    with contextlib.redirect_stdout(tee):
        yield
    command = command_line(script, sys.argv[1:] if args is None else args)
    written = write_block(path, command, tee.kept.getvalue())
    print(f"results written to {written}", file=sys.stderr)
