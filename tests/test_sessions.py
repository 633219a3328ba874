"""Capture sessions: statics per folder (session.toml), statics found among the inputs, statics
as recorded (a step in, one frame), and captures that give no entry without failing."""

from __future__ import annotations

import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mocaplib.statics import STATIC_WINDOW_S, standing_part
from mocaplib.cli import main
from mocaplib.errors import CalibrationError, MocapError, NoCycleError
from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_write import write_c3d
from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
from mocaplib.build.sessions import SESSION_FILE, load_session, plan_captures

pytestmark = pytest.mark.usefixtures("sample_dir")


def _samples():
    from conftest import SAMPLES
    return SAMPLES


def _copy(name, folder, new_name=None):
    folder.mkdir(parents=True, exist_ok=True)
    return shutil.copy(_samples() / f"{name}.c3d", folder / f"{new_name or name}.c3d")


def _stepping_in(folder):
    """The sample static with the subject walking in for its first second: 100 frames of the
    straight walk, then the 201 frames of rest."""
    walk, rest = (read_c3d(_samples() / f"{n}.c3d") for n in ("walk_straight_normal", "rest"))
    assert walk.labels == rest.labels and walk.rate == rest.rate
    markers = np.concatenate([walk.markers[:100], rest.markers])
    return write_c3d(folder / "static_step.c3d", markers, rest.labels, rest.rate)


def test_a_static_with_a_step_in_is_calibrated_on_its_quietest_second(tmp_path):
    trial = read_c3d(_stepping_in(tmp_path))
    part, window = standing_part(trial)
    # the rest starts at frame 100 (1.0 s): the quietest second lies in it
    assert window[0] >= 1.0 and window[1] - window[0] == pytest.approx(STATIC_WINDOW_S)
    assert part.n_frames == round(STATIC_WINDOW_S * trial.rate) + 1
    np.testing.assert_array_equal(part.markers[0], trial.markers[round(window[0] * trial.rate)])
    # a window given is used as it is; one over the step is refused, saying where
    assert standing_part(trial, window=(1.5, 2.5))[1] == (1.5, 2.5)
    with pytest.raises(CalibrationError, match=r"static_step\.c3d: is not a standing static "
                                               r"trial: even the window \(0\.00-1\.50 s\) moves"):
        standing_part(trial, window=(0.0, 1.5))
    with pytest.raises(CalibrationError, match="holds no frame of the static"):
        standing_part(trial, window=(5.0, 6.0))
    # a walk has no quiet second at all
    with pytest.raises(CalibrationError, match="even its quietest 1 s"):
        standing_part(read_c3d(_samples() / "walk_straight_normal.c3d"))


def test_a_single_frame_static_is_accepted(tmp_path):
    rest = read_c3d(_samples() / "rest.c3d")
    one = read_c3d(write_c3d(tmp_path / "one.c3d", rest.markers[:1], rest.labels, rest.rate))
    part, window = standing_part(one)
    assert part.n_frames == 1 and window == (0.0, 0.0)
    walk = _copy("walk_straight_normal", tmp_path)
    result = build_library([walk, one.source], BuildSettings(static=one.source), jobs=1,
                   cache_dir=None, progress=False)
    walked, static = result.captures
    assert walked.ok and walked.static == "one.c3d" and walked.entries, walked.error
    # the static itself is no failure: a frame is too short for a rest entry, and it says so
    assert static.ok and not static.entries and result.ok
    assert static.no_entry.startswith("a static trial: used to calibrate, no entry of its own")


def test_the_hint_for_a_static_given_as_a_motion_says_it_stands(tmp_path):
    path = _stepping_in(tmp_path)
    assert main(["cycles", str(path)]) == 1
    # it has a step or none; either way it is told it stands, not to check POINT:RATE
    from mocaplib.gait.cycles import analyse_cycles
    from mocaplib.gait.foot_events import GaitEvent

    trial = read_c3d(path)
    shoulders = [trial.marker(label) for label in ("LSHO", "RSHO")]
    one_step = [GaitEvent("left", "toe_off", 0.3, 30, 1.0)]
    with pytest.raises(NoCycleError, match="stands still for most of it: a static trial"):
        analyse_cycles(one_step, *shoulders, trial.rate, source=path)


def test_a_standing_file_among_the_inputs_is_a_static(tmp_path):
    walk = _copy("walk_straight_normal", tmp_path)
    rest = _copy("rest", tmp_path)
    pool, planned = plan_captures([walk, rest], BuildSettings())
    assert pool.statics == (str(rest),) and planned == [pool, pool]
    result = build_library([tmp_path], BuildSettings(), jobs=1, cache_dir=None, progress=False)
    static, walked = result.captures                 # in name order
    assert walked.static == "rest.c3d" and static.static == "rest.c3d"
    assert static.entries[0].locomotion_class == "rest" and result.ok
    assert result.library.settings["static"] == "rest.c3d"


