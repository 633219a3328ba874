"""Matplotlib figures of the report, returned as PNG bytes (no pyplot, no global state).

Control-space figures take SI points and show ω in degrees per second, for people.
Per-capture figures read one record of the diagnostics sidecar (see ``docs/library-format.md``).
"""

from __future__ import annotations

import io

import numpy as np

#: Joint angles drawn per capture (the ones a gait lab reads first).
CAPTURE_DOFS = ("hip_flexion_r", "knee_flexion_r", "ankle_dorsiflexion_r", "trunk_rotation")
DPI = 96
#: Palette size of the report's PNGs (:func:`compress_png`).
PALETTE_COLOURS = 256
UNKNOWN_CLASS = "unknown"


def class_colours(classes) -> dict[str, tuple[float, float, float]]:
    """A stable colour per class name (tab10 in sorted order; grey for unknown)."""
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    names = sorted({c for c in classes if c != UNKNOWN_CLASS})
    colours = {name: tuple(float(x) for x in cmap(i % 10)[:3]) for i, name in enumerate(names)}
    colours[UNKNOWN_CLASS] = (0.5, 0.5, 0.5)
    return colours


def new_figure(width: float, height: float, *, margins: dict | None = None):
    """An empty matplotlib Figure of ``width`` x ``height`` inches as every report figure
    starts: :data:`DPI`, an Agg canvas (no pyplot, no display), constrained layout or, when
    ``margins`` (``Figure.subplots_adjust`` keywords) are given, those fixed margins."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI, layout=None if margins else "constrained")
    if margins:
        fig.subplots_adjust(**margins)
    FigureCanvasAgg(fig)
    return fig


#: Fixed margins of the per-capture figure (fractions of the figure): laid out once, since its
#: panels and labels are always the same; constrained layout measured every text of each of the
#: report's many capture figures again and took ~40 % of their rendering time.
CAPTURE_MARGINS = {"left": 0.07, "right": 0.98, "bottom": 0.06, "top": 0.962, "wspace": 1.1,
                   "hspace": 0.45}
#: The poulaine panels: (title, horizontal and vertical coordinate of the travel frame).
POULAINE_VIEWS = (("poulaines, side view (x-z)", 0, 2), ("top view (x-y)", 0, 1),
                  ("front view (y-z)", 1, 2))
SIDE_COLOURS = {"left": "tab:blue", "right": "tab:orange"}


def png_bytes(fig) -> bytes:
    """The figure as a compact PNG (see :func:`compress_png`)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return compress_png(buf.getvalue())


def compress_png(png: bytes, *, colours: int = PALETTE_COLOURS) -> bytes:
    """An RGB(A) PNG re-encoded with a palette of ``colours`` colours, without dithering.

    Plots have few colours (lines, markers, text antialiasing), so an adaptive 256-colour
    palette is visually identical and about 4 times smaller (a 68-capture report: 5.5 MB of
    images down to about 1.5 MB)."""
    from PIL import Image

    image = Image.open(io.BytesIO(png)).convert("RGB")
    out = io.BytesIO()
    image.quantize(colors=colours, method=Image.Quantize.FASTOCTREE,
                   dither=Image.Dither.NONE).save(out, format="PNG", optimize=True)
    return out.getvalue()


def _display(points: np.ndarray, axes: tuple[str, ...]) -> np.ndarray:
    """SI points (…, 3) with ω converted to degrees per second."""
    out = np.array(points, dtype=float, copy=True)
    out[..., axes.index("omega")] = np.degrees(out[..., axes.index("omega")])
    return out


def axis_label(name: str) -> str:
    """Axis title, with its unit, of a control-space coordinate (``v``, ``v_f``, ``omega``,
    ``v_l``); ω̂ in degrees per second, as the plots draw it."""
    return {"v": "v̂ (m/s)", "v_f": "v̂_f (m/s)", "omega": "ω̂ (°/s, > 0 left)",
            "v_l": "v̂_l (m/s, > 0 left)"}[name]


