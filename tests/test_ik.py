"""Joint-angle fitting on forward-kinematics markers with known angles."""

import re

import numpy as np
import pytest
from fk_data import fk_trial, true_model

from mocaplib.errors import FitError
from mocaplib.markersets.protocols import load_protocol
from mocaplib.model.calibration import locked_dofs
from mocaplib.model.ik import fit, fit_filtered, fit_quality, keyframes
from mocaplib.model.motion import Motion
from mocaplib.model.solver import ROBUST_SCALE, initial_pose, normal_equations, solve_poses
from mocaplib.model.subject import SubjectModel
from mocaplib.skeleton import DOF_NAMES, MOVES, SEGMENT_NAMES, Skeleton, twists
from mocaplib.trial import Trial

DEG = np.pi / 180
ROT = np.array([not n.startswith("pelvis_t") for n in DOF_NAMES])


def _angle_rms(q, truth):
    return np.sqrt(((q - truth)[:, ROT] ** 2).mean(axis=0))


def test_exact_markers_give_exact_angles():
    cap = fk_trial(n_frames=60, placement_mm=0, sta_mm=0, noise_mm=0)
    motion = fit(cap.trial, true_model(cap), smoothing=0.0)
    # noise-free markers from the same model: only round-off and the stopping rule remain
    np.testing.assert_allclose(motion.q, cap.q, atol=1e-4)
    assert np.nanmax(motion.residuals) < 1e-5
    assert not motion.failed.any()
    assert list(motion.angles.columns) == list(DOF_NAMES)


def test_noisy_markers_recover_angles_within_a_degree():
    cap = fk_trial(n_frames=150, placement_mm=0, sta_mm=0, noise_mm=1.0, seed=1)
    motion = fit(cap.trial, true_model(cap))
    rms = _angle_rms(motion.q, cap.q)
    # 1 mm noise on markers 5-40 cm from the joints: ~0.1-1 deg per DOF; the foot's
    # inversion rests on markers ~4 cm from its axis, so it gets the widest bound
    assert rms.max() < 1.5 * DEG, dict(zip(np.array(DOF_NAMES)[ROT], np.round(rms / DEG, 2)))
    assert np.median(rms) < 0.5 * DEG
    # marker RMS near the noise level: sqrt(3) x 1 mm per marker, less the fitted DOFs' share
    assert 1.0e-3 < np.sqrt(np.nanmean(motion.residuals ** 2)) < 1.8e-3


def test_missing_markers_drop_out():
    cap = fk_trial(n_frames=80, placement_mm=0, sta_mm=0, noise_mm=0.5, seed=2)
    markers = cap.trial.markers.copy()
    rng = np.random.default_rng(0)
    markers[rng.random(markers.shape[:2]) < 0.2] = np.nan          # 20 % of samples missing
    trial = Trial(markers, cap.trial.labels, cap.trial.rate)
    motion = fit(trial, true_model(cap))
    assert np.isnan(motion.residuals[np.isnan(markers[..., 0])]).all()
    rms = _angle_rms(motion.q, cap.q)
    # fewer markers per frame: same bound as with all markers but for the 20 % loss
    assert rms.max() < 2.0 * DEG and np.median(rms) < 0.5 * DEG


def test_a_bad_marker_does_not_drag_the_pose_and_is_left_out():
    cap = fk_trial(n_frames=60, placement_mm=0, sta_mm=0, noise_mm=0.5, seed=3)
    markers = cap.trial.markers.copy()
    knee = cap.trial.labels.index("RKNE")
    markers[:, knee] += (0.0, 0.08, 0.05)                          # 9 cm off in every frame
    model = true_model(cap)
    hip = DOF_NAMES.index("hip_adduction_r")

    def error(robust_scale):
        q = solve_poses(model.skeleton, markers, model.marker_segments, model.marker_offsets,
                        robust_scale=robust_scale).q
        return np.abs(q[:, hip] - cap.q[:, hip]).mean()

    # the soft-L1 loss keeps the bad marker from dragging the pose
    assert error(ROBUST_SCALE) < 0.5 * error(np.inf), (error(ROBUST_SCALE), error(np.inf))
    assert error(ROBUST_SCALE) < 2.5 * DEG
    # the fit then leaves it out, reported, and fits the others as if it were absent
    motion = fit(Trial(markers, cap.trial.labels, cap.trial.rate), model)
    (repair,) = motion.repairs
    assert (repair.kind, repair.labels, repair.start, repair.stop) == ("drop", ("RKNE",), 0, 60)
    # |(0.08, 0.05)| = 94 mm, less what the robust pose still yields to it
    assert 75 <= int(re.search(r"stays (\d+) mm from its model place", repair.evidence)[1]) <= 94
    assert np.isnan(motion.residuals[:, knee]).all()
    assert np.abs(motion.q[:, hip] - cap.q[:, hip]).mean() < 0.5 * DEG


