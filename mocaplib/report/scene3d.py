"""The 3-D control-space picture: pyvista/VTK off-screen, or matplotlib when OpenGL fails.

VTK can abort the whole process when no OpenGL context can be made, so the pyvista render runs
in a child process (``python -m mocaplib.report.scene3d SCENE.npz OUT.png``); a crash, a
time-out or a blank image there makes :func:`render_control_space` fall back to matplotlib and
say why. ``MOCAPLIB_NO_OPENGL=1`` (or ``renderer="matplotlib"``) skips pyvista altogether.

Coordinates drawn are the normalised ones the triangulation uses (SI / scale), so the three
axes have comparable lengths; the axes are labelled in SI units (ω in °/s) through
``axes_ranges``, so a technician reads velocities, not normalised numbers.
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Seconds the pyvista child process may take before the matplotlib fallback is used.
RENDER_TIMEOUT_S = 120
NO_OPENGL_ENV = "MOCAPLIB_NO_OPENGL"


@dataclass
class Rendered:
    """A 3-D picture: PNG bytes, which renderer made it and, after a fallback, why."""

    png: bytes
    renderer: str
    fallback_reason: str | None = None


def render_control_space(points, colours, labels, axes_titles, *, edges, hull_triangles,
                         envelope_triangles=None, envelope_points=None, axes_bounds=None,
                         axes_ranges=None, axes_intervals=(4, 4, 4), renderer: str = "auto",
                         fallback=None) -> Rendered:
    """Render the scene; ``fallback()`` -> PNG bytes is the matplotlib picture.

    points (E, 3) normalised; colours (E, 3) RGB 0-1; labels (E,) class per point (legend);
    edges (K, 2); hull_triangles (H, 3) rows of points; envelope_points (P, 3) normalised with
    envelope_triangles (G, 3); axes_bounds (6,) the box of the axes (x min, x max, y min, ...;
    default: around all points) and axes_ranges (6,) the values shown at its sides (e.g. SI
    units; default the bounds), each labelled at ``axes_intervals`` (3,) + 1 ticks. renderer: "auto"
    (pyvista, matplotlib if that fails), or "matplotlib".
    """
    if renderer not in ("auto", "matplotlib"):
        raise ValueError(f"renderer must be 'auto' or 'matplotlib', got {renderer!r}")
    if renderer == "matplotlib":
        return Rendered(fallback(), "matplotlib", "matplotlib was requested (--no-opengl)")
    if os.environ.get(NO_OPENGL_ENV, "") not in ("", "0"):
        return Rendered(fallback(), "matplotlib", f"{NO_OPENGL_ENV} is set")
    with tempfile.TemporaryDirectory(prefix="mocaplib-scene-") as tmp:
        scene, out = Path(tmp) / "scene.npz", Path(tmp) / "scene.png"
        np.savez(scene, points=np.asarray(points, float), colours=np.asarray(colours, float),
                 labels=np.asarray(labels, dtype=str), titles=np.asarray(axes_titles, dtype=str),
                 edges=np.asarray(edges, int).reshape(-1, 2),
                 hull=np.asarray(hull_triangles, int).reshape(-1, 3),
                 env_points=np.asarray(envelope_points if envelope_points is not None
                                       else np.zeros((0, 3)), float),
                 env_tris=np.asarray(envelope_triangles if envelope_triangles is not None
                                     else np.zeros((0, 3)), int).reshape(-1, 3),
                 bounds=np.asarray(axes_bounds if axes_bounds is not None else [], float),
                 ranges=np.asarray(axes_ranges if axes_ranges is not None else [], float),
                 intervals=np.asarray(axes_intervals, int).reshape(3))
        reason = _run_renderer(scene, out)
        if reason is None:
            png = out.read_bytes()
            if not _blank(png):
                return Rendered(png, "pyvista")
            reason = "pyvista produced a blank image"
    return Rendered(fallback(), "matplotlib", reason)


def _run_renderer(scene: Path, out: Path) -> str | None:
    """Render in a child process; None on success, else why it failed."""
    env = dict(os.environ)
    package_root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)
    try:
        proc = subprocess.run([sys.executable, "-m", "mocaplib.report.scene3d", str(scene),
                               str(out)], capture_output=True, text=True, env=env,
                              timeout=RENDER_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return f"pyvista did not finish within {RENDER_TIMEOUT_S} s"
    except (OSError, subprocess.SubprocessError) as exc:  # e.g. the interpreter cannot be run
        return f"the pyvista renderer could not be started ({type(exc).__name__}: {exc})"
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["no message"])[-1][:200]
        how = (f"crashed (signal {-proc.returncode})" if proc.returncode < 0
               else f"failed (exit {proc.returncode})")
        return f"pyvista/OpenGL rendering {how}: {last}"
    if not out.is_file():
        return "pyvista wrote no image"
    return None


def _blank(png: bytes) -> bool:
    """True when an image has (almost) a single colour."""

    from matplotlib.image import imread

    img = imread(io.BytesIO(png))
    return float(np.asarray(img)[..., :3].std()) < 1e-3


def _render_pyvista(scene_path: str, out_path: str) -> None:
    """Child-process body: draw the scene with pyvista off-screen and save a PNG."""
    import pyvista as pv

    pv.OFF_SCREEN = True
    s = np.load(scene_path)
    pts, colours = s["points"], s["colours"]
    plotter = pv.Plotter(off_screen=True, window_size=(1000, 760))
    plotter.set_background("white")
    if len(s["hull"]):
        faces = np.hstack([np.full((len(s["hull"]), 1), 3), s["hull"]]).ravel()
        plotter.add_mesh(pv.PolyData(pts, faces), color="lightsteelblue", opacity=0.12,
                         show_edges=True, edge_color="slategray", line_width=1.5)
    if len(s["edges"]):
        lines = np.hstack([np.full((len(s["edges"]), 1), 2), s["edges"]]).ravel()
        plotter.add_mesh(pv.PolyData(pts, lines=lines), color="darkgray", opacity=0.35,
                         line_width=1)
    if len(s["env_tris"]):
        faces = np.hstack([np.full((len(s["env_tris"]), 1), 3), s["env_tris"]]).ravel()
        plotter.add_mesh(pv.PolyData(s["env_points"], faces).extract_feature_edges(
            boundary_edges=False, non_manifold_edges=False, feature_angle=1.0),
            color="red", opacity=0.4, line_width=1.0)
    legend = []
    for name in sorted(set(s["labels"].tolist())):
        sel = s["labels"] == name
        plotter.add_points(pts[sel], color=tuple(colours[sel][0]), point_size=14,
                           render_points_as_spheres=True)
        legend.append([str(name), tuple(colours[sel][0]), "circle"])
    if len(s["env_tris"]):
        legend.append(["target envelope", "red", "line"])  # a line, as drawn, not a dot
    plotter.add_legend(legend, bcolor="white", border=True, size=(0.17, 0.2),
                       loc="upper right")
    titles = s["titles"].tolist()
    everything = np.vstack([pts, s["env_points"]])
    bounds = (s["bounds"].tolist() or
              np.column_stack([everything.min(axis=0), everything.max(axis=0)]).ravel())
    nx, ny, nz = (int(k) + 1 for k in s["intervals"])
    plotter.show_bounds(bounds=bounds, axes_ranges=s["ranges"].tolist() or None,
                        xtitle=titles[0], ytitle=titles[1], ztitle=titles[2], color="black",
                        font_size=11, location="outer", grid=False, fmt="%g", bold=False,
                        n_xlabels=nx, n_ylabels=ny, n_zlabels=nz)
    # v̂ to the right, ω̂ going away, v̂_l up, seen from above, in front and to the right.
    plotter.view_vector((0.8, -1.3, 0.7), viewup=(0.0, 0.0, 1.0))
    plotter.camera.zoom(0.85)
    plotter.screenshot(out_path)
    plotter.close()


if __name__ == "__main__":  # the child process of _run_renderer
    _render_pyvista(sys.argv[1], sys.argv[2])
