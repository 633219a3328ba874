"""``mocaplib inspect``: per-file summary (library) and the command line (JSON, table, exit
codes)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from protocol_trials import walker_trial

from mocaplib.cli import main
from mocaplib.markersets.inspection import SUMMARY_KEYS, inspect_c3d, inspect_trial
from mocaplib.io.c3d_write import write_c3d
from mocaplib.markersets.protocols import load_protocol
from mocaplib.trial import Event, Trial

REQUIRED_KEYS = {"file", "ok", "error", "frames", "rate_hz", "units", "vertical_axis", "labels",
                 "protocol", "missing_landmarks", "warnings", "events"}


@pytest.fixture
def capture(tmp_path):
    """A 60-frame plugin_gait capture with a 12-frame hole in LTOE and two events."""
    trial = walker_trial(load_protocol("plugin_gait"), n_frames=60)
    markers = trial.markers.copy()
    markers[20:32, trial.index("LTOE")] = np.nan
    markers[5:8, trial.index("C7")] = np.nan
    events = [Event("Left", "Foot Off", 0.10), Event("Right", "Foot Strike", 0.25)]
    return write_c3d(tmp_path / "walk.c3d", markers, trial.labels, 100.0, events=events)


def _cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return code, out, err


def test_summary_of_a_written_capture(capture):
    summary = inspect_c3d(capture)
    assert tuple(summary) == SUMMARY_KEYS and REQUIRED_KEYS <= set(summary)
    assert summary["ok"] and summary["error"] is None
    assert (summary["frames"], summary["rate_hz"], summary["units"]) == (60, 100.0, "mm")
    assert summary["protocol"] == "plugin_gait" and summary["missing_landmarks"] == []
    gaps = {m["label"]: m for m in summary["markers"]}
    assert gaps["LTOE"]["longest_gap_frames"] == 12 and gaps["C7"]["longest_gap_frames"] == 3
    # 12 of 60 frames missing is 20 %; 1e-9 only absorbs float rounding
    np.testing.assert_allclose(gaps["LTOE"]["gap_pct"], 20.0, atol=1e-9)
    np.testing.assert_allclose(gaps["LTOE"]["longest_gap_s"], 0.12, atol=1e-9)
    assert gaps["LASI"]["gap_pct"] == 0.0 and gaps["LASI"]["landmark"] == "L_ASIS"
    assert [(e["context"], e["label"]) for e in summary["events"]] == [
        ("Left", "Foot Off"), ("Right", "Foot Strike")]
    # event times go through the file as float32: 1e-6 s is far below a frame (10 ms)
    np.testing.assert_allclose([e["time_s"] for e in summary["events"]], [0.10, 0.25], atol=1e-6)


def test_a_capture_cut_from_a_longer_recording_says_where_its_clock_starts(capsys, tmp_path):
    # the file's frames start at C3D frame 45, its events on the recording's clock (as Vicon
    # writes them): inspect says where the file starts on that clock
    trial = walker_trial(load_protocol("plugin_gait"), n_frames=60)
    path = write_c3d(tmp_path / "cut.c3d", trial.markers, trial.labels, 100.0, first_frame=45,
                     events=[Event("Left", "Foot Off", 0.65)])
    code, out, _ = _cli(capsys, "inspect", str(path))
    assert code == 0 and "60 frames at 100 Hz (0.59 s) from C3D frame 45, units mm" in out
    assert "events (lab clock: the file starts at 0.440 s): Left Foot Off 0.650 s" in out
    plain = write_c3d(tmp_path / "plain.c3d", trial.markers, trial.labels, 100.0,
                      events=[Event("Left", "Foot Off", 0.2)])
    code, out, _ = _cli(capsys, "inspect", str(plain))
    assert "(0.59 s), units mm" in out and "  events: Left Foot Off 0.200 s" in out


def test_a_frame_rate_no_gait_capture_has_is_shown_with_a_warning(tmp_path):
    # inspect still shows the file (it is how one finds the wrong POINT:RATE), and says that
    # the processing commands refuse it
    trial = walker_trial(load_protocol("plugin_gait"), n_frames=60)
    path = write_c3d(tmp_path / "odd.c3d", trial.markers, trial.labels, 2.0)
    summary = inspect_c3d(path)
    assert summary["ok"] and summary["rate_hz"] == 2.0
    assert any("frame rate 2 Hz is outside" in w for w in summary["warnings"])
    assert not any("frame rate" in w for w in inspect_trial(trial)["warnings"])


def test_json_output_and_exit_0(capsys, capture):
    code, out, _ = _cli(capsys, "inspect", "--json", str(capture))
    assert code == 0
    (entry,) = json.loads(out)
    assert REQUIRED_KEYS <= set(entry) and entry["ok"] is True
    assert entry["protocol"] == "plugin_gait"


def test_bad_file_exit_1_with_reason_and_no_traceback(capsys, capture, tmp_path):
    bad = tmp_path / "notes.c3d"
    bad.write_text("this is not a C3D file, just some notes from the session\n" * 20)
    (tmp_path / "empty").mkdir()
    code, out, err = _cli(capsys, "inspect", "--json", str(capture), str(bad),
                          str(tmp_path / "empty"))
    assert code == 1
    good, broken, empty = json.loads(out)
    assert good["ok"] and not broken["ok"] and not empty["ok"]
    assert REQUIRED_KEYS <= set(broken) and broken["frames"] is None
    assert "notes.c3d" in broken["error"] and "no *.c3d files" in empty["error"]
    assert "notes.c3d" in err
    code, out, err = _cli(capsys, "inspect", str(bad))
    assert code == 1 and "FAILED" in out


def test_usage_errors_exit_2(capsys, capture, tmp_path):
    assert main(["inspect"]) == 2
    code, _, err = _cli(capsys, "inspect", "--protocol", "no_such_set", str(capture))
    assert code == 2 and "unknown protocol 'no_such_set'" in err
    broken = tmp_path / "broken.toml"
    broken.write_text("[markers]\nLASI = { landmark = 'L_ASIS' \n")
    code, _, err = _cli(capsys, "inspect", "--protocol", str(broken), str(capture))
    assert code == 2 and "broken.toml" in err


def test_explicit_protocol_and_table(capsys, capture, tmp_path):
    code, out, _ = _cli(capsys, "inspect", "--protocol", "fullbody38", str(capture))
    assert code == 0
    assert "protocol fullbody38: 38/38 markers; missing required landmarks: none" in out
    assert "LTOE" in out and "0.12 s (12 frames)" in out
    assert "4 labels not in protocol fullbody38" in out  # RBAK LFIN RFIN SACR


def test_swap_and_model_outputs_reach_the_warnings():
    protocol = load_protocol("plugin_gait")
    labels = protocol.labels
    i, j = labels.index("LSHO"), labels.index("RSHO")
    labels[i], labels[j] = "RSHO", "LSHO"
    trial = walker_trial(protocol, labels=labels)
    markers = np.concatenate([trial.markers, trial.markers[:, :2]], axis=1)
    trial = type(trial)(markers, labels + ["LHipAngles", "PELO"], trial.rate)
    summary = inspect_trial(trial)
    assert summary["swaps"] and "LSHO (labelled left)" in summary["swaps"][0]
    assert summary["ignored_points"] == ["LHipAngles", "PELO"]
    assert {m["label"] for m in summary["markers"]}.isdisjoint({"LHipAngles", "PELO"})
    assert any("model-output" in w for w in summary["warnings"])


def test_real_files_walking3_and_gait(capsys, real_c3d):
    walking3 = real_c3d("motonms_unipd/Walking3.c3d")
    gait = real_c3d("btkdata/Gait.c3d")
    code, out, _ = _cli(capsys, "inspect", "--json", str(walking3), str(gait))
    assert code == 0
    w3, g = json.loads(out)
    assert (w3["protocol"], w3["vertical_axis"], w3["frames"]) == ("padova30", "Y", 294)
    assert any("LA (labelled left)" in w for w in w3["warnings"])
    assert w3["events"][0] == {"context": "Right", "label": "Foot Strike",
                               "time_s": pytest.approx(2.25, abs=1e-6)}
    assert g["protocol"] == "helen_hayes" and set(g["duplicates"]) >= {"RKNE", "LFOO"}
    # shoulders valid in 40 % of frames (SOURCES.md): at least 55 % missing
    rsho = next(m for m in g["markers"] if m["label"] == "RSHO")
    assert rsho["gap_pct"] > 55


def test_truncated_capture_is_a_failed_entry(capsys, capture, tmp_path):
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(capture.read_bytes()[:1500])
    code, out, err = _cli(capsys, "inspect", "--json", "--protocol", "auto", str(cut))
    (entry,) = json.loads(out)
    assert code == 1 and entry["ok"] is False and entry["error"].startswith(str(cut))
    assert entry["labels"] == [] and entry["protocol"] is None


def test_no_complete_protocol_gives_null_and_the_closest_candidate(tmp_path, capsys):
    from protocol_trials import select

    pig = load_protocol("plugin_gait")
    trial = walker_trial(pig, n_frames=30)
    keep = [i for i, label in enumerate(trial.labels) if label not in ("LSHO", "RSHO")]
    summary = inspect_trial(select(trial, keep))
    closest = summary["closest_protocol"]
    assert summary["protocol"] is None and summary["missing_landmarks"] == []
    assert closest["name"] == "plugin_gait" and closest["markers_found"] == len(keep)
    assert set(closest["missing_landmarks"]) == {"L_ACROMION", "R_ACROMION"}
    # a protocol the user names is reported as such, with what it misses
    named = inspect_trial(select(trial, keep), protocol="plugin_gait")
    assert named["protocol"] == "plugin_gait" and named["closest_protocol"] is None
    path = write_c3d(tmp_path / "no_shoulders.c3d", trial.markers[:, keep],
                     [trial.labels[i] for i in keep], 100.0)
    code, out, _ = _cli(capsys, "inspect", str(path))
    assert code == 0 and "closest plugin_gait (40/42 markers) lacks L_ACROMION, R_ACROMION" in out


def test_a_required_landmark_labelled_but_never_seen_counts_as_missing(real_c3d):
    """LASI present as a label but missing in every frame: the summary says the landmark is
    missing, as when the label is not in the file at all (the fit could do nothing with it)."""
    from mocaplib.io.c3d import read_c3d

    trial = read_c3d(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    keep = [i for i, label in enumerate(trial.labels) if label != "LASI"]
    dropped = inspect_trial(Trial(trial.markers[:, keep], [trial.labels[i] for i in keep],
                                  trial.rate), protocol="plugin_gait")
    trial.markers[:, trial.labels.index("LASI")] = np.nan
    summary = inspect_trial(trial, protocol="plugin_gait")
    assert summary["missing_landmarks"] == dropped["missing_landmarks"] == ["L_ASIS"]
    assert any(w.startswith("missing required landmarks for plugin_gait: L_ASIS")
               for w in summary["warnings"])
