"""The synthetic walker: feet, joints, velocities and markers checked against physics and the
published ranges, independently of the generator's own bookkeeping where possible."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from mocaplib.errors import SynthError
from mocaplib.runs import valid_runs
from mocaplib.skeleton import DOF_NAMES, Skeleton
from mocaplib.library.command import Command
from mocaplib.synth.markers import MarkerSettings
from mocaplib.synth.capture import min_duration, synthesize_capture
from mocaplib.synth.body import SWING_KNEE_FLOOR, body_motion
from mocaplib.synth.gait import FLAT, SWING

DEG = np.pi / 180

#: One command per locomotion type the generator must handle.
TYPES = {
    "straight_slow": Command(v_f=0.6),
    "straight_normal": Command(v_f=1.2),
    "straight_fast": Command(v_f=1.8),
    "curve_left_r1": Command(v_f=1.0, omega=1.0),
    "curve_right_r3": Command(v_f=1.4, omega=-1.4 / 3),
    "spot_left": Command(omega=1.3),
    "spot_right": Command(omega=-0.5),
    "side_left": Command(v_l=0.6),
    "side_right": Command(v_l=-0.3),
    "diagonal_right_60": Command.from_kind("diagonal", speed=0.45, direction=-np.pi / 3),
    "diagonal_left_150": Command.from_kind("diagonal", speed=0.6, direction=5 * np.pi / 6),
    "side_left_curve_right": Command(v_l=0.5, omega=-0.5),
    "run": Command(v_f=3.0, gait="run"),
}


@lru_cache(maxsize=None)
def capture(name: str, seed: int = 1, **settings):
    command = TYPES[name] if name in TYPES else Command(gait="stand")
    return synthesize_capture(command, duration=max(min_duration(command) + 0.3, 2.0),
                              seed=seed, markers=MarkerSettings(**settings))


def true_angles(cap) -> np.ndarray:
    """The truth's fitting-skeleton DOFs (F, 32), rad."""
    return np.asarray(cap.truth["angles"]["values"])


def sole_points(cap, side: str, pose=None) -> np.ndarray:
    """World positions (F, K, 3) of one foot's sole points: heel, the other sole points of the
    rear foot, and the toe tip (on the toes, through the MTP joint), for ``pose`` (default the
    capture's)."""
    body = cap.body
    R, t = body.forward(cap.motion.pose if pose is None else pose)
    foot, toes = body.index(f"foot_{side}"), body.index(f"toes_{side}")
    shape = body.feet[side]
    rear = t[:, foot, None] + np.einsum("fij,kj->fki", R[:, foot],
                                        np.vstack([shape.heel, shape.sole]))
    tip = t[:, toes] + np.einsum("fij,j->fi", R[:, toes], shape.toe_tip - shape.mtp_point)
    return np.concatenate([rear, tip[:, None]], axis=1)


def measured_velocities(cap) -> dict:
    """v̂, ω̂, v̂_l, v̂_f measured from the generated glenohumeral centres, not from the truth's
    bookkeeping: the stride T from the left toe-off events; for start times s spread over one
    stride, the chord M(s+T) - M(s) of the shoulder midpoint (which cancels the body's periodic
    sway exactly) is expressed in the frame of the shoulder line's mean heading over
    [s, s+T] (which cancels its periodic yaw) and averaged; the arc length is chord x
    (Δθ/2)/sin(Δθ/2) with Δθ = ω̂ T, and the chord's direction is the path tangent half-way,
    where the mean heading also is, so θ_T − θ_S = angle(chord)."""
    offs = [e.time_s for e in cap.trial.events if e.context == "Left" and e.label == "Foot Off"]
    T = offs[1] - offs[0]
    left, right = cap.motion.shoulders[:, 0, :2], cap.motion.shoulders[:, 1, :2]
    lr = right - left
    theta = np.unwrap(np.arctan2(lr[:, 1], lr[:, 0]) + np.pi / 2)
    time = cap.trial.time
    mid = CubicSpline(time, 0.5 * (left + right))
    heading = CubicSpline(time, theta)
    s = offs[0] + T * np.arange(50) / 50
    turn = heading(s + T) - heading(s)
    chord = mid(s + T) - mid(s)
    # the mean over [s, s+T] sampled at the middles of 50 equal parts (sampling their starts
    # would put the mean T/100 early, a bias of ω̂T/100 rad in θ_T − θ_S)
    mean_heading = heading(s[:, None] + T * (np.arange(50) + 0.5) / 50).mean(axis=1)
    c, sn = np.cos(mean_heading), np.sin(mean_heading)
    local = np.stack([c * chord[:, 0] + sn * chord[:, 1], -sn * chord[:, 0] + c * chord[:, 1]], 1)
    mean = local.mean(axis=0)
    omega = float(turn.mean() / T)
    half = omega * T / 2
    v = float(np.hypot(*mean) * (half / np.sin(half) if abs(half) > 1e-9 else 1.0) / T)
    rel = np.arctan2(mean[1], mean[0])
    return {"v": v, "omega": omega, "v_l": v * np.sin(rel), "v_f": v * np.cos(rel)}


