"""The report's control-space sections: coverage of the target envelope and what to capture
next, slivers, entries too close to tell apart, the leave-one-out blending error, and the
interactive 3-D view (velocities shown in SI units and degrees where a person reads them)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import MocapError
from ..library.blending_error import leave_one_out
from ..library.controlspace import CLOSE_DISTANCE, SLIVER_QUALITY, ControlSpace, close_entries
from ..library.coverage import Envelope, coverage
from . import figures
from .files import data_uri
from .plan import default_envelope
from .scene3d import render_control_space

#: Sliver tetrahedra listed one by one (the worst first); the rest are summarised.
MAX_SLIVER_ROWS = 10


def add_control_space(context, cs, env, library, label, classes_all, renderer) -> None:
    """Coverage, blending error and the control-space figures into ``context``."""
    warnings = context["warnings"]
    if cs is None:
        velocities = np.array([e.velocity for e in library.entries],
                              dtype=np.float64).reshape(-1, 3)
        finite = np.isfinite(velocities).all(axis=1)
        if finite.any():
            context["projections"] = data_uri(figures.projections(
                velocities[finite],
                [c for c, ok in zip(classes_all, finite) if ok], ("v", "omega", "v_l"),
                envelope=env.vertices))
        return
    cov = coverage(cs, env)
    context["projections"] = data_uri(figures.projections(
        cs.points, cs.classes, cs.axes, envelope=env.vertices, hull_points=cs.points,
        holes=cov.samples[~cov.samples_inside],
        suggestions=cov.capture_next[list(cs.axes)].to_numpy()))
    context["coverage"] = _coverage_context(cov, cs, library, label)
    if any(e.mirrored for e in library.entries):
        context["coverage"]["without_mirrors"] = _coverage_without_mirrors(library, env)
    if context["coverage"]["close"]:
        warnings.append(_close_warning(context["coverage"]["close"]))
    context["loo"] = _loo_context(leave_one_out(cs))
    context["three_d"], context["viewer"] = _three_d(cs, env, renderer)
    if context["three_d"]["fallback_reason"]:
        warnings.append("3-D view drawn with matplotlib: "
                        + context["three_d"]["fallback_reason"])


def resolve_envelope(envelope) -> tuple[Envelope, dict]:
    if isinstance(envelope, Envelope):
        return envelope, {"text": f"given by the caller ({envelope.source})", "plan": None,
                          "plan_name": None, "default": False}
    return default_envelope(None if envelope is None else Path(envelope))


def _coverage_context(cov, cs, library, label) -> dict:
    next_rows = []
    for n, row in enumerate(cov.capture_next.itertuples(index=False), 1):
        values = dict(zip(cs.axes, row[:3]))
        next_rows.append({"n": n, "values": values, "omega_deg": math.degrees(values["omega"]),
                          "gap": row[3], "describe": describe_command(values)})
    hole = dict(zip(cs.axes, cov.largest_hole))
    return {
        "fraction": cov.fraction_inside, "n_samples": cov.n_samples,
        "hole": hole, "hole_omega_deg": math.degrees(hole["omega"]),
        "hole_distance": cov.largest_hole_distance,
        "per_class": cov.entries_per_class,
        "slivers": _sliver_context(cov.slivers),
        "n_tetra": len(cs.tri.simplices), "next": next_rows,
        "close": _close_rows(cs), "other_axes": _other_axes(cs, library, label),
        "without_mirrors": None,
    }


def _coverage_without_mirrors(library, env: Envelope) -> dict:
    """Coverage of ``env`` by the chosen entries that are not mirror images: ``fraction``
    (None when they have no control space, ``reason`` then says why), ``n_entries`` and
    ``n_mirrored`` (the chosen mirror images left out)."""
    chosen = [e for e in library.entries if e.chosen]
    out = {"n_mirrored": sum(e.mirrored for e in chosen),
           "n_entries": sum(not e.mirrored for e in chosen),
           "fraction": None, "reason": None}
    try:
        own = ControlSpace.from_library(library, mirrored=False)
    except MocapError as exc:
        out["reason"] = exc.message
        return out
    out["fraction"] = coverage(own, env).fraction_inside
    return out


def _sliver_context(slivers) -> dict:
    """Sliver count by radius-ratio band, the entries most often in one, the worst few."""
    worst = slivers.sort_values("quality", kind="stable")
    counts = pd.Series([e for entries in slivers["entries"] for e in entries]).value_counts()
    edges = [0.0, 1e-3, 1e-2, SLIVER_QUALITY]
    bands = [{"label": f"{lo:g} – {hi:g}", "count": int(((slivers["quality"] >= lo)
                                                         & (slivers["quality"] < hi)).sum())}
             for lo, hi in zip(edges[:-1], edges[1:])]
    return {"count": len(slivers), "threshold": SLIVER_QUALITY, "bands": bands,
            "frequent": [{"id": k, "count": int(v)} for k, v in counts.head(6).items()],
            "worst": [{"entries": ", ".join(r.entries), "quality": r.quality}
                      for r in worst.head(MAX_SLIVER_ROWS).itertuples(index=False)],
            "not_listed": max(0, len(slivers) - MAX_SLIVER_ROWS)}


def _close_rows(cs) -> list[dict]:
    """Pairs of entries too close to tell apart (:func:`close_entries`), with their gap in SI."""
    rows = []
    index = {k: i for i, k in enumerate(cs.ids)}
    for r in close_entries(cs).itertuples(index=False):
        gap = cs.points[index[r.a]] - cs.points[index[r.b]]
        gap[cs.axes.index("omega")] = math.degrees(gap[cs.axes.index("omega")])
        rows.append({"a": r.a, "b": r.b, "distance": r.distance, "within": CLOSE_DISTANCE,
                     "gap": ", ".join(f"{abs(g):.3f}" for g in gap)})
    return rows


def _close_warning(close: list[dict]) -> str:
    """The report's warning about the pairs of :func:`_close_rows` (not empty)."""
    return (f"{len(close)} pair(s) of entries nearly coincide in the control space (closer "
            f"than {close[0]['within']:.2f} normalised), e.g. {close[0]['a']} and "
            f"{close[0]['b']}: blending switches between them over a tiny change of velocity; "
            "see Coverage")


