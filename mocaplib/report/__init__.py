"""The self-contained HTML report of a motion library (coverage, blending error, capture QC).

:func:`write_report` is the entry point (``mocaplib report``, ``mocaplib build --report``).
Plotting libraries (matplotlib, pyvista) are imported only when a report is made.
"""

from __future__ import annotations

from .files import report_name

__all__ = ["report_name", "write_report"]


def write_report(library_path, out_dir, *, envelope=None, renderer: str = "auto",
                 jobs: int = 1):
    """Write ``<out_dir>/<library stem>-report.html``; see
    :func:`mocaplib.report.html.write_report`."""
    from .html import write_report as _write

    return _write(library_path, out_dir, envelope=envelope, renderer=renderer, jobs=jobs)
