"""The synthetic walker: feet, joints, velocities and markers checked against physics and the
published ranges, independently of the generator's own bookkeeping where possible."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from mocaplib.errors import SynthError
from mocaplib.runs import valid_runs
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton
from mocaplib.synth import Command, MarkerSettings, min_duration, synthesize_capture
from mocaplib.synth.body import SWING_KNEE_FLOOR, body_motion
from mocaplib.synth.gait import FLAT, FootGeometry

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


def _segment_points(cap, segment: str, offsets: np.ndarray) -> np.ndarray:
    """Points fixed in ``segment`` (K, 3) over the capture from the TRUE angles: (F, K, 3)."""
    sk = cap.skeleton
    idx = np.full(len(offsets), SEGMENT_NAMES.index(segment))
    return sk.points(cap.body.q, idx, offsets)


def _soles(cap, side: str) -> np.ndarray:
    g = FootGeometry.from_skeleton(cap.skeleton)
    offsets = np.array([[g.heel, 0, -g.ankle_height], [g.mtp, 0, -g.ankle_height]])
    return _segment_points(cap, f"foot_{side}", offsets)


def measured_velocities(cap) -> dict:
    """v̂, ω̂, v̂_l, v̂_f measured from the shoulder centres of the true angles (FK), not from
    the generator: the stride T from the left toe-off events; for start times s spread over one
    stride, the chord M(s+T) - M(s) of the shoulder midpoint expressed in the shoulder frame at
    s (this cancels the body's periodic sway exactly to first order) is averaged; the arc
    length is chord x (Δθ/2)/sin(Δθ/2) with Δθ = ω̂ T, and the chord's direction is the path
    tangent half-way, so θ_T − θ_S = angle(chord) − Δθ/2."""
    offs = [e.time_s for e in cap.trial.events if e.context == "Left" and e.label == "Foot Off"]
    T = offs[1] - offs[0]
    sk = cap.skeleton
    T_seg = sk.forward(cap.body.q)
    left = T_seg[:, SEGMENT_NAMES.index("humerus_l"), :2, 3]
    right = T_seg[:, SEGMENT_NAMES.index("humerus_r"), :2, 3]
    lr = right - left
    theta = np.unwrap(np.arctan2(lr[:, 1], lr[:, 0]) + np.pi / 2)
    time = cap.trial.time
    mid = CubicSpline(time, 0.5 * (left + right))
    heading = CubicSpline(time, theta)
    s = offs[0] + T * np.arange(50) / 50
    turn = heading(s + T) - heading(s)
    chord = mid(s + T) - mid(s)
    c, sn = np.cos(heading(s)), np.sin(heading(s))
    local = np.stack([c * chord[:, 0] + sn * chord[:, 1], -sn * chord[:, 0] + c * chord[:, 1]], 1)
    mean = local.mean(axis=0)
    omega = float(turn.mean() / T)
    half = omega * T / 2
    v = float(np.hypot(*mean) * (half / np.sin(half) if abs(half) > 1e-9 else 1.0) / T)
    rel = np.arctan2(mean[1], mean[0]) - half
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
        soles = _soles(cap, side)
        # sole points never below the floor (1e-6 m: truth angles are exact, only round-off)
        assert soles[..., 2].min() > -1e-6
        for start, stop in valid_runs(cap.body.contact[:, col] == FLAT):
            drift = np.linalg.norm(soles[start:stop] - soles[start], axis=-1).max()
            assert drift <= 0.005, f"{name}: {side} foot slips {drift * 1000:.1f} mm"
            assert np.abs(soles[start:stop, :, 2]).max() < 1e-6, "a flat foot lies on the floor"


@pytest.mark.parametrize("name", ["straight_normal", "curve_left_r1", "spot_left", "side_left",
                                  "run"])
def test_event_times_are_exact_contacts(name):
    """The body evaluated exactly at each event: at a heel strike the heel is on the floor and
    10 ms earlier it is not; at a toe-off the forefoot is on the floor and 10 ms later it is not."""
    cap = capture(name)
    events = cap.truth["events"]
    times = np.array([e["time_s"] for e in events])
    step = np.array([-0.01 if e["kind"] == "heel_strike" else 0.01 for e in events])
    t_mid = cap.trial.time[-1] / 2
    at, near = (body_motion(cap.command, cap.params, cap.skeleton, 1.75, x, t_mid=t_mid)
                for x in (times, times + step))
    g = FootGeometry.from_skeleton(cap.skeleton)
    soles = np.array([[g.heel, 0, -g.ankle_height], [g.mtp, 0, -g.ankle_height]])
    for k, event in enumerate(events):
        seg = np.array([SEGMENT_NAMES.index(f"foot_{event['side'][0]}")] * 2)
        on = cap.skeleton.points(at.q[k:k + 1], seg, soles)[0, :, 2]
        off = cap.skeleton.points(near.q[k:k + 1], seg, soles)[0, :, 2]
        point = 0 if event["kind"] == "heel_strike" else 1
        assert abs(on[point]) < 1e-6 and on.min() > -1e-6
        assert off.min() > 0.0005, f"{name}: {event} is not the moment of contact"


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
    """Judged from the true sole heights: lowest sole point of each foot above 1 mm = airborne."""
    for name, flight in (("run", True), ("straight_normal", False)):
        cap = capture(name)
        airborne = np.stack([_soles(cap, side)[..., 2].min(axis=1) > 0.001 for side in "lr"], 1)
        both_off, both_on = airborne.all(axis=1).mean(), (~airborne).all(axis=1).mean()
        if flight:
            assert both_off > 0.1 and both_on == 0.0
        else:
            assert both_off == 0.0 and both_on > 0.1


@pytest.mark.parametrize("name", sorted(TYPES) + ["rest"])
def test_joint_angles_within_skeleton_bounds(name):
    q = capture(name).body.q
    lo, hi = Skeleton.bounds()
    assert np.all(q >= lo) and np.all(q <= hi)


def test_normal_walking_joint_patterns_are_human():
    """Sagittal ranges of normal walking (Winter 2009; Perry 2010), generous margins."""
    q = capture("straight_normal").body.q
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


def test_markers_follow_the_true_angles_plus_artefacts():
    clean = capture("straight_normal", placement_sd=0.0, soft_tissue=0.0, noise_sd=0.0)
    segments, offsets = _protocol_offsets(clean)
    fk = clean.skeleton.points(clean.body.q, segments, offsets)
    err = np.linalg.norm(clean.trial.markers - fk, axis=-1)
    lower = [i for i, s in enumerate(segments) if SEGMENT_NAMES[s].split("_")[0]
             in ("pelvis", "femur", "tibia", "foot", "head")]
    # without artefacts, markers on leg, pelvis and head segments ARE the fitting skeleton's FK
    assert err[:, lower].max() < 1e-9
    # the richer body (shoulder girdle) moves arm markers by millimetres, not centimetres
    assert 0.001 < err.max() < 0.03

    real = capture("straight_normal")
    err = np.linalg.norm(real.trial.markers - fk, axis=-1)
    rms = np.sqrt((err ** 2).mean())
    # placement (3 mm/axis) + soft tissue (several mm) + 0.7 mm noise: a few mm overall
    assert 0.004 < rms < 0.015
    assert real.trial.markers[..., 2].min() > 0.0, "no marker below the floor"


def _protocol_offsets(cap):
    from mocaplib.protocols import load_protocol
    return load_protocol("fullbody38").nominal_offsets(cap.truth["subject"]["height"])


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
    np.testing.assert_array_equal(a.body.q, c.body.q)  # the seed touches markers only


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
    from mocaplib.synth import Subject
    quiet = MarkerSettings(placement_sd=0.0, noise_sd=0.0)
    sizes = []
    for mass in (60.0, 100.0):
        cap = synthesize_capture(TYPES["straight_normal"], duration=2.6, seed=3, markers=quiet,
                                 subject=Subject(1.75, mass))
        segments, offsets = _protocol_offsets(cap)
        fk = cap.skeleton.points(cap.body.q, segments, offsets)
        thigh = [i for i, s in enumerate(segments) if SEGMENT_NAMES[s].startswith("femur")]
        sizes.append(np.linalg.norm(cap.trial.markers[:, thigh] - fk[:, thigh], axis=-1).max())
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
    T = cap.skeleton.forward(cap.body.q)
    knee = {s: T[:, SEGMENT_NAMES.index(f"tibia_{s}"), :3, 3] for s in "lr"}
    ankle = {s: T[:, SEGMENT_NAMES.index(f"foot_{s}"), :3, 3] for s in "lr"}
    soles = {s: _soles(cap, s) for s in "lr"}
    # shank axes at least 5 cm apart (two shanks ~10 cm thick may brush, not cross) and the
    # soles' heel-to-metatarsal lines at least 3 cm apart
    assert _closest(knee["l"], ankle["l"], knee["r"], ankle["r"]).min() > 0.05
    assert _closest(soles["l"][:, 0], soles["l"][:, 1], soles["r"][:, 0],
                    soles["r"][:, 1]).min() > 0.03


@pytest.mark.parametrize("name", sorted(TYPES) + ["rest"])
def test_toes_and_markers_stay_above_the_floor(name):
    cap = capture(name)
    g = FootGeometry.from_skeleton(cap.skeleton)
    for col, side in enumerate("lr"):
        foot = cap.skeleton.forward(cap.body.q)[:, SEGMENT_NAMES.index(f"foot_{side}")]
        # toe tip through the toe joint (dorsiflexed by the generator's toe angle)
        tip = g.sole_points(cap.body.toe[:, col])[:, 2]
        z = np.einsum("fj,fj->f", foot[:, 2, :3], tip) + foot[:, 2, 3]
        assert z.min() > -1e-6
    # skin markers sit on top of the skin: never below the floor, even with noise
    assert np.nanmin(cap.trial.markers[..., 2]) > 0.005


@pytest.mark.parametrize("name", sorted(TYPES))
def test_swing_foot_clears_the_floor(name):
    """Mid-swing (the middle half of each swing, judged from the true events), the lowest sole
    point is at least 1 cm up: the foot is carried, not dragged."""
    cap = capture(name)
    time = cap.trial.time
    for side, context in (("l", "Left"), ("r", "Right")):
        low = _soles(cap, side)[..., 2].min(axis=1)
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
    q = cap.body.q / DEG
    for col, side in enumerate("lr"):
        knee = q[:, DOF_NAMES.index(f"knee_flexion_{side}")]
        stance = cap.body.contact[:, col] != 0
        assert 80 <= knee.max() <= 130
        assert 30 <= knee[stance].max() <= 60


def test_bad_settings_raise_synth_error():
    from mocaplib.synth import Subject
    with pytest.raises(SynthError, match="marker settings must be >= 0"):
        MarkerSettings(noise_sd=-0.001)
    with pytest.raises(SynthError, match="out of range"):
        Subject(height=1.75, mass=-3.0)


def test_toe_markers_bend_with_the_toe_joint_the_fit_does_not_have():
    from mocaplib.protocols import load_protocol
    protocol = load_protocol("plugin_gait_ofm")
    exact = MarkerSettings(placement_sd=0.0, soft_tissue=0.0, noise_sd=0.0)
    cap = synthesize_capture(TYPES["straight_normal"], duration=2.6, seed=2,
                             protocol="plugin_gait_ofm", markers=exact)
    segments, offsets = protocol.nominal_offsets(1.75)
    fk = cap.skeleton.points(cap.body.q, segments, offsets)
    hallux = cap.trial.labels.index("LHLX")
    gap = np.linalg.norm(cap.trial.markers[:, hallux] - fk[:, hallux], axis=1)
    toe = cap.body.toe[:, 0]
    assert gap[toe == 0].max() < 1e-9          # toes straight: the rigid foot's point
    assert gap[toe > 0.3].min() > 0.01         # toes bent at push-off: centimetres away
    assert cap.trial.markers[:, hallux, 2].min() > 0.0


def _knee_at(cap, dt: float):
    """True knee flexion (F, 2) (left, right), rad, and contact states (F, 2), every ``dt`` s."""
    t = np.arange(0.0, cap.trial.time[-1], dt)
    body = body_motion(cap.command, cap.params, cap.skeleton, 1.75, t,
                       t_mid=cap.trial.time[-1] / 2)
    knee = body.q[:, [DOF_NAMES.index("knee_flexion_l"), DOF_NAMES.index("knee_flexion_r")]]
    return knee, body.contact


@pytest.mark.parametrize("name", ["straight_fast", "run"])
def test_swing_knee_slows_down_towards_its_floor(name):
    """A swing foot planned beyond the leg's reach (fast walking, running): the knee extends to
    just above the gait's floor (walking terminal swing 0-5°, running late swing 10-20°), never
    below it, and within 15° of the floor its velocity changes by less than 200°/s per 1 ms
    step (a hard stop at the reach made steps of 700-2300°/s)."""
    cap = capture(name)
    floor = SWING_KNEE_FLOOR[cap.params.gait]
    knee, contact = _knee_at(cap, 1e-3)
    for col in range(2):
        swing = contact[:, col] == 0
        assert floor < knee[swing, col].min() < floor + 2 * DEG
        near = swing & (knee[:, col] < floor + 15 * DEG)
        inside = near[:-2] & near[1:-1] & near[2:]
        step = np.abs(np.diff(knee[:, col], 2))[inside] / 1e-3
        assert step.max() < 200 * DEG, f"{name}: knee velocity steps {step.max() / DEG:.0f}°/s"


@pytest.mark.parametrize("name", sorted(TYPES))
def test_swing_knee_velocity_has_no_step(name):
    """Inside swing the knee's acceleration is finite: estimated from 1 ms and from 0.25 ms
    steps it agrees within 15 % (a velocity step — the foot's lowest point jumping from toe to
    heel, or the leg stopping at its reach — makes the second estimate 4 times the first)."""
    cap = capture(name)
    estimates = []
    for dt in (1e-3, 2.5e-4):
        knee, contact = _knee_at(cap, dt)
        swing = contact == 0
        inside = swing[:-2] & swing[1:-1] & swing[2:]
        estimates.append(np.abs(np.diff(knee, 2, axis=0))[inside].max() / dt ** 2)
    np.testing.assert_allclose(estimates[1], estimates[0], rtol=0.15,
                               err_msg=f"{name}: swing knee acceleration does not converge")