def test_joint_ranges_are_respected():
    cap = fk_trial(n_frames=40, placement_mm=0, sta_mm=0, noise_mm=0, seed=4)
    q = cap.q.copy()
    knee = DOF_NAMES.index("knee_flexion_l")
    q[:, knee] = -25 * DEG                                  # hyper-extension beyond -10 deg
    markers = cap.skeleton.points(q, cap.segments, cap.offsets)
    motion = fit(Trial(markers, cap.trial.labels, 100.0), true_model(cap))
    lower, upper = Skeleton.bounds()
    assert (motion.q >= lower - 1e-12).all() and (motion.q <= upper + 1e-12).all()
    np.testing.assert_allclose(motion.q[:, knee], lower[knee], atol=1e-9)  # held at the bound


def test_an_angle_just_inside_its_range_is_fitted_inside_it():
    # an elbow 1e-5 rad above its lower bound: the predicted frames' first step (taken
    # without a trial) may aim past the bound and must be clipped as the iterations' are
    cap = fk_trial(n_frames=60, placement_mm=0, sta_mm=0, noise_mm=0, seed=3)
    q = cap.q.copy()
    lower, upper = Skeleton.bounds()
    elbow = DOF_NAMES.index("elbow_flexion_l")
    q[:, elbow] = lower[elbow] + 1e-5
    markers = cap.skeleton.points(q, cap.segments, cap.offsets)
    motion = fit(Trial(markers, cap.trial.labels, 100.0), true_model(cap))
    assert (motion.q >= lower).all() and (motion.q <= upper).all()


def test_segments_without_markers_are_locked_at_zero_and_reported():
    cap = fk_trial(n_frames=40, placement_mm=0, sta_mm=0, noise_mm=0.5, seed=5)
    proto = load_protocol("fullbody38")
    keep = [i for i, m in enumerate(proto.markers)
            if not m.landmark.segment.startswith(("humerus", "forearm"))]
    locked, left_out = locked_dofs(cap.segments[keep])
    model = SubjectModel(cap.skeleton, proto, [proto.labels[i] for i in keep],
                         cap.segments[keep], cap.offsets[keep], locked_dofs=locked,
                         left_out=left_out)
    motion = fit(cap.trial, model)
    arms = [n for n in DOF_NAMES if n.startswith(("shoulder", "elbow"))]
    assert sorted(motion.locked_dofs) == sorted(arms)
    assert (motion.q[:, [DOF_NAMES.index(n) for n in arms]] == 0).all()
    legs = [DOF_NAMES.index(n) for n in DOF_NAMES if n.startswith(("hip", "knee"))]
    # the legs do not depend on the arms: 0.5 mm noise keeps them within a degree
    assert np.abs(motion.q[:, legs] - cap.q[:, legs]).max() < 1 * DEG


def test_frames_without_pelvis_are_flagged_and_interpolated():
    cap = fk_trial(n_frames=60, placement_mm=0, sta_mm=0, noise_mm=0.5, seed=6)
    markers = cap.trial.markers.copy()
    pelvis = [cap.trial.labels.index(x) for x in ("LASI", "RASI", "LPSI")]
    markers[20:25][:, pelvis] = np.nan
    motion = fit(Trial(markers, cap.trial.labels, 100.0), true_model(cap))
    assert motion.failed.tolist() == [20 <= f < 25 for f in range(60)]
    assert np.isnan(motion.residuals[20:25]).all()
    assert np.isfinite(motion.q).all()