@pytest.mark.parametrize("name", sorted(TYPES))
def test_velocities_from_shoulders_match_command(name):
    cap = capture(name)
    got = measured_velocities(cap)
    cmd = cap.command
    want = {"v": cmd.speed, "omega": cmd.omega, "v_l": cmd.v_l, "v_f": cmd.v_f}
    for key in want:
        # the tolerance: 1 % or 0.01 (m/s, rad/s), whichever is larger
        tol = max(0.01 * abs(want[key]), 0.01)
        assert abs(got[key] - want[key]) <= tol, f"{name} {key}: {got[key]:.4f} vs {want[key]}"


@pytest.mark.parametrize("name", sorted(TYPES))
def test_truth_cycles_equal_command(name):
    cap = capture(name)
    cycles = cap.truth["cycles"]
    assert len(cycles) >= 2, "each moving capture holds two steady cycles"
    cmd = cap.command
    for cyc in cycles:
        assert cyc["end_s"] <= cap.trial.duration + 1e-9
        # v̂ and ω̂ are exact by construction (shoulders average to the commanded point)
        np.testing.assert_allclose([cyc["v"], cyc["omega"]], [cmd.speed, cmd.omega], atol=1e-6)
        # v̂_l, v̂_f differ by the trunk's yaw oscillation only (second order, well under 1 %)
        np.testing.assert_allclose([cyc["v_l"], cyc["v_f"]], [cmd.v_l, cmd.v_f],
                                   atol=0.01 * cmd.speed + 1e-9)


@pytest.mark.parametrize("name", sorted(TYPES) + ["rest"])
def test_stance_foot_does_not_slip_or_sink(name):
    cap = capture(name)
    for col, side in enumerate("lr"):
        soles = sole_points(cap, side)
        # sole points never below the floor (1e-6 m: measured 1e-15 m, round-off, on every
        # capture type and the standing trial)
        assert soles[..., 2].min() > -1e-6
        for start, stop in valid_runs(cap.motion.contact[:, col] == FLAT):
            drift = np.linalg.norm(soles[start:stop] - soles[start], axis=-1).max()
            assert drift <= 0.005, f"{name}: {side} foot slips {drift * 1000:.1f} mm"
            assert np.abs(soles[start:stop, :, 2]).max() < 1e-6, "a flat foot lies on the floor"


@pytest.mark.parametrize("name", ["straight_normal", "curve_left_r1", "spot_left", "side_left",
                                  "run"])