def test_a_session_file_names_its_folders_static_pose_and_protocol(tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    walk_one = _copy("walk_straight_normal", one)
    _copy("rest", one, "Static")
    (one / SESSION_FILE).write_text('static = "Static.c3d"\nstatic_pose = "neutral"\n'
                                    'protocol = "fullbody38"\n')
    walk_two = _copy("walk_straight_slow", two)
    session = load_session(one / SESSION_FILE)
    assert session.statics == (str((one / "Static.c3d").absolute()),)
    assert (session.static_pose, session.protocol) == ("neutral", "fullbody38")
    result = build_library([tmp_path], BuildSettings(), jobs=1, cache_dir=None, progress=False)
    by_name = {c.file: c for c in result.captures}
    assert by_name[walk_one.name].static == "Static.c3d" and by_name["Static.c3d"].ok
    # the other folder has no static of its own: the session's static is not its subject's
    # pool, so it is calibrated from itself (the synthetic subjects are one: no warning)
    assert by_name[walk_two.name].static is None and by_name[walk_two.name].entries
    assert result.ok and len(result.library) == 3


@pytest.mark.parametrize("text, message", [
    ('statik = "S.c3d"\n', "unknown key"),
    ('static = "missing.c3d"\n', "its static .*missing.c3d does not exist"),
    ('static_pose = "neutral"\n', "static_pose 'neutral' describes a static"),
    ('static = "S.c3d"\nstatic_window = [2, 1]\n', r"static_window must be \[start, end\]"),
    ("static = \n", "not valid TOML"),
])
def test_a_bad_session_file_is_named_with_what_to_do(tmp_path, text, message):
    _copy("rest", tmp_path, "S")
    (tmp_path / SESSION_FILE).write_text(text)
    with pytest.raises(MocapError, match=f"{SESSION_FILE}: .*{message}"):
        load_session(tmp_path / SESSION_FILE)
    walk = _copy("walk_straight_normal", tmp_path)
    assert main(["build", str(walk), "-o", str(tmp_path / "l.json"), "--no-cache", "-q"]) == 2


def test_a_capture_without_a_complete_cycle_gives_no_entry_and_says_why(tmp_path, capsys):
    walk = read_c3d(_samples() / "walk_straight_normal.c3d")
    short = write_c3d(tmp_path / "short.c3d", walk.markers[:110], walk.labels, walk.rate)
    whole = _copy("walk_straight_normal", tmp_path)
    result = build_library([short, whole], BuildSettings(), jobs=1, cache_dir=None,
                   progress=False)
    cut, kept = result.captures
    assert cut.ok and not cut.entries and kept.entries and result.ok
    assert cut.no_entry.startswith("no complete cycle: fewer than two left toe-offs")
    record = next(c for c in result.diagnostics()["captures"] if c["source"] == "short.c3d")
    assert record["no_entry"] == cut.no_entry and record["events"]
    others = [str(_samples() / f"{name}.c3d") for name in
              ("side_left_normal", "turn_spot_left_normal", "walk_curve_r2_left_normal")]
    assert main(["build", str(short), str(whole), *others, "-o", str(tmp_path / "l.json"),
                 "--no-cache", "-q"]) == 0     # a capture without entry
    assert "no entry:\n  short.c3d: no complete cycle" in capsys.readouterr().out


def test_static_options_are_checked_before_any_work(tmp_path, capsys):
    walk = _copy("walk_straight_normal", tmp_path / "in")
    out = ["-o", str(tmp_path / "l.json"), "--no-cache", "-q"]
    assert main(["build", str(walk), *out, "--static-window", "2:1"]) == 2
    assert "--static-window: expected START:END" in capsys.readouterr().err
    step = _stepping_in(tmp_path)
    assert main(["build", str(walk), *out, "--static", str(step), "--static-window",
                 "0:1.5"]) == 2
    assert "even the window (0.00-1.50 s) moves" in capsys.readouterr().err
    # the step-in static without a window: its quietest second calibrates, and it is said
    # 1 entry: a valid library without a control space (exit 0, a warning)
    assert main(["build", str(walk), *out, "--static", str(step)]) == 0
    printed = capsys.readouterr().out
    assert "captures 1  ok 1  failed 0" in printed
    assert "static static_step.c3d: calibrated on its stretch" in printed
    with pytest.raises(MocapError, match="requires a static"):
        build_library([walk], replace(BuildSettings(), require_static=True), cache_dir=None,
              progress=False)


def test_the_shared_files_with_two_statics_build_without_failure(shared_c3d, tmp_path, capsys):
    # the target: all 17 shared files with HC030A01 and Static1 as statics exit 0 and
    # keep >= 10 entries (measured 12: docs/guide/build.md lists the captures without entry)
    statics = [shared_c3d / "biomechzoo" / "HC030A01.c3d", shared_c3d / "motonms_unipd" /
               "Static1.c3d"]
    out = tmp_path / "lib.json"
    assert main(["build", str(shared_c3d), "--static", str(statics[0]), "--static",
                 str(statics[1]), "-o", str(out), "--no-cache", "-q", "--jobs", "2"]) == 0
    printed = capsys.readouterr().out
    assert "captures 17  ok 17  failed 0" in printed
    from mocaplib.library.format import load_library

    library = load_library(out)
    assert len(library) >= 10
    by_file = {Path(c["source"]).stem: c for c in json.loads(
        out.with_name("lib.diagnostics.json").read_text())["captures"]}
    # the one-frame static is used, never failed; the jump has no cycle, and says so
    assert by_file["PiG_Calibration-FlatFoot-One"]["no_entry"].startswith("a static trial")
    assert by_file["16_07"]["no_entry"].startswith("no complete cycle")
    # every capture without an entry says why; one left out by QC names its cycles and metrics
    for record in by_file.values():
        if not any(c["entry_id"] for c in record["cycles"]):
            assert record["no_entry"], record["source"]
        if (record["no_entry"] or "").startswith("every complete cycle was left out by QC"):
            assert re.search(r"QC: cycle \d+ \([\d.]+-[\d.]+ s\) \w+ [\d.]+ [<>]",
                             record["no_entry"]), record["no_entry"]
    moving = ("07_01", "07_12", "HC030A22", "Gait", "PiG_Motion-FlatFoot-Full", "running",
              "BTS", "Qualisys")
    assert {e.split("_c")[0] for e in library.table.index} >= set(moving)