def _other_axes(cs, library, label) -> dict | None:
    """Slivers, close pairs and blending error of the other axes variant, to compare (None if
    it cannot be triangulated)."""
    other = "frontal" if cs.variant == "tangential" else "tangential"
    try:
        alt = ControlSpace.from_library(library, axes=other)
    except MocapError:
        return None
    alt.classes = [label(i) for i in alt.ids]
    loo = _loo_context(leave_one_out(alt))
    return {"variant": other, "axes": ", ".join(AXIS_NAMES[a] for a in alt.axes),
            "n_tetra": len(alt.tri.simplices),
            "slivers": int((alt.tetra_quality() < SLIVER_QUALITY).sum()),
            "close": len(close_entries(alt)), "n_tested": loo["n_headline"],
            "median_rms": loo["median"]["rms_deg"],
            "median_stride": loo["median"]["stride_error_mm"]}


def describe_command(values: dict) -> str:
    """A velocity triple in words, for the "capture next" list: below 0.05 m/s (or rad/s) a
    velocity counts as none."""
    v = values.get("v", values.get("v_f", 0.0))
    w, vl = values["omega"], values["v_l"]
    parts = []
    if abs(v) < 0.05 and abs(w) >= 0.05:
        return (f"turn on the spot to the {'left' if w > 0 else 'right'} at "
                f"{abs(math.degrees(w)):.0f}°/s")
    if abs(v) < 0.05:
        return "stand still"
    if abs(vl) >= 0.05:
        direction = math.degrees(math.asin(max(-1.0, min(1.0, vl / v)))) if v else 0.0
        side = "left" if vl > 0 else "right"
        parts.append(f"walk at {v:.2f} m/s heading {abs(direction):.0f}° to the {side} of "
                     f"the body")
    else:
        parts.append(f"walk forward at {v:.2f} m/s")
    if abs(w) >= 0.05:
        parts.append(f"turning {'left' if w > 0 else 'right'} (radius {abs(v / w):.1f} m)")
    return ", ".join(parts)


#: Gait mode of each locomotion class (:func:`_gait_mode`): walking in any direction (the plan's
#: nonholonomic, holonomic and mixed classes and any other named class), running, rest.
GAIT_MODES = {"running": "running", "rest": "rest", figures.UNKNOWN_CLASS: None}