def projections(points, classes, axes, *, envelope=None, hull_points=None, holes=None,
                suggestions=None) -> bytes:
    """The paper's Fig. 9: ω–v and v_l–v planes. Entries coloured by class; the envelope's and
    the library hull's outlines; envelope samples outside the hull (holes) as faint crosses;
    "capture next" suggestions as numbered stars. All arrays SI, shape (…, 3)."""
    from scipy.spatial import ConvexHull, QhullError

    colours = class_colours(classes)
    fig = new_figure(11, 4.6)
    panels = fig.subplots(1, 2)
    for ax, (i, j) in zip(panels, ((0, 1), (0, 2))):
        for outline, style, label in ((envelope, dict(color="tab:red", ls="--"), "envelope"),
                                      (hull_points, dict(color="0.2", ls="-"), "library hull")):
            if outline is None or len(outline) < 3:
                continue
            xy = _display(outline, axes)[:, [i, j]]
            try:
                ring = xy[ConvexHull(xy).vertices]
            except QhullError:
                continue
            ring = np.vstack([ring, ring[:1]])
            ax.plot(ring[:, 0], ring[:, 1], lw=1.2, label=label, **style)
        if holes is not None and len(holes):
            h = _display(holes, axes)
            ax.scatter(h[:, i], h[:, j], marker="x", s=8, color="#f2b8b8", linewidths=0.6,
                       label="envelope outside the library hull", zorder=1)
        p = _display(points, axes)
        for name in sorted(set(classes)):
            sel = np.array([c == name for c in classes])
            ax.scatter(p[sel, i], p[sel, j], s=36, color=colours[name], edgecolor="k",
                       linewidths=0.5, label=name, zorder=3)
        if suggestions is not None and len(suggestions):
            s = _display(suggestions, axes)[:, [i, j]]
            ax.scatter(s[:, 0], s[:, 1], marker="*", s=160, color="gold", edgecolor="k",
                       zorder=4, label="capture next")
            for text, (x, y) in star_labels(s, ax.get_xlim(), ax.get_ylim()):
                ax.annotate(text, (x, y), xytext=(5, 4), textcoords="offset points",
                            fontsize=9, weight="bold")
        ax.set_xlabel(axis_label(axes[i]))
        ax.set_ylabel(axis_label(axes[j]))
        ax.grid(alpha=0.3)
    handles, labels = panels[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize=8)
    return png_bytes(fig)


def star_labels(points: np.ndarray, xlim, ylim, *, near: float = 0.04
                ) -> list[tuple[str, tuple[float, float]]]:
    """Labels of numbered stars (1, 2, ... in the order of ``points`` (S, 2)) on a panel with
    limits ``xlim``, ``ylim``: stars within ``near`` of the panel's size of an earlier one share
    its label ("1, 2"), so no two numbers print on top of each other."""
    span = np.array([xlim[1] - xlim[0], ylim[1] - ylim[0]], float)
    span[span <= 0] = 1.0
    groups: list[list[int]] = []
    for n, p in enumerate(points):
        for group in groups:
            if np.all(np.abs((points[group[0]] - p) / span) < near):
                group.append(n)
                break
        else:
            groups.append([n])
    return [(", ".join(str(n + 1) for n in g), tuple(points[g[0]])) for g in groups]


