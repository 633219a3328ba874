"""The spatial indexes give the answers of the direct computations: :func:`locate` through its
grid of cells against testing every tetrahedron, on a few hundred random and gridded points,
with queries inside, outside, on vertices and on shared faces."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.library.triangulation import LOCATE_TOLERANCE, delaunay_tetrahedra, locate


def locate_directly(tri, x, tol=LOCATE_TOLERANCE):
    """Every tetrahedron's barycentric weights of every point (numpy's inverse): the simplex
    with the largest smallest weight when that is >= -tol (else -1), all weights (Q, S, 4)
    and all smallest weights (Q, S)."""
    vertices = tri.points[tri.simplices]                                   # (S, 4, 3)
    inverse = np.linalg.inv(np.transpose(vertices[:, :3] - vertices[:, 3:], (0, 2, 1)))
    w3 = np.einsum("sij,qsj->qsi", inverse, x[:, None, :] - vertices[None, :, 3])
    w = np.concatenate([w3, 1.0 - w3.sum(axis=2, keepdims=True)], axis=2)  # (Q, S, 4)
    worst = w.min(axis=2)
    best = np.argmax(worst, axis=1)
    q = np.arange(len(x))
    hit = worst[q, best] >= -tol
    return np.where(hit, best, -1), w, worst


def point_sets():
    rng = np.random.default_rng(11)
    grid = np.stack(np.meshgrid(*[np.linspace(-1, 1, 6)] * 3, indexing="ij"), -1).reshape(-1, 3)
    return {"random": rng.uniform(-1.0, 1.0, (300, 3)), "gridded": grid,
            "flat cloud": rng.normal(size=(300, 3)) * [1.0, 0.05, 0.4],
            "few": rng.uniform(-1.0, 1.0, (20, 3))}


@pytest.mark.parametrize("tol", [LOCATE_TOLERANCE, 1e-7])   # the tolerances the cells use
@pytest.mark.parametrize("name", ["random", "gridded", "flat cloud", "few"])
def test_the_grid_locates_as_testing_every_tetrahedron(name, tol):
    # 700 to 1,800 tetrahedra, located on the grid; "few": 20 points, every pair tested
    points = point_sets()[name]
    tri = delaunay_tetrahedra(points)
    rng = np.random.default_rng(5)
    faces = points[tri.simplices[:50, :3]].mean(axis=1)       # on shared faces: ties
    lo, hi = points.min(axis=0), points.max(axis=0)
    box = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), (1500, 3))
    queries = np.vstack([box, points[:50], faces])
    simplex, weights = locate(tri, queries, tol=tol)
    if name != "few":   # the grid tests a few tetrahedra per point, not all of them
        tested = len(tri.grid.candidates(queries)[0]) / len(queries)
        assert tested < 0.25 * len(tri.simplices), tested   # measured 4 % to 11 %
    expected, every_weight, worst = locate_directly(tri, queries, tol)
    np.testing.assert_array_equal(simplex >= 0, expected >= 0)
    assert (simplex >= 0).sum() > 100 and (simplex < 0).sum() > 100, "both kinds tested"
    inside = np.flatnonzero(expected >= 0)
    # the same simplex, or one whose smallest weight ties with the best to rounding (1e-12:
    # both solve the same 3x3 systems, by a closed-form and by LAPACK's inverse)
    best = worst[inside, expected[inside]]
    chosen = worst[inside, simplex[inside]]
    np.testing.assert_allclose(chosen, best, atol=1e-12)
    np.testing.assert_allclose(weights[inside], every_weight[inside, simplex[inside]],
                               atol=1e-12)
    assert (simplex[inside] == expected[inside]).mean() > 0.8   # ties aside, the same one
    # the weights reproduce the point (equation (4))
    rebuilt = np.einsum("qk,qkj->qj", weights[inside],
                        tri.points[tri.simplices[simplex[inside]]])
    np.testing.assert_allclose(rebuilt, queries[inside], atol=1e-12)


def test_hull_faces_are_qhulls_on_thousands_of_points():
    # the faces of one tetrahedron each, found by an integer key per face: the convex hull
    # Qhull gives for the same points (3,000 points: keys beyond 32 bits)
    from scipy.spatial import ConvexHull

    points = np.random.default_rng(4).normal(size=(3000, 3))
    tri = delaunay_tetrahedra(points)
    assert sorted(map(tuple, np.sort(tri.convex_hull, axis=1))) == sorted(
        map(tuple, np.sort(ConvexHull(points).simplices, axis=1)))
