"""The cells a command is blended in: one Delaunay triangulation per gait, the side-step cone
as part of the walk cell, and the answer for a command on a cell's boundary or between cells.

Gaits
-----
An entry's gait comes from its locomotion class (:func:`mocaplib.gait.gaits.class_gait`,
measured from the motion: ``running`` is a run, every other class a walk). Each gait with at
least four entries spanning 3-D has its own cell: the tetrahedra of its entries only
(:func:`~mocaplib.library.triangulation.delaunay_tetrahedra`), so a blend never mixes a walk
with a run. A gait whose entries span no 3-D cell (e.g. runs on one line) cannot be blended.

The tangential axes: forward and the side-step cone
---------------------------------------------------
On the tangential axes (v̂, ω̂, v̂_l) a command's frontal speed is ``v̂_f = +sqrt(v̂² − v̂_l²)``:
the command moves forward or sideways. An entry that moves backwards (its direction
``atan2(v̂_l, v̂_f)`` more than :data:`SIDEWAYS_TOLERANCE` beyond ±90°) has the same (v̂, v̂_l)
as its forward mirror about the sideways direction, so it stays out of the tangential cells
(the frontal axes blend it). Every motion has ``|v̂_l| ≤ v̂``: the cone ``|v̂_l| = v̂`` of pure
side-steps bounds the control space, and measured side-steps lie a hair inside it (their
direction within 0.3° of 90° on the samples). An entry or a command whose direction is within
:data:`SIDEWAYS_TOLERANCE` of ±90° is put on the cone (``v̂_l = ±v̂``, :func:`onto_cone`): the
cone is then a facet of the walk cell, triangulated by the side-stepping entries on it
(the faces of a Delaunay triangulation on a hull facet are the 2-D Delaunay triangles of its
points), and a side-step command is blended from its side-stepping neighbours.

Blending weights on the frontal axes
------------------------------------
Near the cone a command's frontal speed ``v̂_f = sqrt(v̂² − v̂_l²)`` is far from linear in
(v̂, v̂_l), so weights barycentric in (v̂, ω̂, v̂_l) reproduce v̂ and v̂_l but not v̂_f: the blend
walks more sideways and slower than asked (``0.4 0 0.39``: 84.4° from facing, where it asks
77.2°). The tangential cells say whether and by which gait a command is served; its weights
are then its barycentric coordinates in the **frontal tetrahedra** of that gait
(``Cell.frontal``: the Delaunay tetrahedra of the cell's entries at (v̂_f, ω̂, v̂_l),
:func:`to_frontal`, the side-steps on the cone at v̂_f = 0), which reproduce the command's
v̂_f, ω̂ and v̂_l exactly. A served point whose frontal point lies outside the frontal
tetrahedra (near a cell's boundary, where the frontal point of a tangential face bulges
beyond the frontal hull) is blended at the nearest point of their boundary, which keeps the
weights continuous. A cell whose entries span no 3-D on the frontal axes (e.g. side-steps and
spot turns only, all at v̂_f = 0) blends at its tangential weights.

Boundary and gaps
-----------------
A command within :data:`HULL_TOLERANCE` (normalised distance) of a cell is inside it, blended
at its nearest point on the cell. A command farther from every cell but inside the hull of all
the entries (within :data:`HULL_TOLERANCE` of its facets' planes:
:func:`~mocaplib.library.triangulation.outside_planes`; between the walks and the runs) is
served by the nearest cell, at its nearest point on it (``clamped``); outside the hull it is
outside the control space.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from ..gait.gaits import BLEND_GAITS, class_gait
from .triangulation import (Triangulation, closest_on_triangles, degeneracy,
                            delaunay_tetrahedra, locate)

#: Largest angle (rad) between a direction and ±90° from facing that counts as a pure
#: side-step (2°; measured side-steps of the samples: within 0.3°); and the angle beyond ±90°
#: from which an entry moves backwards.
SIDEWAYS_TOLERANCE = np.radians(2.0)
#: A command within this normalised distance of a cell is inside it (stored values have 10
#: significant digits; a point rounded onto a facet is ~1e-10 off it).
HULL_TOLERANCE = 1e-6
#: Barycentric tolerance of locating a command.
WEIGHT_TOLERANCE = 1e-9
#: Barycentric tolerance of locating a point projected onto a cell's boundary.
BOUNDARY_TOLERANCE = 1e-7


def onto_cone(points, /) -> np.ndarray:
    """Tangential points (N, 3) (v̂ m/s, ω̂ rad/s, v̂_l m/s) with the side-steps on the cone:
    ``v̂_l = ±v̂`` where ``v̂ > 0`` and the direction is within :data:`SIDEWAYS_TOLERANCE` of
    ±90° (``cos(tol)·v̂ ≤ |v̂_l| ≤ v̂``, 1e-9 relative of slack); other points unchanged."""
    p = np.array(points, dtype=float).reshape(-1, 3)
    v, lateral = p[:, 0], np.abs(p[:, 2])
    side = (v > 0) & (lateral >= np.cos(SIDEWAYS_TOLERANCE) * v) & (lateral <= v * (1 + 1e-9))
    p[side, 2] = np.sign(p[side, 2]) * v[side]
    return p


def to_frontal(points, /) -> np.ndarray:
    """Tangential points (N, 3) (v̂ m/s, ω̂ rad/s, v̂_l m/s) on the frontal axes (v̂_f, ω̂,
    v̂_l), where ``v̂_f = +sqrt(max(v̂² − v̂_l², 0))``: the command moves forward or sideways.
    Give SI values, not normalised ones: a point on the cone (``|v̂_l| = v̂``) rescaled may
    be an ulp off it, which the square root turns into ~1e-8."""
    p = np.array(points, dtype=float).reshape(-1, 3)
    p[:, 0] = np.sqrt(np.clip(p[:, 0] ** 2 - p[:, 2] ** 2, 0.0, None))
    return p


def backwards(v, v_f, /) -> np.ndarray:
    """(N,) bool: entries of speed ``v`` (N,) and frontal speed ``v_f`` (N,) m/s moving more
    than :data:`SIDEWAYS_TOLERANCE` beyond ±90° from facing (``v̂_f < −v̂·sin(tol)``)."""
    return np.asarray(v_f, dtype=float) < -np.sin(SIDEWAYS_TOLERANCE) * np.asarray(v, dtype=float)


@dataclass(frozen=True)
class Cell:
    """One gait's tetrahedra: ``gait``, ``rows`` (its entries, rows of the control space's
    points), ``tri`` (points: all the control space's normalised points (E, 3); simplices
    and hull triangles as rows of them, of this cell's entries only) and ``frontal`` (the
    same for the Delaunay tetrahedra of its entries on the frontal axes, where blending
    weights are computed; None on the frontal axes, whose cells are frontal already, or when
    its entries span no 3-D there; module docstring)."""

    gait: str
    rows: np.ndarray
    tri: Triangulation
    frontal: Triangulation | None = None


def gait_cells(x, gaits, usable, /, *, source=None, whole: Triangulation | None = None,
               frontal=None) -> tuple[dict[str, Cell], dict[str, str]]:
    """The cells of normalised points x (E, 3) by gait (E,) among the ``usable`` (E,) ones,
    and why each gait without a cell has none (the reason completes "its entries …").
    ``whole``: the Delaunay triangulation of all of x, if made already: the cell of a gait
    that has every point is that one. ``frontal``: the points on the frontal axes,
    normalised (E, 3), whose tetrahedra give each cell's :attr:`Cell.frontal`, or None."""
    x = np.asarray(x, dtype=float)
    gaits = np.asarray(gaits)
    cells, missing = {}, {}
    for gait in BLEND_GAITS:
        rows = np.flatnonzero((gaits == gait) & usable)
        if not len(rows):
            continue
        every = whole is not None and len(rows) == len(x)     # triangulated already
        reason = None if every else degeneracy(x[rows])
        if reason:
            missing[gait] = reason
            continue
        tri = whole if every else _rows_triangulation(x, rows, source)
        blend = (None if frontal is None or degeneracy(frontal[rows])
                 else _rows_triangulation(np.asarray(frontal, dtype=float), rows, source))
        cells[gait] = Cell(gait, rows, tri, blend)
    return cells, missing