def test_event_times_are_exact_contacts(name):
    """The body evaluated exactly at each event: at a heel strike the heel is on the floor and
    10 ms earlier it is not; at a toe-off the tip of the toes is on the floor (every other sole
    point off it) and 10 ms later it is not: the toes left last, with no velocity (their tip
    rises 0.1 mm or more in 10 ms)."""
    cap = capture(name)
    events = cap.truth["events"]
    times = np.array([e["time_s"] for e in events])
    step = np.array([-0.01 if e["kind"] == "heel_strike" else 0.01 for e in events])
    t_mid = cap.trial.time[-1] / 2
    at, near = (body_motion(cap.command, cap.params, cap.body, x, t_mid=t_mid)
                for x in (times, times + step))
    for k, event in enumerate(events):
        side = event["side"][0]
        on = sole_points(cap, side, at.pose.take(slice(k, k + 1)))[0, :, 2]
        off = sole_points(cap, side, near.pose.take(slice(k, k + 1)))[0, :, 2]
        point = 0 if event["kind"] == "heel_strike" else -1          # heel, or toe tip
        assert abs(on[point]) < 1e-6 and on.min() > -1e-6
        assert off.min() > 1e-4, f"{name}: {event} is not the moment of contact"
        if event["kind"] == "toe_off":
            assert np.delete(on, point).min() > 0.002, "the rest of the foot left before"


@pytest.mark.parametrize("name", ["straight_slow", "straight_normal", "straight_fast"])
def test_the_foot_rolls_over_its_toes(name):
    """Push-off as the lab files show it (docs/results/event_accuracy.md): the toe marker (on
    the metatarsal heads) starts rising tens of ms before the toes' tips leave the floor, and
    is about a centimetre up when they do; the heel marker is over 8 cm up by then."""
    cap = capture(name)
    time = cap.trial.time
    for side, label in (("left", "LTOE"), ("right", "RTOE")):
        toe = cap.trial.markers[:, cap.trial.labels.index(label), 2]
        heel = cap.trial.markers[:, cap.trial.labels.index(label[0] + "HEE"), 2]
        stance = np.percentile(toe, 5)
        for off in (e["time_s"] for e in cap.truth["events"]
                    if e["side"] == side and e["kind"] == "toe_off"):
            at = np.interp(off, time, toe) - stance
            before = np.interp(off - 0.03, time, toe) - stance
            assert 0.005 < at < 0.02 and 0.001 < before < at, (name, side, off, at, before)
            assert np.interp(off, time, heel) - np.percentile(heel, 5) > 0.08


@pytest.mark.parametrize("name, cadence_range, step_range", [
    # published adult ranges (Oberg et al. 1993; Grieve 1968): slow ~80-100, normal ~100-120,
    # fast ~115-140 steps/min; step length ~0.4-0.55 / 0.6-0.75 / 0.75-0.9 m for 1.75 m
    ("straight_slow", (75, 100), (0.40, 0.55)),
    ("straight_normal", (100, 120), (0.60, 0.75)),
    ("straight_fast", (115, 140), (0.75, 0.95)),
    # recreational running at 3 m/s: 155-185 steps/min (Cavanagh & Kram 1989)
    ("run", (155, 185), (0.95, 1.20)),
])
def test_cadence_and_step_length(name, cadence_range, step_range):
    cap = capture(name)
    strikes = [e.time_s for e in cap.trial.events if e.label == "Foot Strike"]
    step_time = np.diff(strikes).mean()
    cadence = 60.0 / step_time
    step_length = cap.command.v_f * step_time
    assert cadence_range[0] <= cadence <= cadence_range[1]
    assert step_range[0] <= step_length <= step_range[1]


def test_running_has_a_flight_phase_and_walking_double_support():
    """Judged from the true sole points: lowest of each foot above 1 mm = airborne."""
    for name, flight in (("run", True), ("straight_normal", False)):
        cap = capture(name)
        airborne = np.stack([sole_points(cap, side)[..., 2].min(axis=1) > 0.001
                             for side in "lr"], 1)
        both_off, both_on = airborne.all(axis=1).mean(), (~airborne).all(axis=1).mean()
        if flight:
            assert both_off > 0.1 and both_on == 0.0
        else:
            assert both_off == 0.0 and both_on > 0.1


@pytest.mark.parametrize("name", sorted(TYPES) + ["rest"])
def test_true_angles_within_skeleton_bounds(name):
    q = true_angles(capture(name))
    lo, hi = Skeleton.bounds()
    assert np.all(q >= lo) and np.all(q <= hi)


