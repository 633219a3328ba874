"""Control space: barycentric queries, hull projection, blending, leave-one-out and coverage."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from scipy.spatial import ConvexHull, Delaunay

from mocaplib.library.blending_error import leave_one_out
from mocaplib.library.controlspace import DEFAULT_SCALE, Blend, ControlSpace
from mocaplib.library.coverage import Envelope, coverage
from mocaplib.library.triangulation import delaunay_tetrahedra, tetra_quality
from mocaplib.errors import LibraryError, MocapError
from mocaplib.gait.fourier import root_drift, synthesize
from mocaplib.library.format import assemble_library
from mocaplib.skeleton import DOF_NAMES, JOINT_ANGLES

from entries import plain_entry

D = len(DOF_NAMES)
CUBE = np.array(list(itertools.product((0.0, 1.0), repeat=3)))


def hand_library(points, *, a=None, b=None, T=None, classes=None, v_f=None):
    """A real :class:`Library` assembled by hand from control points (E, 3) and coefficients."""
    points = np.asarray(points, float)
    n = len(points)
    a = np.zeros((n, D, 3)) if a is None else a
    b = np.zeros((n, D, 3)) if b is None else b
    T = np.ones(n) if T is None else T
    entries = []
    for i, (v, w, vl) in enumerate(points):
        entries.append(plain_entry(
            id=f"e{i:02d}", source_file=f"c{i}.c3d", source_sha256="0" * 64, cycle_index=0,
            start_s=0.0, end_s=float(T[i]), T=float(T[i]), pattern={"type": "line"},
            v=v, omega=w, v_l=vl, v_f=(v if v_f is None else v_f[i]), a=a[i], b=b[i],
            root_drift={"u_f_m_s": v, "u_l_m_s": vl, "omega_rad_s": w}, qc={},
            locomotion_class=None if classes is None else classes[i]))
    return assemble_library(entries, settings={})


def random_space(seed=0, n=40, *, axes="tangential"):
    rng = np.random.default_rng(seed)
    pts = rng.uniform([0.0, -1.5, -0.5], [2.0, 1.5, 0.5], (n, 3))
    return ControlSpace(pts, a=rng.normal(size=(n, D, 4)), b=rng.normal(size=(n, D, 4)),
                        T=rng.uniform(0.9, 1.3, n), axes=axes), rng


def test_barycentric_weights_sum_to_one_and_reproduce_the_point():
    # on the frontal axes the weights reproduce the point itself (on the tangential ones its
    # frontal point: tests/test_gait_blending.py)
    cs, rng = random_space(axes="frontal")
    q = rng.uniform([0.0, -1.5, -0.5], [2.0, 1.5, 0.5], (500, 3))
    res = cs.query(q)
    assert 100 < res.inside.sum() < 500  # random points: many inside, some outside
    w, e = res.weights[res.inside], res.entries[res.inside]
    # Weights come from one 3x3 affine solve in normalised units: float64 round-off only.
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)
    assert (w >= 0).all()
    np.testing.assert_allclose(np.einsum("qk,qkj->qj", w, cs.points[e]), q[res.inside],
                               atol=1e-12)
    assert np.isnan(res.weights[~res.inside]).all() and (res.entries[~res.inside] == -1).all()


def test_vertices_get_weight_one_on_themselves():
    cs, _ = random_space(seed=1)
    res = cs.query(cs.points)
    assert res.inside.all()
    rows = np.arange(len(cs.points))
    best = np.argmax(res.weights, axis=1)
    assert (res.entries[rows, best] == rows).all()
    # Barycentric coordinates of a vertex: 1 up to round-off of the affine solve.
    np.testing.assert_allclose(res.weights[rows, best], 1.0, atol=1e-9)


@pytest.mark.parametrize("point, nearest", [
    ((2.0, 0.5, 0.5), (1.0, 0.5, 0.5)),      # in front of a face
    ((2.0, 2.0, 0.5), (1.0, 1.0, 0.5)),      # beside an edge
    ((2.0, 2.0, 2.0), (1.0, 1.0, 1.0)),      # beyond a corner
    ((0.3, 0.6, -3.0), (0.3, 0.6, 0.0)),     # below the bottom face
])
def test_outside_queries_project_exactly_onto_the_hull(point, nearest):
    cs = ControlSpace(np.vstack([CUBE, [[0.5, 0.5, 0.5]]]), scale=[1.0, 1.0, 1.0])
    res = cs.query([point, (0.5, 0.4, 0.3)])
    assert list(res.inside) == [False, True]
    # The projection is closed-form per facet: exact to round-off.
    np.testing.assert_allclose(res.nearest[0], nearest, atol=1e-12)
    np.testing.assert_allclose(res.distance[0], np.linalg.norm(np.subtract(point, nearest)),
                               atol=1e-12)
    np.testing.assert_allclose(res.nearest[1], (0.5, 0.4, 0.3), atol=0)
    assert res.distance[1] == 0


def test_nearest_point_is_on_the_hull_and_closer_than_any_entry():
    cs, rng = random_space(seed=2)
    q = rng.uniform([-1.0, -3.0, -1.5], [3.0, 3.0, 1.5], (300, 3))
    res = cs.query(q)
    out = ~res.inside
    assert out.sum() > 100
    assert cs.contains(res.nearest[out]).all()
    d_entries = np.linalg.norm(cs.normalise(q[out])[:, None] - cs.normalise(cs.points)[None],
                               axis=2).min(axis=1)
    assert (res.distance[out] <= d_entries + 1e-12).all()
    # Distance is measured in normalised units between the point and its projection.
    np.testing.assert_allclose(
        res.distance[out], np.linalg.norm(cs.normalise(q[out] - res.nearest[out]), axis=1),
        atol=1e-12)


def test_blending_identical_entries_reproduces_them():
    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(D, 6)), rng.normal(size=(D, 6))
    b[:, 0] = 0
    pts = np.vstack([CUBE, [[0.4, 0.5, 0.6]]])
    cs = ControlSpace(pts, a=[a] * 9, b=[b] * 9, T=np.full(9, 1.1), scale=[1, 1, 1])
    bl = cs.blend(cs.query(rng.uniform(0, 1, (20, 3))))
    # Weights sum to 1 within 1e-15, so the blend equals the entry to round-off.
    np.testing.assert_allclose(bl.a, np.broadcast_to(a, bl.a.shape), atol=1e-12)
    np.testing.assert_allclose(bl.b, np.broadcast_to(b, bl.b.shape), atol=1e-12)
    np.testing.assert_allclose(bl.T, 1.1, atol=1e-12)


def test_blend_pads_orders_and_weights_coefficients():
    a1, a2 = np.zeros((D, 2)), np.zeros((D, 4))
    a1[0, 1], a2[0, 3] = 1.0, 2.0
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    cs = ControlSpace(pts, a=[a1, a2, a2, a2], b=[np.zeros((D, 2))] + [np.zeros((D, 4))] * 3,
                      T=[1.0, 2.0, 2.0, 2.0], scale=[1, 1, 1])
    res = cs.query([0.25, 0.0, 0.0])  # weight 3/4 on entry 0, 1/4 on entry 1
    bl = cs.blend(res)
    assert bl.a.shape == (1, D, 4)
    np.testing.assert_allclose(bl.a[0, 0], [0, 0.75, 0, 0.5], atol=1e-12)
    np.testing.assert_allclose(bl.T, [1.25], atol=1e-12)
    with pytest.raises(MocapError, match="outside the control space"):
        cs.blend(cs.query([[5.0, 5.0, 5.0]]))


def test_synthesis_matches_the_fourier_convention():
    a, b = np.zeros((D, 3)), np.zeros((D, 3))
    a[3, 0], a[3, 1], b[3, 2] = 0.1, 0.2, -0.3
    T = 1.3
    t = np.linspace(0, T, 50, endpoint=False)
    q = synthesize(a, b, T, t)
    expected = 0.1 + 0.2 * np.cos(2 * np.pi * t / T) - 0.3 * np.sin(2 * np.pi * 2 * t / T)
    np.testing.assert_allclose(q[:, 3], expected, atol=1e-12)
    assert np.count_nonzero(q[:, np.arange(D) != 3]) == 0
    # The library's own evaluation of the same convention agrees.
    pts = np.vstack([CUBE, [[0.5, 0.5, 0.5]]])
    lib = hand_library(pts, a=np.stack([a] * 9), b=np.stack([b] * 9), T=np.full(9, T))
    np.testing.assert_allclose(lib.angles("e00", t), q, atol=1e-12)
    cs = ControlSpace.from_library(lib)
    t_blend, q_blend = cs.blend(cs.query([[0.5, 0.5, 0.5]])).synthesize(0, rate=100.0)
    assert len(t_blend) == 130  # 1.3 s at 100 Hz
    np.testing.assert_allclose(q_blend, lib.angles("e00", t_blend), atol=1e-9)


def test_leave_one_out_known_answer():
    # Corners carry zero angles; the centre carries a constant 0.05 rad on one DOF. Corners lie
    # on the hull of the others (not evaluated); the centre is rebuilt from corners as 0.
    pts = np.vstack([CUBE, [[0.5, 0.5, 0.5]]])
    a = np.zeros((9, D, 3))
    k = DOF_NAMES.index("knee_flexion_r")
    a[8, k, 0] = 0.05
    T = np.array([1.0] * 8 + [1.2])
    df = leave_one_out(ControlSpace.from_library(hand_library(pts, a=a, T=T)))
    assert df["inside"].tolist() == [False] * 8 + [True]
    row = df.iloc[8]
    n_joints = int(JOINT_ANGLES.sum())
    assert n_joints == 28  # 32 DOFs minus pelvis_tx/ty/tz and the heading pelvis_rotation
    # Error 0.05 rad on 1 of the joint angles, constant over the cycle.
    np.testing.assert_allclose(row["max_deg"], np.degrees(0.05), atol=1e-9)
    np.testing.assert_allclose(row["rms_deg"], np.degrees(0.05) / np.sqrt(n_joints), atol=1e-9)
    assert row["worst_dof"] == "knee_flexion_r"
    assert row["heading_rms_deg"] == 0 and row["root_rms_mm"] == 0
    np.testing.assert_allclose(row["T_error_s"], -0.2, atol=1e-9)
    np.testing.assert_allclose(sum(row["weights"]), 1.0, atol=1e-12)
    assert set(row["neighbours"]) <= {f"e{i:02d}" for i in range(8)}


def test_leave_one_out_keeps_root_channels_and_drift_apart():
    # The centre's root is 10 mm ahead and 0.02 rad left of its path frame and its period is
    # 1.2 s against the corners' 1.0 s; the drift (u_f, u_l, ω) = (v, v_l, ω) is affine in the
    # control point, so the blended drift velocities are the centre's own.
    pts = np.vstack([CUBE, [[0.5, 0.5, 0.5]]])
    a = np.zeros((9, D, 3))
    a[8, DOF_NAMES.index("pelvis_tx"), 0] = 0.010
    a[8, DOF_NAMES.index("pelvis_rotation"), 0] = 0.02
    T = np.array([1.0] * 8 + [1.2])
    row = leave_one_out(ControlSpace.from_library(hand_library(pts, a=a, T=T),
                                                  axes="frontal")).iloc[8]
    assert row["inside"] and row["rms_deg"] == 0  # metres and heading stay out of the joints
    # Constant offsets: RMS over pelvis_tx/ty/tz of (10, 0, 0) mm; heading 0.02 rad.
    np.testing.assert_allclose(row["root_rms_mm"], 10 / np.sqrt(3), atol=1e-9)
    np.testing.assert_allclose(row["heading_rms_deg"], np.degrees(0.02), atol=1e-9)
    # Per cycle the frame turns ω·T and moves along an arc: ∫0^T R(ωt) (u_f, u_l) dt.
    u, w = np.array([0.5, 0.5]), 0.5

    def arc(t):
        c, s = np.sin(w * t) / w, (1 - np.cos(w * t)) / w
        return np.array([[c, -s], [s, c]]) @ u
    np.testing.assert_allclose(row["turn_error_deg"], np.degrees(w * (1.0 - 1.2)), atol=1e-9)
    np.testing.assert_allclose(row["stride_error_mm"],
                               1000 * np.linalg.norm(arc(1.0) - arc(1.2)), atol=1e-6)


def test_gridded_library_has_no_flat_tetrahedra():
    # A 4 x 5 x 3 grid: every cube cell has 8 cospherical corners. Qhull's triangulated output
    # (scipy's Delaunay) fans such cells into tetrahedra some of which are flat; ours must not.
    axes = (np.linspace(0, 1.5, 4), np.linspace(-1.2, 1.2, 5), np.linspace(-0.5, 0.5, 3))
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    x = grid / [DEFAULT_SCALE[k] for k in ("v", "omega", "v_l")]
    p = x[Delaunay(x).simplices]
    qhull_volumes = np.abs(np.linalg.det(p[:, 1:] - p[:, :1])) / 6
    assert (qhull_volumes < 1e-12).sum() > 0  # the degeneracy this test is about exists
    cs = ControlSpace(grid, axes="frontal")       # the weights reproduce the point itself
    p = cs.tri.points[cs.tri.simplices]
    volumes = np.abs(np.linalg.det(p[:, 1:] - p[:, :1])) / 6
    hull = ConvexHull(x).volume
    # Each grid cell is split into tetrahedra of at least 1/6 of a cell (a corner tetrahedron)
    # (3 x 4 x 2 = 24 cells); they tile the hull exactly (round-off only).
    assert volumes.min() >= hull / 24 / 6 * (1 - 1e-9)
    np.testing.assert_allclose(volumes.sum(), hull, rtol=1e-12)
    # Cells are 0.33 x 0.38 x 1 normalised boxes: corner tetrahedra have radius ratio ~0.38.
    assert cs.tetra_quality().min() > 0.3 and len(cs.tri.simplices) >= 24 * 5
    # Conforming: every face inside the hull is shared by exactly two tetrahedra.
    faces = np.sort(cs.tri.simplices[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]]
                    .reshape(-1, 3), axis=1)
    _, count = np.unique(faces, axis=0, return_counts=True)
    assert set(count) == {1, 2} and (count == 1).sum() == len(cs.hull_facets)
    assert len(cs.hull_facets) == 2 * (3 * 4 + 3 * 2 + 4 * 2) * 2  # the box's grid squares, x 2
    # Queries anywhere in the box (on grid planes too) get valid weights reproducing the point.
    rng = np.random.default_rng(7)
    q = np.vstack([rng.uniform([0, -1.2, -0.5], [1.5, 1.2, 0.5], (300, 3)),
                   np.column_stack([rng.uniform(0, 1.5, 50), np.full(50, 0.6), np.zeros(50)])])
    res = cs.query(q)
    assert res.inside.all() and (res.weights >= 0).all()
    np.testing.assert_allclose(res.weights.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("qk,qkj->qj", res.weights, cs.points[res.entries]), q,
                               atol=1e-12)  # one affine solve per point: round-off only
    assert coverage(cs, Envelope.box({"v_f": (0, 1.5), "omega": (-1.2, 1.2),
                                      "v_l": (-0.5, 0.5)})).slivers.empty


def test_triangulation_does_not_depend_on_entry_order():
    # The tie-breaking heights hash each point, so leaving an entry out or reordering the
    # library keeps the same tetrahedra among the others (a 3 x 3 x 3 grid is full of ties).
    grid = np.array(list(itertools.product((0.0, 0.5, 1.0), repeat=3)))
    order = np.random.default_rng(3).permutation(len(grid))
    first = {frozenset(map(tuple, grid[s])) for s in delaunay_tetrahedra(grid).simplices}
    again = {frozenset(map(tuple, grid[order][s]))
             for s in delaunay_tetrahedra(grid[order]).simplices}
    assert first == again


def test_leave_one_out_is_exact_for_affine_coefficients():
    # Barycentric blending reproduces any affine function of the point weighed exactly (on
    # the frontal axes the control point itself).
    rng = np.random.default_rng(5)
    pts = rng.uniform(0, 1, (30, 3))
    M, c = rng.normal(size=(D, 3, 3)), rng.normal(size=(D, 3))
    a = np.einsum("dnj,ej->edn", M, pts) + c
    cs = ControlSpace(pts, a=a, b=np.zeros_like(a), T=1 + pts[:, 0], scale=[1, 1, 1],
                      axes="frontal")
    df = leave_one_out(cs)
    assert df["inside"].sum() >= 5
    # Round-off of the weights times coefficients of size ~3 rad: far below 1e-9 degrees.
    np.testing.assert_allclose(df.loc[df["inside"], "rms_deg"], 0.0, atol=1e-9)
    np.testing.assert_allclose(df.loc[df["inside"], "T_error_s"], 0.0, atol=1e-12)


@pytest.mark.parametrize("kind", ["random", "grid"])
def test_leave_one_out_locates_each_entry_as_the_others_triangulated_whole_do(kind):
    # Each entry is located among its star's neighbours only; the definition triangulates all
    # the others: the same tetrahedron and weights, for scattered points and for a grid with
    # its cospherical ties, hull points on faces and a duplicated entry.
    rng = np.random.default_rng(7)
    if kind == "random":
        pts = rng.uniform([0.0, -1.5, -0.5], [2.0, 1.5, 0.5], (60, 3))
    else:
        pts = np.array(list(itertools.product([0.3, 0.9, 1.5], [-0.6, 0.0, 0.6],
                                              [-0.3, 0.0, 0.3])), float)
        pts = np.vstack([pts, pts[13]])
    n = len(pts)
    cs = ControlSpace(pts, a=rng.normal(size=(n, D, 3)), b=rng.normal(size=(n, D, 3)),
                      T=rng.uniform(0.9, 1.3, n))
    rows = leave_one_out(cs)
    for i, row in rows.iterrows():
        keep = np.arange(n) != i
        others = ControlSpace(pts[keep], ids=[cs.ids[j] for j in np.flatnonzero(keep)])
        res = others.query(pts[i])
        assert row["inside"] == bool(res.inside[0]), i
        if row["inside"]:
            expected = {others.ids[j]: w for j, w in zip(res.entries[0], res.weights[0])
                        if w > 1e-12}
            got = {k: w for k, w in zip(row["neighbours"], row["weights"]) if w > 1e-12}
            assert got.keys() == expected.keys(), i
            np.testing.assert_allclose([got[k] for k in expected], list(expected.values()),
                                       rtol=0, atol=1e-9)


def test_coverage_of_a_cube_library_against_a_bigger_box():
    pts = np.vstack([CUBE, [[0.5, 0.5, 0.5]]])
    classes = ["walk"] * 4 + ["turn"] * 4 + [None]
    cs = ControlSpace(pts, classes=classes, scale=[1.0, 1.0, 1.0])
    env = Envelope.box({"v": (0, 2), "omega": (0, 2), "v_l": (0, 2)})
    cov = coverage(cs, env, n_grid=21, n_next=3)
    # Grid step 0.1 on [0, 2]^3: 21^3 samples, of which 11^3 lie in the closed unit cube.
    assert cov.n_samples == 21 ** 3
    np.testing.assert_allclose(cov.fraction_inside, 11 ** 3 / 21 ** 3, atol=1e-12)
    np.testing.assert_allclose(cov.largest_hole, [2, 2, 2], atol=1e-12)
    np.testing.assert_allclose(cov.largest_hole_distance, np.sqrt(3), atol=1e-12)
    # Greedy farthest point: the far corner first, then the corners farthest from it and the
    # cube ((2, 2, 0)-type corners at distance sqrt(2) from the cube... and 2 from (2,2,2)).
    np.testing.assert_allclose(cov.capture_next.iloc[0][["v", "omega", "v_l"]], [2, 2, 2],
                               atol=1e-12)
    np.testing.assert_allclose(cov.capture_next["gap"].iloc[0], np.sqrt(3), atol=1e-12)
    assert (np.diff(cov.capture_next["gap"]) <= 0).all()
    assert cov.entries_per_class == {"turn": 4, "unknown": 1, "walk": 4}
    # Cube + centre: 12 congruent tetrahedra (centre + half a face), none a sliver.
    assert len(cs.tri.simplices) == 12 and cov.slivers.empty


def test_tetra_quality_regular_and_flat():
    regular = np.array([[[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1.0]]])
    flat = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 1e-9]]])
    np.testing.assert_allclose(tetra_quality(regular), [1.0], atol=1e-12)
    assert tetra_quality(flat)[0] < 1e-6
    # The classic sliver: a square with corners lifted alternately by ±1 cm, under an apex
    # outside its circumsphere, so Delaunay keeps the flat tetrahedron of the four corners.
    square = [[0, 0, 0.01], [1, 0, -0.01], [1, 1, 0.01], [0, 1, -0.01], [0.5, 0.5, 1.0]]
    sliver_space = ControlSpace(square, scale=[1, 1, 1])
    cov = coverage(sliver_space, Envelope.box({"v": (0, 1), "omega": (0, 1), "v_l": (0, 1)}))
    assert len(cov.slivers) >= 1 and (cov.slivers["quality"] < 0.1).all()


def test_degenerate_and_tiny_libraries_are_refused():
    flat = np.column_stack([np.linspace(0, 2, 6), np.linspace(-1, 1, 6) ** 2, np.zeros(6)])
    with pytest.raises(LibraryError, match="degenerate.*plane"):
        ControlSpace(flat)
    with pytest.raises(LibraryError, match="at least 4 entries"):
        ControlSpace(CUBE[:3])
    with pytest.raises(MocapError, match="axes"):
        ControlSpace(CUBE, axes="polar")


def test_from_library_uses_stored_scale_and_frontal_variant():
    pts = np.vstack([CUBE * [2.0, 1.0, 0.5], [[1.0, 0.5, 0.25]]])
    lib = hand_library(pts, v_f=pts[:, 0] * 0.9, classes=["walk"] * 9)
    cs = ControlSpace.from_library(lib)
    np.testing.assert_allclose(cs.scale, lib.control_scale)
    np.testing.assert_allclose(cs.scale, [DEFAULT_SCALE[k] for k in ("v", "omega", "v_l")])
    assert cs.ids == [f"e{i:02d}" for i in range(9)]
    front = ControlSpace.from_library(lib, axes="frontal")
    assert front.axes == ("v_f", "omega", "v_l")
    np.testing.assert_allclose(front.points[:, 0], pts[:, 0] * 0.9)
    bl = cs.blend(cs.query([[1.0, 0.5, 0.25]]))
    # Drift velocities (u_f, u_l, omega) = (v, v_l, omega) here: affine, so blended exactly.
    np.testing.assert_allclose(bl.drift[0], [1.0, 0.25, 0.5], atol=1e-12)


@pytest.mark.parametrize("dx, dy, dth", [(1.2, 0.0, 0.0), (0.8, 0.3, 0.6), (0.0, 0.0, -1.1)])
def test_world_cycle_reaches_the_drift_displacement(dx, dy, dth):
    T = 1.1
    end = np.zeros(D)
    end[[0, 1, 3]] = dx, dy, dth  # pelvis_tx, pelvis_ty, pelvis_rotation after one cycle
    d = root_drift(np.zeros(D), end, T)  # the library's drift velocities for that displacement
    u = np.array([d.u_f, d.u_l, d.omega])
    a = np.zeros((1, D, 2))
    a[0, DOF_NAMES.index("pelvis_tx"), 1] = 0.02  # the pelvis sways in the path frame
    bl = Blend(a, np.zeros_like(a), np.array([T]), u[None])
    t, q = bl.world(0, rate=1000.0, cycles=2)
    # Over one cycle the root (zero in the path frame) moves by the stored displacement;
    # t = T is sample 1100 of the 2-cycle series. Closed-form frame motion: round-off only.
    # At t = T the local pose is the start pose (0.02 m forward), seen from the turned frame.
    i = np.argmin(np.abs(t - T))
    root = [DOF_NAMES.index(n) for n in ("pelvis_tx", "pelvis_ty", "pelvis_rotation")]
    expected = [dx + 0.02 * np.cos(dth), dy + 0.02 * np.sin(dth), dth]
    np.testing.assert_allclose(q[i, root], expected, atol=1e-9)
    assert len(t) == 2200


def test_envelope_from_toml(tmp_path):
    box = tmp_path / "box.toml"
    box.write_text("[envelope]\nv = [0.0, 1.8]\nomega = [-1.5, 1.5]\nv_l = [-0.5, 0.5]\n")
    env = Envelope.from_toml(box)
    np.testing.assert_allclose(env.vertices.min(axis=0), [0, -1.5, -0.5])
    np.testing.assert_allclose(env.vertices.max(axis=0), [1.8, 1.5, 0.5])
    pts = tmp_path / "pts.toml"
    pts.write_text("[envelope]\naxes = ['v_f', 'omega', 'v_l']\n"
                   "points = [[0,0,0],[1,0,0],[0,1,0],[0,0,1]]\n")
    env = Envelope.from_toml(pts)
    assert env.axes == ("v_f", "omega", "v_l") and len(env.sample(np.ones(3), n=11)) == 286
    bad = tmp_path / "bad.toml"
    bad.write_text("[envelope]\nv = [0.0, 1.8]\n")
    with pytest.raises(MocapError, match="bad.toml.*omega, v_l"):
        Envelope.from_toml(bad)
    with pytest.raises(MocapError, match="no \\[envelope\\] table"):
        (tmp_path / "none.toml").write_text("x = 1\n")
        Envelope.from_toml(tmp_path / "none.toml")


# --------------------------------------------------------------------------- mocaplib query
def _query(argv):
    """Run ``mocaplib query ARGV`` through its own parser (no other sub-command needed)."""
    import argparse

    from mocaplib.cli import query

    parser = argparse.ArgumentParser()
    query.register(parser.add_subparsers())
    args = parser.parse_args(["query", *map(str, argv)])
    return args.run(args)


@pytest.fixture
def cube_library(tmp_path):
    pts = np.vstack([CUBE * [1.5, 1.0, 0.5], [[0.75, 0.5, 0.25]]])
    path = tmp_path / "lib.json"
    hand_library(pts, T=np.linspace(1.0, 1.2, 9)).write(path)
    return path


def test_query_command_json_inside_and_outside(cube_library, capsys):
    import json

    assert _query([cube_library, 0.7, 0.4, 0.2, "--json"]) == 0
    inside = json.loads(capsys.readouterr().out)
    assert inside["inside"] is True and len(inside["entries"]) == 4
    np.testing.assert_allclose(sum(inside["weights"]), 1.0, atol=1e-12)
    assert 1.0 <= inside["T_s"] <= 1.2
    assert _query([cube_library, 3.0, 0.5, 0.25, "--json"]) == 0
    outside = json.loads(capsys.readouterr().out)
    assert outside["inside"] is False and outside["entries"] == []
    # Beyond the v = 1.5 face: the nearest hull point keeps omega and v_l (exact projection).
    np.testing.assert_allclose(outside["nearest"], [1.5, 0.5, 0.25], atol=1e-12)
    np.testing.assert_allclose(outside["distance"], 1.5 / 1.5, atol=1e-12)  # v scale 1.5 m/s


def test_an_outside_command_is_told_in_plain_numbers(cube_library):
    from mocaplib.library.format import load_library

    cs = ControlSpace.from_library(load_library(cube_library))
    text = cs.outside_text(cs.query([[3.0, 0.5, 0.25]]))
    # what a person reads: the command and the nearest point as numbers, no numpy reprs
    assert text.startswith("(3, 0.5, 0.25) is outside the control space by 1 (normalised)"), text
    assert "(1.5, 0.5, 0.25)" in text and "np." not in text, text


def test_query_command_bvh(cube_library, tmp_path, capsys):
    out = tmp_path / "blend.bvh"
    import json

    assert _query([cube_library, 0.7, 0.4, 0.2, "--bvh", out, "--rate", 50, "--cycles", 2,
                   "--json"]) == 0
    answer = json.loads(capsys.readouterr().out)
    assert answer["bvh"] == str(out)
    frames = int(out.read_text().split("Frames:")[1].split()[0])
    assert frames == 2 * round(answer["T_s"] * 50)  # two blended cycles in whole frames, 50 Hz
    assert _query([cube_library, 0.7, 0.4, 0.2]) == 0
    assert "inside the control space" in capsys.readouterr().out
    with pytest.raises(MocapError, match="outside the control space.*--clamp"):
        _query([cube_library, 3.0, 0.5, 0.25, "--bvh", out])
    assert _query([cube_library, 3.0, 0.5, 0.25, "--bvh", out, "--clamp"]) == 0
    assert "blending at that point (--clamp)" in capsys.readouterr().out
    from mocaplib.cli import main

    for bad in (["--cycles", "0"], ["--rate", "-5"], ["--rate", "fast"]):  # usage errors
        assert main(["query", str(cube_library), "0.7", "0.4", "0.2", *bad]) == 2
    assert "must be > 0" in capsys.readouterr().err


def test_a_gait_cell_of_every_point_is_the_whole_triangulation():
    """Where every entry is of one gait and none is put on the cone, the gait's cell is the
    control space's own triangulation (made once), the tetrahedra of triangulating it apart;
    a side-step put on the cone gets its own."""
    from mocaplib.library.triangulation import delaunay_tetrahedra

    rng = np.random.default_rng(5)
    points = np.column_stack([rng.uniform(0.5, 1.5, 30), rng.uniform(-0.5, 0.5, 30),
                              rng.uniform(-0.3, 0.3, 30)])
    cs = ControlSpace(points)
    assert cs.cells["walk"].tri is cs.tri
    apart = delaunay_tetrahedra(cs.normalise(points))
    np.testing.assert_array_equal(cs.tri.simplices, apart.simplices)
    stepping = points.copy()
    stepping[0] = [0.4, 0.0, 0.4 * 0.9998]          # 1.1° from sideways: put on the cone
    cs = ControlSpace(stepping)
    assert cs.cells["walk"].tri is not cs.tri


def test_a_star_is_taken_among_the_triangulated_points_only():
    """The tetrahedra of some of the points (a gait's cell, its frontal tetrahedra): a point
    outside them has no star there, and no star holds it."""
    from mocaplib.library.blending_error import star_neighbours

    x = np.random.default_rng(7).uniform(size=(30, 3))
    tri = delaunay_tetrahedra(x[:20])
    stars = star_neighbours(tri.simplices, 30, np.arange(20))
    assert all(len(star) == 0 for star in stars[20:])
    assert all(len(star) and star.max() < 20 for star in stars[:20])
    everyone = star_neighbours(delaunay_tetrahedra(x).simplices, 30)
    assert all(len(star) for star in everyone)