def test_frames_that_cannot_be_posed_are_not_solved_and_leave_their_neighbours_alone(
        monkeypatch):
    # the subject half out of view (as motonms' walks start): no pelvis marker and two others
    # on frames 40-79; those frames fail whatever their pose, so they are not solved (their
    # free poses would take the solver's full iterations and pull their neighbours through
    # the continuity term), and the frames beside them are fitted as the ends of a capture
    # (1.3 deg from the truth at most; 0.5 deg without the gap: a one-sided continuity term)
    import mocaplib.model.ik as ik

    cap = fk_trial(n_frames=120, placement_mm=0, sta_mm=0, noise_mm=0.5, seed=7)
    markers = cap.trial.markers.copy()
    markers[40:80, 2:] = np.nan
    model = true_model(cap)
    pelvis = np.flatnonzero(model.marker_segments == SEGMENT_NAMES.index("pelvis"))
    assert not set(pelvis) & {0, 1}
    solved = []

    def solve_poses(skeleton, x, *args, **kwargs):
        solved.append(np.isfinite(x[:, pelvis, 0]).sum(axis=1).min())
        return ik.solve_poses.__wrapped__(skeleton, x, *args, **kwargs)

    solve_poses.__wrapped__ = ik.solve_poses
    monkeypatch.setattr(ik, "solve_poses", solve_poses)
    motion, _ = fit_filtered(Trial(markers, cap.trial.labels, 100.0), model, cutoff=6.0)
    assert solved and min(solved) >= ik.MIN_PELVIS_MARKERS
    assert motion.failed.tolist() == [40 <= f < 80 for f in range(120)]
    beside = np.r_[30:40, 80:90]
    assert np.abs(motion.q[beside] - cap.q[beside])[:, ROT].max() < 2 * DEG


def test_a_frame_with_two_pelvis_markers_is_not_posed():
    # three markers place the pelvis, the root, by its own; with two, its turn about the line
    # through them rests on the legs' and trunk's soft tissue (motonms' walks entering the
    # volume: pelvis tilt at its -45 deg limit, tests/test_fit_real.py), so such frames fail:
    # flagged, their angles interpolated between the posed frames around them
    cap = fk_trial(n_frames=120, placement_mm=0, sta_mm=0, noise_mm=0.5, seed=7)
    markers = cap.trial.markers.copy()
    model = true_model(cap)
    one_side = [model.labels.index(label) for label in ("LASI", "LPSI")]
    assert all(model.marker_segments[j] == SEGMENT_NAMES.index("pelvis") for j in one_side)
    markers[40:80, [cap.trial.labels.index(label) for label in ("LASI", "LPSI")]] = np.nan
    motion, _ = fit_filtered(Trial(markers, cap.trial.labels, 100.0), model, cutoff=6.0)
    assert motion.failed.tolist() == [40 <= f < 80 for f in range(120)]
    assert fit_quality(motion)["failed_frames"] == list(range(40, 80))


def test_failed_frames_do_not_count_at_a_joint_limit():
    # the angles of unsolved frames are copies of the solved frames beside them: a capture
    # whose first solved frame sits at a limit would otherwise seem to spend its whole
    # unsolved start there (Walking1's pelvis tilt: 30 % of all its frames, 3.5 % of the solved)
    skeleton = Skeleton.from_height(1.75)
    lower, _ = skeleton.bounds()
    j = DOF_NAMES.index("pelvis_tilt")
    q = np.zeros((100, len(DOF_NAMES)))
    q[:31, j] = lower[j]                              # 30 unsolved frames and one solved
    failed = np.arange(100) < 30
    assert Motion(q, skeleton, 100.0).limit_shares() == pytest.approx({"pelvis_tilt": 0.31})
    motion = Motion(q, skeleton, 100.0, failed=failed)
    assert motion.limit_shares() == pytest.approx({"pelvis_tilt": 1 / 70})
    assert motion.limit_shares(np.arange(100) < 50) == pytest.approx({"pelvis_tilt": 0.05})
    assert motion.limit_warnings() == []              # 1.4 %, under the 2 % warning


def test_initial_pose_is_exact_on_exact_markers():
    cap = fk_trial(n_frames=30, placement_mm=0, sta_mm=0, noise_mm=0, seed=7)
    q0 = initial_pose(cap.skeleton, cap.trial.markers, cap.segments, cap.offsets)
    # rigid fits of exact points, decomposed exactly: round-off only
    np.testing.assert_allclose(q0, cap.q, atol=1e-9)


