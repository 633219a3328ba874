"""The library's control space: Delaunay tetrahedra of the entries' velocities, blending, coverage.

Axes and normalisation
----------------------
Each entry is a point ``(v̂, ω̂, v̂_l)`` (m/s, rad/s, m/s; the paper's section III), or with
``axes="frontal"`` ``(v̂_f, ω̂, v̂_l)``. Points are stored in SI units; the triangulation, the
hull distances and the coverage distances use **normalised** coordinates ``x / scale`` with one
scale per axis (:data:`DEFAULT_SCALE`, or the ``control_space.scale`` stored in the library), so
that 1 normalised unit is "a lot" of each velocity: 1.5 m/s of walking speed, π/2 rad/s of
turning, 0.5 m/s of side-stepping. Queries are normalised the same way. Barycentric weights are
affine invariant, so they do not depend on the scales; which tetrahedra Delaunay chooses, the
distances and the coverage figures do.

Triangulation of degenerate (gridded) libraries
-----------------------------------------------
Libraries are often gridded: many entries share v̂_l = 0 or a speed, and four or more lie on a
common plane or sphere. Their Delaunay subdivision then has cells that are not tetrahedra
(a grid's cube cell has 8 cospherical corners), and Qhull's triangulated output (``Qt``, which
``scipy.spatial.Delaunay`` always uses) splits such cells into fans that include **zero-volume
tetrahedra** (34 of 178 on a grid of 4×5×3 points, cells 0.33×0.5×0.5). Joggling the input
(``QJ``) is worse here: the tetrahedra are flat only after the joggle is undone, and it gives
156 flat ones of 296 on the same grid. Dropping the flat ones leaves a non-conforming mesh
(100 interior faces of that grid had no neighbour), so blending would jump across faces.
:func:`delaunay_tetrahedra` instead lifts the normalised points onto the paraboloid ``|x|²`` plus a
tiny deterministic height per point (:data:`LIFT_PERTURBATION` times a hash of the point, so the
same entry gets the same height in every sub-library) and keeps the lower hull of the lifted points:
a *regular* triangulation that refines the Delaunay subdivision. Every tetrahedron is a Delaunay
tetrahedron of the original points, has positive volume, the mesh is conforming (each interior face
shared by exactly two tetrahedra) and the tetrahedra tile the convex hull exactly (142 on that grid,
smallest radius ratio 0.54). Thin tetrahedra that remain are genuine slivers of the point set, which
is what the sliver count reports: on the sample library, side-steps within ~1e-5 (normalised) of the
cone |v̂_l| = v̂ with spot turns on its edge, and 60°/120° diagonal walks that share v̂ and v̂_l
(:func:`close_entries` finds such pairs; the frontal axes separate them).

Blending (Truong et al. 2010, equations (4)-(6))
------------------------------------------------
A query point inside the hull lies in one tetrahedron; its barycentric weights ``w`` (four,
summing to 1, reproducing the point) blend the four entries' Fourier coefficients and periods:
``a_d = Σ w_i a_i``, ``b_d = Σ w_i b_i``, ``T_d = Σ w_i T_i`` (entries with fewer harmonics are
padded with zeros), and the joint angles are synthesised with the team's convention
``q(t) = a_0 + Σ_k a_k cos(2πkt/T_d) + b_k sin(2πkt/T_d)``, ``t ∈ [0, T_d)``.

Coverage
--------
A target :class:`Envelope` (the convex hull of a few points, SI units; by default the commanded
velocities of a capture plan) is sampled on a regular grid; :func:`coverage` reports the
fraction of those samples inside the library's hull, the largest hole (the sample farthest from
every entry), sliver tetrahedra, entries per class and a greedy farthest-point "capture next" list.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import ConvexHull, QhullError, cKDTree

from ..errors import LibraryError, MocapError
from ..gait.fourier import RootDrift, synthesize
from ..io.tomlfile import read_toml
from ..skeleton import DOF_NAMES, JOINT_ANGLES, ROOT_HEADING, TRANSLATION
from .entry import DRIFT_VELOCITIES

#: Axis names of the two control-space variants.
AXES = {"tangential": ("v", "omega", "v_l"), "frontal": ("v_f", "omega", "v_l")}
#: Units of each axis.
AXIS_UNITS = {"v": "m/s", "v_f": "m/s", "omega": "rad/s", "v_l": "m/s"}
#: Normalisation scale of each axis (normalised = SI / scale): brisk walking speed, a 90°/s
#: turn, a brisk side-step.
DEFAULT_SCALE = {"v": 1.5, "v_f": 1.5, "omega": np.pi / 2, "v_l": 0.5}
#: Tetrahedra whose radius ratio 3·r_in/R_circ (1 = regular, 0 = flat) is below this are slivers.
SLIVER_QUALITY = 0.1
#: Entries closer than this (normalised: 30 mm/s of v̂, 1.8°/s, 10 mm/s of v̂_l) are hard to tell
#: apart in the control space: blending between them switches motions over a tiny distance.
CLOSE_DISTANCE = 0.02
#: Height perturbation of the lifted points (relative to the lift's range) that breaks the ties
#: of cospherical entries; far above Qhull's round-off (~1e-14), far below any real difference.
LIFT_PERTURBATION = 1e-8
#: Largest ratio s3/s1 of the singular values of centred, normalised points that counts as
#: flat (on a plane or a line: no tetrahedra). Measured (12 points on a plane, 6 of them moved
#: off it by ±eps, 3 draws): the triangulation fails at s3/s1 ≈ 1e-12 and "succeeds" above,
#: but at 1e-6 its thinnest tetrahedra have radius ratios ≤ 1e-13, a slab no query falls into;
#: the chosen entries of the libraries at hand have s3/s1 ≥ 0.13 (17 real files; the 68 samples
#: 0.49). Values are stored with 10 significant digits, so points on a plane before rounding
#: stay below 1e-9 after it.
DEGENERACY_TOLERANCE = 1e-6
#: What to do about a degenerate control space (see :func:`degeneracy`).
DEGENERACY_HINT = ("add captures with other speeds, turns and side-steps so the entries span "
                   "all three axes")
def degeneracy(x) -> str | None:
    """Why finite normalised points x (E, 3) have no 3-D triangulation, or None when they have.

    The one rule of library validation and :class:`ControlSpace`: fewer than 4 distinct points
    (equal to 12 decimals, relative to the largest coordinate when it exceeds 1), or distinct
    points within a plane or a line (singular values of the centred points: s3 <=
    :data:`DEGENERACY_TOLERANCE` · s1). The reason completes "the control space is degenerate:
    it …": "needs at least 4 entries with distinct velocities, got 3" or "lies on a plane, so
    there are no tetrahedra".
    """
    x = np.asarray(x, dtype=float).reshape(-1, 3)
    size = max(float(np.abs(x).max(initial=0.0)), 1.0)
    distinct = np.unique(np.round(x / size, 12), axis=0)
    if len(distinct) < 4:
        return f"needs at least 4 entries with distinct velocities, got {len(distinct)}"
    centred = distinct - distinct.mean(axis=0)
    sv = np.linalg.svd(centred / np.abs(centred).max(), compute_uv=False)
    if sv[2] <= DEGENERACY_TOLERANCE * sv[0]:
        flat = "a line" if sv[1] <= DEGENERACY_TOLERANCE * sv[0] else "a plane"
        return f"lies on {flat}, so there are no tetrahedra"
    return None


def _stack_padded(arrays) -> np.ndarray:
    """Coefficient arrays of shapes (D, N_i+1) stacked into (E, D, max N_i + 1), zero-padded
    (a missing harmonic is a zero harmonic, so padding changes nothing)."""
    arrays = [np.asarray(x, dtype=float) for x in arrays]
    out = np.zeros((len(arrays), arrays[0].shape[0], max(x.shape[1] for x in arrays)))
    for i, x in enumerate(arrays):
        out[i, :, :x.shape[1]] = x
    return out


# --------------------------------------------------------------------------- geometry
def _closest_on_triangles(p: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray):
    """Closest point of each triangle (A, B, C each (H, 3)) to each point p (Q, 3).

    Returns the points (Q, H, 3) and their squared distances (Q, H): the projection onto the
    triangle's plane when it falls inside the triangle, else the closest point of its edges.
    """
    n = np.cross(B - A, C - A)                       # (H, 3)
    nn = np.einsum("hi,hi->h", n, n)
    d = p[:, None, :] - A[None]                      # (Q, H, 3)
    proj = p[:, None, :] - (np.einsum("qhi,hi->qh", d, n) / nn)[..., None] * n[None]
    # Barycentric sign tests of the projection: inside when all three edge tests agree with n.
    inside = np.ones(proj.shape[:2], bool)
    for U, V in ((A, B), (B, C), (C, A)):
        inside &= np.einsum("qhi,hi->qh", np.cross(V - U, proj - U[None]), n) >= 0
    best = proj.copy()
    best_d = np.where(inside, np.einsum("qhi,qhi->qh", p[:, None] - proj, p[:, None] - proj),
                      np.inf)
    for U, V in ((A, B), (B, C), (C, A)):
        e = V - U
        s = np.clip(np.einsum("qhi,hi->qh", p[:, None] - U[None], e)
                    / np.einsum("hi,hi->h", e, e), 0.0, 1.0)
        c = U[None] + s[..., None] * e[None]
        dd = np.einsum("qhi,qhi->qh", p[:, None] - c, p[:, None] - c)
        closer = (dd < best_d) & ~inside
        best[closer] = c[closer]
        best_d = np.where(closer, dd, best_d)
    return best, best_d


@dataclass(frozen=True)
class Triangulation:
    """Tetrahedra of a point set: ``points`` (E, 3), ``simplices`` (S, 4) and the boundary
    triangles ``convex_hull`` (H, 3), both as row numbers of ``points``."""

    points: np.ndarray
    simplices: np.ndarray
    convex_hull: np.ndarray


def _lift_heights(x: np.ndarray) -> np.ndarray:
    """A pseudo-random number in [0, 1) per point (E,), a hash of its coordinates (so a point
    gets the same one whatever the other points are)."""
    rows = np.ascontiguousarray(x, dtype=np.float64) + 0.0  # -0.0 hashes as 0.0
    return np.array([int.from_bytes(hashlib.blake2b(r.tobytes(), digest_size=8).digest(),
                                    "little") / 2.0 ** 64 for r in rows])


def _volumes(vertices: np.ndarray) -> np.ndarray:
    """Volumes (T,) of tetrahedra (T, 4, 3)."""
    p0, p1, p2, p3 = (vertices[:, i] for i in range(4))
    return np.abs(np.einsum("ti,ti->t", p1 - p0, np.cross(p2 - p0, p3 - p0))) / 6.0


def delaunay_tetrahedra(x: np.ndarray, *, source=None) -> Triangulation:
    """Delaunay tetrahedra of points x (E, 3) spanning 3-D, none flat, even for gridded points.

    The lower hull of the points lifted onto ``|x|²`` + :data:`LIFT_PERTURBATION` × a per-point
    hash (see the module docstring): a conforming triangulation refining the Delaunay
    subdivision, whose tetrahedra all have positive volume and tile the convex hull. Raises
    LibraryError if Qhull fails or the tetrahedra do not tile the hull.
    """
    x = np.asarray(x, dtype=float)
    c = x - x.mean(axis=0)
    c = c / np.abs(c).max()  # well-conditioned lift whatever the units
    lift = np.einsum("ij,ij->i", c, c)
    lift = lift + LIFT_PERTURBATION * max(float(np.ptp(lift)), 1.0) * _lift_heights(x)
    # One point high above the centroid (Qhull's "Qz") makes 4 entries enough; it is never on
    # the lower hull, so never in a tetrahedron.
    above = np.append(np.zeros(3), 2.0 * lift.max() + 1.0)
    try:
        lifted = ConvexHull(np.vstack([np.column_stack([c, lift]), above]))
        hull_volume = ConvexHull(x).volume
    except QhullError as exc:
        raise LibraryError(f"Delaunay triangulation failed: {exc}", path=source) from exc
    simplices = lifted.simplices[lifted.equations[:, 3] < 0]  # lower hull: facing down
    volume = _volumes(x[simplices])
    simplices = simplices[volume > 1e-12 * hull_volume]  # vertical facets of the silhouette
    covered = volume[volume > 1e-12 * hull_volume].sum()
    if not abs(covered - hull_volume) <= 1e-9 * hull_volume:
        raise LibraryError(f"the tetrahedra cover {covered / hull_volume:.9f} of the hull",
                           path=source, hint="report this library as a bug")
    faces = np.sort(simplices[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3),
                    axis=1)
    faces, count = np.unique(faces, axis=0, return_counts=True)
    return Triangulation(x, simplices, faces[count == 1])


def locate(tri: Triangulation, x: np.ndarray, *, tol: float = 1e-9, chunk: int = 256):
    """Enclosing simplex (Q,) (-1 outside) and barycentric weights (Q, 4) of points x (Q, 3).

    Plain numpy, closed-form 3x3 inverses (scipy's ``find_simplex`` calls LAPACK per simplex,
    which can stall for a second on a busy multi-threaded BLAS); brute force over simplices,
    fine for libraries of hundreds of entries. A point within ``tol`` of a face counts inside;
    the simplex with the largest smallest weight is chosen.
    """
    pts = tri.points[tri.simplices]                        # (S, 4, 3)
    a, b, c = (pts[:, i] - pts[:, 3] for i in range(3))
    rows = np.stack([np.cross(b, c), np.cross(c, a), np.cross(a, b)], axis=1)  # (S, 3, 3)
    det = np.einsum("si,si->s", a, rows[:, 0])             # 6 × signed volume, never 0
    inv = rows / det[:, None, None]                        # rows of the inverse of [a b c]
    origin = pts[:, 3]
    simplex = np.full(len(x), -1)
    weights = np.full((len(x), 4), np.nan)
    for lo in range(0, len(x), chunk):
        w3 = np.einsum("sij,qsj->qsi", inv, x[lo:lo + chunk, None, :] - origin[None])
        w = np.concatenate([w3, 1.0 - w3.sum(axis=2, keepdims=True)], axis=2)  # (q, S, 4)
        worst = w.min(axis=2)
        best = np.argmax(worst, axis=1)
        q = np.arange(len(best))
        hit = worst[q, best] >= -tol
        simplex[lo:lo + chunk] = np.where(hit, best, -1)
        weights[lo:lo + chunk][hit] = w[q[hit], best[hit]]
    return simplex, weights


def tetra_quality(vertices: np.ndarray) -> np.ndarray:
    """Radius ratio ``3 r_in / R_circ`` of tetrahedra (T, 4, 3): 1 regular, 0 degenerate."""
    p0, p1, p2, p3 = (vertices[:, i] for i in range(4))
    vol = _volumes(vertices)
    faces = ((p1, p2, p3), (p0, p2, p3), (p0, p1, p3), (p0, p1, p2))
    area = sum(np.linalg.norm(np.cross(b - a, c - a), axis=1) / 2 for a, b, c in faces)
    r_in = 3 * vol / np.where(area > 0, area, np.inf)
    # Circumcentre relative to p0 in closed form (stable for nearly flat tetrahedra).
    u, v, w = p1 - p0, p2 - p0, p3 - p0
    num = (np.einsum("ti,ti->t", u, u)[:, None] * np.cross(v, w)
           + np.einsum("ti,ti->t", v, v)[:, None] * np.cross(w, u)
           + np.einsum("ti,ti->t", w, w)[:, None] * np.cross(u, v))
    with np.errstate(divide="ignore", invalid="ignore"):
        R = np.linalg.norm(num, axis=1) / (12 * vol)
        q = np.where(vol > 0, 3 * r_in / R, 0.0)
    return np.clip(np.nan_to_num(q), 0.0, 1.0)


# --------------------------------------------------------------------------- results
@dataclass
class QueryResult:
    """Answer to :meth:`ControlSpace.query` for Q points.

    Attributes
    ----------
    points : (Q, 3) the query points, SI units.
    inside : (Q,) bool, True when the point is inside the hull of the entries.
    entries : (Q, 4) int, row numbers (in :attr:`ControlSpace.ids`) of the enclosing
        tetrahedron's entries; -1 when outside.
    weights : (Q, 4) barycentric weights (sum 1, reproduce the point); NaN when outside.
    nearest : (Q, 3) nearest point on the hull, SI units (the point itself when inside).
    distance : (Q,) normalised distance from the point to the hull (0 inside).
    """

    points: np.ndarray
    inside: np.ndarray
    entries: np.ndarray
    weights: np.ndarray
    nearest: np.ndarray
    distance: np.ndarray


@dataclass
class Blend:
    """Blended cycles (equation (5)): coefficients (Q, D, N+1), periods T (Q,) in seconds and,
    when the entries have one, the blended root drift velocities (Q, 3) (:data:`~mocaplib.library.entry.DRIFT_VELOCITIES`)."""

    a: np.ndarray
    b: np.ndarray
    T: np.ndarray
    drift: np.ndarray | None = None

    def synthesize(self, i: int = 0, *, rate: float = 100.0,
                   cycles: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Blend ``i`` sampled at ``rate`` Hz over ``cycles`` cycles: times (F,) s, angles (F, D).

        Root channels are in the path frame, as stored in the library (see :meth:`world`).
        """
        t = np.arange(int(np.ceil(cycles * self.T[i] * rate - 1e-9))) / rate
        return t, synthesize(self.a[i], self.b[i], self.T[i], t)

    def world(self, i: int = 0, *, rate: float = 100.0,
              cycles: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Like :meth:`synthesize` with the root moved into the world frame by the blended drift.

        The path frame starts at the origin facing +X and moves with the blended constant
        velocity and turn rate (:class:`mocaplib.gait.fourier.RootDrift`: a line or circular arc);
        ``pelvis_tx/ty`` and ``pelvis_rotation`` are composed with it. Without drift, the same
        as :meth:`synthesize` (the cycle stays in place).
        """
        t, q = self.synthesize(i, rate=rate, cycles=cycles)
        if self.drift is None:
            return t, q
        return t, RootDrift(0.0, 0.0, 0.0, *(float(v) for v in self.drift[i])).restore(q, t)


# --------------------------------------------------------------------------- control space
class ControlSpace:
    """Delaunay tetrahedralisation of library entries in the normalised control space.

    Parameters
    ----------
    points : (E, 3) entries' velocities on ``axes``, SI units.
    a, b : E Fourier coefficient arrays (D, N_i+1) (zero-padded to the largest N), or None.
    T : (E,) periods, s, or None.
    drift : (E, 3) root drift velocities (:data:`~mocaplib.library.entry.DRIFT_VELOCITIES`), or None.
    ids : E entry ids; classes : E locomotion classes (None when unknown).
    axes : "tangential" (v, ω, v_l) or "frontal" (v_f, ω, v_l).
    scale : (3,) normalisation scales, default :data:`DEFAULT_SCALE` for those axes.
    source : the library file, for error messages.

    Raises
    ------
    LibraryError
        Fewer than 4 distinct entries, or entries that span only a plane or a line.
    """

    def __init__(self, points, *, a=None, b=None, T=None, drift=None, ids=None, classes=None,
                 axes: str = "tangential", scale=None, source=None):
        if axes not in AXES:
            raise MocapError(f"unknown control-space axes {axes!r}; use one of {', '.join(AXES)}")
        self.variant = axes
        self.axes = AXES[axes]
        self.source = source
        self.points = np.asarray(points, dtype=float).reshape(-1, 3)
        n = len(self.points)
        self.ids = [str(i) for i in (ids if ids is not None else range(n))]
        self.classes = list(classes) if classes is not None else [None] * n
        self.scale = (np.array([DEFAULT_SCALE[k] for k in self.axes]) if scale is None
                      else np.asarray(scale, dtype=float))
        if not np.all(np.isfinite(self.points)):
            raise LibraryError("control-space points must be finite", path=source,
                               hint="drop entries without velocities before building")
        self.tri = self._triangulate()
        self.a = None if a is None else _stack_padded(a)
        self.b = None if b is None else _stack_padded(b)
        self.T = None if T is None else np.asarray(T, dtype=float)
        self.drift = None if drift is None else np.asarray(drift, dtype=float)

    @classmethod
    def from_library(cls, library, *, axes: str = "tangential", chosen_only: bool = True,
                     mirrored: bool = True, source=None) -> "ControlSpace":
        """Control space of a :class:`mocaplib.library.format.Library`.

        Uses the entries with finite velocities and period (only those marked ``chosen`` when
        ``chosen_only``; without the mirror images unless ``mirrored``), their Fourier
        coefficients and root drift, and the library's stored ``control_space.scale`` (for
        the frontal variant the same scales, v̂_f taking v̂'s). Blending takes phase 0 as the
        left toe-off: an entry whose cycle starts at another event (``cycle_start``) is
        expressed from its left toe-off (:func:`mocaplib.library.phase.from_left_toe_off`).
        """
        from .phase import from_left_toe_off

        entries = [from_left_toe_off(e) for e in library.entries]
        # (E, 4): the axes' velocities and the period, NaN where null
        values = np.array([[getattr(e, key) for key in (*AXES[axes], "T")] for e in entries],
                          dtype=np.float64).reshape(-1, 4)
        usable = ~np.isnan(values).any(axis=1)
        if chosen_only:
            usable &= np.array([e.chosen for e in entries], dtype=bool)
        if not mirrored:
            usable &= ~np.array([e.mirrored for e in entries], dtype=bool)
        a, b = library.coefficient_arrays()
        for i, (entry, stored) in enumerate(zip(entries, library.entries)):
            if entry is not stored:
                a[i], b[i] = entry.fourier.a, entry.fourier.b
        kept = [e for e, use in zip(entries, usable) if use]
        ids = [e.id for e in kept]
        drift = np.array([e.root_drift.velocities for e in kept],
                         dtype=np.float64).reshape(-1, 3)
        lacking = [i for i, row in zip(ids, drift) if not np.isfinite(row).all()]
        if lacking:  # blending without it would drop every entry's root motion
            raise LibraryError(f"entries without a finite root_drift "
                               f"{'/'.join(DRIFT_VELOCITIES)}: {', '.join(lacking[:5])}"
                               + (" …" if len(lacking) > 5 else ""), path=source,
                               hint="build the library again with mocaplib build (run "
                                    "`mocaplib validate` on it for every problem)")
        return cls(values[usable, :3], a=a[usable], b=b[usable], T=values[usable, 3],
                   drift=drift, ids=ids, classes=[e.locomotion_class for e in kept], axes=axes,
                   scale=library.control_scale, source=source)

    def normalise(self, x) -> np.ndarray:
        """SI points (…, 3) to normalised coordinates."""
        return np.asarray(x, dtype=float) / self.scale

    def _triangulate(self) -> Triangulation:
        x = self.normalise(self.points)
        reason = degeneracy(x)
        if reason:
            raise LibraryError(f"the control space of the entries' ({', '.join(self.axes)}) "
                               f"is degenerate: it {reason}", path=self.source,
                               hint=DEGENERACY_HINT)
        return delaunay_tetrahedra(x, source=self.source)

    # ----------------------------------------------------------------- queries
    @property
    def hull_facets(self) -> np.ndarray:
        """Triangles of the hull, (H, 3) row numbers of entries."""
        return self.tri.convex_hull

    def query(self, points) -> QueryResult:
        """Enclosing tetrahedra and barycentric weights (equation (4)) of points (Q, 3), SI."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        if p.ndim != 2 or p.shape[1] != 3:
            raise MocapError(f"query points must have shape (Q, 3), got {np.shape(points)}")
        x = self.normalise(p)
        simplex, w = locate(self.tri, x)
        inside = simplex >= 0
        entries = np.full((len(p), 4), -1)
        weights = np.full((len(p), 4), np.nan)
        if inside.any():
            w = np.clip(w[inside], 0.0, None)
            weights[inside] = w / w.sum(axis=1, keepdims=True)
            entries[inside] = self.tri.simplices[simplex[inside]]
        nearest = p.copy()
        distance = np.zeros(len(p))
        if (~inside).any():
            near_x, dist = self._nearest_on_hull(x[~inside])
            nearest[~inside] = near_x * self.scale
            distance[~inside] = dist
        return QueryResult(p, inside, entries, weights, nearest, distance)

    def _nearest_on_hull(self, x: np.ndarray, chunk: int = 1024):
        """Exact projection of normalised points (Q, 3) onto the hull's facets."""
        pts = self.tri.points
        A, B, C = (pts[self.hull_facets[:, i]] for i in range(3))
        near = np.empty_like(x)
        dist = np.empty(len(x))
        for lo in range(0, len(x), chunk):
            c, d = _closest_on_triangles(x[lo:lo + chunk], A, B, C)
            j = np.argmin(d, axis=1)
            rows = np.arange(len(j))
            near[lo:lo + chunk] = c[rows, j]
            dist[lo:lo + chunk] = np.sqrt(d[rows, j])
        return near, dist

    def contains(self, points) -> np.ndarray:
        """(Q,) bool: SI points (Q, 3) inside the hull."""
        return locate(self.tri, self.normalise(np.atleast_2d(points)))[0] >= 0

    # ----------------------------------------------------------------- blending
    def blend(self, result: QueryResult) -> Blend:
        """Weighted coefficients and periods (equation (5)) of every inside query."""
        if self.a is None or self.T is None:
            raise MocapError("this control space has no Fourier coefficients to blend",
                             path=self.source)
        if not result.inside.all():
            bad = np.flatnonzero(~result.inside)
            raise MocapError(
                f"{len(bad)} query point(s) are outside the control space, first "
                f"{tuple(np.round(result.points[bad[0]], 4))}", path=self.source,
                hint=f"the nearest point on the hull is "
                     f"{tuple(np.round(result.nearest[bad[0]], 4))}")
        e, w = result.entries, result.weights
        return Blend(np.einsum("qk,qkdn->qdn", w, self.a[e]),
                     np.einsum("qk,qkdn->qdn", w, self.b[e]),
                     np.einsum("qk,qk->q", w, self.T[e]),
                     None if self.drift is None else np.einsum("qk,qkj->qj", w, self.drift[e]))

    def tetra_quality(self) -> np.ndarray:
        """Radius ratio of every tetrahedron in normalised coordinates, shape (nsimplex,)."""
        return tetra_quality(self.tri.points[self.tri.simplices])


def close_entries(cs: ControlSpace, *, within: float = CLOSE_DISTANCE) -> pd.DataFrame:
    """Pairs of entries closer than ``within`` (normalised distance): columns ``a``, ``b`` (ids)
    and ``distance``, nearest first. E.g. 60° and 120° diagonal walks have the same v̂ and v̂_l,
    so they coincide on the tangential axes but not on the frontal ones."""
    x = cs.normalise(cs.points)
    pairs = np.array(sorted(cKDTree(x).query_pairs(within)), dtype=int).reshape(-1, 2)
    d = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    order = np.argsort(d, kind="stable")
    return pd.DataFrame({"a": [cs.ids[i] for i in pairs[order, 0]],
                         "b": [cs.ids[j] for j in pairs[order, 1]], "distance": d[order]})


# --------------------------------------------------------------------------- leave-one-out
def leave_one_out(cs: ControlSpace, *, n_phase: int = 100) -> pd.DataFrame:
    """Blending error of the library: each entry inside the hull of the others, rebuilt from them.

    Both cycles are compared at ``n_phase`` equally spaced phases of their own period, channel by
    channel in the units they are stored in (the Fourier convention: root in the path frame,
    per-cycle drift apart). Columns: ``id``, ``class``, ``inside`` (False when the entry is on
    the hull of the others, or the others are degenerate), ``neighbours`` (ids), ``weights``;
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
    for i in range(len(cs.points)):
        keep = np.arange(len(cs.points)) != i
        row = {"id": cs.ids[i], "class": cs.classes[i], "inside": False, "neighbours": [],
               "weights": [], "rms_deg": np.nan, "max_deg": np.nan, "worst_dof": None,
               "heading_rms_deg": np.nan, "root_rms_mm": np.nan, "stride_error_mm": np.nan,
               "turn_error_deg": np.nan, "T_error_s": np.nan}
        try:
            others = ControlSpace(cs.points[keep], a=cs.a[keep], b=cs.b[keep], T=cs.T[keep],
                                  drift=None if cs.drift is None else cs.drift[keep],
                                  ids=[cs.ids[j] for j in np.flatnonzero(keep)],
                                  axes=cs.variant, scale=cs.scale, source=cs.source)
        except LibraryError:
            rows.append(row)
            continue
        res = others.query(cs.points[i])
        if res.inside[0]:
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


def _cycle_displacement(drift: np.ndarray, T: float) -> tuple[float, float, float]:
    """Displacement (m, in the start frame) and heading change (rad) over one cycle of the path
    frame moving with drift velocities (u_f, u_l, ω) (:data:`~mocaplib.library.entry.DRIFT_VELOCITIES`) for ``T`` s."""
    x, y, turned = RootDrift(0.0, 0.0, 0.0, *(float(v) for v in drift)).frame(T)
    return float(x), float(y), float(turned)


# --------------------------------------------------------------------------- coverage
@dataclass
class Envelope:
    """The target region of the control space: convex hull of ``vertices`` (P, 3), SI units.

    Build one with :meth:`box`, :meth:`from_toml` or :meth:`from_commands`.
    """

    vertices: np.ndarray
    axes: tuple[str, str, str] = AXES["tangential"]
    source: str = "explicit"

    @classmethod
    def box(cls, ranges: dict[str, tuple[float, float]], *, source: str = "box") -> "Envelope":
        """Axis-aligned box, e.g. ``{"v": (0, 1.8), "omega": (-1.5, 1.5), "v_l": (-.5, .5)}``."""
        axes = AXES["frontal"] if "v_f" in ranges else AXES["tangential"]
        missing = [k for k in axes if k not in ranges]
        if missing:
            raise MocapError(f"envelope box needs ranges for {', '.join(missing)}", path=source)
        lo = np.array([min(ranges[k]) for k in axes], float)
        hi = np.array([max(ranges[k]) for k in axes], float)
        corners = np.array([[(lo, hi)[(c >> i) & 1][i] for i in range(3)] for c in range(8)])
        return cls(corners, axes, source)

    @classmethod
    def from_commands(cls, commands: pd.DataFrame, *, source: str = "commands") -> "Envelope":
        """Hull of commanded velocities: a DataFrame with columns v_f, omega, v_l (SI)."""
        v = np.hypot(commands["v_f"].to_numpy(float), commands["v_l"].to_numpy(float))
        pts = np.column_stack([v, commands["omega"].to_numpy(float),
                               commands["v_l"].to_numpy(float)])
        return cls(pts, AXES["tangential"], source)

    @classmethod
    def from_toml(cls, path) -> "Envelope":
        """Read an ``[envelope]`` table: either ``points = [[v, omega, v_l], ...]`` (optionally
        ``axes = ["v_f", "omega", "v_l"]``) or one ``[lo, hi]`` range per axis name. Values
        must be finite numbers (:class:`MocapError` naming the file and key otherwise)."""
        path = Path(path)
        table = read_toml(path, what="envelope file",
                          hint="give a TOML file with an [envelope] table").get("envelope")
        if not isinstance(table, dict):
            raise MocapError("no [envelope] table", path=path,
                             hint="add [envelope] with v/omega/v_l ranges or points")
        try:
            if "points" in table:
                axes = tuple(table.get("axes", AXES["tangential"]))
                if axes not in AXES.values():
                    raise ValueError(f"axes must be one of {list(AXES.values())}")
                pts = _finite_numbers("points", table["points"], "triples of finite numbers")
                if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4:
                    raise ValueError("points must be at least 4 triples")
                return cls(pts, axes, str(path))
            ranges = {}
            for k, v in table.items():
                if k in AXIS_UNITS:
                    ranges[k] = tuple(_finite_numbers(k, v, "[lo, hi], two finite numbers"))
                    if len(ranges[k]) != 2:
                        raise ValueError(f"{k} must be [lo, hi], two finite numbers, got {v!r}")
            return cls.box(ranges, source=str(path))
        except (ValueError, TypeError) as exc:
            raise MocapError(f"bad [envelope] table: {exc}", path=path,
                             hint="ranges are [lo, hi] in m/s or rad/s") from exc

    def sample(self, scale: np.ndarray, *, n: int = 25) -> np.ndarray:
        """Regular grid of about n³ points over the bounding box, the points inside the hull
        (S, 3). An axis whose range straddles 0 is gridded through 0 (steps of
        (hi - lo)/(n - 1) from 0; with odd n on a symmetric range that is linspace), so straight
        walks, no turning and no side-step are sampled exactly, not ± half a step away."""
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        axes = [_grid_through_zero(a, b, n) for a, b in zip(lo, hi)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        x = self.vertices / scale
        if degeneracy(x) is not None:
            return grid  # a flat envelope: its bounding box is the envelope
        inside = locate(delaunay_tetrahedra(x, source=self.source), grid / scale)[0] >= 0
        return grid[inside]


def _finite_numbers(key: str, value, expected: str) -> np.ndarray:
    """``value`` (a list of numbers, or of lists of numbers, from a TOML file) as a float
    array; ValueError naming ``key`` and what was ``expected`` for text, booleans, NaN or
    infinity."""
    def bad(x) -> bool:
        if isinstance(x, list):
            return any(bad(y) for y in x)
        return isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x)
    if not isinstance(value, list) or bad(value):
        raise ValueError(f"{key} must be {expected}, got {repr(value)[:80]}")
    return np.asarray(value, dtype=float)


def _grid_through_zero(lo: float, hi: float, n: int) -> np.ndarray:
    """n (about) evenly spaced values over [lo, hi]; through 0 when lo < 0 < hi."""
    if not hi > lo:
        return np.array([lo])
    if not lo < 0.0 < hi:
        return np.linspace(lo, hi, n)
    step = (hi - lo) / (n - 1)
    k = np.arange(np.ceil(lo / step - 1e-9), np.floor(hi / step + 1e-9) + 1)
    return np.clip(k * step, lo, hi)


@dataclass
class Coverage:
    """Coverage of an :class:`Envelope` by a :class:`ControlSpace` (distances normalised).

    Attributes
    ----------
    fraction_inside : share of envelope samples inside the hull of the entries.
    n_samples : number of envelope samples.
    largest_hole : (3,) the envelope sample farthest from every entry, SI.
    largest_hole_distance : its normalised distance to the nearest entry.
    slivers : DataFrame of tetrahedra with quality < threshold: ``entries`` (ids), ``quality``.
    entries_per_class : counts of entries by locomotion class ("unknown" when None).
    capture_next : DataFrame of suggested velocity triples (axes columns, SI) and the
        normalised ``gap`` each one fills (greedy farthest point).
    axes : the control-space axes of every triple above.
    samples : (S, 3) the envelope samples, SI; samples_inside : (S,) bool, inside the hull.
    """

    fraction_inside: float
    n_samples: int
    largest_hole: np.ndarray
    largest_hole_distance: float
    slivers: pd.DataFrame
    entries_per_class: dict[str, int]
    capture_next: pd.DataFrame
    axes: tuple[str, str, str] = AXES["tangential"]
    samples_inside: np.ndarray = field(default=None, repr=False)
    samples: np.ndarray = field(default=None, repr=False)


def coverage(cs: ControlSpace, envelope: Envelope, *, n_grid: int = 25, n_next: int = 5,
             sliver_quality: float = SLIVER_QUALITY) -> Coverage:
    """How well the entries cover ``envelope`` (see :class:`Coverage`).

    Samples equally far from the entries (mirror images on a symmetric library) are told
    apart by their distance to the envelope's centre, nearest first, so ties do not fall to
    whichever side the grid lists first."""
    if tuple(envelope.axes) != tuple(cs.axes):
        raise MocapError(f"envelope axes {envelope.axes} differ from the control space's "
                         f"{cs.axes}", path=envelope.source)
    samples = envelope.sample(cs.scale, n=n_grid)
    inside = cs.contains(samples)
    xs = cs.normalise(samples)
    dist, _ = cKDTree(cs.normalise(cs.points)).query(xs)
    centre = cs.normalise(envelope.vertices).mean(axis=0)
    off_centre = np.linalg.norm(xs - centre, axis=1)
    hole = _farthest(dist, off_centre)
    picks, gaps = [], []
    d = dist.copy()
    for _ in range(min(n_next, len(xs))):
        j = _farthest(d, off_centre)
        if d[j] <= 0:
            break
        picks.append(samples[j])
        gaps.append(d[j])
        d = np.minimum(d, np.linalg.norm(xs - xs[j], axis=1))
    nxt = pd.DataFrame(np.reshape(picks, (-1, 3)), columns=list(cs.axes))
    nxt["gap"] = gaps
    quality = cs.tetra_quality()
    bad = np.flatnonzero(quality < sliver_quality)
    slivers = pd.DataFrame({"entries": [[cs.ids[k] for k in cs.tri.simplices[s]] for s in bad],
                            "quality": quality[bad]})
    classes = pd.Series([c if c is not None and c == c else "unknown" for c in cs.classes])
    return Coverage(fraction_inside=float(inside.mean()) if len(inside) else float("nan"),
                    n_samples=len(samples), largest_hole=samples[hole],
                    largest_hole_distance=float(dist[hole]), slivers=slivers,
                    entries_per_class={str(k): int(v) for k, v in
                                       classes.value_counts().sort_index().items()},
                    capture_next=nxt, axes=cs.axes, samples_inside=inside, samples=samples)


def _farthest(distance: np.ndarray, off_centre: np.ndarray, *, tol: float = 1e-9) -> int:
    """Index of the largest ``distance``; among ties (within ``tol``) the smallest
    ``off_centre``, then the first."""
    ties = np.flatnonzero(distance >= distance.max() - tol)
    return int(ties[np.argmin(off_centre[ties])])