#: A leave-one-out row is flagged when at least this share of its blend weight comes from
#: entries of another gait mode (walking rebuilt mostly from running, ...).
CROSS_MODE_SHARE = 0.5


def _gait_mode(cls: str | None) -> str | None:
    """"walking", "running" or "rest" for a locomotion class; None when unknown."""
    if cls is None or cls != cls:
        return None
    return GAIT_MODES.get(cls, "walking")


def _loo_context(df) -> dict:
    """The leave-one-out table and its medians.

    The headline medians leave out rest entries: a standing pose rebuilt from other standing
    poses (other subjects' statics, at the same point (0, 0, 0)) measures how the poses differ,
    not blending; they get their own median. Rows whose blend takes at least
    :data:`CROSS_MODE_SHARE` of its weight from another gait mode are flagged (``cross``) and a
    median without them is given too."""
    mode_of = dict(zip(df["id"], (_gait_mode(c) for c in df["class"])))
    rows = []
    for r in df.sort_values("rms_deg", ascending=False, kind="stable").to_dict("records"):
        rows.append({"id": r["id"], "class": r["class"] or figures.UNKNOWN_CLASS,
                     "inside": bool(r["inside"]), "rest": mode_of[r["id"]] == "rest",
                     "cross": _cross_mode(mode_of[r["id"]], r["neighbours"], r["weights"],
                                          mode_of),
                     "rebuilt_from": ", ".join(f"{n} ({w:.2f})" for n, w in
                                               zip(r["neighbours"], r["weights"])),
                     **{k: r[k] for k in LOO_COLUMNS}, "worst_dof": r["worst_dof"]})
    tested = [r for r in rows if r["inside"]]
    headline = [r for r in tested if not r["rest"]]
    same_mode = [r for r in headline if not r["cross"]]
    rest = [r for r in tested if r["rest"]]
    median = _medians(headline)
    return {"rows": rows, "n_inside": len(tested), "n": len(rows), "median": median,
            "n_headline": len(headline), "median_rms": median["rms_deg"],
            "max_rms": max((r["rms_deg"] for r in headline), default=None),
            "n_rest": len(rest), "rest_median_rms": _medians(rest)["rms_deg"],
            "n_cross": len(headline) - len(same_mode), "cross_share": CROSS_MODE_SHARE,
            "same_mode_median_rms": _medians(same_mode)["rms_deg"]}


def _medians(rows: list[dict]) -> dict:
    """Median of |value| of each :data:`LOO_COLUMNS` over ``rows``, NaN left out (None when
    there is no value)."""
    values = {k: [abs(r[k]) for r in rows if r[k] == r[k]] for k in LOO_COLUMNS}
    return {k: float(np.median(v)) if v else None for k, v in values.items()}


def _cross_mode(mode: str | None, neighbours, weights, mode_of: dict) -> dict | None:
    """The other gait mode giving a blend at least :data:`CROSS_MODE_SHARE` of its weight
    (``{"mode", "share"}``), or None (also when a mode is unknown)."""
    if mode is None:
        return None
    shares: dict[str, float] = {}
    for n, w in zip(neighbours, weights):
        if mode_of.get(n) is not None and mode_of[n] != mode:
            shares[mode_of[n]] = shares.get(mode_of[n], 0.0) + w
    other = max(shares, key=shares.get, default=None)
    if other is None or shares[other] < CROSS_MODE_SHARE:
        return None
    return {"mode": other, "share": shares[other]}


#: Numeric columns of :func:`mocaplib.library.blending_error.leave_one_out` shown in the report.
LOO_COLUMNS = ("rms_deg", "max_deg", "heading_rms_deg", "root_rms_mm", "stride_error_mm",
               "turn_error_deg", "T_error_s")


#: Axis names as the report's tables show them.
AXIS_NAMES = {"v": "v̂", "v_f": "v̂_f", "omega": "ω̂", "v_l": "v̂_l"}


