"""The command line as a whole: usage errors (exit 2, the sub-command's own usage), output on
a console that is not UTF-8, and the usage checks of ``inspect`` and ``query``."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from conftest import REPO, SAMPLES
from mocaplib.cli import main
from test_controlspace import CUBE, hand_library


@pytest.fixture
def cube_library(tmp_path):
    path = tmp_path / "lib.json"
    hand_library(CUBE * [1.5, 1.0, 0.5]).write(path)
    return path


def run(*argv, encoding: str) -> subprocess.CompletedProcess:
    """``python -m mocaplib ARGV`` with stdout and stderr encoded as ``encoding``."""
    env = {**os.environ, "PYTHONIOENCODING": encoding, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "mocaplib", *map(str, argv)], env=env,
                          capture_output=True, timeout=120)


@pytest.mark.parametrize("encoding", ["ascii", "cp1252"])
def test_a_console_that_is_not_utf8_gets_replacement_characters_not_a_traceback(
        cube_library, encoding):
    answer = run("query", cube_library, 0.7, 0.4, 0.2, encoding=encoding)
    assert answer.returncode == 0 and b"Traceback" not in answer.stderr
    assert answer.stderr == b""
    degrees = "°".encode(encoding, errors="replace")   # '?' in ASCII, 0xb0 in cp1252
    assert b"0.400 rad/s = 22.9" + degrees + b"/s" in answer.stdout
    helped = run("query", "--help", encoding=encoding)  # v̂, ω̂: not in either code page
    assert helped.returncode == 0 and b"tangential speed v?" in helped.stdout


@pytest.mark.usefixtures("sample_dir")
def test_extra_arguments_show_the_sub_command_usage(capsys):
    walk = SAMPLES / "walk_straight_normal.c3d"
    assert main(["events", str(walk), str(walk)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("usage: mocaplib events ")
    assert f"mocaplib events: error: unrecognized arguments: {walk}" in error


@pytest.mark.usefixtures("sample_dir")
def test_inspect_a_path_that_does_not_exist_is_a_usage_error(tmp_path, capsys):
    walk = SAMPLES / "walk_straight_normal.c3d"
    assert main(["inspect", str(walk), str(tmp_path / "missing.c3d")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and f"{tmp_path / 'missing.c3d'}: no such file or folder" in err
    (tmp_path / "empty").mkdir()
    assert main(["inspect", str(tmp_path / "empty")]) == 1
    assert "no *.c3d files in this folder or its subfolders (give C3D files" in \
        capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["{missing}", "1", "0", "0"], "missing.json: no such file or folder (check the path; "
                                   "`mocaplib build` writes a library)"),
    (["{lib}", "1", "0", "0", "--cycles", "2"], "--cycles only apply to the animation outputs"),
    (["{lib}", "1", "0", "0", "--cycles", "2", "--rate", "50"], "--cycles and --rate only"),
    (["{lib}", "1", "0", "0", "--bvh", "{d}/a.bvh", "--rate", "0.01"],
     "argument --rate: must be >= 10 Hz"),
])
def test_query_usage_errors(args, message, cube_library, tmp_path, capsys):
    names = {"lib": cube_library, "d": tmp_path, "missing": tmp_path / "missing.json"}
    assert main(["query", *(a.format(**names) for a in args)]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "a.bvh").exists()


@pytest.mark.parametrize("omega", ["-5e-05", "-5E-5", "-.00005", "-0.00005e0"])
def test_a_negative_number_in_exponent_form_is_a_value(omega, cube_library, capsys):
    # as Python prints small numbers; argparse alone reads "-5e-05" as an unknown option
    assert main(["query", str(cube_library), "0.7", omega, "0.2", "--json"]) == 0
    answer = json.loads(capsys.readouterr().out)
    assert answer["point"][1] == -5e-05, answer["point"]
    assert main(["query", str(cube_library), "0.7", "-5x", "0.2"]) == 2
    assert "the following arguments are required: VL" in capsys.readouterr().err  # not a number


def test_c3d_errors_say_what_to_give_instead(tmp_path, capsys):
    notes = tmp_path / "notes.c3d"
    notes.write_text("session notes, not a capture\n" * 40)
    assert main(["inspect", str(notes)]) == 1
    assert "not a C3D file: byte 2 is 0x65, a C3D file has 0x50 (give the trial exported as " \
        "C3D by the capture software)" in capsys.readouterr().err
    assert main(["fit", str(tmp_path), "-o", str(tmp_path / "a.csv")]) == 1
    assert "is a folder, not a C3D file (give a .c3d file; build and inspect also search " \
        "folders)" in capsys.readouterr().err


@pytest.mark.parametrize("args", [
    ["validate", "{missing}"], ["report", "{missing}", "-o", "{d}/reports"],
    ["query", "{missing}", "1", "0", "0"], ["inspect", "{missing}"],
    ["synth", "{missing}", "-o", "{d}/out"],
])
def test_a_path_that_does_not_exist_is_a_usage_error_in_every_command(args, tmp_path, capsys):
    missing = tmp_path / "missing.json"
    assert main([a.format(missing=missing, d=tmp_path) for a in args]) == 2
    out, err = capsys.readouterr()
    assert f"{missing}: no such file or folder (check the path" in err and out == ""
    assert list(tmp_path.iterdir()) == []
