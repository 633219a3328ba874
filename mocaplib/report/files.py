"""Where a library's HTML report is written, and how its images are embedded (no plotting
imports: the command line checks the output folder with it before any work)."""

from __future__ import annotations

import base64
import os
from pathlib import Path


def report_name(library_path: str | os.PathLike) -> str:
    """The report's file name for a library file: ``<stem>-report.html``."""
    return f"{Path(library_path).stem}-report.html"


def data_uri(png: bytes) -> str:
    """A PNG image as a ``data:`` URI an HTML page embeds (the report is one self-contained file)."""
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")
