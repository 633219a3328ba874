"""Cycles: cut at left toe-offs, velocities per cycle, the steadiest chosen, rest entries."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.gait.cycles import (REST_PERIOD, analyse_cycles, choose_cycle, choose_cycles,
                                  cycle_bounds)
from mocaplib.errors import EventError
from mocaplib.gait.foot_events import GaitEvent
from mocaplib.skeleton import DOF_NAMES

from gait_model import shoulders

RATE = 100.0
PERIOD = 1.1
TIME = np.arange(0, 5.0, 1 / RATE)


def events(first=0.31, n=4, quality=1.0):
    """Left toe-offs every PERIOD from ``first`` and right toe-offs/heel-strikes between."""
    out = []
    for k in range(n):
        t = first + k * PERIOD
        out += [GaitEvent("left", "toe_off", t, round(t * RATE), quality),
                GaitEvent("right", "heel_strike", t + 0.1, round((t + 0.1) * RATE), 1.0),
                GaitEvent("right", "toe_off", t + 0.55, round((t + 0.55) * RATE), 1.0)]
    return out


def test_bounds_are_consecutive_left_toe_offs():
    pairs = cycle_bounds(events(n=4))
    np.testing.assert_allclose([(a.time_s, b.time_s) for a, b in pairs],
                               [(0.31 + k * PERIOD, 0.31 + (k + 1) * PERIOD) for k in range(3)],
                               atol=1e-12)  # the events' own times
    assert all(a.side == b.side == "left" and a.kind == b.kind == "toe_off" for a, b in pairs)


def test_every_cycle_measured_and_one_chosen_by_the_choice():
    left, right = shoulders(TIME, v_f=1.0, omega=0.4, period=PERIOD, noise=0.001)
    cycles = analyse_cycles(events(), left, right, RATE)
    assert len(cycles) == 3 and not any(c.chosen for c in cycles)   # measured, not chosen
    assert len(choose_cycles(cycles)) == 1 and sum(c.chosen for c in cycles) == 1
    for c in cycles:
        # steady left curve of radius 2.5 m: issue targets (2 %, 0.02 rad/s, 0.02 m/s)
        np.testing.assert_allclose(c.velocities.v, 1.0, rtol=0.02)
        np.testing.assert_allclose(c.velocities.omega, 0.4, atol=0.02)
        np.testing.assert_allclose(c.velocities.v_l, 0.0, atol=0.02)
        np.testing.assert_allclose(c.period, PERIOD, atol=1e-12)
        assert c.velocities.pattern.kind == "arc" and not c.rest
    data = cycles[0].to_dict()
    for key in ("start_s", "end_s", "T", "pattern", "v", "omega", "v_l", "v_f",
                "fourier_n", "fourier_rms_deg", "chosen"):
        assert key in data
    assert data["pattern"]["type"] == "arc" and data["pattern"]["arc_angle_rad"] > 0


def test_steadiest_cycle_is_chosen_not_gait_initiation():
    # speeding up from 0.4 to 1.2 m/s during the first cycle, steady afterwards
    speed = np.clip(0.4 + 0.8 * (TIME - 0.31) / PERIOD, 0.4, 1.2)
    x = np.concatenate([[0.0], np.cumsum(speed[1:] / RATE)])
    left = np.column_stack([x, np.full_like(x, 0.18), np.full_like(x, 1.4)])
    right = left - [0.0, 0.36, 0.0]
    cycles = analyse_cycles(events(), left, right, RATE)
    choose_cycles(cycles)
    assert cycles[0].unsteadiness > 0.3  # |v2 - v1| ~ 0.4 m/s while accelerating
    assert not cycles[0].chosen and max(c.unsteadiness for c in cycles[1:]) < 0.01


def test_low_quality_events_are_avoided_when_possible():
    left, right = shoulders(TIME, period=PERIOD)
    evs = events()
    evs[3] = GaitEvent("left", "toe_off", evs[3].time_s, evs[3].frame, 0.2)  # 2nd toe-off
    cycles = analyse_cycles(evs, left, right, RATE)
    choose_cycles(cycles)
    assert cycles[2].chosen  # cycles 0 and 1 touch the poor toe-off
    for c in cycles:
        c.unsteadiness = 0.0
    assert choose_cycle(cycles) is cycles[2]


def test_standing_gives_one_rest_entry():
    left, right = shoulders(TIME, v_f=0.0, sway=0.0, noise=0.001)
    q = np.zeros((len(TIME), len(DOF_NAMES)))
    q[:, DOF_NAMES.index("knee_flexion_r")] = 0.05 + 0.002 * np.sin(TIME)
    (rest,) = analyse_cycles([], left, right, RATE, q=q)
    assert rest.rest and rest.chosen and rest.period == REST_PERIOD
    assert (rest.velocities.v, rest.velocities.omega, rest.velocities.v_l) == (0, 0, 0)
    assert rest.encoding.order == 0
    # order 0 holds the mean posture over the nominal period
    np.testing.assert_allclose(rest.encoding.series.a[DOF_NAMES.index("knee_flexion_r"), 0],
                               0.05 + 0.002 * np.mean(np.sin(TIME[TIME < REST_PERIOD])),
                               atol=1e-9)


@pytest.mark.parametrize("n_frames", [1, 2, 30, 99, 100])
def test_a_capture_shorter_than_the_rest_period_is_not_a_rest_entry(n_frames):
    # 2 frames of walking (no gait event in 0.02 s) became a 1 s rest entry in the library;
    # 100 frames at 100 Hz span 0.99 s (first to last frame) and were accepted
    left, right = shoulders(TIME, v_f=1.2, period=PERIOD)
    q = np.zeros((len(TIME), len(DOF_NAMES)))
    with pytest.raises(EventError, match=rf"short.c3d: a capture of {n_frames} frame\(s\) "
                                         r"cannot be a rest entry: .* s without a gait event"):
        analyse_cycles([], left[:n_frames], right[:n_frames], RATE, q=q[:n_frames],
                       source="short.c3d")
    (rest,) = analyse_cycles([], left[:101], right[:101], RATE, q=q[:101])  # 1 s is enough
    assert rest.rest


def test_cycles_with_fourier():
    left, right = shoulders(TIME, v_f=1.2, period=PERIOD)
    q = np.zeros((len(TIME), len(DOF_NAMES)))
    q[:, DOF_NAMES.index("hip_flexion_l")] = 0.4 * np.sin(2 * np.pi * TIME / PERIOD)
    q[:, DOF_NAMES.index("pelvis_tx")] = 1.2 * TIME
    cycles = analyse_cycles(events(), left, right, RATE, q=q)
    assert len(cycles) == 3
    for c in cycles:
        assert c.encoding.order == 1   # one harmonic reproduces a pure sine exactly
        assert c.to_dict()["fourier_rms_deg"] < 0.01


def test_no_complete_cycle_is_an_error():
    left, right = shoulders(TIME)
    with pytest.raises(EventError, match="walk.c3d: no complete cycle"):
        analyse_cycles(events(n=1), left, right, RATE, source="walk.c3d")


def truth_shoulder_centres(truth):
    """The true glenohumeral centres (F, 3) x 2 (left, right) of a truth file."""
    centres = np.asarray(truth["shoulders"]["values"])
    return centres[:, 0], centres[:, 1]


@pytest.mark.usefixtures("sample_dir")
def test_synthetic_truth_shoulders_give_the_true_velocities():
    from mocaplib.gait.patterns import cycle_velocities

    from sample_captures import samples

    checked = 0
    for name, trial, _, _, truth in samples():
        left, right = truth_shoulder_centres(truth)
        for true in truth["cycles"]:
            checked += 1
            got = cycle_velocities(left, right, trial.rate, true["start_s"], true["end_s"])
            # the targets: v 2 % (0.02 m/s near 0), omega 0.02 rad/s, v_l 0.02 m/s
            np.testing.assert_allclose(got.v, true["v"], atol=max(0.02 * true["v"], 0.02),
                                       err_msg=name)
            np.testing.assert_allclose(got.omega, true["omega"], atol=0.02, err_msg=name)
            np.testing.assert_allclose(got.v_l, true["v_l"], atol=0.02, err_msg=name)
            assert got.pattern.kind == true["pattern"]["type"] or (
                true["pattern"]["type"] == "arc" and abs(true["pattern"]["arc_angle"]) < 0.35
            ), name  # an arc turning < 20° over a cycle may be chosen as a line
    assert checked == 134  # two cycles in each of the 67 moving captures


@pytest.mark.usefixtures("sample_dir")
def test_synthetic_captures_from_markers():
    from sample_captures import samples

    from mocaplib.gait.events import ground_velocity
    from mocaplib.gait.feet import feet_of

    checked = 0
    for name, trial, match, events, truth in samples():
        label = {m.landmark.name: m.label for m in match.protocol.markers}
        # the ground velocity as the pipeline passes it: a false treadmill on a fast
        # overground gait (0.25 m/s of belt) would take that much off v
        cycles = analyse_cycles(events, match.marker(trial, label["L_ACROMION"]),
                                match.marker(trial, label["R_ACROMION"]), trial.rate,
                                ground=ground_velocity(feet_of(trial, match)[0], trial.rate),
                                source=name)
        assert len(choose_cycles(cycles)) == 1 or cycles[0].rest, name
        if not truth["cycles"]:
            assert cycles[0].rest, name
            continue
        for cycle in cycles:
            true = min(truth["cycles"], key=lambda c: abs(c["start_s"] - cycle.start_s))
            assert abs(true["start_s"] - cycle.start_s) < 0.02, name  # cut at the toe-offs
            vel = cycle.velocities
            np.testing.assert_allclose(vel.v, true["v"], atol=max(0.02 * true["v"], 0.02),
                                       err_msg=name)
            np.testing.assert_allclose(vel.omega, true["omega"], atol=0.02, err_msg=name)
            # v_l from skin markers carries their placement error (3 mm per marker yaws the
            # shoulder line by up to ~1°: 0.07 m/s at 3.5 m/s);
            # docs/results/velocity_accuracy.md reports it
            np.testing.assert_allclose(vel.v_l, true["v_l"], atol=0.02 + 0.02 * true["v"],
                                       err_msg=name)
            checked += 1
    assert checked >= 100


@pytest.mark.usefixtures("sample_dir")
def test_cli_cycles_json(capsys):
    import json

    from conftest import SAMPLES
    from mocaplib.cli import main

    path = SAMPLES / "walk_curve_r2_left_normal.c3d"
    assert main(["cycles", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["file"] == str(path) and len(out["cycles"]) >= 2
    for row in out["cycles"]:
        assert {"start_s", "end_s", "T", "pattern", "v", "omega", "v_l", "v_f", "fourier_n",
                "fourier_rms_deg", "chosen"} <= set(row)
        assert row["pattern"]["type"] == "arc" and row["pattern"]["arc_angle_rad"] > 0
        np.testing.assert_allclose(row["omega"], 0.5, atol=0.02)  # 1.0 m/s on a 2 m radius
        # fitted shoulder centres: the 0.02 m/s target on v_l (truth 0 to 1e-3)
        np.testing.assert_allclose(row["v_l"], 0.0, atol=0.02)
        assert row["fourier_n"] >= 1
    assert sum(row["chosen"] for row in out["cycles"]) == 1


@pytest.mark.usefixtures("sample_dir")
def test_cli_cycles_cutoff_reaches_the_fit(capsys):
    # `cycles` fits as `fit` and `build` do, with their --cutoff: raw markers (none) leave the
    # fit's noise on ankle inversion, which the Fourier order then chases (measured N = 20
    # against 9 with the default auto cutoff on this capture)
    import json

    from mocaplib.cli import main

    from conftest import SAMPLES

    path = SAMPLES / "walk_straight_normal.c3d"
    orders = {}
    for cutoff in ("auto", "none"):
        assert main(["cycles", str(path), "--json", "--cutoff", cutoff]) == 0
        rows = json.loads(capsys.readouterr().out)["cycles"]
        orders[cutoff] = [row["fourier_n"] for row in rows]
    assert max(orders["auto"]) < min(orders["none"]), orders
    assert main(["cycles", str(path), "--cutoff", "-3"]) == 2  # a usage error


def test_cli_cycles_real_file_with_marker_gaps(capsys, real_c3d):
    import json

    from mocaplib.cli import main

    path = real_c3d("ezc3d_testfiles/BTS.c3d")  # foot markers missing 40-70 % of frames
    assert main(["cycles", str(path), "--json"]) == 0
    cycles = json.loads(capsys.readouterr().out)["cycles"]
    # foot-marker gaps filled from the fitted skeleton between measured samples: of the two
    # strides the left foot's markers span (3.45-6.3 s; the skeleton's foot before 3.45 s put
    # a third toe-off at 3.1 s that no sample supports), the first; the second runs into the
    # last frames, unsolved from 5.95 s (fewer than 3 pelvis markers); a straight walk at
    # 1.3-1.5 m/s
    assert len(cycles) == 1 and cycles[0]["start_s"] >= 3.45
    for row in cycles:
        assert 1.2 <= row["v"] <= 1.6 and abs(row["omega"]) < 0.1


def test_unfitted_dof_is_named():
    left, right = shoulders(TIME, period=PERIOD)
    q = np.zeros((len(TIME), len(DOF_NAMES)))
    q[:, DOF_NAMES.index("knee_flexion_r")] = np.nan
    with pytest.raises(EventError, match="walk.c3d: joint coordinate knee_flexion_r is missing"):
        analyse_cycles(events(), left, right, RATE, q=q, source="walk.c3d")
    with pytest.raises(EventError, match=r"q must have shape \(500, 32\)"):
        analyse_cycles(events(), left, right, RATE, q=q[:, :5])


def test_treadmill_cycles_relative_to_the_belt():
    speed = 1.2
    left, right = shoulders(TIME, v_f=speed, period=PERIOD, noise=0.001)
    belt = np.outer(TIME, [speed, 0.0, 0.0])  # the walker stays in place on the belt
    q = np.zeros((len(TIME), len(DOF_NAMES)))
    q[:, DOF_NAMES.index("pelvis_tx")] = 0.01 * np.sin(2 * np.pi * TIME / PERIOD)
    on_spot = analyse_cycles(events(), left - belt, right - belt, RATE, q=q)
    assert on_spot[0].velocities.pattern.kind == "point"
    moving = analyse_cycles(events(), left - belt, right - belt, RATE, q=q,
                            ground=np.array([-speed, 0.0, 0.0]))
    assert len(moving) == 3
    for c in moving:
        np.testing.assert_allclose(c.velocities.v, speed, rtol=0.02)  # the 2 % target
        np.testing.assert_allclose(c.velocities.v_f, speed, rtol=0.02)
        # the root drifts forwards with the belt speed in the encoding too
        np.testing.assert_allclose(c.encoding.drift.u_f, speed, rtol=0.02)


@pytest.mark.parametrize("command", [dict(v_f=3.5, gait="run"), dict(v_f=1.8),
                                     dict(v_f=1.2, omega=-1.2), dict(v_f=0.8, v_l=0.6, omega=0.3)])
def test_velocities_are_the_truths_time_averages(command):
    from mocaplib.gait.patterns import cycle_velocities
    from mocaplib.synth.capture import min_duration, synthesize_capture
    from mocaplib.library.command import Command

    cmd = Command(**command)
    capture = synthesize_capture(cmd, duration=min_duration(cmd) + 0.2, seed=1)
    left, right = capture.motion.shoulders[:, 0], capture.motion.shoulders[:, 1]
    assert len(capture.truth["cycles"]) >= 2
    for true in capture.truth["cycles"]:
        got = cycle_velocities(left, right, capture.trial.rate, true["start_s"], true["end_s"])
        # the generator's own glenohumeral centres: only the pattern fit and the sampling
        # differ from the truth; measured <= 0.0008 m/s with time averages, 0.006 m/s with the
        # plain mean of the samples (both ends of the cycle, the same phase, counted twice)
        np.testing.assert_allclose(got.v_l, true["v_l"], atol=0.002)
        np.testing.assert_allclose(got.v_f, true["v_f"], atol=0.002)
        np.testing.assert_allclose(got.v, true["v"], atol=0.001)


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("name", ["run_2p0", "walk_curve_r1_right_normal"])
def test_cli_cycles_with_static_meet_the_targets(name, capsys):
    import json

    from conftest import SAMPLES
    from mocaplib.cli import main

    path, rest = SAMPLES / f"{name}.c3d", SAMPLES / "rest.c3d"
    # rest is the synthetic session's static in the anatomical neutral pose
    assert main(["cycles", str(path), "--static", str(rest), "--static-pose", "neutral",
                 "--json"]) == 0
    truth = json.loads(path.with_suffix(".truth.json").read_text())["cycles"]
    rows = json.loads(capsys.readouterr().out)["cycles"]
    assert len(rows) >= 2, name
    for row in rows:
        true = min(truth, key=lambda c: abs(c["start_s"] - row["start_s"]))
        # the velocity targets, end to end from markers (a false treadmill would put run_2p0's
        # v 0.25 m/s low). Measured v within 0.001, v_l within 0.011 (run) and 0.005 (curve)
        np.testing.assert_allclose(row["v"], true["v"], atol=0.02 * true["v"], err_msg=name)
        np.testing.assert_allclose(row["omega"], true["omega"], atol=0.02, err_msg=name)
        np.testing.assert_allclose(row["v_l"], true["v_l"], atol=0.02, err_msg=name)


def stride_events(times: dict[str, list[float]]) -> list[GaitEvent]:
    """Events from ``{"left_toe_off": [s, ...], ...}``."""
    return [GaitEvent(name.split("_", 1)[0], name.split("_", 1)[1], t, round(t * RATE), 1.0)
            for name, ts in times.items() for t in ts]


#: One left toe-off in view (1.2 s), the right foot's two toe-offs around it: walking order
#: (left toe-off, left heel-strike, right toe-off, right heel-strike) with a 1.1 s stride.
ONE_LEFT_TOE_OFF = {"right_toe_off": [0.65, 1.75], "right_heel_strike": [1.1],
                    "left_toe_off": [1.2], "left_heel_strike": [1.65]}


def test_one_left_toe_off_cuts_from_the_protocol_s_fallback_event_flagged():
    from mocaplib.errors import NoCycleError

    left, right = shoulders(TIME, v_f=1.0, period=PERIOD)
    evs = stride_events(ONE_LEFT_TOE_OFF)
    with pytest.raises(NoCycleError, match="fewer than two left toe-offs") as caught:
        analyse_cycles(evs, left, right, RATE)
    assert "fallback_starts" in caught.value.hint   # says how to let cycles start elsewhere
    cycles = analyse_cycles(evs, left, right, RATE,
                            fallback_starts=("left_heel_strike", "right_toe_off"))
    # no left heel-strike pair: the right toe-offs cut the cycle
    assert len(cycles) == 1 and cycles[0].start_event == "right_toe_off"
    cycle = cycles[0]
    np.testing.assert_allclose((cycle.start_s, cycle.end_s), (0.65, 1.75), atol=1e-12)
    np.testing.assert_allclose(cycle.left_toe_off, 0.55, atol=1e-12)   # 1.2 s - 0.65 s
    assert cycle.right_toe_off == 0.0
    np.testing.assert_allclose(cycle.velocities.v, 1.0, rtol=0.02)
    data = cycle.to_dict()
    assert data["start_event"] == "right_toe_off" and data["left_toe_off_s"] == cycle.left_toe_off


def test_a_fallback_cycle_holds_one_stride_in_walking_or_running_order():
    # running: left toe-off, right heel-strike, right toe-off, left heel-strike
    running = stride_events({"right_toe_off": [0.65, 1.35], "left_heel_strike": [0.78],
                             "left_toe_off": [1.0], "right_heel_strike": [1.13]})
    assert len(cycle_bounds(running, start="right_toe_off")) == 1
    # a jump: both feet leave together and land together
    jump = stride_events({"right_toe_off": [0.65, 1.75], "left_toe_off": [0.66],
                          "left_heel_strike": [1.1], "right_heel_strike": [1.11]})
    assert cycle_bounds(jump, start="right_toe_off") == []
    # a second right heel-strike (a stride and more): not one stride
    extra = stride_events({**ONE_LEFT_TOE_OFF, "right_heel_strike": [1.1, 1.3]})
    assert cycle_bounds(extra, start="right_toe_off") == []


@pytest.mark.parametrize("gap_s, kept", [(0.2, True), (0.3, False)])
def test_cycles_span_gaps_up_to_max_gap_s(gap_s, kept):
    from mocaplib.gait.cycles import MAX_GAP_S
    from mocaplib.errors import NoCycleError

    assert MAX_GAP_S == 0.25
    left, right = shoulders(TIME, v_f=1.0, period=PERIOD)
    filled = np.zeros(len(TIME), dtype=bool)
    # frames the fit interpolated inside the second cycle (1.41-2.51 s): the gap between the
    # solved frames around them spans gap_s
    first = 180
    filled[first:first + int(round(gap_s * RATE)) - 1] = True
    cycles = analyse_cycles(events(), left, right, RATE, filled=filled)
    starts = [round(c.start_s, 2) for c in cycles]
    assert starts == ([0.31, 1.41, 2.51] if kept else [0.31, 2.51])
    # a limit above the gap keeps it; when every cycle spans too long a gap, no cycle, and why
    assert len(analyse_cycles(events(), left, right, RATE, filled=filled, max_gap_s=0.35)) == 3
    if not kept:
        with pytest.raises(NoCycleError, match=r"every cycle spans a gap longer than max_gap_s "
                                               r"0.25 s: 1.41-2.51 s \(left_toe_off\) spans "
                                               r"0.30 s the fit could not solve"):
            analyse_cycles(events(n=2, first=1.41), left, right, RATE, filled=filled)


def test_no_cycle_reaches_into_the_unsolved_frames_at_either_end():
    from mocaplib.errors import NoCycleError

    # a walker leaving the volume (ezc3d's BTS.c3d): the last frames unsolved. Their angles
    # are held from the last solved frame, not interpolated, so the shoulders would stand still
    # there: the cycle reaching 0.1 s into them is not cut, whatever max_gap_s says
    left, right = shoulders(TIME, v_f=1.0, period=PERIOD)
    evs = events(n=4)                                 # cycles 0.31-1.41, 1.41-2.51, 2.51-3.61
    filled = TIME > 3.51
    cycles = analyse_cycles(evs, left, right, RATE, filled=filled, max_gap_s=10.0)
    assert [round(c.start_s, 2) for c in cycles] == [0.31, 1.41]
    # entering the volume: the same at the start
    cycles = analyse_cycles(evs, left, right, RATE, filled=TIME < 0.41, max_gap_s=10.0)
    assert [round(c.start_s, 2) for c in cycles] == [1.41, 2.51]
    # ending at the last solved frame is fine, and a run inside the capture is still a gap
    assert len(analyse_cycles(evs, left, right, RATE, filled=TIME > 3.615)) == 3
    with pytest.raises(NoCycleError, match=r"2.51-3.61 s \(left_toe_off\) reaches into the "
                                           r"frames the fit could not solve at the capture's"):
        analyse_cycles(events(n=2, first=2.51), left, right, RATE, filled=filled)


def test_one_gap_limit_for_the_events_the_cycles_the_build_and_the_cli():
    from mocaplib.cli._common import MAX_GAP_DEFAULT, MAX_GAP_LIMIT
    from mocaplib.gait.cycles import MAX_GAP_S
    from mocaplib.errors import MocapError
    from mocaplib.gait.events import EventSettings
    from mocaplib.build.settings import MAX_GAP_LIMIT_S, BuildSettings

    assert MAX_GAP_DEFAULT == MAX_GAP_S == EventSettings().max_gap_s == \
        BuildSettings().max_gap_s == 0.25
    assert BuildSettings(max_gap_s=0.5).to_dict()["max_gap_s"] == 0.5   # recorded
    assert MAX_GAP_LIMIT == MAX_GAP_LIMIT_S
    with pytest.raises(MocapError, match="max_gap_s must be a number of seconds from 0 to "
                                         "3600, got 1e"):
        BuildSettings(max_gap_s=1e308)
    with pytest.raises(MocapError, match="max_gap_s must be a number of seconds from 0 to "
                                         "3600, got -1"):
        BuildSettings(max_gap_s=-1)
