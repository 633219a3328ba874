"""Long takes cut by activity, stairs and slopes, session choices of cycles, outlier samples,
the build's own validation and the captures' provenance (:mod:`mocaplib.gait.activity`,
:mod:`mocaplib.build.sessions`, :func:`mocaplib.build.pipeline.valid_library`)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from conftest import SAMPLES
from mocaplib.build.pipeline import build_library, valid_library
from mocaplib.build.sessions import load_session
from mocaplib.build.settings import BuildSettings
from mocaplib.build.workflow import process_capture
from mocaplib.errors import MocapError
from mocaplib.gait.activity import cycle_activity
from mocaplib.gait.cycles import Cycle
from mocaplib.gait.patterns import CycleVelocities, Pattern
from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_write import write_c3d
from mocaplib.library.command import Command
from mocaplib.library.validation import entry_problems, validate_library
from mocaplib.report import write_report
from mocaplib.skeleton import DOF_NAMES
from mocaplib.synth.capture import synthesize_capture
from stairs import stairs

REST = SAMPLES / "rest.c3d"
#: The mixed take: a forward walk, a turn on the spot, a backward walk and a side-step, each
#: long enough for two steady cycles after the change of activity.
MIXED = [(Command(v_f=1.2), 4.0, "forwards"), (Command(omega=1.2), 4.0, "turning on the spot"),
         (Command(v_f=-0.8), 4.5, "backwards"), (Command(v_l=0.5), 4.5, "sideways")]


def _cycle(v_f=0.0, v_l=0.0, omega=0.0, rise=0.0, rest=False):
    v = float(np.hypot(v_f, v_l))
    return Cycle(0, 0.0, 1.0, CycleVelocities(Pattern("point", {}), 1.0, v, omega, v_l, v_f),
                 0.0, 1.0, rest=rest, rise_per_step=rise)


@pytest.mark.parametrize("cycle, activity", [
    (_cycle(rest=True), "standing"),
    (_cycle(v_f=0.05), "stepping in place"),
    (_cycle(omega=1.0), "turning on the spot"),
    (_cycle(v_f=1.2, omega=0.4), "forwards"),           # a curve is a forward walk
    (_cycle(v_f=-0.8), "backwards"),
    (_cycle(v_l=0.5), "sideways"),
    (_cycle(v_f=0.5, v_l=0.5), "sideways"),             # a 45° diagonal
    (_cycle(v_f=-0.87, v_l=0.51), "sideways"),          # the plan's 150° diagonal, 149.6°
    (_cycle(v_f=-0.86, v_l=0.5), "sideways"),           # and 150.2°
    (_cycle(v_f=1.0, rise=-0.17), "descending"),        # a stair's riser per step
    (_cycle(v_f=1.0, rise=0.05), "ascending"),          # a ramp's
    (_cycle(v_f=1.0, rise=0.011), "forwards"),          # the most a real level walk rises
])
def test_the_activity_comes_from_the_motion(cycle, activity):
    assert cycle_activity(cycle, []) == activity


def _heading(shoulders: np.ndarray, frame: int) -> float:
    left, right = shoulders[frame]
    return float(np.arctan2(*(right - left)[1::-1]) + np.pi / 2)


def mixed_take(folder, parts=MIXED):
    """One C3D file of the synthetic walker doing each part in turn (one subject, one marker
    placement): each part turned and moved so that it starts where and as the one before ends
    (the legs' phase jumps at the joins, as a person changing activity does, more abruptly)."""
    captures = [synthesize_capture(command, duration=duration, seed=11 + i, session_seed=11)
                for i, (command, duration, _) in enumerate(parts)]
    markers = [captures[0].trial.markers]
    before = np.asarray(captures[0].truth["shoulders"]["values"])
    for capture in captures[1:]:
        shoulders = np.asarray(capture.truth["shoulders"]["values"])
        turn = _heading(before, -1) - _heading(shoulders, 0)
        c, s = np.cos(turn), np.sin(turn)
        rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        start, end = shoulders[0].mean(axis=0), before[-1].mean(axis=0)
        start[2] = end[2] = 0.0
        markers.append((capture.trial.markers - start) @ rotation.T + end)
        before = (shoulders - start) @ rotation.T + end
    trial = captures[0].trial
    return write_c3d(folder / "mixed.c3d", np.concatenate(markers), trial.labels, trial.rate)


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """The mixed take's file and its result with the default settings."""
    path = mixed_take(tmp_path_factory.mktemp("mixed"))
    return path, process_capture(path, BuildSettings())


def test_a_mixed_take_gives_one_entry_per_activity(mixed):
    _, result = mixed
    assert result.ok, result.error
    cycles = result.diagnostics["cycles"]
    kept = [c for c in cycles if c["entry_id"]]
    # one entry per activity, in the order of the take, each its segment's steadiest cycle
    assert [c["activity"] for c in kept] == [activity for *_, activity in MIXED]
    assert [e.id for e in result.entries] == [f"mixed_c{c['index']}" for c in kept]
    for c in kept:
        same = [o for o in cycles if o["activity"] == c["activity"]]
        assert c["unsteadiness"] == min(o["unsteadiness"] for o in same)
        # a steady cycle (the synthetic walk's own measure 0.06-0.11 m/s), not a change of
        # activity (0.6-0.95 m/s, measured on this take)
        assert c["unsteadiness"] < 0.2, c
    by_activity = {c["activity"]: c for c in kept}
    np.testing.assert_allclose(by_activity["forwards"]["v_f"], 1.2, atol=0.05)
    np.testing.assert_allclose(by_activity["backwards"]["v_f"], -0.8, atol=0.05)
    np.testing.assert_allclose(by_activity["turning on the spot"]["omega"], 1.2, atol=0.05)
    np.testing.assert_allclose(by_activity["sideways"]["v_l"], 0.5, atol=0.05)


def test_a_session_trims_and_picks_the_cycles_of_a_capture(mixed, tmp_path):
    path, result = mixed
    cycles = result.diagnostics["cycles"]
    forwards = [c for c in cycles if c["activity"] == "forwards"]
    end = forwards[-1]["end_s"] + 0.01
    picked = [c["index"] for c in cycles if c["activity"] == "backwards"][-2:]
    dropped = next(c["index"] for c in forwards if c["entry_id"])
    folder = path.parent
    (folder / "session.toml").write_text(
        f'[capture."mixed.c3d"]\ntrim = [[0, {end}]]\ndrop_cycles = [{dropped}]\n')
    trimmed = process_capture(path, _session_settings(folder, path))
    assert [e.cycle_index for e in trimmed.entries] == [
        min((c for c in forwards if c["index"] != dropped), key=lambda c: c["unsteadiness"])
        ["index"]]
    assert any("outside the session's trim windows" in c["left_out"]
               for c in trimmed.diagnostics["cycles"] if c["left_out"])
    (folder / "session.toml").write_text(f'[capture."mixed.c3d"]\ncycles = {picked}\n')
    chosen = process_capture(path, _session_settings(folder, path))
    assert [e.cycle_index for e in chosen.entries] == picked
    (folder / "session.toml").unlink()


def _session_settings(folder, path) -> BuildSettings:
    session = load_session(folder / "session.toml")
    choice = session.choice(path)
    return BuildSettings(trim=choice.trim, cycles=choice.cycles, drop_cycles=choice.drop_cycles)


@pytest.mark.parametrize("text, message", [
    ('[capture."mixed.c3d"]\ntrim = [[3, 1]]\n',
     r'\[capture."mixed.c3d"\]: trim must be a list of \[start, end\] windows'),
    ('[capture."mixed.c3d"]\ncycles = [1]\ndrop_cycles = [1]\n',
     r"cycle\(s\) 1 both in cycles and in drop_cycles"),
    ('[capture."mixed.c3d"]\ncycle = [1]\n', r"unknown key\(s\) cycle; known: trim"),
    ('[capture."other.c3d"]\ncycles = [1]\n', r"no capture other.c3d beside the session file"),
    ('[capture."mixed.c3d"]\ncycles = [-1]\n', r"cycles must be a list of cycle indices"),
    ("keep_non_level = 1\n", r"keep_non_level must be true or false"),
])
def test_a_wrong_capture_choice_names_the_session_file_and_the_key(tmp_path, text, message):
    (tmp_path / "mixed.c3d").write_bytes(b"")
    (tmp_path / "session.toml").write_text(text)
    with pytest.raises(MocapError, match=message) as caught:
        load_session(tmp_path / "session.toml")
    assert str(caught.value).startswith(f"{tmp_path / 'session.toml'}: ")


def _drifting(path, settings):
    """:func:`process_capture`, with the knee's mean of the capture's second entry moved past
    its range (2.7 rad, 155°), as a cycle that is not periodic gives once its start-to-end
    drift is taken out (the lab's mixed take with ``--all-cycles --qc waive``)."""
    result = process_capture(path, settings)
    bad = result.entries[1]
    a = bad.fourier.a.copy()
    a[DOF_NAMES.index("knee_flexion_r"), 0] = 2.7
    result.entries[1] = replace(bad, fourier=replace(bad.fourier, a=a))
    return result


def test_all_cycles_with_qc_waived_never_writes_what_validate_refuses(mixed, tmp_path):
    path, _ = mixed
    result = build_library([path], BuildSettings(all_cycles=True, qc_policy="waive"),
                           progress=False, process=_drifting)
    capture = result.captures[0]
    assert len(result.library) == capture.n_cycles - 1 == 15
    (warning,) = [w for w in capture.warnings if "the library's validation refuses it" in w]
    assert warning.startswith("cycle 1 (") and "mean knee_flexion_r 2.7 rad (154.7°" in warning
    written, _ = result.write(tmp_path / "lib.json")
    assert validate_library(written) == []


def test_an_entry_validation_refuses_is_left_out_with_a_warning(mixed):
    _, result = mixed
    capture = replace(result, entries=list(result.entries), warnings=[],
                      diagnostics=json.loads(json.dumps(result.diagnostics)))
    bad = capture.entries[1]
    knee = DOF_NAMES.index("knee_flexion_r")
    a = bad.fourier.a.copy()
    a[knee, 0] = 2.7                      # 155°: past the knee's range, as a drifting cycle
    capture.entries[1] = replace(bad, fourier=replace(bad.fourier, a=a))
    library = valid_library([capture], settings={}, qc_thresholds=BuildSettings().qc_thresholds)
    assert [e.id for e in library.entries] == sorted(e.id for e in result.entries
                                                     if e.id != bad.id)
    (warning,) = capture.warnings
    assert warning.startswith(f"cycle {bad.cycle_index} (") and "validation refuses it" in warning
    assert "mean knee_flexion_r 2.7 rad (154.7°" in warning and "not periodic" in warning
    assert not any(c["entry_id"] == bad.id for c in capture.diagnostics["cycles"])
    assert entry_problems(library) == {}


@pytest.mark.usefixtures("sample_dir")
def test_a_slope_is_measured_left_out_by_default_and_kept_flagged_on_request(tmp_path):
    # the sample walk down steps of 5 cm (a 1:12 ramp's rise per step)
    trial = read_c3d(SAMPLES / "walk_straight_normal.c3d")
    truth = json.loads((SAMPLES / "walk_straight_normal.truth.json").read_text())
    down = stairs(trial, truth, 0.05)
    path = write_c3d(tmp_path / "down.c3d", down.markers, down.labels, down.rate)
    level = BuildSettings(static=str(REST))
    left_out = process_capture(path, level)
    said = "not level: the pelvis drops 0.050 m per step (stairs or a slope"
    assert not left_out.entries and said in left_out.no_entry
    assert any("left out of the level-locomotion library: " + said in w
               and "--keep-non-level keeps it" in w for w in left_out.warnings)
    cycles = left_out.diagnostics["cycles"]
    assert {c["activity"] for c in cycles} == {"descending"}
    np.testing.assert_allclose(cycles[-1]["rise_per_step_m"], -0.05, atol=0.002)
    kept = process_capture(path, replace(level, keep_non_level=True))
    (entry,) = kept.entries
    assert any(w.startswith(f"cycle {entry.cycle_index} (") and "kept, flagged " + said in w
               for w in kept.warnings)
    # the level walk itself passes: its pelvis returns to its height
    flat = process_capture(SAMPLES / "walk_straight_normal.c3d", level)
    assert flat.entries and all(abs(c["rise_per_step_m"]) < 0.001
                                for c in flat.diagnostics["cycles"])


@pytest.mark.usefixtures("sample_dir")
def test_a_marker_sample_removed_as_an_outlier_keeps_its_cycle_and_is_not_a_gap(tmp_path):
    trial = read_c3d(SAMPLES / "walk_straight_normal.c3d")
    markers = trial.markers.copy()
    markers[int(1.6 * trial.rate), trial.labels.index("RANK"), 2] += 0.05    # a 5 cm spike
    path = write_c3d(tmp_path / "spike.c3d", markers, trial.labels, trial.rate)
    (entry,) = process_capture(path, BuildSettings(static=str(REST))).entries
    assert entry.start_s < 1.6 < entry.end_s
    assert entry.qc["marker_max_m"] < 0.02            # the spike is not the cycle's maximum
    assert entry.qc["gap_fraction"] == 0.0            # and not a gap: the sample has no gap


@pytest.mark.usefixtures("sample_dir")
def test_the_library_and_the_report_say_what_each_capture_was_calibrated_from(tmp_path):
    session = tmp_path / "session"
    alone = tmp_path / "alone"
    for folder, names in ((session, ("walk_straight_normal", "rest")),
                          (alone, ("side_left_normal", "walk_curve_r2_left_normal"))):
        folder.mkdir()
        for name in names:
            (folder / f"{name}.c3d").write_bytes((SAMPLES / f"{name}.c3d").read_bytes())
    (session / "session.toml").write_text('static = "rest.c3d"\nstatic_pose = "neutral"\n')
    result = build_library([session, alone], BuildSettings(), progress=False)
    written, _ = result.write(tmp_path / "lib.json")
    settings = json.loads(written.read_text())["settings"]
    by_file = {c["file"]: c for c in settings["captures"]}
    assert by_file["walk_straight_normal.c3d"] == {
        "file": "walk_straight_normal.c3d", "calibrated_from": "session.toml",
        "static": "rest.c3d", "static_pose": "neutral", "protocol": "fullbody38",
        "protocol_origin": "shipped"}
    assert by_file["side_left_normal.c3d"]["calibrated_from"] == "the capture itself"
    assert by_file["side_left_normal.c3d"]["static"] is None
    html = write_report(written, tmp_path / "report").read_text()
    assert "rest.c3d, walk_straight_normal.c3d calibrated from the static rest.c3d (neutral " \
           "pose, named by a session.toml)" in html
    assert "side_left_normal.c3d, walk_curve_r2_left_normal.c3d calibrated from themselves" \
        in html
    assert "each capture calibrated from itself" not in html
    named = build_library([alone], BuildSettings(static=str(REST)), progress=False)
    assert {c["calibrated_from"] for c in named.library.settings["captures"]} == {"command line"}
