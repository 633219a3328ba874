"""MkDocs hook: the guide's figures, drawn at build time from the shipped samples
(``sample_c3d/``) by ``docs/figures/guide.py`` with mocaplib's own functions and matplotlib's
Agg backend (offline, no display). Each becomes ``img/NAME`` in the site; pages link to it as
``![...](../img/NAME)``. Nothing is written into ``docs/``: the images live in the site only.

A figure that fails to draw fails the build, naming the figure."""

from __future__ import annotations

import logging
import sys
import time
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File

FIGURES_DIR = Path(__file__).resolve().parents[1] / "figures"
log = logging.getLogger("mkdocs.hooks.figures")


def on_files(files, config):
    if str(FIGURES_DIR) not in sys.path:
        sys.path.insert(0, str(FIGURES_DIR))
    import matplotlib

    matplotlib.use("Agg")
    import guide

    start = time.perf_counter()
    for name, draw in guide.FIGURES.items():
        try:
            png = draw()
        except Exception as error:            # any failure names the figure, then stops the build
            raise PluginError(f"docs figure img/{name} ({draw.__name__} in "
                              f"docs/figures/guide.py) failed: {error!r}") from error
        files.append(File.generated(config, f"img/{name}", content=png))
    log.info(f"figures: {len(guide.FIGURES)} drawn in {time.perf_counter() - start:.1f} s")
    return files
