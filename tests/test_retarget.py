"""Retargeting a library cycle to another body: IK on the poulaine with secondary tasks."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from mocaplib.cli import main
from mocaplib.errors import MocapError
from mocaplib.gait.poulaine import ankle_centres
from mocaplib.export.formats import suffixes
from mocaplib.library.retarget import TASK_DOFS, Weights, foot_skate, retarget
from mocaplib.skeleton import DOF_NAMES, Skeleton

#: The target: joint-angle RMS of the pelvis, hip and knee DOFs (the IK's, TASK_DOFS)
#: between a cycle retargeted to its own body and the captured cycle, rad.
SELF_RMS = 0.05


def self_rms(library, entry_id: str, captured: dict) -> dict[str, float]:
    """RMS (rad) per pelvis, hip and knee DOF between the IK's solution (``poulaine_q``, before
    planting) of ``entry_id`` retargeted to its own body and its captured cycle (the
    diagnostics sidecar's ``angles``, root in the path frame)."""
    own = library.entry_skeleton(entry_id)
    result = retarget(library, entry_id, skeleton=own)
    q = result.poulaine_q
    t = np.asarray(captured["time_s"])
    return {DOF_NAMES[j]: float(np.sqrt(np.mean((np.interp(t, result.time_s, q[:, j])
                                                 - np.asarray(captured[DOF_NAMES[j]])) ** 2)))
            for j in TASK_DOFS}


def _self_retargeting(library, records) -> pd.Series:
    worst = {entry: max(self_rms(library, entry, records[entry]["angles"]).values())
             for entry in library.table.index if entry in records}
    return pd.Series(worst)


def test_self_retargeting_target_on_the_synthetic_walks():
    from walking_library import synthetic_walks

    worst = _self_retargeting(*synthetic_walks())
    assert len(worst) == 21
    assert (worst <= SELF_RMS).mean() >= 0.9, worst.round(3).to_dict()
    assert worst.max() < 0.03     # measured 0.017 rad at most (docs/results/retarget.md)


@pytest.fixture(scope="module")
def real_self_retargeting() -> pd.Series:
    from walking_library import real_walks

    return _self_retargeting(*real_walks())


@pytest.mark.real
def test_self_retargeting_on_the_real_walks_is_no_worse_than_measured(real_self_retargeting):
    # measured on the 10 real chosen cycles: worst-DOF RMS median 0.065 rad, worst 0.111
    # (PiG_Motion-FlatFoot-Full_c1), 2 of 10 within 0.05 rad
    assert len(real_self_retargeting) == 10
    assert real_self_retargeting.median() <= 0.07, real_self_retargeting.round(3).to_dict()
    assert real_self_retargeting.max() <= 0.12, real_self_retargeting.round(3).to_dict()


@pytest.mark.real
@pytest.mark.xfail(strict=True, reason="measured on the 10 real chosen cycles: 2 of 10 within "
                   "0.05 rad of their captured cycle (IK before planting), median 0.065 rad")
def test_self_retargeting_target_on_the_real_walks(real_self_retargeting):
    assert (real_self_retargeting <= SELF_RMS).mean() >= 0.9, \
        real_self_retargeting.round(3).to_dict()


def test_most_real_walks_give_a_chosen_cycle_to_retarget():
    from walking_library import real_walks

    assert len(_self_retargeting(*real_walks())) >= 8


@pytest.fixture(scope="module")
def walks():
    from walking_library import synthetic_walks

    return synthetic_walks()[0]


@pytest.mark.parametrize("factor", [0.85, 1.15])
def test_retargeting_to_a_shorter_or_taller_body(walks, factor):
    entry = "walk_straight_normal_c1"
    own = walks.entry_skeleton(entry)
    body = own.scaled(factor)
    result = retarget(walks, entry, skeleton=body)
    source = walks.poulaine(entry)
    # the defaults: the entry's step length and stance times the leg ratio, spacing the hips'
    np.testing.assert_allclose(result.requested, np.multiply(source.parameters, factor))
    assert result.limit_violations() == 0
    assert result.ankle_error_m < 0.005, result.ankle_error_m
    # a body scaled as a whole walks the entry's own poulaine scaled (the poulaines are
    # compared as if walked by the target body): its ankles reach it
    assert result.sources == (entry,) * 3 and result.ankle_error_m < 1e-6
    # the feet slide at most 2.5 times as fast in support as the entry's (measured 1.3 and 2.0:
    # the blend mixes poulaines of other walks, the Fourier series of the entry's own)
    t = result.time_s
    entry_skate = foot_skate(own, walks.root_drift(entry).restore(walks.angles(entry, t), t), t)
    assert foot_skate(body, result.q, result.time_s) < 2.5 * entry_skate
    # the output's feet are planted: a flat foot's ankle centre stands the target's ankle height
    # above the floor (within 1 mm: the flat-foot hover target), the entry's 17-18 mm higher
    lowest = ankle_centres(body, result.q)[..., 2].min()
    assert lowest == pytest.approx(body.lengths["ankle_height"], abs=0.001)
    # every criterion computed, of the same order as the entry's
    for key, value in result.criteria["output"].items():
        reference = result.criteria["input"][key]
        assert np.isfinite(value) and value >= 0, key
        if key != "cycle_closure_rad":
            assert 0.5 * reference < value < 2 * reference, (key, value, reference)


def test_requested_values_are_met_exactly_and_checked(walks):
    entry = "walk_straight_normal_c1"
    body = Skeleton.from_height(1.6)
    result = retarget(walks, entry, skeleton=body, step_length=0.55, foot_spacing=0.12,
                      stance=0.74)
    assert result.requested == (0.55, 0.12, 0.74)
    assert result.ankle_error_m < 1e-5
    # the IK's ankles, where the entry passes its characteristic points, have them; the planted
    # output's within 4 mm (measured 3.3 mm: the flat foot's roll taken out, the hover)
    from mocaplib.gait.poulaine import travel_coordinates

    own = walks.poulaine(entry)
    phase = result.time_s / result.time_s[-1]

    def parameters(q_path):
        ankles = ankle_centres(body, travel_coordinates(q_path, own.travel))

        def at(kind):
            return np.array([[np.interp(p.phases[p.kinds.index(kind)], phase,
                                        ankles[:, side, axis]) for axis in range(3)]
                             for side, p in enumerate((own.left, own.right))])

        under = at("under_pelvis")
        return [np.mean(at("foremost")[:, 0] - at("rearmost")[:, 0]),
                under[0, 1] - under[1, 1], -under[:, 2].mean()]

    # 1 mm: linear interpolation between the 100 Hz samples
    np.testing.assert_allclose(parameters(result.poulaine_q), result.requested, atol=1e-3)
    np.testing.assert_allclose(parameters(result.path_coordinates()), result.requested,
                               atol=4e-3)
    with pytest.raises(MocapError, match="must be > 0 m"):
        retarget(walks, entry, skeleton=body, stance=-0.7)
    with pytest.raises(MocapError, match="metres, not centimetres"):
        retarget(walks, entry, skeleton=body, step_length=55.0)
    with pytest.raises(MocapError, match="weights must be finite"):
        Weights(reference=float("nan"))


def test_each_secondary_task_pulls_the_null_space_its_way(walks):
    entry = "walk_curve_r2_left_normal_c1"
    body = Skeleton.from_height(1.6)
    base = retarget(walks, entry, skeleton=body)
    still = retarget(walks, entry, skeleton=body, weights=Weights(kinetic=10.0))
    free = retarget(walks, entry, skeleton=body, weights=Weights(reference=1e-3, kinetic=0.0))
    central = retarget(walks, entry, skeleton=body, weights=Weights(joint_limits=1.0))
    task = list(TASK_DOFS)
    reference = walks.angles(entry, base.time_s)[:, task]

    # the IK's own solution (poulaine_q), before the feet are planted
    def distance(result):      # to the entry's posture, pelvis heading aside
        return np.sqrt(np.mean((result.poulaine_q[:, task[1:]] - reference[:, 1:]) ** 2))

    def speed(result):
        return np.sqrt(np.mean(np.diff(result.poulaine_q[:, task], axis=0) ** 2))

    def crowding(result):      # Chan & Dubey's criterion over the bounded task DOFs
        lower, upper = (bound[task[1:]] for bound in Skeleton.bounds())
        theta = result.poulaine_q[:, task[1:]]
        return np.mean((upper - lower) ** 2 / (4 * (upper - theta) * (theta - lower)))

    assert distance(free) > distance(base)          # less pull to the reference posture
    assert speed(still) < speed(base)               # more weight on the rotational energy
    assert crowding(central) < crowding(base)       # more weight on the joint limits
    for result in (base, still, free, central):
        assert result.ankle_error_m < 0.005 and result.limit_violations() == 0


def test_outputs_are_written_by_suffix(walks, tmp_path):
    from bvh_reader import bvh_positions, to_z_up

    slow = next(entry for entry in walks.table.index if entry.startswith("walk_straight_slow_"))
    result = retarget(walks, slow, skeleton=Skeleton.from_height(1.7))
    csv = pd.read_csv(result.write(tmp_path / "out.csv"))
    assert list(csv.columns) == ["time_s", *DOF_NAMES]
    np.testing.assert_allclose(csv.to_numpy()[:, 1:], result.q, atol=1e-8)
    mot = np.loadtxt(result.write(tmp_path / "out.mot"), skiprows=7)
    np.testing.assert_allclose(np.radians(mot[:, 1 + DOF_NAMES.index("knee_flexion_r")]),
                               result.q[:, DOF_NAMES.index("knee_flexion_r")], atol=1e-7)
    names, positions, frame_time = bvh_positions(result.write(tmp_path / "out.bvh").read_text())
    assert frame_time == pytest.approx(1 / result.rate)
    # a loop: the closing frame (the first pose one cycle on) is left out
    np.testing.assert_allclose(to_z_up(positions),
                               result.skeleton.forward(result.q[:-1])[..., :3, 3], atol=1e-6)
    with pytest.raises(MocapError, match="end the file name with .csv, .mot, .bvh, .gltf, .glb"):
        result.write(tmp_path / "out.txt")


def test_a_rest_entry_has_nothing_to_retarget(tmp_path):
    from test_library import entry as library_entry
    from mocaplib.library.format import assemble_library

    lib = assemble_library([library_entry(i, locomotion_class="rest") for i in range(5)],
                           settings={})
    with pytest.raises(MocapError, match="no poulaine to retarget .a rest entry"):
        retarget(lib, "capture00_c0", skeleton=Skeleton.from_height(1.7))


# --------------------------------------------------------------------------- command line
@pytest.fixture(scope="module")
def library_file(walks, tmp_path_factory):
    path = tmp_path_factory.mktemp("lib") / "walks.json"
    walks.write(path)
    return path


def test_cli_retarget_writes_every_output_and_reports_the_criteria(library_file, tmp_path,
                                                                   capsys):
    outs = [tmp_path / f"out{suffix}" for suffix in suffixes("motion")]
    args = ["retarget", str(library_file), "walk_straight_normal_c1", "--height", "1.6"]
    assert main(args + [a for out in outs for a in ("-o", str(out))]) == 0
    printed = capsys.readouterr().out
    assert "C3 internal power (W/kg)" in printed and all(out.is_file() for out in outs)
    lengths = tmp_path / "body.json"
    lengths.write_text(json.dumps(Skeleton.from_height(1.9).lengths))
    assert main(["retarget", str(library_file), "walk_straight_normal_c1", "--segment-lengths",
                 str(lengths), "--stance", "0.95", "--weight-kinetic", "0", "-o",
                 str(tmp_path / "tall.csv"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["requested_m"][2] == 0.95 and summary["weights"]["kinetic"] == 0.0
    assert summary["limit_violations"] == 0 and set(summary["criteria"]) == {"input", "output"}


@pytest.mark.parametrize("args, message", [
    (["walk_straight_normal", "--height", "1.7", "-o", "x.csv"],
     "did you mean walk_straight_normal_c1"),
    (["nope", "--height", "1.7", "-o", "x.csv"], "ids are walk_curve_r1_left_fast_c"),
    (["walk_straight_normal_c1", "-o", "x.csv"], "one of the arguments --height"),
    (["walk_straight_normal_c1", "--height", "1.7", "--segment-lengths", "b.json", "-o", "x.csv"],
     "not allowed with argument"),
    (["walk_straight_normal_c1", "--height", "1.7", "-o", "x.txt"], "unknown output type"),
    (["walk_straight_normal_c1", "--height", "9", "-o", "x.csv"], "--height: standing height"),
    (["walk_straight_normal_c1", "--segment-lengths", "BODY", "-o", "x.csv"],
     "BODY: skeleton lengths missing"),
    (["walk_straight_normal_c1", "--height", "1.7", "--weight-reference", "-1", "-o", "x.csv"],
     "weights must be finite and >= 0"),
    (["walk_straight_normal_c1", "--height", "1.7", "--foot-spacing", "nan", "-o", "x.csv"],
     "must be a number within"),
])
def test_cli_retarget_usage_errors(library_file, tmp_path, capsys, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    body = tmp_path / "body.json"
    body.write_text(json.dumps({"thigh": 0.4}))
    args = [str(body) if a == "BODY" else a for a in args]
    assert main(["retarget", str(library_file), *args]) == 2
    error = capsys.readouterr().err
    assert message.replace("BODY", str(body)) in error, error
    assert not (tmp_path / "x.csv").exists()
