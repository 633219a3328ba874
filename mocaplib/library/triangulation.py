"""The Delaunay tetrahedra of the control space's points, and locating a query in them: which
tetrahedron holds a point and its barycentric weights (:func:`locate`), the points nearest on
the hull's faces, each tetrahedron's quality, and whether the points span three dimensions
(:func:`degeneracy`).

Points are ``(N, 3)`` arrays in the control space's normalised units.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..errors import LibraryError

#: Height perturbation of the lifted points (normalised units squared) that breaks the ties of
#: cospherical entries; far above Qhull's round-off (~1e-14), far below any real difference.
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
    distinct = unique_rows(np.round(x / size, 12) + 0.0)        # + 0.0: -0.0 is 0.0
    if len(distinct) < 4:
        return f"needs at least 4 entries with distinct velocities, got {len(distinct)}"
    centred = distinct - distinct.mean(axis=0)
    sv = np.linalg.svd(centred / np.abs(centred).max(), compute_uv=False)
    if sv[2] <= DEGENERACY_TOLERANCE * sv[0]:
        flat = "a line" if sv[1] <= DEGENERACY_TOLERANCE * sv[0] else "a plane"
        return f"lies on {flat}, so there are no tetrahedra"
    return None


def unique_rows(x: np.ndarray) -> np.ndarray:
    """The distinct rows of x (E, K), sorted as ``np.unique(x, axis=0)`` gives them (a sort of
    the columns, last first: for a few dozen rows ten times faster than its byte view)."""
    if not len(x):
        return x
    x = x[np.lexsort(x.T[::-1])]
    return x[np.r_[True, np.any(x[1:] != x[:-1], axis=1)]]


def cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Cross products of vectors u, v (..., 3): ``np.cross`` without its axis handling, which
    costs more than the products on the small arrays of a leave-one-out star."""
    return np.stack([u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1],
                     u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
                     u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]], axis=-1)


def stack_padded(arrays) -> np.ndarray:
    """Coefficient arrays of shapes (D, N_i+1) stacked into (E, D, max N_i + 1), zero-padded
    (a missing harmonic is a zero harmonic, so padding changes nothing)."""
    if isinstance(arrays, np.ndarray) and arrays.ndim == 3:        # stacked already
        return arrays.astype(float)
    arrays = [np.asarray(x, dtype=float) for x in arrays]
    out = np.zeros((len(arrays), arrays[0].shape[0], max(x.shape[1] for x in arrays)))
    for i, x in enumerate(arrays):
        out[i, :, :x.shape[1]] = x
    return out


# --------------------------------------------------------------------------- geometry
def closest_on_triangles(p: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray):
    """Closest point of each triangle (A, B, C each (H, 3)) to each point p (Q, 3).

    Returns the points (Q, H, 3) and their squared distances (Q, H): the projection onto the
    triangle's plane when it falls inside the triangle, else the closest point of its edges.
    """
    n = cross(B - A, C - A)                       # (H, 3)
    nn = np.einsum("hi,hi->h", n, n)
    d = p[:, None, :] - A[None]                      # (Q, H, 3)
    proj = p[:, None, :] - (np.einsum("qhi,hi->qh", d, n) / nn)[..., None] * n[None]
    # Barycentric sign tests of the projection: inside when all three edge tests agree with n.
    inside = np.ones(proj.shape[:2], bool)
    for U, V in ((A, B), (B, C), (C, A)):
        inside &= np.einsum("qhi,hi->qh", cross(V - U, proj - U[None]), n) >= 0
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

    @cached_property
    def barycentric(self) -> tuple[np.ndarray, np.ndarray]:
        """Per tetrahedron the rows of the inverse of [v0-v3, v1-v3, v2-v3] (S, 3, 3) and v3
        (S, 3): the first three barycentric weights of x are ``inverse @ (x - v3)``.
        Closed-form 3x3 inverses (scipy's ``find_simplex`` calls LAPACK per simplex, which
        can stall for a second on a busy multi-threaded BLAS)."""
        pts = self.points[self.simplices]                      # (S, 4, 3)
        a, b, c = (pts[:, i] - pts[:, 3] for i in range(3))
        rows = np.stack([cross(b, c), cross(c, a), cross(a, b)], axis=1)
        det = np.einsum("si,si->s", a, rows[:, 0])             # 6 × signed volume, never 0
        return rows / det[:, None, None], pts[:, 3]

    @cached_property
    def grid(self) -> "TetraGrid":
        """The :class:`TetraGrid` :func:`locate` searches (built on first use)."""
        return TetraGrid.of(self.points[self.simplices])