def _rows_triangulation(x: np.ndarray, rows: np.ndarray, source) -> Triangulation:
    """The Delaunay tetrahedra of the points x[rows] (x (E, 3) normalised), as rows of x."""
    tri = delaunay_tetrahedra(x[rows], source=source)
    return Triangulation(x, rows[tri.simplices], rows[tri.convex_hull])


def build_cells(points, scale, /, *, classes=None, v_f=None, tangential: bool = True,
                source=None, whole: Triangulation | None = None
                ) -> tuple[dict[str, Cell], dict[str, str]]:
    """The cells of entries at SI ``points`` (E, 3) on the tangential (or frontal) axes,
    normalised by ``scale`` (3,), of locomotion ``classes`` (E,) (None: all walks) and frontal
    speeds ``v_f`` (E,) m/s (None or NaN: not backwards); on the tangential axes side-steps
    are put on the cone, backward entries left out and each cell given its frontal
    tetrahedra (module docstring). Returns the cells by gait and, per gait without one, why
    (:func:`gait_cells`). ``whole``: the Delaunay triangulation of all the points normalised,
    if made already (used where no point is put on the cone)."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    scale = np.asarray(scale, dtype=float)
    gaits = [class_gait(c) for c in (classes if classes is not None else [None] * len(p))]
    usable = np.ones(len(p), bool)
    frontal = None
    if tangential:
        if v_f is not None:
            usable &= ~backwards(p[:, 0], v_f)
        coned = onto_cone(p)
        whole = whole if np.array_equal(coned, p) else None
        p = coned
        frontal = to_frontal(p) / scale
    return gait_cells(p / scale, gaits, usable, source=source, whole=whole, frontal=frontal)


def union(cells, /) -> Triangulation:
    """The tetrahedra of several cells (sharing their points) as one triangulation. The same
    cells give the same object (the last :data:`_UNIONS`' ``maxlen`` are kept), so its
    locating grid (:attr:`Triangulation.grid`) is built once, not at every query."""
    cells = tuple(cells)
    for held, tri in _UNIONS:
        if len(held) == len(cells) and all(a is b for a, b in zip(held, cells)):
            return tri
    tri = Triangulation(cells[0].tri.points,
                        np.concatenate([c.tri.simplices for c in cells]).reshape(-1, 4),
                        np.concatenate([c.tri.convex_hull for c in cells]).reshape(-1, 3))
    _UNIONS.appendleft((cells, tri))
    return tri


#: The last unions made, with their cells (:func:`union`).
_UNIONS: deque = deque(maxlen=4)


def cell_tetrahedra(cells, /) -> tuple[np.ndarray, list[str]]:
    """The tetrahedra of ``cells`` (a dict by gait, in :data:`BLEND_GAITS` order) as rows of
    their points (S, 4), walks first, and the gait of each (S,): what the library file stores
    and the report's viewer locates a command in."""
    cells = list(cells.values())
    return union(cells).simplices, [c.gait for c in cells for _ in c.tri.simplices]


def frontal_tetrahedra(cells, /) -> tuple[np.ndarray, list[str]]:
    """The frontal tetrahedra (:attr:`Cell.frontal`) of ``cells`` (a dict by gait) that have
    them, as rows of their points (S, 4), walks first, and the gait of each (S,): where the
    library file's readers and the report's viewer compute a served command's weights."""
    have = [c for c in cells.values() if c.frontal is not None]
    simplices = [c.frontal.simplices for c in have]
    return (np.concatenate(simplices).reshape(-1, 4) if have else np.zeros((0, 4), int),
            [c.gait for c in have for _ in c.frontal.simplices])


def nearest_on_hull(tri: Triangulation, x, /, *, chunk: int = 1024):
    """Nearest points (Q, 3) on the boundary triangles of ``tri`` to normalised points x
    (Q, 3), and their distances (Q,)."""
    pts = tri.points
    A, B, C = (pts[tri.convex_hull[:, i]] for i in range(3))
    near = np.empty_like(x)
    dist = np.empty(len(x))
    for lo in range(0, len(x), chunk):
        c, d = closest_on_triangles(x[lo:lo + chunk], A, B, C)
        j = np.argmin(d, axis=1)
        rows = np.arange(len(j))
        near[lo:lo + chunk] = c[rows, j]
        dist[lo:lo + chunk] = np.sqrt(d[rows, j])
    return near, dist


@dataclass
class Served:
    """Where normalised commands (Q, 3) are blended: ``point`` (Q, 3) normalised (the command,
    or its nearest point on the serving cell), ``simplex`` (Q, 4) rows of entries (-1 when
    outside every cell's reach), ``weights`` (Q, 4), ``gait`` (Q,) the serving (or nearest)
    cell's gait, ``distance`` (Q,) normalised from the command to ``point``, ``clamped`` (Q,)
    served at a point farther than :data:`HULL_TOLERANCE` from it."""

    point: np.ndarray
    simplex: np.ndarray
    weights: np.ndarray
    gait: np.ndarray
    distance: np.ndarray
    clamped: np.ndarray


def serve(cells: dict[str, Cell], x, in_hull, /) -> Served:
    """Blend points of normalised commands x (Q, 3) in ``cells``: located in a cell's
    tetrahedra (the one whose smallest weight is largest, over all the cells), else at the
    nearest point of the nearest cell when within :data:`HULL_TOLERANCE` or when ``in_hull``
    (Q,) bool (between cells); else unserved (module docstring)."""
    x = np.asarray(x, dtype=float).reshape(-1, 3)
    cells = list(cells.values())
    gait_of_row = {int(r): c.gait for c in cells for r in c.rows}
    simplex, w = locate(union(cells), x, tol=WEIGHT_TOLERANCE)
    q = len(x)
    out = Served(x.copy(), np.full((q, 4), -1), np.full((q, 4), np.nan),
                 np.full(q, None, dtype=object), np.zeros(q), np.zeros(q, bool))
    found = simplex >= 0
    tets = union(cells).simplices
    out.simplex[found] = tets[simplex[found]]
    out.weights[found] = w[found]
    out.gait[found] = [gait_of_row[int(s[0])] for s in out.simplex[found]]
    rest = np.flatnonzero(~found)
    if not len(rest):
        return out
    nearest = [nearest_on_hull(c.tri, x[rest]) for c in cells]
    best = np.argmin(np.stack([d for _, d in nearest]), axis=0)
    for k, cell in enumerate(cells):
        mine = rest[best == k]
        point, dist = (a[best == k] for a in nearest[k])
        out.point[mine], out.distance[mine], out.gait[mine] = point, dist, cell.gait
        take = (dist <= HULL_TOLERANCE) | np.asarray(in_hull)[mine]
        s, w = locate(cell.tri, point[take], tol=BOUNDARY_TOLERANCE)
        ok = s >= 0
        where = mine[take][ok]
        out.simplex[where] = cell.tri.simplices[s[ok]]
        out.weights[where] = w[ok]
        out.clamped[where] = dist[take][ok] > HULL_TOLERANCE
    return out


def weigh_on_frontal_axes(cells: dict[str, Cell], served: Served, frontal, /) -> Served:
    """``served`` (:func:`serve`, tangential cells) with each served point's entries and
    weights taken from its gait's frontal tetrahedra (module docstring): the barycentric
    coordinates there of its point on the frontal axes (``frontal`` (Q, 3), normalised:
    :func:`to_frontal` of the SI point served, / the scales), or of their boundary's nearest
    point when it lies outside them; cells without frontal tetrahedra keep the tangential
    weights. Changes ``served`` in place and returns it."""
    for cell in cells.values():
        if cell.frontal is None:
            continue
        mine = np.flatnonzero((served.simplex[:, 0] >= 0) & (served.gait == cell.gait))
        if not len(mine):
            continue
        f = np.asarray(frontal, dtype=float)[mine]
        simplex, w = locate(cell.frontal, f, tol=WEIGHT_TOLERANCE)
        beyond = simplex < 0
        if beyond.any():
            near, _ = nearest_on_hull(cell.frontal, f[beyond])
            simplex[beyond], w[beyond] = locate(cell.frontal, near, tol=BOUNDARY_TOLERANCE)
        found = simplex >= 0
        served.simplex[mine[found]] = cell.frontal.simplices[simplex[found]]
        served.weights[mine[found]] = w[found]
    return served
