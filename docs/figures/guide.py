"""The user guide's figures, drawn from the shipped samples with mocaplib's own functions.

Each function returns one figure as PNG bytes; :data:`FIGURES` names the file each one becomes
in the site (``img/NAME``). ``docs/hooks/figures.py`` runs them at build time.
"""

from __future__ import annotations

import io

import numpy as np

import data

DPI = 110
SIDES = {"left": "tab:blue", "right": "tab:orange"}


def _figure(width: float, height: float):
    """An empty Agg figure (no pyplot, no display) with constrained layout."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


# ------------------------------------------------------------------------------ skeleton
#: Sticks drawn between segment origins (besides each segment to its parent).
_EXTRA_LINES = (("femur_l", "femur_r"), ("humerus_l", "humerus_r"))
#: (DOF, label) whose positive direction each view shows as an arrow.
_SIDE_VIEW_DOFS = (("trunk_flexion", "trunk flexion (pelvis tilt alike)"),
                   ("neck_flexion", "neck flexion"), ("shoulder_flexion_r", "shoulder flexion"),
                   ("elbow_flexion_r", "elbow flexion"), ("hip_flexion_r", "hip flexion"),
                   ("knee_flexion_r", "knee flexion"),
                   ("ankle_dorsiflexion_r", "ankle dorsiflexion"))
_FRONT_VIEW_DOFS = (("shoulder_abduction_l", "shoulder abduction"),
                    ("shoulder_abduction_r", "shoulder abduction"),
                    ("hip_adduction_l", "hip adduction"),
                    ("ankle_inversion_l", "ankle inversion"), ("pelvis_list", "pelvis list"),
                    ("trunk_bending", "trunk bending"))


def _standing():
    """A skeleton of the samples' subject and its neutral standing pose (D,)."""
    from mocaplib.skeleton import DOF_NAMES, Skeleton

    skeleton = Skeleton.from_height(1.75)
    q = np.zeros(len(DOF_NAMES))
    q[DOF_NAMES.index("pelvis_tz")] = skeleton.lengths["hip_height"]
    return skeleton, q


def _sticks(skeleton, q) -> list[np.ndarray]:
    """The skeleton's bones at pose ``q`` as (2, 3) world segments, metres."""
    from mocaplib.export.bvh import end_sites
    from mocaplib.skeleton import SEGMENT_NAMES, SEGMENTS

    T = skeleton.forward(q)[0]
    origin = T[:, :3, 3]
    lines = [np.array([origin[SEGMENT_NAMES.index(s.parent)], origin[i]])
             for i, s in enumerate(SEGMENTS) if s.parent is not None]
    lines += [np.array([origin[SEGMENT_NAMES.index(a)], origin[SEGMENT_NAMES.index(b)]])
              for a, b in _EXTRA_LINES]
    for name, tip in end_sites(skeleton).items():
        i = SEGMENT_NAMES.index(name)
        lines.append(np.array([origin[i], T[i, :3, :3] @ np.asarray(tip) + origin[i]]))
    return lines


def _moved_point(skeleton, q, dof: str, angle: float) -> np.ndarray:
    """Where the distal end of ``dof``'s segment goes when ``dof`` turns by ``angle`` rad."""
    from mocaplib.export.bvh import end_sites
    from mocaplib.skeleton import DOF_NAMES, DOFS, SEGMENT_NAMES, SEGMENTS

    segment = DOFS[DOF_NAMES.index(dof)].segment
    i = SEGMENT_NAMES.index(segment)
    children = [k for k, s in enumerate(SEGMENTS) if s.parent == segment]
    moved = q.copy()
    moved[DOF_NAMES.index(dof)] += angle
    T = skeleton.forward(moved)[0]
    if segment == "pelvis":       # the pelvis turns the trunk: show the torso's top
        children = [SEGMENT_NAMES.index("head")]
    if children:
        return T[children[0], :3, 3]
    return T[i, :3, :3] @ np.asarray(end_sites(skeleton)[segment]) + T[i, :3, 3]


