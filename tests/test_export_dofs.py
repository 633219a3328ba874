"""Every export takes its columns and channels from the skeleton's DOF list
(:data:`mocaplib.skeleton.DOFS`): each DOF is one column of the tables, one coordinate of
the .osim, one channel of the BVH and moves its segment's rotation in the glTF; and a DOF added
to the skeleton reaches every file without a change to the writers."""

from __future__ import annotations

import subprocess
import sys
from xml.etree import ElementTree as ET

import numpy as np
from conftest import REPO
from fk_data import fk_trial, true_model
from bvh_reader import parse_bvh

from mocaplib.export.formats import write
from mocaplib.model.motion import Motion
from mocaplib.skeleton import DOF_NAMES, DOFS, SEGMENT_NAMES, SEGMENTS, TRANSLATION, Skeleton


def _mot_header(path) -> list[str]:
    lines = path.read_text().splitlines()
    return lines[lines.index("endheader") + 1].split("\t")


def _osim_coordinates(path) -> list[str]:
    return [c.get("name") for c in ET.parse(path).iter("Coordinate")]


def test_tables_and_the_osim_list_the_dofs_in_order(tmp_path):
    cap = fk_trial(n_frames=3)
    motion = Motion(cap.q, cap.skeleton, 100.0)
    csv = write(motion, tmp_path / "a.csv").read_text().splitlines()[0].split(",")
    assert csv == ["time_s", *DOF_NAMES]
    assert _mot_header(write(motion, tmp_path / "a.mot")) == ["time", *DOF_NAMES]
    assert _osim_coordinates(write(true_model(cap), tmp_path / "m.osim")) == list(DOF_NAMES)


def test_each_dof_drives_one_bvh_channel_and_its_segment_in_the_gltf(tmp_path):
    from gltf_reader import animated_positions

    sk = Skeleton.from_height(1.75)
    rest = np.zeros((1, len(DOF_NAMES)))
    joints, _, base = parse_bvh(write(Motion(rest, sk, 100.0), tmp_path / "rest.bvh")
                                .read_text())
    names = [j["name"] for j in joints if j["name"] is not None]
    owners = [name for name in names for _ in range(len(
        next(j for j in joints if j["name"] == name)["channels"]))]
    moved_bvh = []
    for j, dof in enumerate(DOFS):
        q = rest.copy()
        q[0, j] = 0.3
        _, _, values = parse_bvh(write(Motion(q, sk, 100.0), tmp_path / "one.bvh").read_text())
        changed = np.flatnonzero(np.abs(values[0] - base[0]) > 1e-9)
        assert len(changed) == 1, dof.name                     # one channel per DOF
        assert owners[changed[0]] == dof.segment, dof.name     # of the DOF's own joint
        moved_bvh.append(int(changed[0]))
    assert len(set(moved_bvh)) == len(DOFS)                    # no two DOFs share a channel
    # glTF: every segment and end site lands where the forward kinematics puts it when each
    # DOF alone moves (a DOF missing from the rotations would leave its segment's children
    # behind; the toes and finger tips show the last joints' DOFs)
    q = np.repeat(rest, len(DOFS), axis=0)
    q[np.arange(len(DOFS)), np.arange(len(DOFS))] = 0.3
    _, positions, node_names = animated_positions(write(Motion(q, sk, 100.0),
                                                        tmp_path / "each.gltf"))
    expected = sk.forward(q)[:, :, :3, 3]
    np.testing.assert_allclose(positions[:, [node_names.index(n) for n in SEGMENT_NAMES]],
                               expected, atol=1e-4)
    from mocaplib.export.bvh import end_sites

    for segment, tip in end_sites(sk).items():
        s = SEGMENT_NAMES.index(segment)
        ours = sk.points(q, np.array([s]), np.array([tip]))[:, 0]
        np.testing.assert_allclose(positions[:, node_names.index(f"{segment}_end")], ours,
                                   atol=1e-4)


