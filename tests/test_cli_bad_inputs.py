"""Hostile but plausible command lines and files: a clear error, the right exit code, no
traceback (``main`` returning, not raising), inputs untouched, nothing half-written."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import warnings
from pathlib import Path

import pytest

from mocaplib.cli import main
from conftest import SAMPLES


def sample(name: str, folder: Path) -> Path:
    """A copy of the sample capture ``name`` in ``folder``."""
    source = SAMPLES / f"{name}.c3d"
    folder.mkdir(parents=True, exist_ok=True)
    return Path(shutil.copy(source, folder / source.name))


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def library(tmp_path_factory) -> Path:
    """A small valid library built from four sample captures."""
    folder = tmp_path_factory.mktemp("lib")
    names = ["walk_straight_normal", "turn_spot_left_normal", "side_left_normal",
             "walk_curve_r2_left_normal", "rest"]
    captures = [sample(name, folder / "caps") for name in names]
    out = folder / "lib.json"
    assert main(["build", *map(str, captures), "-o", str(out), "--no-cache", "-q"]) == 0
    return out


def broken_library(library: Path, folder: Path, edit) -> Path:
    document = json.loads(library.read_text())
    edit(document)
    path = folder / "broken.json"
    path.write_text(json.dumps(document))
    return path


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("args", [
    ["fit", "{w}", "-o", "{w}"],
    ["fit", "{w}", "-o", "{d}/a.csv", "--mot", "{w}"],
    ["fit", "{w}", "-o", "{d}/a.csv", "--mot", "{d}/a.csv"],
    ["fit", "{w}", "-o", "{d}"],
    ["fit", "{w}", "-o", "{r}", "--static", "{r}"],
    ["build", "{d}", "-o", "{w}", "-q"],
    ["build", "{w}", "-o", "{d}", "-q"],
    ["build", "{w}", "-o", "{d}/lib.json", "--report", "{r}", "-q"],
    ["report", "{lib}", "-o", "{w}"],
    ["query", "{lib}", "1.0", "0", "0", "--bvh", "{lib}"],
])
def test_an_output_that_would_overwrite_an_input_is_a_usage_error(args, tmp_path, library,
                                                                  capsys):
    walk = sample("walk_straight_normal", tmp_path / "in")
    static = sample("rest", tmp_path / "in")
    before = {p: digest(p) for p in (walk, static, library)}
    names = {"w": walk, "r": static, "d": tmp_path / "in", "lib": library}
    assert main([a.format(**names) for a in args]) == 2
    error = capsys.readouterr().err
    assert "error:" in error and ("input" in error or "folder" in error or "same file" in error)
    assert {p: digest(p) for p in before} == before
    assert sorted(p.name for p in (tmp_path / "in").iterdir()) == ["rest.c3d",
                                                                   "walk_straight_normal.c3d"]


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("args", [
    ["query", "{lib}", "inf", "0", "0"],
    ["query", "{lib}", "nan", "0", "0"],
    ["query", "{lib}", "1e308", "0", "0"],
    ["query", "{lib}", "1", "0", "0", "--bvh", "{d}/a.bvh", "--rate", "inf"],
    ["query", "{lib}", "1", "0", "0", "--bvh", "{d}/a.bvh", "--cycles", "1000000000"],
    ["fit", "{w}", "-o", "{d}/a.csv", "--cutoff", "inf"],
    ["fit", "{w}", "-o", "{d}/a.csv", "--subject", "knee_width=999"],
    ["fit", "{w}", "-o", "{d}/a.csv", "--subject", "knee_width=0.5"],
    ["build", "{w}", "-o", "{d}/a.json", "--max-gap", "1e308"],
])
def test_numbers_no_command_can_use_are_usage_errors(args, tmp_path, library, capsys):
    walk = sample("walk_straight_normal", tmp_path)
    assert main([a.format(lib=library, d=tmp_path, w=walk) for a in args]) == 2
    assert "error: argument" in capsys.readouterr().err
    assert not list(tmp_path.glob("a.*"))


@pytest.mark.parametrize("edit, problem", [
    (lambda d: d["entries"][0]["fourier"]["a"].pop(), "coefficients must be"),
    (lambda d: d["entries"][0]["fourier"]["a"][0].pop(), "coefficients must be"),
    (lambda d: d["entries"][0].update(v=1e300), "not a locomotion's"),
    (lambda d: d["entries"][0]["fourier"]["a"][0].__setitem__(1, 1e300), "not a joint's"),
])
def test_a_library_with_unusable_numbers_is_refused_by_query_and_report(edit, problem,
                                                                        tmp_path, library,
                                                                        capsys):
    broken = broken_library(library, tmp_path, edit)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow on the way to the refusal
        assert main(["validate", str(broken)]) == 1
        assert problem in capsys.readouterr().out
        assert main(["query", str(broken), "1.0", "0", "0"]) == 1
        assert main(["report", str(broken), "-o", str(tmp_path / "r"), "--no-opengl"]) == 1
    error = capsys.readouterr().err
    assert f"{broken}: not a valid mocaplib library" in error and problem in error
    assert not (tmp_path / "r").exists()


def test_json_nested_too_deep_is_not_a_library(tmp_path, capsys):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100000 + "]" * 100000)
    assert main(["validate", str(deep)]) == 1
    assert main(["query", str(deep), "1", "0", "0"]) == 1
    assert "nested too deep" in capsys.readouterr().err


def _sidecar_copy(library: Path, folder: Path, edit) -> tuple[Path, dict]:
    """The library and its diagnostics sidecar, edited by ``edit(sidecar)``, in ``folder``."""
    copy = Path(shutil.copy(library, folder / "lib.json"))
    sidecar = json.loads(library.with_name("lib.diagnostics.json").read_text())
    edit(sidecar)
    (folder / "lib.diagnostics.json").write_text(json.dumps(sidecar))
    return copy, sidecar


def test_a_malformed_capture_record_in_the_sidecar_loses_only_its_plots(tmp_path, library,
                                                                        monkeypatch):
    from mocaplib.library.format import load_library
    from mocaplib.report import html
    from mocaplib.report.html import _captures
    from mocaplib.report.diagnostics import read_diagnostics

    monkeypatch.setattr(html, "MAX_CAPTURE_FIGURES", 2)  # the bad record and the next one
    copy, sidecar = _sidecar_copy(library, tmp_path,
                                  lambda s: s["captures"][0].update(time_s="oops"))
    lib = load_library(copy)
    captures = _captures(read_diagnostics(copy, lib)[0], lib)
    assert len(captures) == len(sidecar["captures"])
    assert captures[0]["figure"] is None and captures[0]["figure_error"].startswith(
        "its record in the diagnostics sidecar is malformed")
    assert captures[1]["figure"] and not captures[1]["figure_error"]


@pytest.mark.parametrize("edit, problem", [
    (lambda s: s["captures"].__setitem__(0, [1, 2]), "capture record 0 left out of the "
                                                     "report: a list, not an object"),
    (lambda s: s["captures"][1]["cycles"].__setitem__(0, 1), "capture record 1 ("),
    (lambda s: s["captures"][1]["cycles"][0].update(pattern=[]), "pattern = [] has the wrong"),
    (lambda s: s["captures"][2].update(ok="yes"), 'ok = "yes" is not true or false'),
    (lambda s: s["captures"][2].update(warnings=3), "its warnings are not a list"),
])
def test_a_capture_record_of_the_wrong_shape_is_left_out_with_a_warning(edit, problem, tmp_path,
                                                                        library, monkeypatch):
    # These crashed `mocaplib report` (AttributeError) in the summary, the planned captures or
    # the capture tables, which all read the sidecar's records (figures are not drawn here).
    from mocaplib.library.format import load_library
    from mocaplib.report import html
    from mocaplib.report.html import _captures, _summary
    from mocaplib.report.diagnostics import read_diagnostics
    from mocaplib.report.plan import find_plan, plan_commands, planned_status

    monkeypatch.setattr(html, "MAX_CAPTURE_FIGURES", 0)

    copy, sidecar = _sidecar_copy(library, tmp_path, edit)
    lib = load_library(copy)
    diagnostics, warnings = read_diagnostics(copy, lib)
    assert len(warnings) == 1 and problem in warnings[0]
    assert len(diagnostics["captures"]) == len(sidecar["captures"]) - 1
    assert _summary(lib, diagnostics, None)["captures"] == len(sidecar["captures"]) - 1
    planned_status(plan_commands(find_plan()), "plan", lib.entries, diagnostics)
    assert len(_captures(diagnostics, lib)) == len(sidecar["captures"]) - 1


@pytest.mark.parametrize("table, key", [
    ("v = [0.0, inf]", "v"), ("v = [0.0, nan]", "v"), ('v = "fast"', "v"),
])
def test_an_envelope_no_command_can_use_is_a_usage_error(table, key, tmp_path, library, capsys):
    envelope = tmp_path / "envelope.toml"
    envelope.write_text(f"[envelope]\n{table}\nomega = [-1.0, 1.0]\nv_l = [-0.5, 0.5]\n")
    assert main(["report", str(library), "-o", str(tmp_path / "r"), "--envelope",
                 str(envelope), "--no-opengl"]) == 2
    assert f"{envelope}: bad [envelope] table: {key} must be" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("args", [
    ["report", "{lib}", "-o", "{f}/r"],
    ["build", "{w}", "-o", "{d}/new.json", "--report", "{f}/r", "--no-cache", "-q"],
])
def test_a_report_folder_that_cannot_be_written_is_a_usage_error_before_any_work(
        args, tmp_path, library, capsys):
    walk = sample("walk_straight_normal", tmp_path)
    (tmp_path / "plain").write_text("a file where a folder should be")
    names = {"lib": library, "w": walk, "d": tmp_path, "f": tmp_path / "plain"}
    assert main([a.format(**names) for a in args]) == 2
    assert "cannot write into" in capsys.readouterr().err
    assert not (tmp_path / "new.json").exists()  # the build did not start


@pytest.mark.parametrize("text, message", [
    ("capture = [1, 2]\n", "must be a table"),
    ("defaults = 3\ncapture = [{name = 'a'}]\n", "must be tables"),
    (b"\x80\x81 not text", "not UTF-8 text"),
    (None, "cannot read the capture plan"),
])
def test_a_broken_capture_plan_is_a_clear_error(text, message, tmp_path, capsys):
    plan = tmp_path / "plan.toml"
    if text is None:
        plan.mkdir()
    elif isinstance(text, bytes):
        plan.write_bytes(text)
    else:
        plan.write_text(text)
    assert main(["synth", str(plan), "-o", str(tmp_path / "out"), "--no-progress"]) == 1
    assert f"{plan}: " in (error := capsys.readouterr().err) and message in error


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("kind", ["folder", "binary"])
def test_a_protocol_path_that_is_not_a_toml_text_is_a_usage_error(kind, tmp_path, capsys):
    walk = sample("walk_straight_normal", tmp_path)
    protocol = tmp_path / "mine.toml"
    protocol.mkdir() if kind == "folder" else protocol.write_bytes(b"\xff\xfe\x00binary")
    assert main(["events", str(walk), "--protocol", str(protocol)]) == 2
    assert str(protocol) in capsys.readouterr().err


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_a_pipe_named_like_a_capture_is_refused_not_read_forever(tmp_path, capsys):
    walk = sample("walk_straight_normal", tmp_path / "caps")
    pipe = tmp_path / "caps" / "pipe.c3d"
    os.mkfifo(pipe)
    assert main(["events", str(pipe)]) == 1
    assert "not a regular file" in capsys.readouterr().err
    out = tmp_path / "lib.json"
    # in a folder or named directly, the pipe is a capture that fails alone, saying why
    for inputs in ([tmp_path / "caps"], [pipe, walk]):
        assert main(["build", *map(str, inputs), "-o", str(out), "--no-cache", "-q"]) == 1
        printed = capsys.readouterr().out
        assert "captures 2  ok 1  failed 1" in printed and out.is_file()
        assert "pipe.c3d [read]: cannot read: not a regular file" in printed


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("rate", [1.0, 5e5])
def test_a_frame_rate_no_gait_capture_has_is_an_error(rate, tmp_path, capsys):
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    trial = read_c3d(sample("walk_straight_normal", tmp_path))
    path = tmp_path / "odd_rate.c3d"
    write_c3d(path, trial.markers, trial.labels, rate)
    for command in ("events", "cycles"):
        assert main([command, str(path)]) == 1
        assert f"{path}: frame rate {rate:g} Hz is outside" in capsys.readouterr().err


@pytest.mark.usefixtures("sample_dir")
def test_a_corrupt_processor_byte_gives_an_error_and_no_numpy_warning(tmp_path, capsys):
    data = bytearray(sample("walk_straight_normal", tmp_path).read_bytes())
    data[512 + 3] = 85  # DEC floats on an Intel file: the rate decodes to nonsense
    path = tmp_path / "dec.c3d"
    path.write_bytes(bytes(data))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["events", str(path)]) == 1
    assert str(path) in capsys.readouterr().err


@pytest.mark.usefixtures("sample_dir")
def test_an_unusable_cache_folder_does_not_stop_the_build(tmp_path, capsys):
    walk = sample("walk_straight_normal", tmp_path / "caps")
    (tmp_path / "cache").write_text("a file where the cache folder should be")
    out = tmp_path / "lib.json"
    assert main(["build", str(walk), "-o", str(out), "--cache-dir", str(tmp_path / "cache"),
                 "-q"]) == 0  # one entry: valid, without a control space (a warning)
    printed = capsys.readouterr()
    assert "note: results not cached" in printed.out and out.is_file()
    assert "failed 0" in printed.out and "no control space" in printed.err


@pytest.mark.usefixtures("sample_dir")
def test_an_address_that_is_not_a_scheduler_is_a_clear_error(tmp_path, capsys):
    walk = sample("walk_straight_normal", tmp_path)
    pytest.importorskip("distributed")
    assert main(["build", str(walk), "-o", str(tmp_path / "l.json"), "--scheduler",
                 "not an address", "-q"]) == 1
    assert "cannot connect to the Dask scheduler" in capsys.readouterr().err


#: The output options each processing command needs, for the usage-error tests below.
OUTPUTS = {"fit": ["-o", "{d}/a.csv"], "events": [], "cycles": [],
           "build": ["-o", "{d}/l.json", "--no-cache", "-q"]}


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("command", ["fit", "cycles", "build"])
def test_a_bad_static_is_a_usage_error_in_every_command(command, tmp_path, capsys):
    # fit and cycles exited 1 (after reading the capture), build 2, for the same static
    walk = sample("walk_straight_normal", tmp_path)
    other = sample("walk_straight_slow", tmp_path)
    (tmp_path / "empty.c3d").write_bytes(b"")
    outputs = [option.format(d=tmp_path) for option in OUTPUTS[command]]
    for static, message in [(other, f"--static: {other}: is not a standing static trial"),
                            (tmp_path / "gone.c3d",
                             f"--static: {tmp_path / 'gone.c3d'}: no such file or folder"),
                            (tmp_path / "empty.c3d",
                             f"--static: {tmp_path / 'empty.c3d'}: the file is empty")]:
        assert main([command, str(walk), *outputs, "--static", str(static)]) == 2, static
        captured = capsys.readouterr()
        assert message in captured.err and not captured.out
    assert not list(tmp_path.glob("l.*")) and not (tmp_path / "a.csv").exists()


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("command", ["fit", "cycles", "build"])
def test_a_neutral_static_pose_without_a_static_is_a_usage_error(command, tmp_path, capsys):
    walk = sample("walk_straight_normal", tmp_path)
    outputs = [option.format(d=tmp_path) for option in OUTPUTS[command]]
    assert main([command, str(walk), *outputs, "--static-pose", "neutral"]) == 2
    captured = capsys.readouterr()
    assert "--static-pose neutral describes the static trial: give it with --static FILE" \
        in captured.err and not captured.out
    assert not list(tmp_path.glob("l.*")) and not (tmp_path / "a.csv").exists()


@pytest.mark.parametrize("command", ["fit", "events", "cycles", "build"])
def test_a_missing_input_is_a_usage_error_in_every_command(command, tmp_path, capsys):
    outputs = [option.format(d=tmp_path) for option in OUTPUTS[command]]
    assert main([command, str(tmp_path / "nope.c3d"), *outputs]) == 2
    assert f"{tmp_path / 'nope.c3d'}: no such file or folder" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.mark.usefixtures("sample_dir")
def test_the_statics_at_hand_count_as_standing(real_c3d):
    from mocaplib.statics import check_standing
    from mocaplib.io.c3d import read_c3d

    rest = SAMPLES / "rest.c3d"
    check_standing(read_c3d(rest))
    for name in ("motonms_unipd/Static1.c3d", "biomechzoo/HC030A01.c3d",
                 "btkdata/PiG_Calibration2-NoOption.c3d"):
        check_standing(read_c3d(real_c3d(name)))


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("inputs, message", [
    (["{w}", "{d}/nope.c3d"], "nope.c3d: no such file or folder"),
    (["{d}/empty"], "no C3D captures (*.c3d) in"),
])
def test_build_inputs_that_are_not_captures_are_usage_errors(inputs, message, tmp_path,
                                                             capsys):
    walk = sample("walk_straight_normal", tmp_path)
    (tmp_path / "empty").mkdir()
    paths = [i.format(w=walk, d=tmp_path) for i in inputs]
    assert main(["build", *paths, "-o", str(tmp_path / "l.json"), "--no-cache", "-q"]) == 2
    assert message in capsys.readouterr().err and not (tmp_path / "l.json").exists()


@pytest.mark.usefixtures("sample_dir")
def test_an_output_where_nothing_can_be_written_stops_fit_before_it_writes(tmp_path, capsys):
    walk = sample("walk_straight_normal", tmp_path)
    (tmp_path / "plain").write_text("a file")
    assert main(["fit", str(walk), "-o", str(tmp_path / "a.csv"), "--mot",
                 str(tmp_path / "plain" / "a.mot")]) == 2
    assert "cannot write into" in capsys.readouterr().err
    assert not (tmp_path / "a.csv").exists()


def test_an_envelope_file_that_is_not_text_is_a_clear_error(tmp_path, library, capsys):
    envelope = tmp_path / "envelope.toml"
    envelope.write_bytes(b"\x80\x81\x82")
    assert main(["report", str(library), "-o", str(tmp_path / "r"), "--envelope",
                 str(envelope), "--no-opengl"]) == 2
    assert f"{envelope}: the envelope file is not UTF-8 text" in capsys.readouterr().err


@pytest.mark.usefixtures("sample_dir")
def test_a_capture_missing_required_landmarks_fails_cycles_and_is_named_by_fit_and_events(
        tmp_path, capsys):
    # fit, events and cycles went through such a capture without a word
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    trial = read_c3d(sample("walk_straight_normal", tmp_path))
    path = write_c3d(tmp_path / "renamed.c3d", trial.markers,
                     ["LSHX" if label == "LSHO" else label for label in trial.labels], trial.rate)
    named = (f"{path}: the capture has no label for required landmark of protocol "
             "'fullbody38': L_ACROMION (expects LSHO)")
    assert main(["cycles", str(path)]) == 1
    captured = capsys.readouterr()
    assert f"mocaplib cycles: error: {named}" in captured.err and not captured.out
    for command in (["fit", str(path), "-o", str(tmp_path / "a.csv")], ["events", str(path)]):
        assert main(command) == 0
        captured = capsys.readouterr()
        assert f"warning: {named}" in captured.err and captured.out
        assert all(remedy in captured.err for remedy in ("rename", "alias", "--protocol"))


@pytest.mark.usefixtures("sample_dir")
def test_events_and_cycles_agree_that_a_few_frames_are_not_rest(tmp_path, capsys):
    # events called 5 frames (0.04 s) "standing still (rest)", cycles and build refused them
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    trial = read_c3d(sample("rest", tmp_path))
    path = write_c3d(tmp_path / "short.c3d", trial.markers[:5], trial.labels, trial.rate)
    message = f"{path}: a capture of 5 frame(s) cannot be a rest entry"
    for command in ("events", "cycles"):
        assert main([command, str(path)]) == 1
        assert message in capsys.readouterr().err, command
    assert main(["events", str(SAMPLES / "rest.c3d")]) == 0
    assert "none: standing still (rest)" in capsys.readouterr().out


def test_the_diagnostics_sidecar_given_for_the_library_is_named_as_such(tmp_path, capsys):
    sidecar = tmp_path / "lib.diagnostics.json"
    sidecar.write_text(json.dumps({"format": "mocaplib-diagnostics", "version": 1,
                                   "library": "lib.json", "captures": []}))
    said = "this is a build's diagnostics sidecar, not a library (give the library beside it, " \
        "lib.json)"
    assert main(["validate", str(sidecar)]) == 1
    assert said in capsys.readouterr().out
    assert main(["query", str(sidecar), "1", "0", "0"]) == 1
    assert said in capsys.readouterr().err


@pytest.mark.usefixtures("sample_dir")
def test_an_upside_down_capture_is_refused_not_fitted_upside_down(tmp_path, capsys):
    # a file whose vertical axis points down (turned 180 deg about X): fitted, every joint
    # turned (angles a median 30 deg off); the calibration sees the pelvis below the feet
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    trial = read_c3d(sample("walk_straight_normal", tmp_path))
    markers = trial.markers * (1.0, -1.0, -1.0)
    path = write_c3d(tmp_path / "down.c3d", markers, trial.labels, trial.rate)
    assert read_c3d(path).vertical_axis == "Z"
    assert main(["fit", str(path), "-o", str(tmp_path / "angles.csv")]) == 1
    err = capsys.readouterr().err
    assert f"{path}: the pelvis markers lie " in err and "vertical axis points down" in err
    assert "Traceback" not in err and not (tmp_path / "angles.csv").exists()
    assert main(["fit", str(SAMPLES / "walk_straight_normal.c3d"),
                 "-o", str(tmp_path / "angles.csv")]) == 0


@pytest.mark.usefixtures("sample_dir")
def test_left_and_right_labels_exchanged_throughout_are_refused(tmp_path, capsys):
    # every L* label named R* and the other way round: a mirrored body was fitted, and the
    # calibration blamed pairs like C7/CLAV; the sides of the left/right pairs tell it
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    trial = read_c3d(sample("walk_straight_normal", tmp_path))
    mirrored = [{"L": "R", "R": "L"}.get(label[0], label[0]) + label[1:] for label in trial.labels]
    assert sorted(mirrored) == sorted(trial.labels) and mirrored != trial.labels
    path = write_c3d(tmp_path / "mirrored.c3d", trial.markers, mirrored, trial.rate)
    assert main(["fit", str(path), "-o", str(tmp_path / "angles.csv")]) == 1
    err = capsys.readouterr().err
    assert f"{path}: " in err and " left markers that have a right one lie on the subject's " \
        "right of it" in err
    assert "left and right labels are exchanged" in err and "Traceback" not in err


@pytest.mark.usefixtures("sample_dir")
def test_a_retarget_rate_that_cannot_be_delivered_is_a_usage_error(tmp_path, library, capsys):
    assert main(["retarget", str(library), "walk_straight_normal_c1", "--height", "1.7",
                 "--rate", "0.001", "-o", str(tmp_path / "a.csv")]) == 2
    assert "fewer than 8 samples over the cycle" in capsys.readouterr().err
    assert not (tmp_path / "a.csv").exists()


@pytest.mark.usefixtures("sample_dir")
def test_a_foot_spacing_the_body_cannot_reach_writes_nothing(tmp_path, library, capsys):
    assert main(["retarget", str(library), "walk_straight_normal_c1", "--height", "1.7",
                 "--foot-spacing", "5", "-o", str(tmp_path / "a.csv")]) == 1
    err = capsys.readouterr().err
    assert "the body cannot follow the request: its ankles stay up to" in err, err
    assert not (tmp_path / "a.csv").exists()
