"""Gait cells, the side-step cone and the path follower on a library of sample captures: walks
(straight and curved), side-steps (straight and curving), 60° diagonals, spot turns, the rest
entry and the runs, built as `mocaplib build` builds the quick start's library."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from mocaplib.library.cells import onto_cone, to_frontal
from mocaplib.library.controlspace import Blend, ControlSpace
from mocaplib.library.follow import read_path
from mocaplib.skeleton import DOF_NAMES, ROOT_HEADING, ROOT_X, ROOT_Y

# the paths of benchmarks/path_follow.py (its page: docs/results/path_follow.md)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from path_follow import PATHS, followed_and_errors, met  # noqa: E402

CAPTURES = ("walk_straight_slow", "walk_straight_normal", "walk_straight_fast",
            *(f"walk_curve_r{r}_{side}_{pace}" for r in (1, 2, 3) for side in ("left", "right")
              for pace in ("normal", "fast")),
            *(f"side_{side}_{pace}" for side in ("left", "right")
              for pace in ("slow", "normal", "fast")),
            *(f"side_{side}_curve_{turn}_r2" for side in ("left", "right")
              for turn in ("left", "right")),
            *(f"diag_{side}_60_{pace}" for side in ("left", "right")
              for pace in ("slow", "normal", "fast")),
            *(f"diag_{side}_120_normal" for side in ("left", "right")),
            *(f"turn_spot_{side}_normal" for side in ("left", "right")),
            "run_2p0", "run_2p5", "run_3p0", "run_3p5", "rest")


@pytest.fixture(scope="module")
def space(sample_dir):
    from mocaplib.build.pipeline import build_library
    from mocaplib.build.settings import BuildSettings

    settings = BuildSettings(static=str(sample_dir / "rest.c3d"), static_pose="neutral")
    result = build_library([sample_dir / f"{name}.c3d" for name in CAPTURES], settings,
                           jobs=2, progress=False)
    assert result.ok, result.summary_text()
    return ControlSpace.from_library(result.library), result.library


def travel_direction_deg(blend) -> float:
    """Direction (deg) of the blended root's travel over one cycle relative to where it faces
    (the circular mean of pelvis_rotation), from the world-frame frames."""
    _, q = blend.world(0, rate=200.0)
    travel = np.arctan2(q[-1, ROOT_Y] - q[0, ROOT_Y], q[-1, ROOT_X] - q[0, ROOT_X])
    facing = np.angle(np.mean(np.exp(1j * q[:, ROOT_HEADING])))
    return float(np.degrees(np.angle(np.exp(1j * (travel - facing)))))


def test_a_blend_never_mixes_walks_and_runs(space):
    cs, _ = space
    gaits = {i: ("run" if c == "running" else "walk") for i, c in zip(cs.ids, cs.classes)}
    assert set(cs.cells) == {"walk", "run"}
    for simplex in cs.cells["walk"].tri.simplices.tolist() + cs.cells["run"].tri.simplices.tolist():
        assert len({gaits[cs.ids[k]] for k in simplex}) == 1
    # a fast walk between the walks and the runs: walks only, clamped, said so
    res = cs.query([1.75, 0.19, 0.0])
    assert res.inside[0] and res.clamped[0] and res.gait[0] == "walk"
    assert {gaits[cs.ids[k]] for k, w in zip(res.entries[0], res.weights[0]) if w > 0} == {"walk"}
    assert 0 < res.distance[0] < 0.02, res.distance[0]   # just beyond the walks' hull
    _, q = cs.blend(res).synthesize(0)
    knee = np.degrees(q[:, DOF_NAMES.index("knee_flexion_r")])
    elbow = np.degrees(q[:, DOF_NAMES.index("elbow_flexion_r")])
    assert knee.min() < 10 and elbow.max() < 50, (knee.min(), elbow.max())  # a walk's, not 24°/72°
    asked = cs.query([1.75, 0.19, 0.0], gait="run")
    assert asked.gait[0] == "run" and asked.clamped[0]
    assert {gaits[cs.ids[k]] for k in asked.entries[0]} == {"run"}


def test_query_says_a_command_between_the_gait_cells_is_served_clamped(space, tmp_path,
                                                                       capsys):
    from mocaplib.cli import main

    _, library = space
    lib = library.write(tmp_path / "library.json")
    assert main(["query", str(lib), "1.75", "0.19", "0"]) == 0
    first, second = capsys.readouterr().out.splitlines()[:2]
    assert first.endswith(": inside the control space, between its gait cells"), first
    assert second.strip().startswith("between the gaits' cells: blended at the nearest point "
                                     "of the walk cell"), second


def test_side_steps_on_the_cone_are_inside_and_walk_sideways(space):
    cs, _ = space
    for v_l, expected in ((0.4, 90.0), (-0.4, -90.0)):
        res = cs.query([0.4, 0.0, v_l])
        assert res.inside[0] and not res.clamped[0] and res.distance[0] == 0
        ids = [cs.ids[k] for k, w in zip(res.entries[0], res.weights[0]) if w > 0.05]
        assert all(i.startswith("side_") for i in ids), ids     # the side-steps on the cone
        assert abs(travel_direction_deg(cs.blend(res)) - expected) < 1.5


def test_a_near_side_step_does_not_walk_backwards(space):
    cs, _ = space
    direction = travel_direction_deg(cs.blend(cs.query([0.4, 0.0, 0.39])))
    # forward at atan2(v_l, +sqrt(v² - v_l²)) = 77.2° (DESIGN.md: v_l = v sin(θ_T - θ_S))
    assert 70.0 < direction < 85.0, direction       # 84.4° measured (95° blending backwards)


def test_a_near_side_step_walks_in_the_direction_it_asks(space):
    cs, _ = space
    expected = np.degrees(np.arctan2(0.39, np.sqrt(0.4 ** 2 - 0.39 ** 2)))
    # 77.1° measured (weights on the frontal axes); 84.4° with weights on the tangential ones
    assert abs(travel_direction_deg(cs.blend(cs.query([0.4, 0.0, 0.39]))) - expected) < 3.0


def walk_cell_grid(cs):
    """Commands (Q, 3) served inside the walk cell, not clamped: v̂ 0.3-1.8 m/s, |v̂_l| from 0
    to the cone (both sides), ω̂ ±1.4 rad/s (the cell's range)."""
    v, ratio, omega, side = np.meshgrid(np.linspace(0.3, 1.8, 11),
                                        [0, 0.2, 0.4, 0.6, 0.8, 0.9, 0.95, 0.975, 0.99, 1.0],
                                        np.linspace(-1.4, 1.4, 15), [1.0, -1.0], indexing="ij")
    commands = np.unique(np.column_stack([v.ravel(), omega.ravel(),
                                          (side * ratio * v).ravel()]), axis=0)
    res = cs.query(commands)
    return commands[res.inside & ~res.clamped & (res.gait == "walk")]


def test_blends_inside_the_walk_cell_travel_in_the_direction_and_at_the_speed_asked(space):
    cs, _ = space
    commands = walk_cell_grid(cs)
    assert len(commands) > 400, len(commands)          # 460 of the 3,135 commands
    blend = cs.blend(cs.query(commands))
    asked = np.degrees(np.arctan2(commands[:, 2], np.sqrt(commands[:, 0] ** 2
                                                          - commands[:, 2] ** 2)))
    travelled = np.array([travel_direction_deg(Blend(blend.a[i:i + 1], blend.b[i:i + 1],
                                                     blend.T[i:i + 1], blend.drift[i:i + 1]))
                          for i in range(len(commands))])
    direction = np.abs(travelled - asked)
    speed = np.abs(np.hypot(blend.drift[:, 0], blend.drift[:, 1]) - commands[:, 0])
    # measured: direction median 0.52°, 90th percentile 1.9°, worst 5.0° (0.3 m/s turning at
    # 1 rad/s: spot turns in the blend); speed median 3 mm/s, worst 0.11 m/s. With weights on
    # the tangential axes: 3.1°, 15°, 23° and 37 mm/s, 0.27 m/s. The entries themselves travel
    # within 1.5° of their own direction (side-steps 89.0° asked, 89.7° travelled).
    assert np.median(direction) < 1.0 and direction.max() < 6.0, (
        np.median(direction), direction.max(), commands[np.argmax(direction)])
    assert np.median(speed) < 0.01 and speed.max() < 0.15, (
        np.median(speed), speed.max(), commands[np.argmax(speed)])


def test_a_blend_inside_the_cell_reproduces_the_frontal_speed_asked(space):
    """The weights reproduce each command's (v̂_f, ω̂, v̂_l), v̂_f = sqrt(v̂² − v̂_l²), from the
    entries' (put on the cone) where its frontal point is inside the frontal tetrahedra."""
    cs, _ = space
    commands = walk_cell_grid(cs)
    res = cs.query(commands)
    frontal = to_frontal(onto_cone(cs.points))[res.entries]             # (Q, 4, 3)
    blended = np.einsum("qk,qkj->qj", res.weights, frontal)
    error = np.abs(blended - to_frontal(onto_cone(commands))) / cs.scale   # normalised
    exact = error.max(axis=1) < 1e-6
    # measured: 416 of 460 reproduced (372 of them within 1e-12); the other 44 lie beyond the
    # frontal tetrahedra (commands near the cell's boundary whose frontal point bulges out of
    # the frontal hull), blended at its nearest point: at most 0.062 normalised away (0.9 -0.4
    # 0.36 m/s, rad/s, m/s). With weights on the tangential axes: 16 of 460, worst 0.20.
    assert exact.sum() >= 410 and error.max() < 0.07, (exact.sum(), error.max())


def test_outside_says_how_far_which_entries_and_what_serves_it(space):
    cs, _ = space
    res = cs.query([0.4, 0.0, 0.45])                # |v_l| > v: no motion does it
    assert not res.inside[0] and res.distance[0] > 0.01
    text = cs.outside_text(res)
    assert f"{res.distance[0]:.3g}" in text and "side_left_normal_c" in text
    assert len(cs.nearest_ids(res.points[0])) == 3
    assert cs.query(res.nearest, gait=res.gait[0]).inside[0]    # what --clamp blends


@pytest.mark.parametrize("name", list(PATHS))
def test_the_path_follower_keeps_to_the_path(space, name):
    cs, library = space
    _, errors = followed_and_errors(library.skeleton, cs, PATHS[name])
    # root within 5 cm, heading within 5°, the cross-fade adds at most 1 % to the cycles' own
    # largest change per frame, and the planted feet slide at most 2 mm, stay out of the floor
    # and hover at most 3 mm
    assert met(errors) == [], errors


def read_bvh_frames(path):
    """(frame count, frame time s, motion rows) of a BVH file, read independently."""
    lines = path.read_text().splitlines()
    at = lines.index("MOTION")
    count = int(lines[at + 1].split(":")[1])
    frame_time = float(lines[at + 2].split(":")[1])
    rows = [list(map(float, line.split())) for line in lines[at + 3:] if line.strip()]
    return count, frame_time, np.array(rows)


def test_animate_writes_the_requested_rate_exactly(space, tmp_path):
    from mocaplib.cli import main

    _, library = space
    lib = library.write(tmp_path / "library.json")
    (tmp_path / "side.csv").write_text("t,v,omega,v_l\n0,0.4,0,0.4\n3,0.4,0,0.4\n")
    out = tmp_path / "side.bvh"
    assert main(["animate", str(lib), "--path", str(tmp_path / "side.csv"), "--bvh", str(out),
                 "--csv", str(tmp_path / "side.csv.out.csv"), "--rate", "60"]) == 0
    count, frame_time, rows = read_bvh_frames(out)
    assert frame_time == pytest.approx(1 / 60, abs=5e-12)   # BVH prints 11 decimals
    assert len(rows) == count and count > 150


def test_a_path_file_that_is_no_path_is_named(tmp_path):
    from mocaplib.errors import MocapError

    bad = tmp_path / "path.csv"
    bad.write_text("a,b\n1,2\n3,4\n")
    with pytest.raises(MocapError, match="path.csv.*neither a polyline nor a timeline"):
        read_path(bad)
    bad.write_text("x,y\n0,0\n1,oops\n")
    with pytest.raises(MocapError, match="row 3"):
        read_path(bad)