def control_space_3d(points, classes, axes, *, edges=(), envelope=None) -> bytes:
    """Matplotlib 3-D view of the control space (the fallback without OpenGL).

    ``points`` SI (E, 3); ``edges`` (K, 2) row pairs of Delaunay edges; ``envelope`` SI (P, 3)
    vertices drawn as their convex hull's edges."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection
    from scipy.spatial import ConvexHull, QhullError

    colours = class_colours(classes)
    fig = new_figure(8, 6.5)
    ax = fig.add_subplot(projection="3d")
    p = _display(points, axes)
    edges = np.asarray(edges, dtype=int).reshape(-1, 2)
    if len(edges):      # one artist for every edge: thousands of plot calls take minutes
        ax.add_collection3d(Line3DCollection(p[edges], colors="0.6", linewidths=0.6))
    if envelope is not None and len(envelope) >= 4:
        e = _display(envelope, axes)
        try:
            for tri in ConvexHull(e).simplices:
                ring = e[np.r_[tri, tri[:1]]]
                ax.plot(*ring.T, color="tab:red", lw=0.5, ls="--", alpha=0.5)
        except QhullError:
            pass
    for name in sorted(set(classes)):
        sel = np.array([c == name for c in classes])
        ax.scatter(*p[sel].T, s=40, color=colours[name], edgecolor="k", label=name,
                   depthshade=False)
    ax.set_xlabel(axis_label(axes[0]))
    ax.set_ylabel(axis_label(axes[1]))
    ax.set_zlabel(axis_label(axes[2]))
    ax.legend(fontsize=8, loc="upper left")
    return png_bytes(fig)


# --------------------------------------------------------------------------- per capture
def capture_figure(record: dict, reconstructions: dict[str, tuple[np.ndarray, np.ndarray]],
                   poulaine: dict | None = None) -> bytes:
    """Quality panels of one capture: shoulder path (top view) with the fitted pattern and cycle
    bounds; marker RMS over time; gait events; joint angles with their Fourier reconstruction;
    the chosen cycle's poulaines in three views, measured and modelled.

    ``record``: one capture of the diagnostics sidecar. ``reconstructions``: DOF name ->
    (times s, angles rad) of the library entries' Fourier series, placed on the capture's time.
    ``poulaine``: the chosen cycle's entry's model, ``path`` (n, 2, 3) m over the cycle and its
    characteristic ``points`` (2, 4, 3) m, left then right; None when it has none.
    """
    fig = new_figure(11, 8.4, margins=CAPTURE_MARGINS)
    grid = fig.add_gridspec(3, 6, height_ratios=(1.0, 1.0, 0.8))
    panels = [fig.add_subplot(grid[row, 3 * col:3 * col + 3]) for row in (0, 1) for col in (0, 1)]
    cycles = record.get("cycles") or []
    _path_panel(panels[0], record, cycles)
    _rms_panel(panels[1], record, cycles)
    _events_panel(panels[2], record, cycles)
    _angles_panel(panels[3], record, reconstructions)
    for k, view in enumerate(POULAINE_VIEWS):
        _poulaine_panel(fig.add_subplot(grid[2, 2 * k:2 * k + 2]), record.get("poulaine"),
                        poulaine, view, legend=k == 0)
    return png_bytes(fig)


def _poulaine_panel(ax, measured: dict | None, model: dict | None, view, *, legend: bool):
    """One view of both ankles' poulaines: the sidecar's measured paths (wide, pale) and the
    entry's model (thin, its characteristic points as dots)."""
    title, across, up = view
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(f"{'xyz'[across]} (m)")
    ax.set_ylabel(f"{'xyz'[up]} (m)")
    if not measured and not model:
        ax.text(0.5, 0.5, "no poulaine", ha="center", transform=ax.transAxes)
        return
    for k, side in enumerate(SIDE_COLOURS):
        colour = SIDE_COLOURS[side]
        if measured:
            path = np.asarray(measured[f"{side}_m"], dtype=float).reshape(-1, 3)
            ax.plot(path[:, across], path[:, up], color=colour, lw=4, alpha=0.3,
                    solid_capstyle="butt", label=f"{side}, measured")
        if model:
            path = np.asarray(model["path"], dtype=float)[:, k]
            ax.plot(path[:, across], path[:, up], color=colour, lw=1.1, label=f"{side}, model")
            points = np.asarray(model["points"], dtype=float)[k]
            ax.plot(points[:, across], points[:, up], "o", color=colour, ms=3.5)
    ax.set_aspect("equal", adjustable="datalim")
    ax.locator_params(nbins=4)     # few ticks: drawing them is most of a panel's time
    ax.grid(alpha=0.3)
    if legend:
        ax.legend(fontsize=7, loc="upper right")


def _headroom(ax, share: float = 0.3):
    """Extend the y axis upwards so a legend in the top corner covers no data."""
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + share * (hi - lo))


def _shade_cycles(ax, cycles):
    for c in cycles:
        ax.axvspan(c["start_s"], c["end_s"], color="tab:green" if c.get("chosen") else "0.6",
                   alpha=0.15, lw=0)


def _path_panel(ax, record, cycles):
    xy = np.asarray(record.get("shoulder_mid_xy") or np.zeros((0, 2)), dtype=float).reshape(-1, 2)
    t = np.asarray(record.get("time_s") or [], dtype=float)
    ax.set_title("shoulder midpoint, top view", fontsize=10)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if not len(xy):
        ax.text(0.5, 0.5, "no shoulder path", ha="center", transform=ax.transAxes)
        return
    ax.plot(xy[:, 0], xy[:, 1], color="0.4", lw=1, label="path")
    ax.plot(*xy[0], "o", color="0.4", ms=4)
    for c in cycles:
        inside = (t >= c["start_s"]) & (t <= c["end_s"]) if len(t) == len(xy) else slice(None)
        seg = xy[inside]
        if not len(seg):
            continue
        colour = "tab:green" if c.get("chosen") else "tab:blue"
        ax.plot(*seg[[0, -1]].T, "|", color=colour, ms=14, mew=2)
        fitted = pattern_curve(c.get("pattern") or {}, seg)
        if fitted is not None:
            which = "chosen cycle" if c.get("chosen") else "other cycle"
            ax.plot(fitted[:, 0], fitted[:, 1], color=colour, lw=2.2, alpha=0.7,
                    label=f"{which}: {(c.get('pattern') or {}).get('type', '?')} fit")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    unique = dict(zip(labels, handles))
    ax.legend(unique.values(), unique.keys(), fontsize=7)