def test_normal_walking_joint_patterns_are_human():
    """Sagittal ranges of normal walking (Winter 2009; Perry 2010), generous margins, in the
    fit's conventions."""
    q = true_angles(capture("straight_normal"))
    col = {n: q[:, DOF_NAMES.index(n)] / DEG for n in DOF_NAMES}
    for side in "lr":
        knee, hip = col[f"knee_flexion_{side}"], col[f"hip_flexion_{side}"]
        ankle = col[f"ankle_dorsiflexion_{side}"]
        assert 50 <= knee.max() <= 75 and 0 <= knee.min() <= 15
        assert 30 <= np.ptp(hip) <= 55 and -20 <= hip.min() <= 5
        assert 15 <= np.ptp(ankle) <= 40
    # arms swing opposite the legs: right shoulder flexion peaks near left hip flexion peak
    assert np.corrcoef(col["shoulder_flexion_r"], col["hip_flexion_l"])[0, 1] > 0.5
    assert np.corrcoef(col["shoulder_flexion_r"], col["hip_flexion_r"])[0, 1] < -0.5
    # the thorax counter-rotates against the pelvis
    pelvis = col["pelvis_rotation"] - col["pelvis_rotation"].mean()
    thorax = pelvis + col["trunk_rotation"]
    assert np.corrcoef(pelvis, thorax)[0, 1] < 0


@pytest.mark.parametrize("name", ["straight_normal", "side_left", "spot_right", "run"])
def test_the_ankle_complex_and_knee_move_within_human_ranges(name):
    """What the fitting skeleton cannot hold stays within what bone-pin and foot studies report:
    knee rotation and ab/adduction a few degrees, the foot's turn about the shank under 20°,
    the hip's rotation within ±30° (Lafortune et al. 1992; Benoit et al. 2006)."""
    cap = capture(name)
    extras = dict(zip(cap.truth["extras"]["names"], np.asarray(cap.truth["extras"]["values"]).T))
    q = true_angles(cap)
    for side in "lr":
        assert np.abs(extras[f"knee_adduction_{side}"]).max() < 5 * DEG
        assert np.abs(extras[f"knee_rotation_{side}"]).max() < 10 * DEG
        assert np.abs(extras[f"ankle_rotation_{side}"]).max() < 20 * DEG
        assert np.abs(q[:, DOF_NAMES.index(f"hip_rotation_{side}")]).max() < 30 * DEG


def test_markers_ride_on_the_body_with_artefacts():
    """Without artefacts every marker is exactly where the generator's body puts its landmark
    (its own catalogue, synthetic_body.toml), and that is not where the fit's catalogue puts
    it; with them, a few millimetres off."""
    from mocaplib.markersets.protocols import load_protocol
    clean = capture("straight_normal", placement_sd=0.0, soft_tissue=0.0, noise_sd=0.0)
    names = [m.landmark.name for m in load_protocol("fullbody38").markers]
    exact = clean.body.landmark_points(clean.motion.pose, names)
    np.testing.assert_allclose(clean.trial.markers, exact, atol=1e-9)
    real = capture("straight_normal")
    err = np.linalg.norm(real.trial.markers - exact, axis=-1)
    rms = np.sqrt((err ** 2).mean())
    # placement (3 mm/axis) + soft tissue (several mm) + 0.7 mm noise: a few mm overall
    assert 0.004 < rms < 0.015
    assert real.trial.markers[..., 2].min() > 0.0, "no marker below the floor"