#: Barycentric tolerance of :func:`locate`: a point within it of a face counts inside.
LOCATE_TOLERANCE = 1e-9
#: Largest tolerance :class:`TetraGrid`'s cells hold the tetrahedra for (the tolerances used:
#: 1e-9 and 1e-7); :func:`locate` tests every tetrahedron for a larger one.
GRID_TOLERANCE = 1e-6
#: Up to this many tetrahedra :func:`locate` tests every one (a leave-one-out star, an
#: envelope); beyond, those of the point's cell of the :class:`TetraGrid`.
FEW_TETRAHEDRA = 256


@dataclass(frozen=True)
class TetraGrid:
    """A uniform grid of cells over the tetrahedra's bounding boxes: the tetrahedra whose box
    (grown by :data:`GRID_TOLERANCE` of its size) meets each cell, so that a point is tested
    against the few tetrahedra of its cell, not all of them.

    ``origin`` (3,) and ``size`` (3,) place the ``cells`` (n per axis, n³ in all) in
    normalised units; the tetrahedra of cell ``k`` are ``members[starts[k]:starts[k + 1]]``.
    n = (S / 8)^(1/3): a tetrahedron's box meets about 8 cells, a cell about 60 tetrahedra
    (50,000 random points: 335,000 tetrahedra in 2.7 million cell memberships). Building
    takes O(S), a query tests O(1) tetrahedra.
    """

    origin: np.ndarray
    size: np.ndarray
    cells: int
    starts: np.ndarray
    members: np.ndarray

    @classmethod
    def of(cls, vertices: np.ndarray) -> "TetraGrid":
        """The grid of tetrahedra ``vertices`` (S, 4, 3)."""
        lo, hi = vertices.min(axis=1), vertices.max(axis=1)
        # a point whose weights are all >= -tol lies within 3 tol of the box on each axis
        margin = 4 * GRID_TOLERANCE * (hi - lo) + 1e-12
        lo, hi = lo - margin, hi + margin
        origin = lo.min(axis=0)
        n = max(1, round((len(vertices) / 8) ** (1 / 3)))
        size = (hi.max(axis=0) - origin) / n
        first, last = (np.clip(np.floor((b - origin) / size), 0, n - 1).astype(np.int64)
                       for b in (lo, hi))
        span = last - first + 1                                  # (S, 3) cells per axis
        count = span.prod(axis=1)
        tetra = np.repeat(np.arange(len(vertices)), count)
        k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        span, first = span[tetra], first[tetra]
        i = first[:, 0] + k % span[:, 0]
        j = first[:, 1] + (k // span[:, 0]) % span[:, 1]
        m = first[:, 2] + k // (span[:, 0] * span[:, 1])
        cell = (i * n + j) * n + m
        order = np.argsort(cell, kind="stable")
        starts = np.searchsorted(cell[order], np.arange(n ** 3 + 1))
        return cls(origin, size, n, starts, tetra[order])

    def candidates(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pairs (point row, tetrahedron) (P,), (P,) to test for points x (Q, 3): the
        tetrahedra of each point's cell (none for a point outside the grid)."""
        c = np.floor((x - self.origin) / self.size)
        inside = np.all((c >= 0) & (c < self.cells), axis=1)
        rows = np.flatnonzero(inside)
        c = c[inside].astype(np.int64)
        cell = (c[:, 0] * self.cells + c[:, 1]) * self.cells + c[:, 2]
        lo, count = self.starts[cell], self.starts[cell + 1] - self.starts[cell]
        point = np.repeat(rows, count)
        k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        return point, self.members[np.repeat(lo, count) + k]


def _lift_heights(x: np.ndarray) -> np.ndarray:
    """A pseudo-random number in [0, 1) per point (E,), a hash of its coordinates (so a point
    gets the same one whatever the other points are)."""
    rows = np.ascontiguousarray(x, dtype=np.float64) + 0.0  # -0.0 hashes as 0.0
    return np.array([int.from_bytes(hashlib.blake2b(r.tobytes(), digest_size=8).digest(),
                                    "little") / 2.0 ** 64 for r in rows])


def _volumes(vertices: np.ndarray) -> np.ndarray:
    """Volumes (T,) of tetrahedra (T, 4, 3)."""
    p0, p1, p2, p3 = (vertices[:, i] for i in range(4))
    return np.abs(np.einsum("ti,ti->t", p1 - p0, cross(p2 - p0, p3 - p0))) / 6.0


def delaunay_tetrahedra(x: np.ndarray, *, source=None) -> Triangulation:
    """Delaunay tetrahedra of points x (E, 3) spanning 3-D, none flat, even for gridded points.

    The lower hull of the points lifted onto ``|x|²`` + :data:`LIFT_PERTURBATION` × a per-point
    hash (see the module docstring): a conforming triangulation refining the Delaunay
    subdivision, whose tetrahedra all have positive volume and tile the convex hull. A point's
    height depends on its coordinates alone (normalised units, of order 1), never on the other
    points, so removing a point changes the tetrahedra around it only. Raises
    LibraryError if Qhull fails or the tetrahedra do not tile the hull.
    """
    x = np.asarray(x, dtype=float)
    lift = np.einsum("ij,ij->i", x, x) + LIFT_PERTURBATION * _lift_heights(x)
    # One point high above the centroid (Qhull's "Qz") makes 4 entries enough; it is never on
    # the lower hull, so never in a tetrahedron.
    above = np.append(x.mean(axis=0), 2.0 * np.abs(lift).max() + 1.0)
    try:
        lifted = ConvexHull(np.vstack([np.column_stack([x, lift]), above]))
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
    # each face once, by a key of its three sorted vertices (int64: n³ fits up to 2 million
    # points): a face of one tetrahedron is on the hull, a face of two is inside
    faces, n = faces.astype(np.int64), len(x) + 1
    keys, count = np.unique((faces[:, 0] * n + faces[:, 1]) * n + faces[:, 2],
                            return_counts=True)
    hull = keys[count == 1]
    return Triangulation(x, simplices, np.column_stack([hull // (n * n), hull // n % n,
                                                        hull % n]))


def locate(tri: Triangulation, x: np.ndarray, *, tol: float = LOCATE_TOLERANCE):
    """Enclosing simplex (Q,) (-1 outside) and barycentric weights (Q, 4) of points x (Q, 3).

    A point within ``tol`` of a face counts inside; of the tetrahedra holding it, the one with
    the largest smallest weight is chosen (the first such in ``tri.simplices``). Beyond
    :data:`FEW_TETRAHEDRA`, only the tetrahedra of the point's cell of
    :attr:`Triangulation.grid` are tested: every tetrahedron that can hold the point is among
    them, so the answer is the one testing all would give.
    """
    x = np.asarray(x, dtype=float).reshape(-1, 3)
    inverse, origin = tri.barycentric
    n = len(tri.simplices)
    if n <= FEW_TETRAHEDRA or tol > GRID_TOLERANCE:     # every pair
        point, tetra = np.repeat(np.arange(len(x)), n), np.tile(np.arange(n), len(x))
    else:
        point, tetra = tri.grid.candidates(x)
    w3 = np.einsum("pij,pj->pi", inverse[tetra], x[point] - origin[tetra])
    w = np.concatenate([w3, 1.0 - w3.sum(axis=1, keepdims=True)], axis=1)   # (P, 4)
    worst = w.min(axis=1)
    held = worst >= -tol
    point, tetra, w, worst = point[held], tetra[held], w[held], worst[held]
    order = np.lexsort((tetra, -worst, point))     # per point: best first, ties by simplex
    first = order[np.r_[True, point[order][1:] != point[order][:-1]]] if len(order) else order
    simplex = np.full(len(x), -1)
    weights = np.full((len(x), 4), np.nan)
    simplex[point[first]] = tetra[first]
    weights[point[first]] = w[first]
    return simplex, weights


def outside_planes(tri: Triangulation, x: np.ndarray) -> np.ndarray:
    """Largest signed distance (Q,) of points x (Q, 3) beyond the planes of the boundary
    triangles of ``tri`` (each oriented away from the centroid of its points); <= 0 inside the
    convex hull, the distance beyond the farthest facet plane outside it."""
    A, B, C = (tri.points[tri.convex_hull[:, i]] for i in range(3))
    n = np.cross(B - A, C - A)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    inward = np.einsum("hi,hi->h", n, tri.points.mean(axis=0) - A)
    n *= np.where(inward > 0, -1.0, 1.0)[:, None]
    return np.einsum("hi,qhi->qh", n, np.asarray(x, dtype=float)[:, None, :] - A[None]).max(
        axis=1)


def tetra_quality(vertices: np.ndarray) -> np.ndarray:
    """Radius ratio ``3 r_in / R_circ`` of tetrahedra (T, 4, 3): 1 regular, 0 degenerate."""
    p0, p1, p2, p3 = (vertices[:, i] for i in range(4))
    vol = _volumes(vertices)
    faces = ((p1, p2, p3), (p0, p2, p3), (p0, p1, p3), (p0, p1, p2))
    area = sum(np.linalg.norm(cross(b - a, c - a), axis=1) / 2 for a, b, c in faces)
    r_in = 3 * vol / np.where(area > 0, area, np.inf)
    # Circumcentre relative to p0 in closed form (stable for nearly flat tetrahedra).
    u, v, w = p1 - p0, p2 - p0, p3 - p0
    num = (np.einsum("ti,ti->t", u, u)[:, None] * cross(v, w)
           + np.einsum("ti,ti->t", v, v)[:, None] * cross(w, u)
           + np.einsum("ti,ti->t", w, w)[:, None] * cross(u, v))
    with np.errstate(divide="ignore", invalid="ignore"):
        R = np.linalg.norm(num, axis=1) / (12 * vol)
        q = np.where(vol > 0, 3 * r_in / R, 0.0)
    return np.clip(np.nan_to_num(q), 0.0, 1.0)
