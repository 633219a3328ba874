"""Gait events timed by force plates (:mod:`mocaplib.gait.plate_events`): a plate under one
stance of a sample walk, and the real files' plates against their labs' events."""

from __future__ import annotations

import dataclasses
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from mocaplib.gait.events import capture_events
from mocaplib.gait.feet import LAB_EVENT_KINDS, feet_of
from mocaplib.gait.plate_events import (MAX_PLATE_SHIFT_S, PLATE_MATCH_S, load_spans,
                                         readable)
from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_analog import ForcePlate
from mocaplib.markersets.matching import detect_protocol

SAMPLE = "walk_straight_normal"
ANALOG_RATE = 1000.0


def _walk(sample_dir, name=SAMPLE):
    """The sample walk (or sample ``name``), its protocol match and its true events [(side,
    kind, time_s)]."""
    trial = read_c3d(sample_dir / f"{name}.c3d")
    truth = json.loads((sample_dir / f"{name}.truth.json").read_text())
    return trial, detect_protocol(trial), [(e["side"], e["kind"], e["time_s"])
                                           for e in truth["events"]]


def _stance(events, side):
    """The first true (heel strike, toe-off) of ``side`` with both in the capture (s)."""
    strikes = sorted(t for s, k, t in events if s == side and k == "heel_strike")
    offs = sorted(t for s, k, t in events if s == side and k == "toe_off")
    strike = strikes[0]
    return strike, min(t for t in offs if t > strike)


def _plate(trial, match, side, strike, off, *, along=(-0.3, 0.3), across=0.2, noise_n=2.0,
           shift_s=0.0, number=1):
    """A plate under ``side``'s foot as it stands from ``strike`` to ``off`` (s): its corners
    ``along`` (m, from the foot's mid-stance centre along heel to toe) and ``across`` (m,
    each way) the foot; a body weight's bump between the two times (moved by ``shift_s``),
    crossing 20 N within a sample of them, with noise of SD ``noise_n`` N."""
    heel, toe = feet_of(trial, match)[0][side]
    middle = round(0.5 * (strike + off) * trial.rate)
    centre = 0.5 * (heel[middle] + toe[middle])
    forward = (toe[middle] - heel[middle]) * [1, 1, 0]
    forward /= np.linalg.norm(forward)
    sideways = np.array([-forward[1], forward[0], 0.0])
    corners = np.array([centre + a * forward + b * sideways
                        for a, b in ((along[0], -across), (along[1], -across),
                                     (along[1], across), (along[0], across))]) * [1, 1, 0]
    t = np.arange(round(trial.duration * ANALOG_RATE)) / ANALOG_RATE - shift_s
    # 30 ms ramps to a body weight: over 20 N from 0.86 ms after the strike to as long
    # before the toe-off
    force = np.interp(t, [strike, strike + 0.03, off - 0.03, off], [0.0, 700.0, 700.0, 0.0],
                      left=0.0, right=0.0)
    force += np.random.default_rng(number).normal(0.0, noise_n, t.size)
    return ForcePlate(number=number, kind=2, corners=corners, force=force, rate=ANALOG_RATE)


def _timed(trial, match, plates):
    """The sample's events with ``plates`` and with the markers alone."""
    with_plates, _ = capture_events(dataclasses.replace(trial, force_plates=plates), match)
    alone, _ = capture_events(trial, match)
    assert [e.plate for e in alone] == [None] * len(alone)
    return with_plates, alone


def _by_plate(events):
    return {(e.side, e.kind): e for e in events if e.plate is not None}


