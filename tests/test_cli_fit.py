"""``mocaplib fit`` end to end on a small C3D written in tmp_path."""

import json

import numpy as np
import pandas as pd
import pytest
from fk_data import fk_trial

from mocaplib.cli import main
from mocaplib.io.c3d_write import write_c3d
from mocaplib.skeleton import DOF_NAMES


def test_fit_writes_angles_mot_osim_and_prints_quality(tmp_path, capsys):
    cap = fk_trial(n_frames=60, placement_mm=0, sta_mm=0, noise_mm=0.5, seed=2)
    path = write_c3d(tmp_path / "walk.c3d", cap.trial.markers, cap.trial.labels, 100.0)
    out = tmp_path / "out" / "angles.csv"
    out.parent.mkdir()  # a file output goes into an existing folder
    code = main(["fit", str(path), "--protocol", "fullbody38", "-o", str(out),
                 "--mot", str(tmp_path / "a.mot"), "--osim", str(tmp_path / "m.osim"), "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report) >= {"marker_rms_mm", "max_marker_error_mm", "per_marker_rms_mm",
                           "locked_dofs", "failed_frames"}
    # 0.5 mm noise per axis: the per-frame RMS sits near sqrt(3) x 0.5 mm, well below 2 mm
    assert 0.3 < report["marker_rms_mm"] < 2.0
    assert report["locked_dofs"] == [] and report["held_dofs"] == {}
    assert report["failed_frames"] == [] and report["at_limit"] == {}
    assert set(report["per_marker_rms_mm"]) == set(cap.trial.labels)
    angles = pd.read_csv(out)
    assert list(angles.columns) == ["time_s", *DOF_NAMES]
    np.testing.assert_allclose(angles["time_s"], np.arange(60) / 100.0, atol=1e-9)
    knee = DOF_NAMES.index("knee_flexion_r")
    # radians, against the generating angles: 0.5 mm noise and calibration keep it within 2 deg
    assert np.abs(angles["knee_flexion_r"] - cap.q[:, knee]).max() < np.radians(2)
    assert (tmp_path / "a.mot").read_text().count("inDegrees=yes") == 1
    assert "<CustomJoint" in (tmp_path / "m.osim").read_text()


def test_fit_reports_a_bad_file_in_one_line(tmp_path, capsys):
    bad = tmp_path / "broken.c3d"
    bad.write_bytes(b"not a c3d file at all")
    code = main(["fit", str(bad), "-o", str(tmp_path / "x.csv")])
    err = capsys.readouterr().err
    assert code == 1
    assert "broken.c3d" in err and "Traceback" not in err
    assert not (tmp_path / "x.csv").exists()


def test_unknown_protocol_is_a_usage_error(tmp_path, capsys):
    cap = fk_trial(n_frames=5)
    path = write_c3d(tmp_path / "walk.c3d", cap.trial.markers, cap.trial.labels, 100.0)
    code = main(["fit", str(path), "--protocol", "nonesuch", "-o", str(tmp_path / "x.csv")])
    assert code == 2
    assert "--protocol" in capsys.readouterr().err


def test_cutoff_option(tmp_path, capsys):
    cap = fk_trial(n_frames=120, placement_mm=0, sta_mm=0, noise_mm=0.5, seed=2)
    path = write_c3d(tmp_path / "walk.c3d", cap.trial.markers, cap.trial.labels, 100.0)
    reports = {}
    for cutoff in ("none", "8", "auto"):
        assert main(["fit", str(path), "--protocol", "fullbody38", "--cutoff", cutoff,
                     "-o", str(tmp_path / f"{cutoff}.csv"), "--json"]) == 0
        reports[cutoff] = json.loads(capsys.readouterr().out)
    assert reports["none"]["cutoff_hz"] is None and reports["8"]["cutoff_hz"] == 8.0
    assert 2.0 <= reports["auto"]["cutoff_hz"] <= 20.0
    # low-passed markers lose their 0.5 mm white noise, so they lie closer to the model
    assert reports["8"]["marker_rms_mm"] < reports["none"]["marker_rms_mm"]
    for cutoff, said in (("none", "markers not low-passed ->"),
                         ("8", "markers low-passed at 8 Hz ->")):
        assert main(["fit", str(path), "--protocol", "fullbody38", "--cutoff", cutoff,
                     "-o", str(tmp_path / "text.csv")]) == 0
        assert said in capsys.readouterr().out
    # argparse: a usage error
    assert main(["fit", str(path), "--cutoff", "-3", "-o", str(tmp_path / "x.csv")]) == 2
    assert "--cutoff: must be > 0 Hz" in capsys.readouterr().err


@pytest.mark.usefixtures("sample_dir")
def test_fit_takes_the_static_that_shows_the_subject(tmp_path, capsys):
    # --static repeated (one per subject or session), as in build: the matching one is used
    from conftest import SAMPLES, plan_capture

    made, _ = plan_capture("rest", 1.85, tmp_path)
    other_rest = made.rename(tmp_path / "rest.c3d")     # the same file name as the right one
    walk = SAMPLES / "walk_straight_normal.c3d"
    args = ["fit", str(walk), "-o", str(tmp_path / "a.csv"), "--static-pose", "neutral"]
    assert main([*args, "--static", str(other_rest), "--static", str(SAMPLES / "rest.c3d"),
                 "--json"]) == 0
    # named as build names it (calibration.static_names): both files are rest.c3d, so the
    # folder tells them apart (fit said only "rest.c3d")
    assert json.loads(capsys.readouterr().out)["static"] == f"{SAMPLES.name}/rest.c3d"
    assert main([*args, "--static", str(other_rest)]) == 1          # the other subject's only
    assert "does not match the motion trial" in capsys.readouterr().err


def test_fit_says_what_the_reader_noticed(tmp_path, capsys):
    """A label stored twice (the first a stray 30 cm away): the fit uses the first occurrence,
    so it must say the label is duplicated, as inspect and the build's diagnostics do."""
    cap = fk_trial(n_frames=30, placement_mm=0, sta_mm=0, noise_mm=0.5, seed=3)
    markers = np.concatenate([cap.trial.markers[:, :1] + 0.3, cap.trial.markers], axis=1)
    labels = [cap.trial.labels[0], *cap.trial.labels]
    path = write_c3d(tmp_path / "dup.c3d", markers, labels, 100.0)
    assert main(["fit", str(path), "--protocol", "fullbody38",
                 "-o", str(tmp_path / "x.csv")]) == 0
    err = capsys.readouterr().err
    assert f"dup.c3d: duplicate labels kept as separate markers: {labels[0]}" in err


def test_a_file_of_two_subjects_is_fitted_on_the_one_with_most_markers(real_c3d, tmp_path,
                                                                       capsys):
    """Two subjects in one file, 3 m apart, subject A without LASI: the protocol took B's LASI
    for A's and no frame could be fitted; the match keeps to one subject, the one whose labels
    give the most markers (B), and fits it as the file of B alone; the notes say so."""
    from mocaplib.io.c3d import read_c3d

    trial = read_c3d(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    without = [i for i, label in enumerate(trial.labels) if label != "LASI"]
    markers = np.concatenate([trial.markers[:, without], trial.markers + [0.0, 3.0, 0.0]],
                             axis=1)
    labels = [f"A:{trial.labels[i]}" for i in without] + [f"B:{x}" for x in trial.labels]
    path = write_c3d(tmp_path / "pair.c3d", markers, labels, trial.rate)
    alone = write_c3d(tmp_path / "alone.c3d", trial.markers + [0.0, 3.0, 0.0],
                      [f"B:{x}" for x in trial.labels], trial.rate)
    assert main(["fit", str(path), "-o", str(tmp_path / "pair.csv")]) == 0
    err = capsys.readouterr().err
    assert "pair.c3d: labels of 2 subjects (A, B)" in err
    assert "pair.c3d: matched on subject B's labels, the other subjects' left aside" in err
    assert main(["fit", str(alone), "-o", str(tmp_path / "alone.csv")]) == 0
    assert (tmp_path / "pair.csv").read_bytes() == (tmp_path / "alone.csv").read_bytes()