def skeleton_axes() -> bytes:
    """The 32-DOF skeleton standing in the neutral pose, side and front views, with the
    positive direction of each sagittal and frontal DOF as the path its segment takes."""
    from mocaplib.skeleton import DOF_NAMES

    skeleton, q = _standing()
    fig = _figure(9.5, 6.6)
    side, front = fig.subplots(1, 2)
    views = ((side, 0, "side view from the subject's right", _SIDE_VIEW_DOFS),
             (front, 1, "front view, facing the subject", _FRONT_VIEW_DOFS))
    for ax, horizontal, title, dofs in views:
        for line in _sticks(skeleton, q):
            ax.plot(line[:, horizontal], line[:, 2], color="0.35", lw=2.2, solid_capstyle="round")
        for k, (dof, label) in enumerate(dofs):
            path = np.array([_moved_point(skeleton, q, dof, a)
                             for a in np.radians(np.linspace(0.0, 30.0, 16))])
            x, z = path[:, horizontal], path[:, 2]
            colour = f"C{k % 10}"
            ax.plot(x, z, color=colour, lw=1.6)
            ax.annotate("", xy=(x[-1], z[-1]), xytext=(x[-3], z[-3]),
                        arrowprops=dict(arrowstyle="-|>", color=colour, lw=1.6))
            leftwards = x[-1] < x[0]
            ax.annotate(f"{label} +", (x[-1], z[-1]), xytext=(-4 if leftwards else 4, 3),
                        textcoords="offset points", color=colour, fontsize=8,
                        ha="right" if leftwards else "left")
        ax.set_xlabel("X, forward (m)" if horizontal == 0 else
                      "Y (m): the subject's right ← → left")
        ax.set_ylabel("Z, up (m)")
        ax.set_title(title, fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlim(-0.55, 0.55)
        ax.grid(alpha=0.3)
    fig.suptitle(f"The skeleton ({len(DOF_NAMES)} DOFs) in the neutral pose: each arrow is the "
                 "path of a segment's end\nas one DOF turns from 0 to +30°", fontsize=11)
    return _png(fig)


# ---------------------------------------------------------------------------- marker set
def marker_set() -> bytes:
    """The samples' static trial: every marker of the fullbody38 protocol on the fitted
    skeleton, front and side views."""
    trial, fitted = data.static(), data.capture_static()
    X = np.nanmean(trial.markers, axis=0)
    q = np.nanmedian(fitted.motion.q, axis=0)
    skeleton = fitted.model.skeleton
    fig = _figure(9.5, 7.6)
    front, side = fig.subplots(1, 2, width_ratios=(2, 1))
    heading = q[3]
    c, s = np.cos(-heading), np.sin(-heading)
    centre = q[:3]

    def turned(points):
        """Points (N, 3) turned about the pelvis so that the subject faces +X."""
        p = np.asarray(points) - centre
        return np.column_stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1],
                                p[:, 2] + centre[2]])

    groups = {"left (L…)": [k for k, label in enumerate(trial.labels) if label[0] == "L"],
              "right (R…)": [k for k, label in enumerate(trial.labels) if label[0] == "R"]}
    groups["midline"] = [k for k in range(len(trial.labels))
                         if not any(k in g for g in groups.values())]
    colours = dict(zip(groups, (SIDES["left"], SIDES["right"], "tab:green")))
    for ax, h, title in ((front, 1, "front view, facing the subject"),
                         (side, 0, "side view from its right")):
        for line in _sticks(skeleton, q):
            p = turned(line)
            ax.plot(p[:, h], p[:, 2], color="0.75", lw=2.0, zorder=1)
        p = turned(X)
        for name, members in groups.items():
            ax.scatter(p[members, h], p[members, 2], s=24, color=colours[name],
                       edgecolor="k", linewidths=0.4, zorder=3, label=f"{name} markers")
        if h == 1:
            for label, point in zip(trial.labels, p):
                ax.annotate(label, (point[h], point[2]), xytext=(3, 2),
                            textcoords="offset points", fontsize=6.5)
        ax.set_xlabel("Y (m): the subject's right ← → left" if h == 1 else "X, forward (m)")
        ax.set_ylabel("Z, up (m)")
        ax.set_title(title, fontsize=10)
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    handles, labels = front.get_legend_handles_labels()
    handles.append(front.plot([], [], color="0.75", lw=2.0)[0])
    fig.legend(handles, labels + ["calibrated skeleton"], loc="outside lower center", ncols=4,
               fontsize=8)
    fig.suptitle(f"The marker set of the samples ({fitted.match.protocol.name}, "
                 f"{len(trial.labels)} markers) on the calibrated skeleton, sample_c3d/rest.c3d",
                 fontsize=11)
    return _png(fig)