def test_solve_poses_many_frames_at_once_matches_one_by_one():
    cap = fk_trial(n_frames=6, placement_mm=0, sta_mm=0, noise_mm=2.0, seed=8)
    args = (cap.skeleton, cap.trial.markers, cap.segments, cap.offsets)
    batch = solve_poses(*args, smoothing=0.0)
    single = [solve_poses(cap.skeleton, cap.trial.markers[f:f + 1], cap.segments, cap.offsets,
                          smoothing=0.0).q[0] for f in range(6)]
    # same minimum per frame; both stop within the 1e-4 rad step tolerance
    np.testing.assert_allclose(batch.q, np.array(single), atol=2e-4)


def test_trial_without_model_markers_is_refused():
    cap = fk_trial(n_frames=5)
    other = Trial(cap.trial.markers, [f"X{i}" for i in range(cap.trial.n_markers)], 100.0,
                  source="other.c3d")
    with pytest.raises(FitError, match="other.c3d: none of the model's markers"):
        fit(other, true_model(cap))


def test_locked_dofs_rule():
    proto = load_protocol("fullbody38")
    segments, _ = proto.nominal_offsets()
    assert locked_dofs(segments) == ([], [])
    no_arms = segments[[i for i, m in enumerate(proto.markers)
                        if "humerus" not in m.landmark.segment
                        and "forearm" not in m.landmark.segment]]
    locked, left_out = locked_dofs(no_arms)
    assert left_out == ["humerus_r", "forearm_r", "humerus_l", "forearm_l"]
    assert set(locked) == {n for n in DOF_NAMES if n.startswith(("shoulder", "elbow"))}


def test_jumping_and_mislabelled_samples_are_removed_and_counted():
    cap = fk_trial(n_frames=120, placement_mm=0, sta_mm=3, noise_mm=0.7, seed=4)
    clean = fit(cap.trial, true_model(cap))
    assert not clean.rejected.any(), "soft tissue and noise alone are never outliers"
    markers = cap.trial.markers.copy()
    toe, psis = cap.trial.labels.index("LTOE"), cap.trial.labels.index("RPSI")
    markers[40:45, toe] += (0.0, 0.0, 0.06)          # a 60 mm jump for five frames
    markers[90, psis] += (0.20, 0.05, 0.0)           # another trajectory labelled RPSI
    trial = Trial(markers, cap.trial.labels, cap.trial.rate, source="glitch.c3d")
    motion = fit(trial, true_model(cap))
    expected = np.zeros_like(motion.rejected)
    expected[40:45, toe] = expected[90, psis] = True
    np.testing.assert_array_equal(motion.rejected, expected)
    assert np.isnan(motion.residuals[expected]).all()
    # without them the frames fit as the clean capture does (0.3 mm: refit round-off and
    # noise); the foot without its toe marker rests on fewer markers near its axis, so its
    # angles may move by up to ~1 deg in those frames (measured 0.48 deg)
    assert np.nanmax(motion.residuals) < np.nanmax(clean.residuals) + 3e-4
    np.testing.assert_allclose(motion.q[:, ROT], clean.q[:, ROT], atol=1.0 * DEG)
    quality = fit_quality(motion)
    assert quality["rejected_samples"] == 6
    assert quality["rejected_per_marker"] == {"LTOE": 5, "RPSI": 1}


def test_a_marker_drifting_smoothly_away_is_kept():
    # a toe marker the skeleton cannot follow drifts 60 mm away and back over 0.4 s: a large
    # residual, but no jump, so it stays (and shows in the residuals) instead of being removed
    cap = fk_trial(n_frames=120, placement_mm=0, sta_mm=3, noise_mm=0.7, seed=4)
    markers = cap.trial.markers.copy()
    toe = cap.trial.labels.index("LTOE")
    markers[40:80, toe, 2] += 0.06 * np.sin(np.linspace(0, np.pi, 40))
    motion = fit(Trial(markers, cap.trial.labels, cap.trial.rate), true_model(cap))
    assert not motion.rejected.any()
    # the robust fit shares the drift with the foot's pose (measured 28 mm left on the toe);
    # fitted without the toe it would be 60 mm off and, but for the jump rule, removed
    assert np.nanmax(motion.residuals[:, toe]) > 0.02