def _untouched(with_plates, alone):
    """The events no plate timed are the markers' own: ``alone`` less, for each event a plate
    timed, the markers' event of its side and kind nearest it; each toe-off among them moved
    by the same :attr:`GaitEvent.plate_shift_s`, the median of the plates' times minus the
    markers' toe-offs they replaced (none moved without a toe-off a plate timed)."""
    replaced = [min((e for e in alone if (e.side, e.kind) == (t.side, t.kind)),
                    key=lambda e: abs(e.time_s - t.time_s))
                for t in with_plates if t.plate is not None]
    measured = [t.time_s - m.time_s for t, m in
                zip((t for t in with_plates if t.plate is not None), replaced)
                if t.kind == "toe_off"]
    shift = float(np.median(measured)) if measured else 0.0
    kept = [e for e in alone if e not in replaced]
    others = [e for e in with_plates if e.plate is None]
    assert [(e.side, e.kind, e.window, e.quality) for e in others] == [
        (e.side, e.kind, e.window, e.quality) for e in kept]
    for event, own in zip(others, kept):
        moved = shift if event.kind == "toe_off" and event.placed else 0.0
        assert event.plate_shift_s == moved
        assert event.time_s == pytest.approx(own.time_s + moved, abs=1e-12)
    return shift


@pytest.mark.parametrize("side", ["left", "right"])
def test_a_plate_under_one_foot_times_its_heel_strike_and_toe_off(sample_dir, side):
    trial, match, truth = _walk(sample_dir)
    strike, off = _stance(truth, side)
    with_plates, alone = _timed(trial, match, [_plate(trial, match, side, strike, off)])
    timed = _by_plate(with_plates)
    assert set(timed) == {(side, "heel_strike"), (side, "toe_off")}
    # the plate's crossings: the first sample above, and the first below, 20 N
    assert timed[side, "heel_strike"].time_s == pytest.approx(strike, abs=2.0 / ANALOG_RATE)
    assert timed[side, "toe_off"].time_s == pytest.approx(off, abs=2.0 / ANALOG_RATE)
    assert all(e.plate == 1 and e.placed and e.quality == 1.0 for e in timed.values())
    # the markers' other toe-offs moved by what the plate measured of them: within a frame
    shift = _untouched(with_plates, alone)
    assert 0 < abs(shift) <= 1.0 / trial.rate


@pytest.mark.parametrize("name, late_s", [(SAMPLE, 0.015), (SAMPLE, -0.01),
                                          ("run_3p5", 0.015)])
def test_the_markers_other_toe_offs_move_as_the_plates_found_them_off(sample_dir, name,
                                                                      late_s):
    # a plate that unloads later or earlier than the toes' tips leave (another threshold, a
    # foot whose markers sit elsewhere): the markers' toe-offs off it move by as much; a
    # run's too (its toe-off the forefoot's lift)
    trial, match, truth = _walk(sample_dir, name)
    strike, off = _stance(truth, "left")
    plate = _plate(trial, match, "left", strike, off, shift_s=late_s)
    with_plates, alone = _timed(trial, match, [plate])
    shift = _untouched(with_plates, alone)
    assert shift == pytest.approx(late_s, abs=1.0 / trial.rate)
    moved = [e for e in with_plates if e.plate_shift_s]
    assert {e.kind for e in moved} == {"toe_off"} and len(moved) >= 4
    assert with_plates == sorted(with_plates, key=lambda e: (e.time_s, e.side))
    true_offs = [t for side, kind, t in truth if kind == "toe_off"]
    for event in moved:                 # as far from the truth as the plate is
        nearest = min(true_offs, key=lambda t: abs(t - event.time_s))
        assert event.time_s - nearest == pytest.approx(late_s, abs=1.0 / trial.rate)


def test_a_plate_far_from_the_markers_moves_no_other_toe_off(sample_dir):
    # 50 ms between the plate's unloading and the markers' toe-off: a contact misread
    trial, match, truth = _walk(sample_dir)
    strike, off = _stance(truth, "left")
    plate = _plate(trial, match, "left", strike, off, shift_s=MAX_PLATE_SHIFT_S + 0.02)
    with_plates, alone = _timed(trial, match, [plate])
    assert set(_by_plate(with_plates)) == {("left", "heel_strike"), ("left", "toe_off")}
    assert not any(e.plate_shift_s for e in with_plates)
    assert [e for e in with_plates if e.plate is None] == [
        e for e in alone if e in with_plates]