def test_the_body_is_not_the_fitting_skeleton():
    """The generator's geometry is its own: its hip centres are Bell's, about a centimetre from
    where Harrington's regression (the fit's) puts them from the same ASIS and PSIS, and its
    knee markers are further apart than the fit's landmark catalogue has them."""
    from mocaplib.model.anatomy import harrington_hips
    from mocaplib.markersets.protocols import load_landmarks
    from mocaplib.synth.bones import synthetic_body
    from mocaplib.synth.truth import neutral_pose
    body = synthetic_body(1.75)
    pose = neutral_pose(body)
    names = ["L_ASIS", "R_ASIS", "L_PSIS", "R_PSIS"]
    lasi, rasi, lpsi, rpsi = body.landmark_points(pose, names)[0]
    left, right = (h[0] for h in harrington_hips(lasi[None], rasi[None],
                                                  0.5 * (lpsi + rpsi)[None]))
    _, t = body.forward(pose)
    bell = t[0, body.index("femur_l")], t[0, body.index("femur_r")]
    for ours, theirs in zip(bell, (left, right)):
        assert 0.005 < np.linalg.norm(ours - theirs) < 0.02
    # the catalogue's epicondyle markers are 100 mm apart, the body's 112 mm
    catalogue = load_landmarks()
    ours = np.linalg.norm(np.subtract(*body.landmark_points(pose, ["L_KNEE_LAT",
                                                                   "L_KNEE_MED"])[0]))
    theirs = np.linalg.norm(np.subtract(catalogue["L_KNEE_LAT"].position,
                                        catalogue["L_KNEE_MED"].position))
    assert abs(ours - theirs) > 0.005


def test_the_truth_reads_the_neutral_pose_as_zero_and_the_patterns_exactly():
    """The conversion (mocaplib.synth.truth): in the neutral pose every DOF reads 0; the
    pelvis, whose frame the patterns drive directly, reads its pattern exactly."""
    from mocaplib.synth.body import _patterns
    from mocaplib.synth.bones import synthetic_body
    from mocaplib.synth.command import reference_path
    from mocaplib.synth.truth import neutral_pose, true_angles as convert
    body = synthetic_body(1.75)
    q = convert(body, neutral_pose(body))
    rotations = ~np.isin(DOF_NAMES, ["pelvis_tx", "pelvis_ty", "pelvis_tz"])
    np.testing.assert_allclose(q[0, rotations], 0.0, atol=1e-9)
    cap = capture("curve_left_r1")
    t = cap.trial.time
    xy, theta = reference_path(cap.command, t, t_mid=t[-1] / 2)
    pattern = _patterns(cap.params, t, xy, theta, np.zeros(2))    # angles need no offset
    got = true_angles(cap)
    for name in ("pelvis_list", "pelvis_tilt"):
        np.testing.assert_allclose(got[:, DOF_NAMES.index(name)], pattern[name], atol=1e-9)


def test_gaps_and_label_swap_are_recorded():
    cap = capture("side_left", seed=5, gaps=3, swap=True)
    gaps = cap.truth["generator"]["gaps"]
    assert len(gaps) == 3
    for gap in gaps:
        m = cap.trial.labels.index(gap["label"])
        rows = np.isnan(cap.trial.markers[gap["start_frame"] - 1:gap["end_frame"], m, 0])
        assert rows.all()
    left, right = cap.truth["generator"]["swap"]
    assert left.startswith("L") and right == "R" + left[1:]
    # same seed without the swap: same positions, the pair's labels exchanged
    plain = capture("side_left", seed=5, gaps=3)
    np.testing.assert_array_equal(cap.trial.markers, plain.trial.markers)
    assert cap.trial.labels.index(left) == plain.trial.labels.index(right)
    assert cap.trial.labels.index(right) == plain.trial.labels.index(left)


def test_same_seed_same_capture_other_seed_other_markers():
    a = synthesize_capture(TYPES["curve_left_r1"], duration=2.7, seed=7)
    b = synthesize_capture(TYPES["curve_left_r1"], duration=2.7, seed=7)
    c = synthesize_capture(TYPES["curve_left_r1"], duration=2.7, seed=8)
    np.testing.assert_array_equal(a.trial.markers, b.trial.markers)
    assert np.abs(a.trial.markers - c.trial.markers).max() > 0.001
    np.testing.assert_array_equal(true_angles(a), true_angles(c))  # the seed touches markers