def test_outliers_are_found_before_the_low_pass_spreads_them():
    from mocaplib.model.filtering import filter_trial

    cap = fk_trial(n_frames=150, placement_mm=0, sta_mm=3, noise_mm=0.7, seed=5)
    markers = cap.trial.markers.copy()
    t10 = cap.trial.labels.index("T10")
    markers[70:74, t10] += (-0.045, 0.0, 0.0)        # four frames of a 45 mm jump
    trial = Trial(markers, cap.trial.labels, cap.trial.rate, source="jump.c3d")
    model = true_model(cap)
    motion, cutoff = fit_filtered(trial, model, cutoff=6.0)
    assert cutoff == 6.0
    expected = np.zeros_like(motion.rejected)
    expected[70:74, t10] = True
    np.testing.assert_array_equal(motion.rejected, expected)
    # filtered first, the jump becomes a smooth bump the jump rule does not remove (this is why
    # fit_filtered looks at the raw markers first)
    smeared = fit(filter_trial(trial, cutoff=6.0)[0], model)
    assert not smeared.rejected[:, t10].any()
    # with the jump gapped before filtering, the kept samples fit as the clean capture does
    assert np.nanmax(motion.residuals[:, t10]) < 0.01


def test_points_outside_the_model_do_not_change_the_filtered_fit():
    # fit_filtered filters and refits the model's markers only: a file's other points (here
    # noisy virtual points, as CMU's files hold hundreds of) change nothing
    cap = fk_trial(n_frames=120, placement_mm=0, sta_mm=3, noise_mm=0.7, seed=8)
    model = true_model(cap)
    extra = np.random.default_rng(1).normal(0, 0.5, (120, 30, 3))
    wide = Trial(np.concatenate([extra, cap.trial.markers], axis=1),
                 [f"V{i}" for i in range(30)] + cap.trial.labels, cap.trial.rate)
    alone, _ = fit_filtered(cap.trial, model, cutoff=6.0)
    among, _ = fit_filtered(wide, model, cutoff=6.0)
    np.testing.assert_array_equal(among.q, alone.q)
    np.testing.assert_array_equal(among.rejected, alone.rejected)


def test_normal_equations_from_moments_equal_the_jacobians():
    cap = fk_trial(n_frames=4, placement_mm=0, sta_mm=6, noise_mm=1, seed=9)
    q = cap.q + np.random.default_rng(0).normal(0, 2 * DEG, cap.q.shape)
    chain = cap.skeleton.chain(q)
    pts, jac = cap.skeleton.marker_jacobian(q, cap.segments, cap.offsets, chain=chain)
    r = cap.trial.markers - pts
    w = np.random.default_rng(1).uniform(0.2, 1.0, r.shape[:2])
    twist, origin = twists(chain)
    about = pts.transpose(0, 2, 1) - origin[:, :, None]
    A, g = normal_equations(twist, about, MOVES[cap.segments].astype(float),
                             r.transpose(0, 2, 1).copy(), w)
    J = jac.reshape(len(q), -1, len(DOF_NAMES))
    W = np.repeat(w, 3, axis=1)[..., None]
    # the same sums in another order: round-off only (entries up to ~30 m²)
    np.testing.assert_allclose(A, J.transpose(0, 2, 1) @ (W * J), atol=1e-12)
    np.testing.assert_allclose(g, np.einsum("fkd,fk->fd", J, W[..., 0] * r.reshape(len(q), -1)),
                               atol=1e-14)


def test_keyframes_are_sparse_when_still_and_dense_when_moving():
    walk = fk_trial(n_frames=200, placement_mm=0, sta_mm=0, noise_mm=0.5)
    still = np.repeat(walk.trial.markers[:1], 200, axis=0)
    still = still + np.random.default_rng(0).normal(0, 0.0005, still.shape)
    keys = keyframes(still)
    # 0.5 mm noise stays within 5 mm of a straight line: every 32nd frame and the last
    assert keys.tolist() == list(range(0, 200, 32)) + [199]
    gaps = np.diff(keyframes(walk.trial.markers))
    assert gaps.min() == 4 and gaps.max() <= 32 and len(gaps) > 200 / 16
    still[20:40, 3] = np.nan            # unseen at keyframe 32, seen between it and 0 and 64
    assert np.isin([16, 48], keyframes(still)).all()