def test_the_corners_may_come_in_any_order(sample_dir):
    trial, match, truth = _walk(sample_dir)
    strike, off = _stance(truth, "left")
    plate = _plate(trial, match, "left", strike, off)
    timed = []
    for order in ([0, 1, 2, 3], [3, 2, 1, 0], [2, 0, 3, 1]):
        shuffled = dataclasses.replace(plate, corners=plate.corners[order])
        timed.append(_by_plate(_timed(trial, match, [shuffled])[0]))
    assert len(timed[0]) == 2 and timed[1] == timed[0] and timed[2] == timed[0]


def test_a_plate_under_the_forefoot_only_times_the_toe_off(sample_dir):
    # the heel marker off the plate: the foot loads it once its forefoot is down
    trial, match, truth = _walk(sample_dir)
    strike, off = _stance(truth, "left")
    plate = _plate(trial, match, "left", strike, off, along=(0.0, 0.3))
    with_plates, _ = _timed(trial, match, [plate])
    assert set(_by_plate(with_plates)) == {("left", "toe_off")}


def test_a_plate_both_feet_stand_on_times_nothing(sample_dir):
    trial, match, truth = _walk(sample_dir)
    strike, off = _stance(truth, "left")
    plate = _plate(trial, match, "left", strike, off, along=(-1.5, 1.5), across=1.0)
    with_plates, alone = _timed(trial, match, [plate])
    assert _by_plate(with_plates) == {}
    assert with_plates == alone


def test_a_plate_that_reads_more_than_noise_empty_times_nothing(sample_dir):
    # an instrumented treadmill's belt: both feet on it at times, shaken by the belt
    trial, match, truth = _walk(sample_dir)
    strike, off = _stance(truth, "left")
    plate = _plate(trial, match, "left", strike, off, noise_n=40.0)
    assert not readable(plate.force)
    with_plates, alone = _timed(trial, match, [plate])
    assert with_plates == alone


def test_a_plate_stance_the_markers_do_not_show_times_nothing(sample_dir):
    # the plate's times 0.15 s from the foot's: another stance than the markers'
    trial, match, truth = _walk(sample_dir)
    strike, off = _stance(truth, "left")
    plate = _plate(trial, match, "left", strike, off, shift_s=PLATE_MATCH_S + 0.05)
    with_plates, alone = _timed(trial, match, [plate])
    assert with_plates == alone


def test_force_plates_off_leaves_every_event_to_the_markers(sample_dir):
    trial, match, truth = _walk(sample_dir)
    strike, off = _stance(truth, "left")
    plated = dataclasses.replace(trial, force_plates=[_plate(trial, match, "left", strike, off)])
    alone, _ = capture_events(trial, match)
    assert capture_events(plated, match, force_plates=False)[0] == alone


def test_a_recording_cut_to_zero_is_extrapolated_along_the_force():
    # the software zeroes the plate under 40 N: the 20 N crossings lie past the cuts
    rate = 1000.0
    t = np.arange(0, 1.0, 1 / rate)
    force = np.interp(t, [0.2, 0.25, 0.7, 0.75], [0.0, 800.0, 800.0, 0.0], left=0, right=0)
    cut = np.where(force < 40.0, 0.0, force)
    (strike, off), = load_spans(cut, rate)
    assert strike == pytest.approx(0.2 + 20 / 800 * 0.05, abs=1e-6)     # 0.20125 s
    assert off == pytest.approx(0.75 - 20 / 800 * 0.05, abs=1e-6)       # 0.74875 s
    (whole_strike, whole_off), = load_spans(force, rate)
    assert whole_strike == pytest.approx(strike, abs=1.5 / rate)
    assert whole_off == pytest.approx(off, abs=1.5 / rate)


#: The real files with force plates: the stances one foot makes alone on a plate whose
#: markers lie over it, (side, kind) each plate times.
PLATED = {
    "biomechzoo/HC030A05.c3d": 4, "biomechzoo/HC030A22.c3d": 4, "btkdata/Gait.c3d": 4,
    "btkdata/PiG_Motion-FlatFoot-Full.c3d": 3, "ezc3d_testfiles/BTS.c3d": 6,
    "ezc3d_testfiles/Qualisys.c3d": 4, "motonms_unipd/Walking1.c3d": 3,
    "motonms_unipd/Walking3.c3d": 3,
}


