"""The library's blending error (:func:`leave_one_out`): each entry of a control space rebuilt
by blending the others around it, and compared with itself."""

from __future__ import annotations

import functools

import numpy as np
import pandas as pd

from ..errors import LibraryError, MocapError
from ..gait.fourier import RootDrift, synthesize
from ..gait.gaits import class_gait
from ..skeleton import DOF_NAMES, JOINT_ANGLES, ROOT_HEADING, TRANSLATION
from .controlspace import ControlSpace


def leave_one_out(cs: ControlSpace, *, n_phase: int = 100) -> pd.DataFrame:
    """Blending error of the library: each entry inside the cell of the others of its gait,
    rebuilt from them.

    Removing an entry changes the tetrahedra around it only (its star), which the tetrahedra of
    its neighbours tile again (:func:`star_neighbours`, in the tangential and the frontal
    tetrahedra): each entry is located and weighed among those, so the cost grows with the
    entries, not their square.

    Both cycles are compared at ``n_phase`` equally spaced phases of their own period, channel by
    channel in the units they are stored in (the Fourier convention: root in the path frame,
    per-cycle drift apart). Columns: ``id``, ``class``, ``inside`` (False when the entry is on
    the hull of the others of its gait, or they have no cell), ``neighbours`` (ids), ``weights``;
    joint angles (:data:`mocaplib.skeleton.JOINT_ANGLES`, 28 DOFs): ``rms_deg`` (RMS over DOFs
    and phases), ``max_deg``, ``worst_dof``; root: ``heading_rms_deg`` (``pelvis_rotation``
    relative to the path frame), ``root_rms_mm`` (``pelvis_tx/ty/tz`` in the path frame, RMS
    over the three and the phases); drift over one cycle: ``stride_error_mm`` (distance
    between the blended and the entry's displacement per cycle), ``turn_error_deg`` (heading
    change per cycle, blended minus entry's; NaN without drift); ``T_error_s`` (blended minus
    entry's period).
    """
    if cs.a is None:
        raise MocapError("leave-one-out needs Fourier coefficients", path=cs.source)
    phase = np.arange(n_phase) / n_phase
    joint_names = np.asarray(DOF_NAMES)[JOINT_ANGLES]
    rows = []
    n = len(cs.points)
    stars = [star_neighbours(cs.tri.simplices, n)] + [
        star_neighbours(cell.frontal.simplices, n, cell.rows) for cell in cs.cells.values()
        if cell.frontal is not None]
    for i, keep in enumerate(functools.reduce(np.union1d, star) for star in zip(*stars)):
        row = {"id": cs.ids[i], "class": cs.classes[i], "inside": False, "neighbours": [],
               "weights": [], "rms_deg": np.nan, "max_deg": np.nan, "worst_dof": None,
               "heading_rms_deg": np.nan, "root_rms_mm": np.nan, "stride_error_mm": np.nan,
               "turn_error_deg": np.nan, "T_error_s": np.nan}
        try:
            others = ControlSpace(cs.points[keep], a=cs.a[keep], b=cs.b[keep], T=cs.T[keep],
                                  drift=None if cs.drift is None else cs.drift[keep],
                                  ids=[cs.ids[j] for j in keep],
                                  classes=[cs.classes[j] for j in keep],
                                  v_f=None if cs.v_f is None else cs.v_f[keep],
                                  axes=cs.variant, scale=cs.scale, source=cs.source)
        except LibraryError:
            rows.append(row)
            continue
        gait = class_gait(cs.classes[i])
        if gait not in others.cells:
            rows.append(row)
            continue
        res = others.query(cs.points[i], gait=gait)
        if res.inside[0] and not res.clamped[0]:
            bl = others.blend(res)
            err = (synthesize(bl.a[0], bl.b[0], 1.0, phase)
                   - synthesize(cs.a[i], cs.b[i], 1.0, phase))          # (n_phase, D) rad, m
            joints = np.degrees(err[:, JOINT_ANGLES])
            per_dof = np.sqrt(np.mean(joints ** 2, axis=0))
            row.update(inside=True, neighbours=[others.ids[j] for j in res.entries[0]],
                       weights=res.weights[0].tolist(),
                       rms_deg=float(np.sqrt(np.mean(joints ** 2))),
                       max_deg=float(np.abs(joints).max()),
                       worst_dof=str(joint_names[np.argmax(per_dof)]),
                       heading_rms_deg=float(np.degrees(np.sqrt(np.mean(
                           err[:, ROOT_HEADING] ** 2)))),
                       root_rms_mm=float(1000 * np.sqrt(np.mean(err[:, TRANSLATION] ** 2))),
                       T_error_s=float(bl.T[0] - cs.T[i]))
            if bl.drift is not None:
                xb, yb, turned_b = _cycle_displacement(bl.drift[0], bl.T[0])
                xi, yi, turned_i = _cycle_displacement(cs.drift[i], cs.T[i])
                row.update(stride_error_mm=float(1000 * np.hypot(xb - xi, yb - yi)),
                           turn_error_deg=float(np.degrees(turned_b - turned_i)))
        rows.append(row)
    return pd.DataFrame(rows)


def star_neighbours(simplices: np.ndarray, n_points: int, rows=None) -> list[np.ndarray]:
    """Per point of a triangulation with ``simplices`` (S, 4) of the points ``rows`` (default
    all ``n_points``), the row numbers (sorted) of the points whose tetrahedra tile its
    neighbourhood once it is removed: the vertices of the tetrahedra it belongs to, and the
    points of ``rows`` in no tetrahedron (duplicates of a vertex, which take its place when it
    is removed); none for a point not in ``rows``.

    The lifted points' heights do not depend on which points are triangulated
    (:func:`~mocaplib.library.triangulation.delaunay_tetrahedra`), so the tetrahedra of the
    points without ``i`` inside the star of ``i`` are exactly those of these neighbours.
    """
    rows = np.arange(n_points) if rows is None else np.asarray(rows)
    vertex = simplices.ravel()
    owner = np.repeat(np.arange(len(simplices)), simplices.shape[1])
    unused = np.setdiff1d(rows, vertex)
    by_vertex = np.argsort(vertex, kind="stable")
    starts = np.searchsorted(vertex[by_vertex], np.arange(n_points + 1))
    triangulated = np.zeros(n_points, bool)
    triangulated[rows] = True
    out = []
    for i in range(n_points):
        star = simplices[owner[by_vertex[starts[i]:starts[i + 1]]]].ravel()
        out.append(np.setdiff1d(np.union1d(star, unused), [i]) if len(star)
                   else np.setdiff1d(rows, [i]) if triangulated[i] else np.zeros(0, int))
    return out


def _cycle_displacement(drift: np.ndarray, T: float) -> tuple[float, float, float]:
    """Displacement (m, in the start frame) and heading change (rad) over one cycle of the path
    frame moving with drift velocities (u_f, u_l, ω) (:data:`~mocaplib.library.entry.DRIFT_VELOCITIES`) for ``T`` s."""
    x, y, turned = RootDrift(0.0, 0.0, 0.0, *(float(v) for v in drift)).frame(T)
    return float(x), float(y), float(turned)


