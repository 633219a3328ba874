"""Files with no marker points (analog-only force-plate or EMG files, files whose every point
is a declared model output): read as a Trial with M = 0, reported by ``inspect``, refused by
every later stage with a MocapError naming the file; a folder holding one still builds."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from mocaplib.cli import main
from mocaplib.errors import MocapError
from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_axis import detect_vertical_axis
from mocaplib.markersets.draft import draft_protocol
from mocaplib.markersets.inspection import format_summary, inspect_c3d
from mocaplib.markersets.matching import match_trial
from mocaplib.model.calibration import calibrate
from mocaplib.model.fitting import fit_capture
from mocaplib.trial import Trial, require_markers

from c3d_files import capture_bytes
from conftest import SAMPLES

OUTPUTS = ["LHipAngles", "RHipAngles", "LKneeAngles"]
REFUSAL = r"no marker points: the file holds 3 analog channels and no marker trajectories: " \
          r"this looks like an analog-only/force-plate file"


@pytest.fixture
def force_plates(tmp_path):
    """50 frames of 3 analog channels sampled 10 times a frame, and no POINT data."""
    path = tmp_path / "forceplate.c3d"
    path.write_bytes(capture_bytes(np.zeros((50, 0, 3)), [], analog=(3, 10)))
    return path


def test_an_analog_only_file_is_a_trial_without_markers(force_plates):
    trial = read_c3d(force_plates)
    assert trial.markers.shape == (50, 0, 3) and trial.labels == []
    assert trial.analog_channels == 3 and trial.vertical_axis == "Z"
    assert trial.gap_fraction().shape == trial.longest_gap().shape == (0,)


def test_a_file_whose_points_are_all_model_outputs_is_a_trial_without_markers(tmp_path):
    path = tmp_path / "outputs.c3d"
    path.write_bytes(capture_bytes(np.full((20, 3, 3), 0.5), OUTPUTS,
                                   point_params={"ANGLES": OUTPUTS}))
    trial = read_c3d(path)
    assert trial.markers.shape == (20, 0, 3) and trial.analog_channels == 0
    assert any("dropped 3 model outputs" in w for w in trial.warnings)
    with pytest.raises(MocapError, match="no marker points: the file holds no marker "
                                         "trajectories and no analog channels"):
        match_trial(trial)


def test_the_vertical_axis_of_no_markers_is_the_files_word():
    none = np.empty((10, 0, 3))
    assert detect_vertical_axis(none) == ("Z", [])
    assert detect_vertical_axis(none, screen_axis="Y", subjects=[]) == ("Y", [])


def test_require_markers_names_the_file():
    require_markers(Trial(np.zeros((5, 1, 3)), ["A"], 100.0))
    empty = Trial(np.empty((5, 0, 3)), [], 100.0, source="emg.c3d", analog_channels=3)
    with pytest.raises(MocapError, match=rf"^emg.c3d: {REFUSAL} \(give the capture's marker "
                                         r"file"):
        require_markers(empty)


def test_every_stage_refuses_it_naming_the_file(force_plates):
    trial = read_c3d(force_plates)
    for stage in (lambda: match_trial(trial), lambda: calibrate(trial),
                  lambda: fit_capture(trial), lambda: draft_protocol(trial)):
        with pytest.raises(MocapError, match=rf"^{force_plates}: {REFUSAL}"):
            stage()


def test_inspect_reports_what_it_holds_and_fails_it(force_plates):
    summary = inspect_c3d(force_plates)
    assert not summary["ok"] and summary["error"].startswith(f"{force_plates}: {REFUSAL[:17]}")
    assert "3 analog channels" in summary["error"]
    assert (summary["frames"], summary["rate_hz"], summary["analog_channels"]) == (50, 100.0, 3)
    assert summary["labels"] == summary["markers"] == [] and summary["protocol"] is None
    assert format_summary(summary) == f"{force_plates}\n  FAILED: {summary['error']}"


@pytest.mark.usefixtures("sample_dir")
def test_inspect_of_a_folder_holding_one_reports_every_file(force_plates, capsys):
    """Every file reported; the analog-only one fails (exit 1) in one line on stderr."""
    folder = force_plates.parent
    shutil.copy(SAMPLES / "rest.c3d", folder)
    assert main(["inspect", str(folder)]) == 1
    out, err = capsys.readouterr()
    assert f"{force_plates}\n  FAILED: {force_plates}: no marker points" in out
    assert "protocol fullbody38: 38/38 markers" in out
    assert err.splitlines() == [line for line in err.splitlines() if "forceplate.c3d" in line]
    assert len(err.splitlines()) == 1 and "3 analog channels" in err
    assert main(["inspect", "--json", str(force_plates)]) == 1
    [record] = json.loads(capsys.readouterr().out)
    assert (record["ok"], record["frames"], record["analog_channels"]) == (False, 50, 3)


@pytest.mark.parametrize("command", [["fit", "{file}", "-o", "{folder}/angles.csv"],
                                     ["events", "{file}"], ["cycles", "{file}"],
                                     ["protocol", "draft", "{file}", "-o", "{folder}/p.toml"]])
def test_each_command_refuses_it_in_one_line(force_plates, command, capsys):
    args = [a.format(file=force_plates, folder=force_plates.parent) for a in command]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert f"{force_plates}: no marker points" in err and "Traceback" not in err


@pytest.mark.usefixtures("sample_dir")
def test_as_a_static_it_is_a_usage_error(force_plates, capsys):
    assert main(["fit", str(SAMPLES / "walk_straight_normal.c3d"), "--static",
                 str(force_plates), "-o", str(force_plates.parent / "a.csv")]) == 2
    assert f"--static: {force_plates}: no marker points" in capsys.readouterr().err


@pytest.mark.usefixtures("sample_dir")
def test_a_build_of_a_folder_holding_one_fails_it_alone(force_plates, capsys):
    """The analog-only file fails at the protocol stage, named; it is not taken for a
    static (nothing in it moves); the walk beside it is built."""
    folder = force_plates.parent
    shutil.copy(SAMPLES / "walk_straight_normal.c3d", folder)
    out = folder / "lib.json"
    assert main(["build", str(folder), "-o", str(out), "--no-cache", "-q"]) == 1
    printed = capsys.readouterr().out
    assert "captures 2  ok 1  failed 1" in printed
    assert f"{force_plates} [protocol]: no marker points" in printed
    assert json.loads(out.read_text())["entries"]