#: Run in a fresh process: the skeleton module with one more DOF on each foot (``toe_out``, about
#: the foot's vertical axis), then every format written and read back.
_EXTRA_DOF = r'''
import importlib.util, sys
import numpy as np

spec = importlib.util.find_spec("mocaplib.skeleton")
source = spec.loader.get_source("mocaplib.skeleton")
old = """            _rot(f"ankle_inversion_{side}", f"foot_{side}", s * X, -35, 40),
        ])"""
assert old in source
source = source.replace(old, """            _rot(f"ankle_inversion_{side}", f"foot_{side}", s * X, -35, 40),
            _rot(f"toe_out_{side}", f"foot_{side}", s * Z, -30, 30),
        ])""")
module = importlib.util.module_from_spec(spec)
sys.modules["mocaplib.skeleton"] = module
exec(compile(source, spec.origin, "exec"), module.__dict__)

from pathlib import Path
from xml.etree import ElementTree as ET
from mocaplib.export.formats import write
from mocaplib.model.motion import Motion
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton
from gltf_reader import animated_positions
from bvh_reader import parse_bvh

out = Path(sys.argv[1])
assert len(DOF_NAMES) == 34 and "toe_out_r" in DOF_NAMES
sk = Skeleton.from_height(1.75)
q = np.zeros((3, len(DOF_NAMES)))
q[:, DOF_NAMES.index("toe_out_r")] = [0.0, 0.2, 0.4]
motion = Motion(q, sk, 100.0)
assert write(motion, out / "a.csv").read_text().split("\n")[0].split(",")[1:] == list(DOF_NAMES)
lines = write(motion, out / "a.mot").read_text().splitlines()
assert lines[lines.index("endheader") + 1].split("\t")[1:] == list(DOF_NAMES)
joints, _, values = parse_bvh(write(motion, out / "a.bvh").read_text())
assert np.count_nonzero(np.abs(values[2] - values[0]) > 1e-9) == 1     # the new channel
_, positions, names = animated_positions(write(motion, out / "a.glb"))
foot = SEGMENT_NAMES.index("foot_r")
from mocaplib.export.bvh import end_sites
toe = sk.points(q, np.array([foot]), np.array([end_sites(sk)["foot_r"]]))[:, 0]
np.testing.assert_allclose(positions[:, names.index("foot_r_end")], toe, atol=1e-4)
assert np.ptp(toe[:, 1]) > 0.01                                         # the toes turned out
from mocaplib.markersets.protocols import load_protocol
from mocaplib.model.subject import SubjectModel
protocol = load_protocol("fullbody38")
model = SubjectModel(sk, protocol, protocol.labels[:1], np.array([0]), np.zeros((1, 3)))
coordinates = [c.get("name") for c in ET.parse(write(model, out / "m.osim")).iter("Coordinate")]
assert coordinates == list(DOF_NAMES), coordinates
print("ok")
'''


def test_a_dof_added_to_the_skeleton_reaches_every_export(tmp_path):
    done = subprocess.run([sys.executable, "-c", _EXTRA_DOF, str(tmp_path)], cwd=REPO / "tests",
                          capture_output=True, text=True,
                          env={"PYTHONPATH": f"{REPO}:{REPO / 'tests'}", "PATH": ""})
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr[-3000:]


def test_the_dof_list_is_what_the_writers_read():
    # every DOF belongs to one segment's joint, in SEGMENTS order: the order of the columns
    assert [d for seg in SEGMENTS for d in seg.dofs] == list(DOF_NAMES)
    assert list(np.flatnonzero(TRANSLATION)) == [j for j, d in enumerate(DOFS) if d.translation]
    for path in (REPO / "mocaplib" / "export").glob("*.py"):
        text = path.read_text()
        assert not [name for name in DOF_NAMES if name in text], path   # no DOF name literals
