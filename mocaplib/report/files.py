"""Where a library's HTML report is written (no plotting imports: the command line checks the
output folder with it before any work)."""

from __future__ import annotations

import os
from pathlib import Path


def report_name(library_path: str | os.PathLike) -> str:
    """The report's file name for a library file: ``<stem>-report.html``."""
    return f"{Path(library_path).stem}-report.html"
