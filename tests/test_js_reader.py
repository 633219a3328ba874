"""The JavaScript reference reader (js/mocaplib-library.js) against mocaplib on a library
Python writes: the same checksum verdict, the same numbers, the same angles at any phase and
the same blend of a command (entries, weights, period, coefficients)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from mocaplib.library.controlspace import ControlSpace
from mocaplib.library.document import FORMAT_VERSION
from mocaplib.library.format import assemble_library, load_library
from mocaplib.library.validation import validate_library
from mocaplib.library.phase import start_later

from test_library import D, entry

JS = Path(__file__).resolve().parents[1] / "js"
FIXTURES = JS / "test" / "fixtures"
NODE = shutil.which("node")
needs_node = pytest.mark.skipif(NODE is None, reason="node is not installed")
#: Both evaluate the same double-precision formulas; only the order of additions differs.
TOLERANCE = 1e-9


@pytest.fixture(scope="module")
def node_modules():
    """js/node_modules as package-lock.json pins it (npm ci when absent)."""
    if not (JS / "node_modules" / "ajv").is_dir():
        npm = shutil.which("npm")
        assert npm, "npm is needed to install the reader's packages: run `npm ci` in js/"
        subprocess.run([npm, "ci", "--no-audit", "--no-fund"], cwd=JS, check=True,
                       capture_output=True, timeout=300)
    return JS / "node_modules"


def run_reader(*args) -> dict:
    done = subprocess.run([NODE, str(JS / "mocaplib-library.js"), *map(str, args)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def library_with_ramps_and_a_late_start(tmp_path):
    """Five entries with ramps, one of them cut at a right toe-off (``cycle_start``): what
    blending reads from its left toe-off on."""
    ramp = np.linspace(-0.02, 0.03, D)
    ramp[[0, 1, 3]] = 0.0
    entries = [entry(i, ramp=ramp) for i in range(5)]
    entries[2] = start_later(entries[2], 0.4, cycle_start="right_toe_off",
                             left_toe_off_s=1.1 - 0.4)
    path = assemble_library(entries, settings={}).write(tmp_path / "library.json")
    return load_library(path), path


@needs_node
def test_the_js_reader_reads_angles_and_blends_as_mocaplib_does(tmp_path, node_modules):
    library, path = library_with_ramps_and_a_late_start(tmp_path)
    cs = ControlSpace.from_library(library)
    # each tetrahedron's centroid and a point near a vertex, and one command outside
    commands = [cs.points[s].mean(axis=0) for s in cs.tri.simplices]
    commands += [0.9 * cs.points[0] + 0.1 * cs.points.mean(axis=0), np.array([5.0, 0.0, 0.0])]
    phases = 16
    queries = [arg for c in commands for arg in ("--query", *(repr(float(x)) for x in c))]
    report = run_reader(path, "--phases", phases, *queries)
    assert report["checksum"] == "verified"
    for e in library.entries:
        t = e.T * np.arange(phases) / phases
        np.testing.assert_allclose(report["angles"][e.id], library.angles(e.id, t),
                                   rtol=0, atol=TOLERANCE, err_msg=e.id)
    results = cs.query(np.array(commands))
    assert [b["inside"] for b in report["blends"]] == results.inside.tolist()
    assert results.inside.sum() == len(commands) - 1
    python = cs.blend(cs.query(np.array(commands[:-1])))
    for q, got in enumerate(report["blends"][:-1]):
        assert got["entries"] == [cs.ids[k] for k in results.entries[q]]
        np.testing.assert_allclose(got["weights"], results.weights[q], rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(got["T"], python.T[q], rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(got["a"], python.a[q], rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(got["b"], python.b[q], rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(got["drift"], python.drift[q], rtol=0, atol=TOLERANCE)
    # the late-starting entry takes part in a blend, so its shift is compared too
    assert any("capture02_c0" in b["entries"] for b in report["blends"][:-1])


@needs_node
def test_node_reads_every_number_as_python_does(tmp_path, node_modules):
    # JSON.parse in Node, printed back as ECMAScript does (JCS's number text): the same doubles
    _, path = library_with_ramps_and_a_late_start(tmp_path)
    script = ("import { numbers } from './mocaplib-library.js';"
              "import { readFileSync } from 'node:fs';"
              f"console.log(JSON.stringify(numbers(JSON.parse(readFileSync({json.dumps(str(path))},"
              " 'utf8')))));")
    done = subprocess.run([NODE, "--input-type=module", "-e", script], cwd=JS,
                          capture_output=True, text=True, timeout=60, check=True)
    from test_library_checksum import numbers

    python = list(numbers(json.loads(path.read_text())))
    assert json.loads(done.stdout) == python and len(python) > 1000


@needs_node
def test_the_js_reader_refuses_what_mocaplib_refuses(tmp_path, node_modules):
    _, path = library_with_ramps_and_a_late_start(tmp_path)
    document = json.loads(path.read_text())
    document["format_version"] = 6
    path.write_text(json.dumps(document))
    done = subprocess.run([NODE, str(JS / "mocaplib-library.js"), str(path)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and "format_version 6" in done.stderr


def test_the_js_fixture_holds_what_mocaplib_answers_on_it():
    # js/test/reader.test.js compares the reader with queries.json: it must be this mocaplib's
    # answers on library.json, a valid library of this version (js/test/fixtures/make_fixtures.py)
    library = load_library(FIXTURES / "library.json")
    assert library.document["format_version"] == FORMAT_VERSION
    assert validate_library(library) == []
    cs = ControlSpace.from_library(library)
    stored = json.loads((FIXTURES / "queries.json").read_text(encoding="utf-8"))
    for q in stored:
        res = cs.query(q["command"], gait=q["gait_asked"])
        what = f"{q['command']} gait {q['gait_asked']}"
        assert (bool(res.inside[0]), res.gait[0], bool(res.clamped[0])) == (
            q["inside"], q["gait"], q["clamped"]), what
        np.testing.assert_allclose(res.nearest[0], q["nearest"], rtol=0, atol=1e-12,
                                   err_msg=what)
        if q["inside"]:
            assert [cs.ids[k] for k in res.entries[0]] == q["entries"], what
            np.testing.assert_allclose(res.weights[0], q["weights"], rtol=0, atol=1e-12,
                                       err_msg=what)
    assert {q["gait"] for q in stored if q["inside"]} == {"walk", "run"}