@pytest.mark.parametrize("static", [True, False])
def test_fit_reaches_the_minimum_of_a_full_solve(static):
    cap = fk_trial(n_frames=120, placement_mm=0, sta_mm=6, noise_mm=1, static=static, seed=10)
    model = true_model(cap)
    motion = fit(cap.trial, model)
    full = solve_poses(cap.skeleton, cap.trial.markers, cap.segments, cap.offsets,
                       free=model.free, weights=model.marker_weights, tol=1e-9,
                       step_tol=1e-7)                               # every frame, rigid starts
    off = np.abs(motion.q - full.q)
    # keyframe predictions and their step test stop within step_tol (5e-4 rad) of the minimum,
    # as the iterations do; along the few flat directions (ankle inversion, shoulder rotation:
    # markers a few cm from the axis) the relative-cost rule (1e-4) may stop up to ~0.2 deg off
    assert np.quantile(off, 0.99) < 5e-4 and off.max() < 5e-3, (np.quantile(off, 0.99), off.max())


@pytest.mark.parametrize("still", [True, False])
def test_a_warm_started_fit_reaches_the_minimum_of_a_full_solve(still):
    from dataclasses import replace

    from mocaplib.model.ik import LONGEST_STRIDE, OUTLIER_PASS

    cap = fk_trial(n_frames=120, placement_mm=0, sta_mm=6, noise_mm=0, seed=10)
    rng = np.random.default_rng(3)
    markers = np.repeat(cap.trial.markers[:1], 120, axis=0) if still else cap.trial.markers
    trial = replace(cap.trial, markers=markers + rng.normal(0, 0.0005, markers.shape))
    noisier = replace(cap.trial, markers=markers + rng.normal(0, 0.0015, markers.shape))
    # still: keyframes 32 frames apart, so the refit predicts the frames between them from
    # the keyframes solved again; moving: every frame starts from the previous fit
    assert (np.diff(keyframes(trial.markers)).max() == LONGEST_STRIDE) == still
    model = true_model(cap)
    start = fit(noisier, model, **OUTLIER_PASS).q            # as fit_filtered's raw pass
    motion = fit(trial, model, q0=start)
    full = solve_poses(cap.skeleton, trial.markers, cap.segments, cap.offsets,
                       free=model.free, weights=model.marker_weights, tol=1e-9, step_tol=1e-7)
    off = np.abs(motion.q - full.q)
    # the same stopping rules as from the coarse start (the test above)
    assert np.quantile(off, 0.99) < 5e-4 and off.max() < 5e-3, (np.quantile(off, 0.99), off.max())


def test_initial_pose_interpolates_a_segment_unseen_for_a_while():
    cap = fk_trial(n_frames=40, placement_mm=0, sta_mm=0, noise_mm=0)
    markers = cap.trial.markers.copy()
    forearm = SEGMENT_NAMES.index("forearm_r")
    markers[10:20, cap.segments == forearm] = np.nan
    q0 = initial_pose(cap.skeleton, markers, cap.segments, cap.offsets)
    elbow = DOF_NAMES.index("elbow_flexion_r")
    # the other segments are seen: exact (round-off); the elbow is the straight line over the gap
    others = np.arange(len(DOF_NAMES)) != elbow
    np.testing.assert_allclose(q0[:, others], cap.q[:, others], atol=1e-9)
    expected = np.interp(np.arange(10, 20), [9, 20], cap.q[[9, 20], elbow])
    np.testing.assert_allclose(q0[10:20, elbow], expected, atol=1e-9)


def test_fit_stops_by_the_callers_tolerances(monkeypatch):
    import mocaplib.model.ik as ik

    cap = fk_trial(n_frames=60, placement_mm=0, sta_mm=6, noise_mm=1, seed=12)
    model = true_model(cap)
    settings = dict(robust_scale=np.inf, smoothing=0.0)
    default = fit(cap.trial, model, **settings)
    asked = []

    def solve(*args, **kwargs):
        asked.append((kwargs["tol"], kwargs["step_tol"]))
        return solve_poses(*args, **kwargs)

    monkeypatch.setattr(ik, "solve_poses", solve)
    tight = fit(cap.trial, model, tol=1e-10, step_tol=1e-7, **settings)
    assert asked and set(asked) == {(1e-10, 1e-7)}          # every solve, the caller's rule

    def cost(motion):
        return np.nansum(motion.residuals ** 2, axis=1)

    # the default rule (1e-4 relative, 5e-4 rad) leaves the plain least-squares objective
    # within 1e-4 of the tight rule's in every frame (measured 1.6e-6 at most)
    np.testing.assert_allclose(cost(default), cost(tight), rtol=1e-4)