# ------------------------------------------------------------------------ events, cycles
def events_cycles() -> bytes:
    """A straight walk's heel and toe heights, its detected toe-offs and heel strikes, and
    the cycles cut at consecutive left toe-offs."""
    name = "walk_straight_normal"
    trial, fitted, events, cycles = data.capture(name)
    t = trial.time
    fig = _figure(10, 6.4)
    axes = fig.subplots(2, 1, sharex=True)
    for ax, side in zip(axes, ("left", "right")):
        letter = side[0].upper()
        for marker, style in ((f"{letter}HEE", "-"), (f"{letter}TOE", "--")):
            ax.plot(t, 1000 * trial.marker(marker)[:, 2], style, color=SIDES[side],
                    label=f"{marker} height")
        for e in events:
            if e.side != side:
                continue
            toe_off = e.kind == "toe_off"
            ax.axvline(e.time_s, color="k" if toe_off else "0.5", ls="-" if toe_off else ":",
                       lw=1.0)
        ax.set_ylabel("height (mm)")
        ax.set_title(f"{side} foot", fontsize=10, loc="left")
        ax.grid(alpha=0.3)
    for cycle in cycles:
        for ax in axes:
            ax.axvspan(cycle.start_s, cycle.end_s, color="tab:green" if cycle.chosen else "0.8",
                       alpha=0.18 if cycle.chosen else 0.25, lw=0)
        axes[0].annotate(f"cycle {cycle.index}" + (" (chosen)" if cycle.chosen else ""),
                         (0.5 * (cycle.start_s + cycle.end_s), 1.0),
                         xycoords=("data", "axes fraction"), xytext=(0, -12),
                         textcoords="offset points", ha="center", fontsize=9)
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = axes[0].get_legend_handles_labels()[0] + axes[1].get_legend_handles_labels()[0]
    handles += [Line2D([], [], color="k", lw=1.0, label="toe-off"),
                Line2D([], [], color="0.5", ls=":", lw=1.0, label="heel strike"),
                Patch(color="tab:green", alpha=0.3, label="cycle kept for the library"),
                Patch(color="0.8", alpha=0.5, label="other cycle")]
    fig.legend(handles=handles, loc="outside lower center", ncols=4, fontsize=8)
    axes[1].set_xlabel("time (s)")
    fig.suptitle(f"Events and cycles of sample_c3d/{name}.c3d: a cycle runs from a left "
                 "toe-off to the next", fontsize=11)
    return _png(fig)


# ---------------------------------------------------------------------------- patterns
def _shown(value: float, digits: int) -> str:
    """``value`` signed, rounded to ``digits``, with no "-0"."""
    return f"{round(float(value), digits) + 0.0:+.{digits}f}"