def test_bad_commands_and_durations_raise_synth_error():
    with pytest.raises(SynthError, match="too short"):
        synthesize_capture(Command(v_f=1.2), duration=1.0, seed=1)
    with pytest.raises(SynthError, match="gait must be"):
        Command(v_f=1.0, gait="hop")
    with pytest.raises(SynthError, match="standing"):
        Command(v_f=1.0, gait="stand")
    with pytest.raises(SynthError, match="radius"):
        Command.from_kind("curve", speed=1.0)
    with pytest.raises(SynthError, match="unknown locomotion kind"):
        Command.from_kind("moonwalk", speed=1.0)
    with pytest.raises(SynthError, match="speed is a magnitude, >= 0, got -50"):
        Command.from_kind("straight", speed=-50.0)


def test_soft_tissue_artefact_grows_with_body_mass():
    from mocaplib.synth.capture import Subject
    quiet = MarkerSettings(placement_sd=0.0, noise_sd=0.0)
    sizes = []
    for mass in (60.0, 100.0):
        cap = synthesize_capture(TYPES["straight_normal"], duration=2.6, seed=3, markers=quiet,
                                 subject=Subject(1.75, mass))
        thigh = [i for i, label in enumerate(cap.trial.labels) if label in ("LTHI", "RTHI")]
        exact = cap.body.landmark_points(cap.motion.pose, ["L_THIGH", "R_THIGH"])
        sizes.append(np.linalg.norm(cap.trial.markers[:, thigh] - exact, axis=-1).max())
    # same seed, same directions: the displacement scales with BMI (100/60 = 1.67)
    np.testing.assert_allclose(sizes[1] / sizes[0], 100.0 / 60.0, rtol=1e-6)
    assert 0.003 < sizes[0] < 0.03, "thigh artefact of a lean subject: several mm"


def _closest(a0, a1, b0, b1, samples: int = 15) -> np.ndarray:
    """Smallest distance (F,) between segments a0-a1 and b0-b1 (F, 3 each), sampled."""
    s = np.linspace(0.0, 1.0, samples)[None, :, None]
    a, b = a0[:, None] + (a1 - a0)[:, None] * s, b0[:, None] + (b1 - b0)[:, None] * s
    return np.linalg.norm(a[:, :, None] - b[:, None], axis=-1).min(axis=(1, 2))


@pytest.mark.parametrize("name", sorted(TYPES))
def test_legs_do_not_pass_through_each_other(name):
    cap = capture(name)
    _, t = cap.body.forward(cap.motion.pose)
    knee = {s: t[:, cap.body.index(f"tibia_{s}")] for s in "lr"}
    ankle = {s: t[:, cap.body.index(f"talus_{s}")] for s in "lr"}
    soles = {s: sole_points(cap, s) for s in "lr"}
    # shank axes at least 5 cm apart (two shanks ~10 cm thick may brush, not cross) and the
    # soles' heel-to-toe-tip lines at least 3 cm apart
    assert _closest(knee["l"], ankle["l"], knee["r"], ankle["r"]).min() > 0.05
    assert _closest(soles["l"][:, 0], soles["l"][:, -1], soles["r"][:, 0],
                    soles["r"][:, -1]).min() > 0.03


@pytest.mark.parametrize("name", sorted(TYPES) + ["rest"])
def test_markers_stay_above_the_floor(name):
    # skin markers sit on top of the skin: never below the floor, even with noise
    assert np.nanmin(capture(name).trial.markers[..., 2]) > 0.005


@pytest.mark.parametrize("name", sorted(TYPES))
def test_swing_foot_clears_the_floor(name):
    """Mid-swing (the middle half of each swing, judged from the true events), the lowest sole
    point is at least 1 cm up: the foot is carried, not dragged."""
    cap = capture(name)
    time = cap.trial.time
    for side, context in (("l", "Left"), ("r", "Right")):
        low = sole_points(cap, side)[..., 2].min(axis=1)
        offs = [e.time_s for e in cap.trial.events if e.context == context
                and e.label == "Foot Off"]
        strikes = [e.time_s for e in cap.trial.events if e.context == context
                   and e.label == "Foot Strike"]
        for off in offs:
            after = [s for s in strikes if s > off]
            if not after:
                continue
            span = after[0] - off
            mid = (time > off + span / 4) & (time < after[0] - span / 4)
            assert low[mid].min() > 0.01, f"{name}: {side} foot drags in swing"


