"""The report's motion viewer in JavaScript (node) against mocaplib's Python: forward
kinematics, the Fourier formula, the root drift, point location and blending."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, TRANSLATION, Skeleton

NODE = shutil.which("node")
MOTION_JS = Path(__file__).parents[1] / "mocaplib" / "report" / "templates" / "motion.js"
pytestmark = pytest.mark.skipif(NODE is None, reason="node is not installed")


def _node(calls: list[tuple[str, list]]) -> list:
    """Results of MocapMotion.<name>(*args) for each call, run by node on motion.js."""
    script = ("const M = require(process.argv[1]);"
              "const calls = JSON.parse(require('fs').readFileSync(0, 'utf8'));"
              "process.stdout.write(JSON.stringify(calls.map(([f, args]) => M[f](...args))));")
    done = subprocess.run([NODE, "-e", script, str(MOTION_JS)], input=json.dumps(calls),
                          capture_output=True, text=True, timeout=60, check=True)
    return json.loads(done.stdout)


def test_forward_kinematics_in_javascript_is_mocaplibs():
    """Segment transforms of random poses (root anywhere, every joint over its range) from
    the page's skeleton description, to 1e-9 m and 1e-12 in the rotations (round-off of ~8
    products of rotations in either language)."""
    from mocaplib.report.figureview import skeleton_data

    # a calibrated subject's joint shifts (ankle centres off the knee's plane) included
    skeleton = Skeleton(Skeleton.from_height(1.63).lengths,
                        {"foot_l": (0.0, 0.03, -0.004), "foot_r": (0.002, -0.02, 0.0)})
    lo, hi = skeleton.bounds()
    lo, hi = np.where(np.isfinite(lo), lo, -3.0), np.where(np.isfinite(hi), hi, 3.0)
    lo[TRANSLATION], hi[TRANSLATION] = -5.0, 5.0
    q = np.random.default_rng(16).uniform(lo, hi, (20, len(DOF_NAMES)))
    description = skeleton_data(skeleton)
    js = np.array(_node([("forward", [description, pose]) for pose in q.tolist()]))
    expected = skeleton.forward(q)
    js = js.reshape(expected.shape)
    np.testing.assert_allclose(js[..., :3, 3], expected[..., :3, 3], atol=1e-9)
    np.testing.assert_allclose(js[..., :3, :3], expected[..., :3, :3], atol=1e-12)
    assert [s["name"] for s in description["segments"]] == list(SEGMENT_NAMES)


def test_the_series_and_the_drift_in_javascript_are_mocaplibs():
    from mocaplib.gait.fourier import RootDrift, synthesize

    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(2, 5, 7))
    b[:, 0] = 0
    t = [0.0, 0.31, 1.07, 2.5]
    js = _node([("synthesize", [a.tolist(), b.tolist(), 1.13, x]) for x in t]
               + [("frame", [[1.1, -0.2, w], 1.7]) for w in (0.0, 1e-10, 0.8, -1.3)])
    np.testing.assert_allclose(js[:4], synthesize(a, b, 1.13, t), atol=1e-12)
    for w, got in zip((0.0, 1e-10, 0.8, -1.3), js[4:]):
        expected = RootDrift(0, 0, 0, 1.1, -0.2, w).frame(1.7)
        np.testing.assert_allclose(got, [float(x) for x in expected], atol=1e-12)


def test_blending_in_javascript_is_the_control_spaces():
    """The tetrahedron and weights found in the stored triangulation, and the blended
    coefficients, period and drift, for points inside and outside the hull (on the frontal
    axes, where query weighs a point where it locates it)."""
    from mocaplib.library.controlspace import ControlSpace

    rng = np.random.default_rng(7)
    points = rng.uniform([0.0, -1.5, -0.5], [1.8, 1.5, 0.5], (25, 3))
    n = rng.integers(1, 6, 25)
    a = [rng.normal(size=(4, k + 1)) for k in n]
    b = [np.column_stack([np.zeros(4), rng.normal(size=(4, k))]) for k in n]
    cs = ControlSpace(points, a=a, b=b, T=rng.uniform(0.8, 1.3, 25),
                      drift=rng.normal(size=(25, 3)), axes="frontal")
    queries = np.vstack([rng.uniform([0.2, -1.0, -0.3], [1.5, 1.0, 0.3], (30, 3)),
                         [[5.0, 0.0, 0.0]]])
    space = {"points": cs.normalise(cs.points).tolist(), "simplices": cs.tri.simplices.tolist()}
    found = _node([("locate", [space, x]) for x in cs.normalise(queries).tolist()])
    result = cs.query(queries)
    for k, got in enumerate(found):
        if not result.inside[k]:
            assert got["simplex"] == -1
            continue
        corners = cs.tri.simplices[got["simplex"]]
        np.testing.assert_array_equal(corners, result.entries[k])
        np.testing.assert_allclose(got["weights"], result.weights[k], atol=1e-12)
        entries = [{"a": a[i].tolist(), "b": b[i].tolist(), "T": float(cs.T[i]),
                    "drift": cs.drift[i].tolist()} for i in corners]
        mixed = _node([("blend", [entries, got["weights"]])])[0]
        expected = cs.blend(cs.query(queries[k:k + 1]))
        np.testing.assert_allclose(mixed["a"], expected.a[0][:, :len(mixed["a"][0])],
                                   atol=1e-12)
        np.testing.assert_allclose(mixed["T"], expected.T[0], atol=1e-12)
        np.testing.assert_allclose(mixed["drift"], expected.drift[0], atol=1e-12)


def test_the_viewers_pick_is_located_in_the_gait_cells_as_query_locates_it():
    """The report's clicked blend on the JavaScript reader's fixture (walks, side-steps on the
    cone and off it, runs): a command in a cell gets query's gait, entries and weights
    (weighed on the frontal axes); one between the walks and the runs (clamped by query) or
    outside is in no cell."""
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.format import load_library
    from mocaplib.report.figureview import viewer_data

    fixtures = Path(__file__).parents[1] / "js" / "test" / "fixtures"
    library = load_library(fixtures / "library.json")
    cs = ControlSpace.from_library(library)
    space = viewer_data(library, cs, ["walk"] * len(library.entries), {})["space"]
    asked = [q for q in json.loads((fixtures / "queries.json").read_text())
             if q["gait_asked"] is None]
    commands = [q["command"] for q in asked]
    found = _node([("weigh", [space, c]) for c in commands])
    result = cs.query(commands)
    ids = [library.entries[i].id for i in space["entries"]]
    kinds, elsewhere = set(), 0
    for k, got in enumerate(found):
        if not result.inside[k] or result.clamped[k]:
            assert got["simplex"] == -1, commands[k]
            kinds.add("clamped" if result.clamped[k] else "outside")
            continue
        kinds.add(result.gait[k])
        elsewhere += set(got["corners"]) != set(space["simplices"][got["simplex"]])
        assert space["gaits"][got["simplex"]] == result.gait[k]
        mine = dict(zip([ids[i] for i in got["corners"]], got["weights"]))
        theirs = dict(zip([cs.ids[i] for i in result.entries[k]], result.weights[k]))
        for entry in set(mine) | set(theirs):    # a tie on a shared face is the same blend
            assert abs(max(mine.get(entry, 0.0), 0.0) - theirs.get(entry, 0.0)) < 1e-9
    assert kinds == {"walk", "run", "clamped", "outside"}
    assert elsewhere >= 10, elsewhere    # weighed in another tetrahedron than located in
