"""The shipped samples: the plan, byte-identical regeneration, readers agree, the CLI."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pytest

from conftest import REPO, SAMPLES
from mocaplib.cli import main
from mocaplib.errors import SynthError
from mocaplib.io.c3d import read_c3d
from mocaplib.skeleton import DOF_NAMES
from mocaplib.synth.plan import generate_plan, load_plan
from mocaplib.synth.capture import TRUTH_DECIMALS, min_duration

PLAN = REPO / "protocols" / "paper_plan.toml"
#: One capture of each class that moves differently (regenerating all 68 takes ~30 s).
REGENERATED = ["walk_curve_r1_left_fast", "side_right_normal", "side_left_curve_right_r2",
               "run_3p5", "rest"]


def test_paper_plan_has_the_68_captures():
    plan = load_plan(PLAN)
    assert len(plan.captures) == 68
    assert Counter(c.cls for c in plan.captures) == {
        "nonholonomic": 27, "holonomic": 24, "mixed": 12, "running": 4, "rest": 1}
    for c in plan.captures:
        assert c.duration >= min_duration(c.command, c.subject)
    radii = {round(c.command.radius, 6) for c in plan.captures if c.cls == "nonholonomic"}
    assert radii == {0.0, 1.0, 2.0, 3.0, np.inf}
    directions = {round(np.degrees(c.command.direction)) for c in plan.captures
                  if c.cls == "holonomic"}
    assert directions == {60, 90, 120, 150, -60, -90, -120, -150}


def test_plan_is_not_listed_as_a_protocol():
    from mocaplib.markersets.protocols import list_protocols
    assert "paper_plan" not in list_protocols()


@pytest.mark.usefixtures("sample_dir")
def test_samples_hold_the_whole_plan_and_stay_small():
    names = {c.name for c in load_plan(PLAN).captures}
    assert {p.name[:-len(".c3d")] for p in SAMPLES.glob("*.c3d")} == names
    assert {p.name[:-len(".truth.json")] for p in SAMPLES.glob("*.truth.json")} == names
    size = sum(p.stat().st_size for p in SAMPLES.iterdir())
    assert size < 20e6


def _same_to_the_written_digit(got, shipped, where: str) -> None:
    """Assert two parsed truth files hold the same keys, texts and integers, and floats one
    unit of the last written decimal apart at most (:data:`TRUTH_DECIMALS`): a value computed
    within 1e-16 of a half unit rounds either way with the processor's float kernels."""
    assert type(got) is type(shipped), where
    if isinstance(got, dict):
        assert got.keys() == shipped.keys(), where
        for key in got:
            _same_to_the_written_digit(got[key], shipped[key], f"{where}/{key}")
    elif isinstance(got, list):
        assert len(got) == len(shipped), where
        for k, (a, b) in enumerate(zip(got, shipped)):
            _same_to_the_written_digit(a, b, f"{where}[{k}]")
    elif isinstance(got, float):
        assert abs(got - shipped) <= 1.0001 * 10.0 ** -TRUTH_DECIMALS, where
    else:
        assert got == shipped, where


@pytest.mark.usefixtures("sample_dir")
def test_regenerated_samples_are_identical(tmp_path):
    written = generate_plan(load_plan(PLAN), tmp_path, only=REGENERATED)
    assert len(written) == 2 * len(REGENERATED)
    for path in written:
        if path.suffix == ".c3d":                          # the captures: byte for byte
            assert path.read_bytes() == (SAMPLES / path.name).read_bytes(), path.name
        else:
            _same_to_the_written_digit(json.loads(path.read_text()),
                                       json.loads((SAMPLES / path.name).read_text()), path.name)


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("name", REGENERATED)
def test_sample_reads_the_same_in_ezc3d_and_mocaplib(name):
    ezc3d = pytest.importorskip("ezc3d")
    path = SAMPLES / f"{name}.c3d"
    trial = read_c3d(path)
    ref = ezc3d.c3d(str(path))
    points = ref["data"]["points"][:3].transpose(2, 1, 0) / 1000.0
    # same file, same numbers: only float round-off between the two readers
    np.testing.assert_allclose(trial.markers, points, atol=1e-9)
    assert trial.labels == ref["parameters"]["POINT"]["LABELS"]["value"]
    truth = json.loads((SAMPLES / f"{name}.truth.json").read_text())
    assert trial.labels == truth["labels"] and trial.n_frames == truth["frames"]
    got = [(e.context, e.label) for e in trial.events]
    assert got == [(e["context"], e["label"]) for e in truth["events"]]
    # EVENT:TIMES is float32 in C3D: 1e-6 s
    np.testing.assert_allclose([e.time_s for e in trial.events],
                               [e["time_s"] for e in truth["events"]], atol=1e-6)