def test_running_joint_patterns_are_human():
    """Running at 3 m/s (Novacheck 1998): swing knee flexion ~90-110°, stance knee ~35-55°."""
    cap = capture("run")
    q = true_angles(cap) / DEG
    for col, side in enumerate("lr"):
        knee = q[:, DOF_NAMES.index(f"knee_flexion_{side}")]
        stance = cap.motion.contact[:, col] != SWING
        assert 80 <= knee.max() <= 130
        assert 30 <= knee[stance].max() <= 60


def test_bad_settings_raise_synth_error():
    from mocaplib.synth.capture import Subject
    with pytest.raises(SynthError, match="marker settings must be >= 0"):
        MarkerSettings(noise_sd=-0.001)
    with pytest.raises(SynthError, match="out of range"):
        Subject(height=1.75, mass=-3.0)


def test_toe_markers_bend_with_the_toes():
    """The hallux marker rides on the toes, which bend at the MTP joint in push-off: its distance
    to the heel marker changes by centimetres, that of the 1st metatarsal head's by nothing."""
    exact = MarkerSettings(placement_sd=0.0, soft_tissue=0.0, noise_sd=0.0)
    cap = synthesize_capture(TYPES["straight_normal"], duration=2.6, seed=2,
                             protocol="plugin_gait_ofm", markers=exact)
    X = cap.trial.markers
    heel = X[:, cap.trial.labels.index("LCPG")]
    hallux = np.linalg.norm(X[:, cap.trial.labels.index("LHLX")] - heel, axis=1)
    metatarsal = np.linalg.norm(X[:, cap.trial.labels.index("LD1M")] - heel, axis=1)
    assert np.ptp(hallux) > 0.01 and np.ptp(metatarsal) < 1e-9
    mtp = cap.motion.pose.angles["toes_l"][:, 0]
    assert mtp.max() > 25 * DEG


def _knee_at(cap, dt: float):
    """The generator's knee flexion (F, 2) (left, right), rad, and contact states (F, 2), every
    ``dt`` s."""
    t = np.arange(0.0, cap.trial.time[-1], dt)
    motion = body_motion(cap.command, cap.params, cap.body, t, t_mid=cap.trial.time[-1] / 2)
    knee = np.column_stack([motion.pose.angles["tibia_l"][:, 0],
                            motion.pose.angles["tibia_r"][:, 0]])
    return knee, motion.contact


@pytest.mark.parametrize("name", ["straight_fast", "run"])
def test_swing_knee_never_passes_its_floor(name):
    """A swing leg planned straighter than the stance reach is saturated smoothly towards the
    gait's floor (walking terminal swing 0-5°, running late swing 10-20°) and never below it."""
    cap = capture(name)
    knee, contact = _knee_at(cap, 1e-3)
    swing = contact == SWING
    assert knee[swing].min() > SWING_KNEE_FLOOR[cap.params.gait]


@pytest.mark.parametrize("name", sorted(TYPES))
def test_swing_knee_velocity_has_no_step(name):
    """Inside swing the knee's acceleration is finite: estimated from 1 ms and from 0.25 ms
    steps it agrees within 15 % (a velocity step — the foot's lowest point jumping from toe to
    heel, or the leg stopping at its reach — makes the second estimate 4 times the first)."""
    cap = capture(name)
    estimates = []
    for dt in (1e-3, 2.5e-4):
        knee, contact = _knee_at(cap, dt)
        swing = contact == SWING
        inside = swing[:-2] & swing[1:-1] & swing[2:]
        estimates.append(np.abs(np.diff(knee, 2, axis=0))[inside].max() / dt ** 2)
    np.testing.assert_allclose(estimates[1], estimates[0], rtol=0.15,
                               err_msg=f"{name}: swing knee acceleration does not converge")
