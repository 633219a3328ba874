"""The self-contained HTML report of a motion library (coverage, blending error, capture QC).

:func:`write_report` is the entry point (``mocaplib report``, ``mocaplib build --report``).
Plotting libraries (matplotlib, pyvista) are imported only when a report is made.
"""

from __future__ import annotations

from .files import report_name

__all__ = ["report_name", "write_report"]


def write_report(library_path, out_dir, *, envelope=None, renderer: str = "auto",
                 jobs: int | None = None):
    """Write the self-contained HTML report of a library file.

    Parameters
    ----------
    library_path : str or os.PathLike
        The library file. Its diagnostics sidecar (``<stem>.diagnostics.json``) is read when
        it exists beside it and belongs to it.
    out_dir : str or os.PathLike
        The folder to write into (created when missing).
    envelope : Envelope, str, os.PathLike or None
        The velocities to cover: an :class:`~mocaplib.library.controlspace.Envelope`, a TOML
        file (an ``[envelope]`` table, or a capture plan), or None for the capture plan
        shipped with mocaplib (:func:`mocaplib.report.plan.default_envelope`).
    renderer : {"auto", "matplotlib"}
        The 3-D control-space view: pyvista, falling back to matplotlib without OpenGL, or
        matplotlib.
    jobs : int or None
        Processes drawing the per-capture figures and planting the figure viewer's cycles
        (the report's slowest parts); None: :func:`~mocaplib.report.html.default_jobs`, one per
        500 entries (a capture's figures counting as 60), at most the processors mocaplib may
        use. The page is the same with any number.

    Returns
    -------
    Path
        ``<out_dir>/<library stem>-report.html``.
    """
    from .html import write_report as _write   # jinja2 and the figures: only for a report

    return _write(library_path, out_dir, envelope=envelope, renderer=renderer, jobs=jobs)