@pytest.mark.usefixtures("sample_dir")
def test_truth_file_layout():
    truth = json.loads((SAMPLES / "walk_curve_r1_left_fast.truth.json").read_text())
    angles = np.array(truth["angles"]["values"])
    assert angles.shape == (truth["frames"], len(truth["angles"]["dof_names"]))
    assert truth["class"] == "nonholonomic" and truth["seed"] > 0
    cyc = truth["cycles"][0]
    assert {"start_s", "end_s", "T", "v", "omega", "v_l", "v_f", "pattern"} <= set(cyc)
    assert cyc["pattern"]["type"] == "arc"
    np.testing.assert_allclose(cyc["pattern"]["radius"], 1.0, atol=1e-6)
    kinds = Counter((e["side"], e["kind"]) for e in truth["events"])
    assert all(kinds[(s, k)] >= 2 for s in ("left", "right") for k in ("heel_strike", "toe_off"))


def test_cli_generates_and_reports_bad_plans(tmp_path, capsys):
    assert main(["synth", str(PLAN), "-o", str(tmp_path), "--only", "rest",
                 "--protocol", "plugin_gait", "-q"]) == 0
    truth = json.loads((tmp_path / "rest.truth.json").read_text())
    assert truth["protocol"] == "plugin_gait" and "LFIN" in truth["labels"]
    capsys.readouterr()
    bad = tmp_path / "bad.toml"
    bad.write_text('[[capture]]\nname = "short"\nclass = "x"\n'
                   'command = { kind = "straight", speed = 1.2 }\nduration = 0.5\nseed = 1\n')
    with pytest.raises(SynthError, match="capture 'short'.*too short"):
        generate_plan(load_plan(bad), tmp_path)   # the plan reads: the report may use it
    assert main(["synth", str(bad), "-o", str(tmp_path), "-q"]) == 1
    assert "capture 'short'" in capsys.readouterr().err
    bad.write_text('[[capture]]\nname = "odd"\nclass = "x"\ncommand = { kind = "curve", '
                   'speed = 1.0 }\nduration = 3\nseed = 1\n')
    with pytest.raises(SynthError, match="capture 'odd': a curve needs a radius"):
        load_plan(bad)
    bad.write_text('[[capture]]\nname = "odd"\nclass = "x"\ncommand = { kind = "rest" }\n'
                   'duration = 3\nseed = 1\nprotocol = "no_such_set"\n')
    with pytest.raises(SynthError, match="capture 'odd': unknown protocol 'no_such_set'"):
        generate_plan(load_plan(bad), tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml", "rest.c3d",
                                                          "rest.truth.json"]


def test_a_plan_with_a_bad_capture_writes_nothing(tmp_path, capsys):
    plan = tmp_path / "plan.toml"
    good = 'command = { kind = "straight", speed = 1.2 }\nseed = 1\nclass = "x"\n'
    plan.write_text(f'[[capture]]\nname = "a_ok"\nduration = 3\n{good}'
                    f'[[capture]]\nname = "b_bad"\nduration = 0.01\n{good}')
    assert main(["synth", str(plan), "-o", str(tmp_path / "out"), "-q"]) == 1
    assert "capture 'b_bad': duration 0.01 s is too short" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args, message", [
    (["{plan}", "-o", "{d}", "--only", "walk_straigth_fast"],
     "not in the plan: walk_straigth_fast (did you mean walk_straight_fast"),
    (["{plan}", "-o", "{d}", "--only", "zzz"], "its captures are walk_straight_slow, "),
    (["{plan}", "-o", "{d}", "--only", "rest", "--protocol", "bogus"],
     "--protocol: unknown protocol 'bogus'"),
    (["{plan}", "-o", "{d}/afile", "--only", "rest"], "it is a file, not a folder"),
    (["{plan}", "-o", "{d}/afile/sub", "--only", "rest"], "it is a file, not a folder"),
    (["{d}/nope.toml", "-o", "{d}"],
     "nope.toml: no such file or folder (check the path; protocols/paper_plan.toml is a "),
    (["{plan}", "-o", "{d}", "--only", "rest", "-j"], "usage: mocaplib synth"),
])
def test_synth_usage_errors_exit_2_before_writing(args, message, tmp_path, capsys):
    (tmp_path / "afile").write_text("a file")
    assert main(["synth", *(a.format(plan=PLAN, d=tmp_path) for a in args), "-q"]) == 2
    assert message in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


