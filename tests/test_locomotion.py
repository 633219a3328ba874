"""The locomotion class comes from what the body does: the cycle's velocities and the order of
its gait events, never the capture's file name."""

from __future__ import annotations

import math
import shutil

import pytest
from conftest import SAMPLES

from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
from mocaplib.gait.cycles import Cycle
from mocaplib.gait.foot_events import GaitEvent
from mocaplib.gait.locomotion import locomotion_class, stride_gait
from mocaplib.gait.patterns import CycleVelocities, Pattern


def cycle(v_f: float, v_l: float, omega: float, *, rest: bool = False) -> Cycle:
    """A 1 s cycle from 0 to 1 s moving at (v_f, v_l) m/s and turning at omega rad/s."""
    velocities = CycleVelocities(Pattern("point", {"point": (0.0, 0.0)}, 0.0), 1.0,
                                 math.hypot(v_f, v_l), omega, v_l, v_f)
    return Cycle(0, 0.0, 1.0, velocities, 0.0, 1.0, rest=rest)


def events(*names: str) -> list[GaitEvent]:
    """Gait events named ``<side>_<kind>`` in that order inside the cycle of :func:`cycle`,
    between its two left toe-offs at 0 and 1 s."""
    named = ["left_toe_off", *names, "left_toe_off"]
    times = [i / (len(named) - 1) for i in range(len(named))]
    return [GaitEvent(*name.split("_", 1), time_s=t, frame=round(100 * t), quality=1.0)
            for name, t in zip(named, times)]


WALK = events("left_heel_strike", "right_toe_off", "right_heel_strike")
RUN = events("right_heel_strike", "right_toe_off", "left_heel_strike")


@pytest.mark.parametrize("v_f, v_l, omega, stride, expected", [
    (1.2, 0.0, 0.0, WALK, "nonholonomic"),        # straight ahead
    (1.0, 0.05, 0.5, WALK, "nonholonomic"),       # a curve, facing along the path
    (0.02, 0.0, 0.9, WALK, "nonholonomic"),       # a turn on the spot
    (0.0, 0.4, 0.0, WALK, "holonomic"),           # a side-step to the left
    (0.3, -0.52, 0.01, WALK, "holonomic"),        # a diagonal to the right
    (-0.8, 0.0, 0.0, WALK, "holonomic"),          # walking backwards
    (0.03, 0.02, 0.0, WALK, "holonomic"),         # stepping in place
    (0.0, 0.5, -0.25, WALK, "mixed"),             # side-steps along an arc
    (3.0, 0.0, 0.0, RUN, "running"),              # a flight after each toe-off
    (1.8, 0.0, 0.0, WALK, "nonholonomic"),        # a fast walk is no run
])
def test_the_class_follows_the_velocities_and_the_gait(v_f, v_l, omega, stride, expected):
    assert locomotion_class(cycle(v_f, v_l, omega), stride) == expected


def test_the_gait_is_read_from_the_order_of_the_events_inside_the_cycle():
    assert stride_gait(cycle(1, 0, 0), WALK) == "walking"
    assert stride_gait(cycle(3, 0, 0), RUN) == "running"
    # a missed heel-strike: neither order, and the class falls back on the velocities
    missed = [e for e in RUN if e.kind != "heel_strike" or e.side != "left"]
    assert stride_gait(cycle(3, 0, 0), missed) is None
    assert locomotion_class(cycle(3, 0, 0), missed) == "nonholonomic"
    assert locomotion_class(cycle(0, 0, 0, rest=True), []) == "rest"


@pytest.mark.usefixtures("sample_dir")
def test_a_capture_named_like_a_sample_gets_the_class_of_its_motion(tmp_path):
    # A lab's own side-step saved under a sample's name: the class is the side-step's.
    capture = tmp_path / "walk_straight_normal.c3d"
    shutil.copyfile(SAMPLES / "side_left_normal.c3d", capture)
    settings = BuildSettings(static=str(SAMPLES / "rest.c3d"), static_pose="neutral")
    result = build_library([capture], settings, cache_dir=None, progress=False)
    assert [e.locomotion_class for e in result.library.entries] == ["holonomic"]