@pytest.mark.parametrize("name", sorted(PLATED))
def test_real_plates_time_the_events_of_the_foot_on_them(real_c3d, name):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from event_accuracy import _of_side, cut_unloadings

    trial = read_c3d(real_c3d(name))
    events, _ = capture_events(trial, detect_protocol(trial))
    timed = [e for e in events if e.plate is not None]
    assert len(timed) == PLATED[name], [(e.side, e.kind, e.plate, e.time_s) for e in timed]
    # each toe-off timed is an unloading the benchmark reads with ezc3d
    unloaded = [u.time_s for u in cut_unloadings(real_c3d(name))]
    for event in timed:
        if event.kind == "toe_off":
            assert min(abs(event.time_s - u) for u in unloaded) < 1e-9
    # the lab's events of its kind near a timed one are of its side
    for event in timed:
        near = [lab for lab in trial.events if LAB_EVENT_KINDS.get(lab.label) == event.kind
                and abs(lab.time_s - trial.start_time - event.time_s) < 0.05]
        assert _of_side(near, event.side[0].upper()) == near, (event, near)



def test_the_events_command_names_the_plate_that_timed_an_event(real_c3d, capsys):
    from mocaplib.cli import main

    path = str(real_c3d("btkdata/Gait.c3d"))
    assert main(["events", path, "--json"]) == 0
    plates = sorted((e["side"], e["kind"], e["plate"])
                    for e in json.loads(capsys.readouterr().out)["events"] if e["plate"])
    assert plates == [("left", "heel_strike", 1), ("left", "toe_off", 1),
                      ("right", "heel_strike", 2), ("right", "toe_off", 2)]
    assert main(["events", path]) == 0
    assert capsys.readouterr().out.count("force plate") == 4
    assert main(["events", path, "--markers-only"]) == 0
    assert "force plate" not in capsys.readouterr().out


def test_a_cycle_says_which_plates_timed_its_bounds(real_c3d, capsys):
    from mocaplib.cli import main

    path = str(real_c3d("motonms_unipd/Walking1.c3d"))
    assert main(["cycles", path, "--json"]) == 0
    cycles = json.loads(capsys.readouterr().out)["cycles"]
    # its left toe-off at 3.727 s: the unloading of plate 2
    assert [c["bound_plates"] for c in cycles] == [[None, 2]]
    assert cycles[0]["end_s"] == pytest.approx(3.727, abs=0.001)
    assert main(["cycles", path]) == 0
    assert "cycle 0: its end (left toe off) timed by force plate 2" in capsys.readouterr().out


def test_the_report_says_which_plates_timed_a_cycles_bounds(real_c3d, tmp_path, capsys):
    from mocaplib.cli import main

    library = tmp_path / "lib.json"
    assert main(["build", str(real_c3d("btkdata/Gait.c3d")), "-o", str(library)]) == 0
    assert main(["report", str(library), "-o", str(tmp_path / "report")]) == 0
    page = (tmp_path / "report" / "lib-report.html").read_text()
    # the cycle ends at the left toe-off plate 1's unloading times (3.146 s)
    assert re.search(r"<td class=\"num\">3\.15 \(force plate 1\)</td>", page)


def test_the_other_plates_bring_the_markers_toe_offs_to_the_plates_time(real_c3d):
    # each plate left out in turn: the markers' toe-off there, moved as the capture's other
    # plates measured the markers, against the plate's unloading (measured: median 2.2 ms,
    # worst 12.5, against 7.5 and 19.7 for the markers alone, over 13 in six captures)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from event_accuracy import left_out_plates

    alone, moved = [], []
    for name in sorted(PLATED):
        for kind, _, _, own, shifted in left_out_plates(real_c3d(name)):
            if kind == "toe_off" and np.isfinite(shifted):
                alone.append(abs(own))
                moved.append(abs(shifted))
    assert len(moved) == 13
    assert np.median(moved) <= 0.003 < np.median(alone)
    assert max(moved) <= 0.015 < max(alone)