def patterns() -> bytes:
    """The shoulder midpoint's path over one cycle of a straight walk, a curve and a
    side-step, with the fitted line or arc and the cycle's v̂, ω̂ and v̂_l."""
    from mocaplib.gait.cycles import shoulder_centres
    from mocaplib.gait.patterns import cycle_times, sample_shoulders
    from mocaplib.report.figures import pattern_curve

    fig = _figure(11.5, 4.6)
    panels = fig.subplots(1, 3)
    for ax, name in zip(panels, ("walk_straight_normal", "walk_curve_r2_left_normal",
                                 "side_left_normal")):
        trial, fitted, _, cycles = data.capture(name)
        cycle = next(c for c in cycles if c.chosen)
        left, right = shoulder_centres(fitted.motion)
        times = cycle_times(cycle.start_s, cycle.end_s, trial.rate)
        mid, theta_s = sample_shoulders(left, right, trial.rate, times)
        vel = cycle.velocities
        curve = pattern_curve(vel.pattern.to_dict(), mid[:, :2])
        ax.plot(mid[:, 0], mid[:, 1], color="0.3", lw=2.0, label="shoulder midpoint")
        ax.plot(curve[:, 0], curve[:, 1], color="tab:red", ls="--", lw=1.5,
                label=f"fitted {vel.pattern.kind}")
        step = max(1, len(times) // 6)
        for k in range(0, len(times), step):       # θ_S: where the shoulders face
            ax.annotate("", xy=mid[k, :2] + 0.15 * np.array([np.cos(theta_s[k]),
                                                             np.sin(theta_s[k])]),
                        xytext=mid[k, :2], arrowprops=dict(arrowstyle="->", color="tab:blue"))
        ax.plot([], [], color="tab:blue", label="θ_S: where the shoulders face")
        k = len(times) // 2                         # θ_T: the pattern's direction of travel
        theta_t = vel.pattern.tangent(mid[k:k + 1, :2])[0]
        ax.annotate("", xy=mid[k, :2] + 0.2 * np.array([np.cos(theta_t), np.sin(theta_t)]),
                    xytext=mid[k, :2], arrowprops=dict(arrowstyle="-|>", color="tab:red",
                                                       lw=1.8))
        ax.plot([], [], color="tab:red", label="θ_T: direction of travel")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("X (m)")
        ax.set_ylabel("Y (m)")
        ax.set_title(f"{name}\nv̂ {vel.v:.2f} m/s, ω̂ {_shown(np.degrees(vel.omega), 0)} °/s, "
                     f"v̂_l {_shown(vel.v_l, 2)} m/s", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle("One cycle's path, its pattern and its velocities (v̂_l > 0: moving to the "
                 "subject's left)", fontsize=11)
    return _png(fig)


# ----------------------------------------------------------------------------- Fourier
def fourier() -> bytes:
    """Knee flexion over the chosen cycle of a straight walk and its Fourier reconstruction
    with 1, 3 and the encoder's number of harmonics."""
    from mocaplib.gait.fourier import fit_series
    from mocaplib.gait.patterns import cycle_times
    from mocaplib.model.filtering import resample
    from mocaplib.skeleton import DOF_NAMES

    name, dof = "walk_straight_normal", "knee_flexion_l"
    trial, fitted, _, cycles = data.capture(name)
    cycle = next(c for c in cycles if c.chosen)
    times = cycle_times(cycle.start_s, cycle.end_s, trial.rate)
    j = DOF_NAMES.index(dof)
    angle = resample(fitted.motion.q[:, j:j + 1], trial.rate, times)[:, 0]
    t = times - times[0]
    period = cycle.period
    fine = np.linspace(0.0, period, 200)
    order = cycle.encoding.order
    fig = _figure(9.5, 4.8)
    ax = fig.subplots()
    ax.plot(100 * t / period, np.degrees(angle), "o", ms=3.5, color="0.3",
            label="fitted angle (one sample per frame)")
    for n, colour in ((1, "tab:orange"), (3, "tab:green"), (order, "tab:red")):
        series = fit_series(angle[:-1, None], t[:-1], period, n)
        ax.plot(100 * fine / period, np.degrees(series(fine)[:, 0]),
                color=colour, lw=1.6, label=f"{n} harmonic{'s' * (n > 1)}"
                + (" (the encoder's choice)" if n == order else ""))
    ax.set_xlabel("cycle (% of T, from left toe-off)")
    ax.set_ylabel(f"{dof.replace('_', ' ')} (°)")
    ax.set_title(f"Fourier encoding of {dof} over one cycle of {name} (T = {period:.2f} s)",
                 fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _png(fig)


# ----------------------------------------------------------------------- control space
def control_space() -> bytes:
    """The control space of a small library of the samples: its entries, and a query point
    inside with the four entries it blends and their weights."""
    from mocaplib.library.controlspace import ControlSpace

    cs = ControlSpace.from_library(data.library())
    query = np.array([[0.9, np.radians(20.0), 0.15]])
    answer = cs.query(query)
    fig = _figure(11, 4.8)
    panels = fig.subplots(1, 2)
    used = answer.entries[0]
    for ax, (i, j) in zip(panels, ((0, 1), (0, 2))):
        def shown(points):
            p = np.array(points, dtype=float)
            p[..., 1] = np.degrees(p[..., 1])
            return p[..., [i, j]]
        p = shown(cs.points)
        ax.scatter(p[:, 0], p[:, 1], s=30, color="0.6", edgecolor="k", linewidths=0.4,
                   label="library entries", zorder=2)
        ax.scatter(p[used, 0], p[used, 1], s=70, facecolor="none", edgecolor="tab:red",
                   linewidths=1.5, label="entries of the enclosing tetrahedron", zorder=3)
        q = shown(query)[0]
        for k, w in zip(used, answer.weights[0]):
            ax.plot([q[0], p[k, 0]], [q[1], p[k, 1]], color="tab:red", lw=0.8, alpha=0.7)
            ax.annotate(f"w={w:.2f}", p[k], xytext=(5, -10), textcoords="offset points",
                        fontsize=8, color="tab:red")
        ax.scatter(*q, marker="*", s=220, color="gold", edgecolor="k", zorder=4,
                   label="query (0.9 m/s, 20 °/s, 0.15 m/s)")
        ax.set_xlabel("v̂, tangential velocity (m/s)")
        ax.set_ylabel(("ω̂, angular velocity (°/s)", "v̂_l, lateral velocity (m/s)")[j - 1])
        ax.grid(alpha=0.3)
    panels[0].legend(fontsize=8, loc="upper right")
    fig.suptitle(f"The control space of {len(cs.ids)} sample entries and one query: the "
                 "blend weights are the query's barycentric coordinates", fontsize=11)
    return _png(fig)


def coverage_map() -> bytes:
    """The report's coverage map of the same library against the default envelope."""
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.coverage import coverage
    from mocaplib.report.figures import projections
    from mocaplib.report.plan import default_envelope

    library = data.library()
    cs = ControlSpace.from_library(library)
    envelope, _ = default_envelope(None)
    cover = coverage(cs, envelope)
    classes = [c if c == c and c is not None else "unknown" for c in cs.classes]
    return projections(cs.points, classes, cs.axes, envelope=envelope.vertices,
                       hull_points=cs.points, holes=cover.samples[~cover.samples_inside],
                       suggestions=cover.capture_next[list(cs.axes)].to_numpy())


# ------------------------------------------------------------------------------ pipeline
#: The stages of one capture and of a library, left to right, top to bottom: (name, what it
#: makes).
_STAGES = (("import", "markers\n(F, M, 3) m\nZ up"), ("protocol", "which label\nis which\nlandmark"),
           ("calibrate", "the subject's\nskeleton"), ("fit", "joint angles\n(F, 32)"),
           ("events", "toe-offs,\nheel strikes"), ("cycles", "left toe-off\nto left\ntoe-off"),
           ("pattern", "line or arc;\nv̂, ω̂, v̂_l"), ("Fourier", "coefficients\nper DOF"),
           ("library", "entries,\nvalidated\nJSON"), ("control\nspace", "Delaunay of\n(v̂, ω̂, v̂_l)"),
           ("report", "coverage,\nQC, HTML"), ("query", "blend a\ncommand;\nBVH, glTF"))
#: Commands and the stages they run (first, last index into :data:`_STAGES`).
_COMMANDS = (("inspect", 0, 1), ("fit", 0, 3), ("events", 0, 4), ("cycles", 0, 7),
             ("build", 0, 10), ("report", 9, 10), ("query · retarget", 9, 11))


def pipeline() -> bytes:
    """The stages a capture goes through, what each makes, and the stretch each command runs."""
    from matplotlib.patches import FancyBboxPatch

    fig = _figure(12.0, 4.8)
    ax = fig.subplots()
    width, gap = 1.25, 0.3
    x = np.arange(len(_STAGES)) * (width + gap)
    for k, (name, made) in enumerate(_STAGES):
        library_side = k >= 8
        ax.add_patch(FancyBboxPatch((x[k], 0.0), width, 1.0, boxstyle="round,pad=0.03",
                                    facecolor="#dbe9f6" if not library_side else "#e5f3e0",
                                    edgecolor="0.35"))
        ax.text(x[k] + width / 2, 0.78, name, ha="center", va="center", fontsize=8.5,
                weight="bold", linespacing=0.9)
        ax.text(x[k] + width / 2, 0.32, made, ha="center", va="center", fontsize=7.2)
        if k + 1 < len(_STAGES):
            ax.annotate("", (x[k + 1] - 0.02, 0.5), (x[k] + width + 0.02, 0.5),
                        arrowprops={"arrowstyle": "->", "color": "0.3"})
    for row, (command, first, last) in enumerate(_COMMANDS):
        y = -0.35 - 0.32 * row
        ax.plot([x[first] + 0.05, x[last] + width - 0.05], [y, y], lw=5, color="tab:orange",
                solid_capstyle="round")
        ax.text(x[first] - 0.1, y, f"mocaplib {command}", ha="right", va="center", fontsize=8)
    ax.text(x[0], 1.25, "one capture (python: mocaplib.process)", fontsize=9, color="0.3")
    ax.text(x[8], 1.25, "a library", fontsize=9, color="0.3")
    ax.set_xlim(-2.6, x[-1] + width + 0.1)
    ax.set_ylim(-0.35 - 0.32 * len(_COMMANDS), 1.45)
    ax.axis("off")
    fig.suptitle("From C3D captures to a motion library: the stages, and what each command runs",
                 fontsize=11)
    return _png(fig)


# ------------------------------------------------------------------------------- capture
def capture_heights() -> bytes:
    """A sample capture as the reader gives it: each marker's height over time, grouped by
    where it sits, and the frames where a marker is missing."""
    trial = data.capture("walk_curve_r2_left_normal")[0]
    fig = _figure(9.5, 4.2)
    ax = fig.subplots()
    z = trial.markers[:, :, 2]
    groups = (("head and trunk", lambda l: l[1:] in ("FHD", "BHD") or l in ("C7", "T10", "CLAV",
                                                                              "STRN", "RBAK")),
              ("pelvis", lambda l: l[1:] in ("ASI", "PSI")),
              ("arms", lambda l: l[1:] in ("SHO", "UPA", "ELB", "FRA", "WRA", "WRB", "FIN")),
              ("legs", lambda l: l[1:] in ("THI", "KNE", "TIB", "ANK")),
              ("feet", lambda l: l[1:] in ("HEE", "TOE")))
    colours = ("tab:purple", "tab:green", "tab:red", "tab:blue", "tab:orange")
    drawn = set()
    for (name, member), colour in zip(groups, colours):
        for k, label in enumerate(trial.labels):
            if member(label) and k not in drawn:
                drawn.add(k)
                ax.plot(trial.time, z[:, k], color=colour, lw=0.9,
                        label=name if label == next(l for l in trial.labels if member(l))
                        else None)
    for n, k in enumerate(sorted(set(range(len(trial.labels))) - drawn)):
        ax.plot(trial.time, z[:, k], color="0.6", lw=0.8, label=None if n else "other markers")
    missing = ~np.isfinite(z).all(axis=1)
    if missing.any():
        ax.fill_between(trial.time, 0, 1.9, where=missing, color="0.85", step="mid",
                        label="a marker missing (NaN)")
    ax.set_xlabel("time from the first frame (s)")
    ax.set_ylabel("Z, up (m)")
    ax.set_ylim(0, 1.9)
    ax.legend(loc="upper right", fontsize=8, ncols=3)
    ax.grid(alpha=0.3)
    ax.set_title(f"sample_c3d/walk_curve_r2_left_normal.c3d as read: {trial.n_markers} markers, "
                 f"{trial.n_frames} frames at {trial.rate:g} Hz, metres, Z up", fontsize=10)
    return _png(fig)


#: Site file name (under ``img/``) -> the function that draws it.
FIGURES = {"skeleton-axes.png": skeleton_axes, "marker-set.png": marker_set,
           "events-cycles.png": events_cycles, "patterns.png": patterns,
           "fourier.png": fourier, "control-space.png": control_space,
           "coverage-map.png": coverage_map, "pipeline.png": pipeline,
           "capture-heights.png": capture_heights}
