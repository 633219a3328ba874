"""Planting's leg solve: the legs' kinematics (mocaplib/library/legs.py) are the skeleton's, and
the solve gives what the generic damped Gauss-Newton on the skeleton's full chain gives
(:func:`reference_solve`, kept here as the reference: every DOF's Jacobian from
:meth:`Skeleton.marker_jacobian`, the 13 x 13 normal equations solved whole)."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.gait.fourier import RootDrift
from mocaplib.gait.poulaine import FEET
from mocaplib.library import legs, planting
from mocaplib.library.legs import LEG_DOFS, LegChains
from mocaplib.skeleton import DOF_NAMES, ROOT_Z, SEGMENT_NAMES, Skeleton

#: A body whose joint centres are shifted from where its lengths put them (as calibration
#: measures them), the pelvis's own included.
SKELETON = Skeleton(Skeleton.from_height(1.75).lengths,
                    {"pelvis": (0.01, -0.005, 0.02), "femur_r": (0.0, -0.01, 0.005),
                     "tibia_l": (0.004, 0.0, -0.01), "foot_l": (0.0, 0.012, 0.0)})


def reference_solve(skeleton, q, targets, dofs, *, initial=None):
    """Planting's solve (same arguments as :func:`legs.solve_feet`) on the full chain: Jacobian of
    every DOF from :meth:`Skeleton.marker_jacobian`, the solved DOFs' columns taken, the normal
    equations of all of them solved together."""
    solved = np.array(dofs)
    lower, upper = (bound[solved].copy() for bound in Skeleton.bounds())
    knees = np.isin(solved, legs.KNEES)
    lower[knees] = np.maximum(lower[knees], 0.0)
    segments = np.repeat(FEET, 3)
    offsets = np.tile(np.vstack([np.zeros(3), skeleton.sole()]), (2, 1))
    prior = np.where(solved == ROOT_Z, legs.PELVIS_PRIOR, legs.PRIOR)
    start = q[:, solved].copy()
    out = q.copy()
    out[:, solved] = np.clip(start if initial is None else initial[:, solved],
                             np.where(knees, legs.KNEE_START, lower), upper)
    wanted = targets.reshape(len(q), -1)
    for _ in range(legs.IK_ITERATIONS):
        points, jacobian = skeleton.marker_jacobian(out, segments, offsets)
        J = jacobian.reshape(len(q), -1, len(DOF_NAMES))[:, :, solved]
        gap = wanted - points.reshape(len(q), -1)
        normal = np.einsum("fmi,fmj->fij", J, J) + np.diag(prior + legs.DAMPING)
        rhs = np.einsum("fmi,fm->fi", J, gap) - prior * (out[:, solved] - start)
        step = np.linalg.solve(normal, rhs[..., None])[..., 0]
        out[:, solved] = np.clip(out[:, solved] + step, lower, upper)
        moved = step[:, solved == ROOT_Z] if ROOT_Z in solved else step
        if np.abs(moved).max() < legs.STEP_TOLERANCE:  # with the pelvis: its height's
            break
    return out


def random_poses(n: int, seed: int = 0) -> np.ndarray:
    """``n`` poses (n, D) within the joint limits, the pelvis about 0.9 m up, turned and
    tilted."""
    rng = np.random.default_rng(seed)
    lower, upper = Skeleton.bounds()
    q = rng.uniform(np.maximum(lower, -1.0), np.minimum(upper, 1.0), (n, len(DOF_NAMES)))
    q[:, ROOT_Z] = rng.uniform(0.8, 1.0, n)
    return q


def test_leg_chains_are_the_skeletons_kinematics():
    q = random_poses(50)
    points, jacobian = LegChains(SKELETON, q).feet(q[:, LEG_DOFS], q[:, ROOT_Z])
    segments = np.repeat(FEET, 3)
    offsets = np.tile(np.vstack([np.zeros(3), SKELETON.sole()]), (2, 1))
    want_points, want_jacobian = SKELETON.marker_jacobian(q, segments, offsets)
    want_jacobian = want_jacobian.reshape(50, 2, 3, 3, -1)
    # the same products in another order: round-off, about 1e-16 m on a metre
    np.testing.assert_allclose(points, want_points.reshape(50, 2, 3, 3), atol=1e-12)
    for side in (0, 1):
        np.testing.assert_allclose(jacobian[:, side],
                                   np.take(want_jacobian[:, side], LEG_DOFS[side], axis=-1),
                                   atol=1e-12)
        other = np.take(want_jacobian[:, side], LEG_DOFS[1 - side], axis=-1)
        assert not other.any(), "a leg's DOFs move only its own foot"
    np.testing.assert_array_equal(want_jacobian[..., ROOT_Z], np.broadcast_to([0, 0, 1.0],
                                                                             (50, 2, 3, 3)))


def test_leg_chains_frames_are_the_skeletons_feet_and_hips():
    q = random_poses(40, seed=4)
    points, orientation, hips = LegChains(SKELETON, q).frames(q[:, LEG_DOFS], q[:, ROOT_Z])
    T = SKELETON.forward(q)
    np.testing.assert_allclose(orientation, T[:, list(FEET), :3, :3], atol=1e-12)
    np.testing.assert_allclose(points[:, :, 0], T[:, list(FEET)][..., :3, 3], atol=1e-12)
    thighs = [SEGMENT_NAMES.index("femur_l"), SEGMENT_NAMES.index("femur_r")]
    np.testing.assert_allclose(hips, T[:, thighs][..., :3, 3], atol=1e-12)


@pytest.mark.parametrize("dofs", [legs.SOLVED, legs.LEGS], ids=["pelvis", "legs"])
def test_the_solve_is_the_generic_gauss_newton(dofs):
    q = random_poses(40, seed=1)
    # targets the legs can and cannot reach: the feet's own points moved by up to 10 cm
    points, _ = LegChains(SKELETON, q).feet(q[:, LEG_DOFS], q[:, ROOT_Z])
    targets = points + np.random.default_rng(2).uniform(-0.1, 0.1, points.shape)
    initial = q + 0.01
    got = legs.solve_feet(SKELETON, q, targets, dofs, initial=initial)
    want = reference_solve(SKELETON, q, targets, dofs, initial=initial)
    # the same steps summed in another order: round-off, amplified by the normal equations'
    # condition (straight knees, targets out of reach, the Levenberg damping 1e-5): measured
    # 3e-9 (pelvis) and 1e-7 rad (legs) after the 12 steps, against the 0.01 rad the solve
    # moves the legs
    np.testing.assert_allclose(got, want, atol=1e-6)
    assert np.abs(got - q).max() > 0.01, "the solve moved the legs"


def planted_series_of(library, solve, monkeypatch) -> list[tuple[np.ndarray, np.ndarray]]:
    """The report viewer's planted series (:func:`planting.planted_series`) of every entry of
    ``library`` with ``solve`` as planting's solve."""
    monkeypatch.setattr(planting, "solve_feet", solve)
    out = []
    for e in library.entries:
        drift = RootDrift(0.0, 0.0, 0.0, *e.root_drift.velocities)
        planted = planting.planted_series(library.skeleton, e.fourier.a, e.fourier.b,
                                          float(e.T), drift)
        out.append((planted.a, planted.b))
    monkeypatch.undo()
    return out