@pytest.mark.usefixtures("sample_dir")
def test_synth_replaces_only_its_own_earlier_output(tmp_path, capsys):
    rest = ["synth", str(PLAN), "-o", str(tmp_path), "--only", "rest", "-q"]
    assert main(rest) == 0    # a first time, then again over its own output: allowed
    assert main(rest) == 0
    assert (tmp_path / "rest.c3d").read_bytes() == (SAMPLES / "rest.c3d").read_bytes()
    # another capture's file under this name (as a lab static copied there): refused
    lab = (SAMPLES / "walk_straight_normal.c3d").read_bytes()
    (tmp_path / "rest.c3d").write_bytes(lab)
    capsys.readouterr()
    assert main(rest) == 2
    error = capsys.readouterr().err
    assert "would overwrite" in error and "or pass --overwrite" in error
    assert (tmp_path / "rest.c3d").read_bytes() == lab
    (tmp_path / "rest.truth.json").unlink()     # a C3D without its truth: refused too
    assert main(rest) == 2
    assert "rest.c3d: not written by mocaplib synth" in capsys.readouterr().err
    assert (tmp_path / "rest.c3d").read_bytes() == lab
    assert main([*rest, "--overwrite"]) == 0
    assert (tmp_path / "rest.c3d").read_bytes() == (SAMPLES / "rest.c3d").read_bytes()
    (tmp_path / "walk_straight_slow.truth.json").write_text('{"format": "mine"}')
    with pytest.raises(SynthError, match="walk_straight_slow.truth.json: not written by"):
        generate_plan(load_plan(PLAN), tmp_path, only=["walk_straight_slow"])


def test_synth_draws_no_progress_bar_into_a_pipe(tmp_path, capsys):
    assert main(["synth", str(PLAN), "-o", str(tmp_path), "--only", "rest"]) == 0
    out, err = capsys.readouterr()
    assert out == f"wrote 1 captures to {tmp_path}\n" and err == ""


#: The joint-angle targets against the independent body's truth, every capture (RMS,
#: degrees): a DOF named for a flexion (hip, knee, ankle, trunk, neck, shoulder, elbow) 2°,
#: any other rotation 4°. DOFs that miss them, with the worst capture's figure measured on the
#: shipped samples (static-calibrated, markers low-passed: the quick start's settings) and the
#: modelling difference behind it (docs/results/fit_accuracy.md, "Against the targets").
MISSED_DOFS = {
    "elbow_flexion_r": (2.52, "run_3p0"), "elbow_flexion_l": (2.03, "run_3p5"),
    "hip_flexion_l": (2.10, "run_3p5"),
    "knee_flexion_r": (4.11, "run_3p5"), "knee_flexion_l": (4.22, "diag_right_150_fast"),
    "ankle_dorsiflexion_r": (2.50, "diag_left_60_fast"),
    "ankle_dorsiflexion_l": (3.01, "diag_right_60_fast"),
    "hip_rotation_r": (6.63, "side_right_curve_left_r1"),
    "hip_rotation_l": (6.27, "side_right_curve_right_r1"),
    "ankle_inversion_r": (4.67, "diag_left_150_fast"),
    "ankle_inversion_l": (4.60, "diag_right_150_fast"),
}


@pytest.fixture(scope="module")
def sample_angle_errors():
    """Each shipped capture's RMS joint-angle error (deg) per DOF against its truth: calibrated
    on the session's static (neutral pose), markers low-passed at Winter's cutoff."""
    from mocaplib.model.calibration import calibrate
    from mocaplib.model.filtering import filter_trial
    from mocaplib.model.ik import fit

    static = read_c3d(SAMPLES / "rest.c3d")
    out = {}
    for path in sorted(SAMPLES.glob("*.c3d")):
        truth = json.loads(path.with_suffix(".truth.json").read_text())
        trial, _ = filter_trial(read_c3d(path), cutoff="auto")
        motion = fit(trial, calibrate(trial, static=static, static_pose="neutral"))
        error = motion.q - np.asarray(truth["angles"]["values"])
        out[path.stem] = np.degrees(np.sqrt((error ** 2).mean(axis=0)))
    return out


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("dof", [
    pytest.param(name, marks=pytest.mark.xfail(
        strict=True, reason="measured {:.2f}° ({})".format(*MISSED_DOFS[name]))
        if name in MISSED_DOFS else ())
    for name in DOF_NAMES if not name.startswith("pelvis_t")])
def test_fitted_angles_meet_the_targets_against_the_independent_body(sample_angle_errors, dof):
    j = DOF_NAMES.index(dof)
    target = 2.0 if "flexion" in dof else 4.0
    worst = max(sample_angle_errors, key=lambda name: sample_angle_errors[name][j])
    assert sample_angle_errors[worst][j] <= target, (worst, sample_angle_errors[worst][j])


@pytest.mark.usefixtures("sample_dir")
def test_fitted_angles_that_miss_the_targets_are_no_worse_than_measured(sample_angle_errors):
    # each DOF of MISSED_DOFS at most 0.2 degrees above its measured worst sample
    for dof, (measured, _) in MISSED_DOFS.items():
        j = DOF_NAMES.index(dof)
        worst = max(sample_angle_errors, key=lambda name: sample_angle_errors[name][j])
        assert sample_angle_errors[worst][j] <= measured + 0.2, (dof, worst,
                                                                 sample_angle_errors[worst][j])