def test_markers_whose_two_marks_disagree_move_no_other_toe_off(real_c3d):
    # Walking1's one toe-off a plate times was placed midway between marks 41 ms apart
    # (uncertain): it says nothing of how late the markers place the others
    trial = read_c3d(real_c3d("motonms_unipd/Walking1.c3d"))
    match = detect_protocol(trial)
    markers, _ = capture_events(trial, match, force_plates=False)
    events, _ = capture_events(trial, match)
    timed = [e for e in events if e.kind == "toe_off" and e.plate is not None]
    own = min((e for e in markers if e.kind == "toe_off" and e.side == timed[0].side),
              key=lambda e: abs(e.time_s - timed[0].time_s))
    assert len(timed) == 1 and own.uncertain
    assert not any(e.plate_shift_s for e in events)


def test_the_events_command_says_how_far_the_plates_moved_a_toe_off(real_c3d, capsys):
    from mocaplib.cli import main

    path = str(real_c3d("biomechzoo/HC030A05.c3d"))
    assert main(["events", path, "--json"]) == 0
    events = json.loads(capsys.readouterr().out)["events"]
    moved = [e for e in events if e["plate_shift_s"]]
    # its plates' unloadings lie 17.6 and 19.7 ms before the markers' toe-offs
    assert [e["kind"] for e in moved] == ["toe_off", "toe_off"]
    assert [e["plate_shift_s"] for e in moved] == [pytest.approx(-0.0187, abs=5e-4)] * 2
    assert main(["events", path]) == 0
    assert capsys.readouterr().out.count("moved -18.7 ms by the plates") == 2
    assert main(["events", path, "--markers-only"]) == 0
    assert "moved" not in capsys.readouterr().out


def test_a_cycle_and_the_report_say_how_far_the_plates_moved_its_bounds(real_c3d, tmp_path,
                                                                        capsys):
    from mocaplib.cli import main

    path = str(real_c3d("biomechzoo/HC030A05.c3d"))
    assert main(["cycles", path, "--json"]) == 0
    cycle, = json.loads(capsys.readouterr().out)["cycles"]
    # it starts at a toe-off the markers placed, moved as the plates found them 18.7 ms
    # late, and ends at plate 1's unloading
    assert cycle["bound_plates"] == [None, 1]
    assert cycle["bound_plate_shifts_s"] == [pytest.approx(-0.0187, abs=5e-4), 0.0]
    assert main(["cycles", path]) == 0
    assert ("cycle 0: its start (left toe off) moved -18.7 ms by the force plates"
            in capsys.readouterr().out)
    library = tmp_path / "lib.json"
    assert main(["build", path, "-o", str(library)]) == 0
    assert main(["report", str(library), "-o", str(tmp_path / "report")]) == 0
    page = (tmp_path / "report" / "lib-report.html").read_text()
    assert re.search(r"<td class=\"num\">0\.28 \(moved -18\.7 ms by the plates\)</td>"
                     r"<td class=\"num\">1\.32 \(force plate 1\)</td>", page)


def test_a_toe_off_the_plates_would_move_out_of_the_capture_stays():
    from mocaplib.gait.foot_events import GaitEvent
    from mocaplib.gait.plate_events import _shifted

    frames = 201                                                        # 2 s at 100 Hz
    events = [GaitEvent("left", "toe_off", 0.005, 0, 1.0),
              GaitEvent("right", "heel_strike", 0.5, 50, 1.0),
              GaitEvent("left", "toe_off", 1.0, 100, 1.0),
              GaitEvent("left", "toe_off", 1.995, 200, 1.0)]
    early, _, middle, late = _shifted(events, [-0.012, -0.008], 100.0, frames)
    assert early == events[0]                          # -5 ms: before the first frame
    assert middle.time_s == pytest.approx(0.99) and middle.frame == 99
    assert middle.plate_shift_s == pytest.approx(-0.01)
    assert late.time_s == pytest.approx(1.985)
    assert _shifted(events, [0.015], 100.0, frames)[3] == events[3]   # past the last frame
    assert _shifted(events, [MAX_PLATE_SHIFT_S + 0.001], 100.0, frames) == events