def assert_series_equal(library, monkeypatch):
    """The planted series of every entry of ``library`` are those of the reference solve within
    1e-6 rad (m) per coefficient: both stop on the same step tolerance."""
    fast = planted_series_of(library, legs.solve_feet, monkeypatch)
    slow = planted_series_of(library, reference_solve, monkeypatch)
    worst = max(np.abs(np.concatenate([f[k] - s[k] for k in (0, 1)])).max()
                for f, s in zip(fast, slow))
    assert worst <= 1e-6, worst
    return worst


def test_the_synthetic_walks_planted_series_are_those_of_the_generic_solve(monkeypatch):
    from walking_library import synthetic_walks

    # measured: 4e-15 (round-off)
    assert_series_equal(synthetic_walks()[0], monkeypatch)


@pytest.mark.usefixtures("sample_dir")
def test_the_sample_entries_planted_series_are_those_of_the_generic_solve(monkeypatch):
    from test_planting import sample_library

    # every locomotion type (walks, curves, side-steps, turns on the spot, runs); measured 6e-15
    assert_series_equal(sample_library()[0], monkeypatch)


def test_sole_points_are_the_skeletons_heel_and_toe():
    q = random_poses(30, seed=3)
    T = SKELETON.forward(q)[:, list(FEET)]
    want = np.einsum("fsij,pj->fspi", T[..., :3, :3], SKELETON.sole()) + T[:, :, None, :3, 3]
    # posed down the legs alone: the whole chain's numbers to round-off
    np.testing.assert_allclose(planting.sole_points(SKELETON, q), want, atol=1e-12)