def _three_d(cs: ControlSpace, env: Envelope, renderer: str) -> tuple[dict, dict]:
    """The static 3-D picture (pyvista or matplotlib) and the interactive viewer's data."""
    from scipy.spatial import ConvexHull, QhullError

    classes = cs.classes
    colours = figures.class_colours(classes)
    x = cs.normalise(cs.points)
    edges = _unique_edges(cs.tri.simplices)
    env_x = cs.normalise(env.vertices)
    try:
        env_tris = ConvexHull(env_x).simplices
    except QhullError:  # a flat envelope: drawn as its vertices only
        env_tris = np.zeros((0, 3), int)
    # Axes labelled for people: round SI values (ω in °/s) around everything drawn.
    titles = [VTK_AXIS_TITLES[a] for a in cs.axes]
    everything = np.vstack([x, env_x])
    to_people = cs.scale * np.where(np.asarray(cs.axes) == "omega", 180 / np.pi, 1.0)
    ticks = [nice_range(lo, hi) for lo, hi in zip(everything.min(axis=0) * to_people,
                                                  everything.max(axis=0) * to_people)]
    ranges = np.array([t[:2] for t in ticks])
    rendered = render_control_space(
        x, [colours[c] for c in classes], classes, titles, edges=edges,
        hull_triangles=cs.hull_facets, envelope_points=env_x, envelope_triangles=env_tris,
        axes_bounds=(ranges / to_people[:, None]).ravel(), axes_ranges=ranges.ravel(),
        axes_intervals=[t[2] for t in ticks], renderer=renderer,
        fallback=lambda: figures.control_space_3d(cs.points, classes, cs.axes, edges=edges,
                                                  envelope=env.vertices))
    png = rendered.png if rendered.renderer == "matplotlib" else figures.compress_png(rendered.png)
    viewer = {"points": np.round(x, 5).tolist(), "ids": cs.ids, "classes": classes,
              "colours": css_colours(colours),
              "edges": edges.tolist(),
              "axes": [f"{figures.axis_label(a)}: {lo:.2f} to {hi:.2f}" if a != "omega" else
                       f"{figures.axis_label(a)}: {lo:.0f} to {hi:.0f}"
                       for a, (lo, hi) in zip(cs.axes, ranges)],
              "velocities": [_velocity_text(p, cs.axes) for p in cs.points],
              "envelope": {"points": np.round(env_x, 5).tolist(),
                           "edges": _unique_edges(env_tris).tolist()}}
    return ({"png": data_uri(png), "renderer": rendered.renderer,
             "fallback_reason": rendered.fallback_reason}, viewer)


def css_colours(colours: dict) -> dict[str, str]:
    """Class -> CSS colour ``#rrggbb`` of :func:`mocaplib.report.figures.class_colours`."""
    return {k: "#%02x%02x%02x" % tuple(int(255 * c) for c in v) for k, v in colours.items()}


def nice_range(lo: float, hi: float) -> tuple[float, float, int]:
    """The tightest range containing [lo, hi] split into 3 to 7 equal steps of 1, 2, 2.5, 3 or
    5 × 10^k: (start, stop, number of steps)."""
    span = max(hi - lo, 1e-9)
    best = None
    for k in range(int(np.floor(np.log10(span / 7))), int(np.ceil(np.log10(span))) + 1):
        for step in (m * 10.0 ** k for m in (1.0, 2.0, 2.5, 3.0, 5.0)):
            start = np.floor(lo / step + 1e-9) * step
            n = int(np.ceil((hi - start) / step - 1e-9))
            if 3 <= n <= 7 and (best is None or n * step < best[1] - best[0] - 1e-12):
                best = (float(start), float(start + n * step), n)
    return best


#: Axis titles of the pyvista picture (ASCII: VTK's fonts may lack ω and the hats).
VTK_AXIS_TITLES = {"v": "v (m/s)", "v_f": "v_f (m/s)", "omega": "omega (deg/s, > 0 left)",
                   "v_l": "v_l (m/s, > 0 left)"}


def _velocity_text(point, axes) -> str:
    """One entry's velocities for people, e.g. 'v̂ 1.20 m/s, ω̂ -30 °/s, v̂_l 0.00 m/s'."""
    return ", ".join(f"{AXIS_NAMES[a]} {math.degrees(p):.0f} °/s" if a == "omega"
                     else f"{AXIS_NAMES[a]} {p:.2f} m/s" for a, p in zip(axes, point))


def _unique_edges(cells: np.ndarray) -> np.ndarray:
    """Distinct vertex pairs (K, 2) of cells (n, k) (tetrahedra or triangles)."""
    k = cells.shape[1]
    pairs = [cells[:, [i, j]] for i in range(k) for j in range(i + 1, k)]
    return np.unique(np.sort(np.vstack(pairs), axis=1), axis=0).reshape(-1, 2)