def pattern_curve(pattern: dict, seg: np.ndarray) -> np.ndarray | None:
    """Points (K, 2) of a fitted pattern over the stretch of path ``seg`` (n, 2) it was fitted to.

    ``pattern``: as the library stores it, ``type`` line (``parameters``: ``point``,
    ``direction``), arc (``centre``, ``radius``) or point (``point``); None when the parameters
    are missing."""
    p = pattern.get("parameters") or {}
    kind = pattern.get("type")
    try:
        if kind == "line":
            o, u = np.asarray(p["point"], float), np.asarray(p["direction"], float)
            u = u / np.linalg.norm(u)
            s = (seg - o) @ u
            return o + np.outer([s.min(), s.max()], u)
        if kind == "arc":
            c, r = np.asarray(p["centre"], float), float(p["radius"])
            phi = np.unwrap(np.arctan2(seg[:, 1] - c[1], seg[:, 0] - c[0]))
            ang = np.linspace(phi[0], phi[-1], 100)
            return c + r * np.column_stack([np.cos(ang), np.sin(ang)])
        if kind == "point":
            return np.asarray(p["point"], float).reshape(1, 2)
    except (KeyError, TypeError, ValueError):
        return None
    return None


def _rms_panel(ax, record, cycles):
    t = np.asarray(record.get("time_s") or [], dtype=float)
    rms = np.asarray(record.get("frame_rms_m") or [], dtype=float)
    ax.set_title("marker residual (RMS over markers)", fontsize=10)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("RMS (mm)")
    _shade_cycles(ax, cycles)
    if len(rms) and len(rms) == len(t):
        ax.plot(t, rms * 1000, color="tab:purple", lw=1)
        ax.axhline(20, color="tab:red", ls="--", lw=1, label="20 mm (OpenSim best practice)")
        ax.set_ylim(0, max(25, float(np.nanmax(rms * 1000)) * 1.1 if np.isfinite(rms).any()
                           else 25))
        ax.legend(fontsize=7, loc="upper right")
    else:
        ax.text(0.5, 0.5, "no residuals", ha="center", transform=ax.transAxes)
    ax.grid(alpha=0.3)


def _events_panel(ax, record, cycles):
    events = record.get("events") or []
    ax.set_title("gait events", fontsize=10)
    ax.set_xlabel("time (s)")
    _shade_cycles(ax, cycles)
    kinds = sorted({str(e.get("kind")) for e in events})
    markers = dict(zip(kinds, "^ov*sD"))
    rows = {"left": 1, "right": 0}
    for kind in kinds:
        for side, row in rows.items():
            times = [e["time_s"] for e in events
                     if str(e.get("kind")) == kind and str(e.get("side", "")).lower().startswith(
                         side[0])]
            if times:
                ax.scatter(times, np.full(len(times), row), marker=markers[kind], s=50,
                           color="tab:blue" if side == "left" else "tab:orange",
                           edgecolor="k", label=f"{side} {kind}")
    t = record.get("time_s") or []
    if len(t) > 1 and t[-1] > t[0]:  # a one-frame capture keeps matplotlib's default span
        ax.set_xlim(t[0], t[-1])
    ax.set_yticks([0, 1], ["right", "left"])
    ax.set_ylim(-0.6, 1.6)
    if events:
        ax.legend(fontsize=7, ncol=2, loc="upper right")
    else:
        ax.text(0.5, 0.5, "no events", ha="center", transform=ax.transAxes)
    ax.grid(alpha=0.3, axis="x")


def _angles_panel(ax, record, reconstructions):
    """The sidecar's angles are the chosen cycle's, timed from its start: shifted onto the
    capture's time axis here, where the other panels and the reconstructions are."""
    angles = record.get("angles") or {}
    chosen = [c for c in record.get("cycles") or [] if c.get("chosen")]
    t = np.asarray(angles.get("time_s") or [], dtype=float)
    t = t + (chosen[0]["start_s"] if chosen else 0.0)
    ax.set_title("joint angles of the chosen cycle (wide, pale) and its Fourier series (thin)",
                 fontsize=10)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("angle (°)")
    drawn = False
    for k, dof in enumerate(CAPTURE_DOFS):
        colour = f"C{k}"
        values = angles.get(dof)
        if values is not None and len(values) == len(t):
            ax.plot(t, np.degrees(np.asarray(values, dtype=float)), color=colour, lw=4,
                    alpha=0.3, solid_capstyle="butt", label=dof)
            drawn = True
        if dof in reconstructions:
            rt, rq = reconstructions[dof]
            ax.plot(rt, np.degrees(rq), color=colour, lw=1.1)
    if drawn:
        _headroom(ax)
        ax.legend(fontsize=7, ncol=2, loc="upper right")
    else:
        ax.text(0.5, 0.5, "no joint angles", ha="center", transform=ax.transAxes)
    ax.grid(alpha=0.3)
