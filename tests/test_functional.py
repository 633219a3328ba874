"""Functional joint centres (SCoRE) and hinge axes (SARA) recovered from synthetic relative
motion of two rigid clusters with a known centre and axis."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.markersets.protocols import load_landmarks
from mocaplib.model.functional import (FUNCTIONAL_RANGE, catalogue_origin, functional_joint,
                                       marker_frames, relative_range)


def _rotation(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Rotations (F, 3, 3) by ``angles`` (F,) radians about the unit ``axis`` (3,)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


CENTRE = np.array([0.03, -0.02, 0.48])             # world, metres
PARENT = CENTRE + np.array([[0.08, 0.09, 0.2], [0.0, 0.1, 0.25], [0.05, 0.11, 0.12]])
CHILD = np.array([[0.05, 0.07, -0.15], [-0.03, 0.08, -0.2], [0.02, 0.06, -0.3]])  # from centre


def _clusters(R: np.ndarray, noise: float, seed: int = 0):
    """Parent cluster fixed, child turned by R (F, 3, 3) about CENTRE, as marker frames with
    ``noise`` (m, sd per coordinate)."""
    rng = np.random.default_rng(seed)
    n = len(R)
    child = CENTRE + np.einsum("fij,mj->fmi", R, CHILD)
    parent = np.broadcast_to(PARENT, (n, 3, 3))
    return (marker_frames(parent + rng.normal(0, noise, (n, 3, 3))),
            marker_frames(child + rng.normal(0, noise, child.shape)))


def _ball_motion(n: int = 300) -> np.ndarray:
    """A ball joint's motion: flexion 0-60°, abduction ±15°, rotation ±10° (F, 3, 3)."""
    t = np.linspace(0.0, 4 * np.pi, n)
    return (_rotation(np.array([0.0, 1.0, 0.0]), np.radians(30 - 30 * np.cos(t)))
            @ _rotation(np.array([1.0, 0.0, 0.0]), np.radians(15 * np.sin(0.7 * t)))
            @ _rotation(np.array([0.0, 0.0, 1.0]), np.radians(10 * np.sin(1.3 * t))))


def test_score_recovers_a_ball_joint_centre():
    joint = functional_joint(*_clusters(_ball_motion(), 0.0))
    # exact markers: the centre within 1 mm (least squares of an exact system: to rounding)
    np.testing.assert_allclose(joint.centre, np.broadcast_to(CENTRE, joint.centre.shape),
                               atol=1e-3)
    noisy = functional_joint(*_clusters(_ball_motion(), 0.001))
    # 1 mm of marker noise over 60° of flexion: within 3 mm (Ehrig 2006 report ~1-5 mm)
    error = np.linalg.norm(np.median(noisy.centre, axis=0) - CENTRE)
    assert error < 0.003, error


@pytest.mark.parametrize("noise, limit_deg", [(0.0, 1.0), (0.001, 2.0)])
def test_sara_recovers_a_hinge_axis(noise, limit_deg):
    axis = np.array([0.1, 0.97, -0.2])
    axis /= np.linalg.norm(axis)
    angles = np.radians(30 - 30 * np.cos(np.linspace(0.0, 4 * np.pi, 300)))   # 0-60°
    hint = np.broadcast_to(CENTRE + (0.0, 0.0, 0.42), (300, 3))             # proximal centre
    joint = functional_joint(*_clusters(_rotation(axis, angles), noise), hint=hint)
    assert joint.axis is not None
    error = np.degrees(np.arccos(np.clip(np.abs(joint.axis @ axis), 0.0, 1.0)))
    # exact: within 1°; 1 mm noise on clusters 0.1-0.3 m from the axis: within 2°
    assert np.median(error) < limit_deg, np.median(error)
    # a hinge's centre slides along its axis: taken nearest the hint, so off the true centre
    # only along the axis, within 1 mm across it (exact) or 3 mm (noisy)
    off = np.median(joint.centre, axis=0) - CENTRE
    across = np.linalg.norm(off - (off @ axis) * axis)
    assert across < (0.001 if noise == 0 else 0.003), across
    # the range: exact to the sampling (0.01°); 1 mm of noise on frames 0.1 m wide adds ~0.6°
    # per frame to the largest pairwise angle
    assert joint.range_deg == pytest.approx(60.0, abs=4.0 if noise else 0.01)


def test_the_range_of_a_joint_that_hardly_turns_is_measured_below_the_limit():
    axis = np.array([0.0, 1.0, 0.0])
    angles = np.radians(5 + 5 * np.sin(np.linspace(0.0, 4 * np.pi, 200)))     # 0-10°
    parent, child = _clusters(_rotation(axis, angles), 0.0)
    assert relative_range(parent[0], child[0]) == pytest.approx(10.0, abs=0.01)
    assert functional_joint(parent, child).range_deg < FUNCTIONAL_RANGE
    # too few frames with both clusters seen: nothing to estimate
    child_seen = (child[0].copy(), child[1].copy())
    child_seen[0][5:] = np.nan
    assert functional_joint(parent, child_seen) is None


def test_a_segment_origin_from_its_landmarks_fitted_to_the_catalogue():
    catalogue = load_landmarks()
    names = ["L_HEEL", "L_TOE", "L_MT5"]
    local = np.array([catalogue[name].position for name in names]) * 1.1       # scale 1.1
    turn = _rotation(np.array([0.3, 0.2, 0.93]) / np.linalg.norm([0.3, 0.2, 0.93]),
                     np.radians(np.linspace(-40.0, 60.0, 50)))
    origin = np.array([0.4, -0.1, 0.09]) + np.linspace(0, 1, 50)[:, None] * (1.0, 0.2, 0.0)
    where = {name: np.einsum("fij,j->fi", turn, p) + origin for name, p in zip(names, local)}
    where["L_TOE"][7] = np.nan                                  # a frame with two markers seen
    where["L_ASIS"] = np.zeros((50, 3))                        # on another segment: not used
    found, used = catalogue_origin(where, "foot_l", catalogue, 1.1)
    assert used == names
    # exact markers: the origin to rounding; unknown where fewer than three are seen
    np.testing.assert_allclose(np.delete(found, 7, axis=0), np.delete(origin, 7, axis=0),
                               atol=1e-9)
    assert np.isnan(found[7]).all()
    del where["L_MT5"]
    assert catalogue_origin(where, "foot_l", catalogue, 1.1) is None
