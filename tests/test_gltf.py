"""glTF 2.0 export, read back with pygltflib (a reader mocaplib does not use to write): the
structure follows the spec's rules, and joint positions rebuilt from the node hierarchy and
the animation equal Skeleton.forward's at every keyframe."""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pytest

from conftest import REPO
from fk_data import neutral_q
from mocaplib.cli import main
from mocaplib.errors import MocapError
from mocaplib.export.gltf import write_glb, write_gltf
from mocaplib.library.controlspace import ControlSpace
from mocaplib.library.planting import plant_blend
from mocaplib.library.retarget import retarget
from mocaplib.model.motion import Motion
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton

pytest.importorskip("pygltflib")
from gltf_reader import COMPONENTS, animated_positions, read_gltf  # noqa: E402

#: Joint positions must agree within 0.1 mm: float32 keys give ~1e-7 relative (well below 1 µm
#: over a few metres of travel).
TOLERANCE_M = 1e-4


def check_structure(path):
    """The spec's rules that matter to a reader: buffer length, views and accessors inside it
    and 4-byte aligned, min/max equal to the data, unit quaternions, LINEAR samplers whose
    inputs rise; the skin's inverse bind matrices invert the rest pose."""
    gltf, blob, accessor = read_gltf(path)
    assert gltf.asset.version == "2.0"
    assert gltf.buffers[0].byteLength <= len(blob) < gltf.buffers[0].byteLength + 4
    for i, acc in enumerate(gltf.accessors):
        view = gltf.bufferViews[acc.bufferView]
        assert view.byteOffset % 4 == 0
        assert view.byteLength == acc.count * COMPONENTS[acc.type] * 4
        assert view.byteOffset + view.byteLength <= gltf.buffers[0].byteLength
        data = accessor(i)
        np.testing.assert_array_equal(acc.min, data.min(axis=0))
        np.testing.assert_array_equal(acc.max, data.max(axis=0))
    animation = gltf.animations[0]
    for sampler in animation.samplers:
        assert sampler.interpolation == "LINEAR"
        assert np.all(np.diff(accessor(sampler.input)[:, 0]) > 0)
    for channel in animation.channels:
        if channel.target.path == "rotation":
            keys = accessor(animation.samplers[channel.sampler].output)
            norms = np.linalg.norm(keys, axis=1)
            np.testing.assert_allclose(norms, 1.0, atol=1e-6)   # float32 unit quaternions
            assert np.all(np.sum(keys[1:] * keys[:-1], axis=1) >= 0)   # along the shorter arc
    rotations = {c.target.node for c in animation.channels if c.target.path == "rotation"}
    assert rotations == {i for i, node in enumerate(gltf.nodes) if node.name in SEGMENT_NAMES}
    skin = gltf.skins[0]
    rest = np.zeros((len(gltf.nodes), 3))
    stack = [(skin.skeleton, np.zeros(3))]
    while stack:
        node, parent = stack.pop()
        rest[node] = parent + gltf.nodes[node].translation
        stack += [(c, rest[node]) for c in gltf.nodes[node].children]
    bind = accessor(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)  # columns
    np.testing.assert_allclose(bind[:, :3, 3], -rest[skin.joints], atol=1e-6)
    return gltf


def _joints(positions: np.ndarray, names: list[str]) -> np.ndarray:
    return positions[:, [names.index(name) for name in SEGMENT_NAMES]]


@pytest.mark.parametrize("writer, name", [(write_gltf, "walk.gltf"), (write_glb, "walk.glb")])
def test_random_poses_joint_positions_equal_forward_kinematics(tmp_path, writer, name):
    sk = Skeleton.from_height(1.75)
    rng = np.random.default_rng(5)
    lo, hi = sk.bounds()
    q = rng.uniform(np.maximum(lo, -np.pi), np.minimum(hi, np.pi), size=(9, len(DOF_NAMES)))
    q[:, :3] = rng.uniform(-3, 3, size=(9, 3))            # root translation, metres
    path = writer(Motion(q, sk, 30.0), tmp_path / name)
    check_structure(path)
    times, positions, names = animated_positions(path)
    np.testing.assert_array_equal(times, (np.arange(9) / 30.0).astype(np.float32))
    np.testing.assert_allclose(_joints(positions, names), sk.forward(q)[:, :, :3, 3],
                               atol=TOLERANCE_M)


def test_the_subject_stands_y_up_facing_z():
    sk = Skeleton.from_height(1.75)
    from mocaplib.export.gltf import gltf_document

    document, _ = gltf_document(Motion(neutral_q(sk, 1), sk, 100.0))
    names = [node["name"] for node in document["nodes"]]
    # file +X is the subject's left, +Y up, +Z forward: the left hip lies along +X
    np.testing.assert_allclose(document["nodes"][names.index("femur_l")]["translation"],
                               [sk.lengths["hip_width"] / 2, 0.0, 0.0])
    assert document["nodes"][names.index("head_end")]["translation"][1] > 0.2     # up
    assert document["nodes"][names.index("foot_l_end")]["translation"][2] > 0.1   # toes ahead


def test_nan_is_refused(tmp_path):
    sk = Skeleton.from_height(1.75)
    q = neutral_q(sk, 3)
    q[1, 4] = np.nan
    with pytest.raises(MocapError, match="finite"):
        write_gltf(Motion(q, sk, 100.0, source="walk.c3d"), tmp_path / "walk.gltf")
    assert not (tmp_path / "walk.gltf").exists()


# ------------------------------------------------------------------ the library's motions
@pytest.fixture(scope="module")
def walks(tmp_path_factory):
    from walking_library import synthetic_walks

    library = synthetic_walks()[0]
    path = tmp_path_factory.mktemp("lib") / "walks.json"
    library.write(path)
    return library, path


@pytest.mark.parametrize("name", ["blend.gltf", "blend.glb"])
def test_a_blended_query_as_gltf(walks, tmp_path, capsys, name):
    library, path = walks
    command = library.table[["v", "omega", "v_l"]].mean().to_numpy()   # inside: a centroid
    out = tmp_path / name
    assert main(["query", str(path), *map(str, command), "--gltf", str(out), "--rate", "60",
                 "--cycles", "2", "--json"]) == 0
    answer = json.loads(capsys.readouterr().out)
    assert answer["gltf"] == str(out) and answer["inside"]
    check_structure(out)
    times, positions, names = animated_positions(out)
    space = ControlSpace.from_library(library)
    # the blend's world motion with its feet planted, as the command writes every animation,
    # in whole frames
    q = plant_blend(space.blend(space.query([command])).looped(60.0), library.skeleton,
                    rate=60.0, cycles=2).q
    # keys at exactly k / 60 s, two periods of whole frames long, the first pose not repeated
    # at the end
    assert len(times) == len(q) == 2 * round(answer["T_s"] * 60)
    assert answer["played_T_s"] == pytest.approx(round(answer["T_s"] * 60) / 60)
    np.testing.assert_array_equal(times, (np.arange(len(q)) / 60.0).astype(np.float32))
    assert times[-1] < 2 * answer["played_T_s"]
    np.testing.assert_allclose(_joints(positions, names),
                               library.skeleton.forward(q)[:, :, :3, 3], atol=TOLERANCE_M)


def _animate(path, folder, *outputs: str) -> None:
    """``mocaplib animate`` of the library at ``path`` along a walk and a turn, into
    ``outputs`` (``--bvh NAME``, ``--gltf NAME``... in ``folder``)."""
    route = folder / "route.csv"
    route.write_text("x,y\n0,0\n3,0\n5,1.5\n", encoding="utf-8")
    options = [x if x.startswith("--") else str(folder / x) for x in outputs]
    assert main(["animate", str(path), "--path", str(route), "--speed", "1.2", "--rate", "50",
                 *options]) == 0


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("name", ["path.gltf", "path.glb"])
def test_a_followed_path_as_gltf_poses_what_its_bvh_poses(tmp_path, name):
    from bvh_reader import Character
    from test_planting import sample_library

    _animate(sample_library()[1], tmp_path, "--bvh", "path.bvh", "--gltf", name)
    check_structure(tmp_path / name)
    times, positions, names = animated_positions(tmp_path / name)
    bvh = Character((tmp_path / "path.bvh").read_text())     # an independent BVH reader
    assert len(times) == bvh.frames > 200
    np.testing.assert_array_equal(times, (np.arange(bvh.frames) / 50.0).astype(np.float32))
    for segment in SEGMENT_NAMES:
        np.testing.assert_allclose(positions[:, names.index(segment)], bvh.position(segment),
                                   atol=TOLERANCE_M, err_msg=segment)


#: The Khronos Group's glTF-Validator (npm ``gltf-validator``, a devDependency of js/).
KHRONOS_VALIDATOR = REPO / "js" / "node_modules" / "gltf-validator"
_VALIDATE = ("const v = require(process.argv[1]); const fs = require('fs');"
             "Promise.all(process.argv.slice(2).map((f) => v.validateBytes("
             "new Uint8Array(fs.readFileSync(f)), {maxIssues: 100}))).then((r) => "
             "process.stdout.write(JSON.stringify(r.map((x) => x.issues))));")


@pytest.mark.skipif(shutil.which("node") is None or not KHRONOS_VALIDATOR.is_dir(),
                    reason="node or js/node_modules/gltf-validator (cd js && npm ci) missing")
def test_the_khronos_validator_finds_no_error_nor_warning(walks, tmp_path, capsys):
    # the validator game engines' and DCC tools' glTF pipelines check files with: random poses,
    # a blended query and a retargeted cycle, as .gltf and .glb
    library, path = walks
    sk = Skeleton.from_height(1.75)
    q = np.random.default_rng(5).uniform(-1.0, 1.0, size=(9, len(DOF_NAMES)))
    files = [writer(Motion(q, sk, 30.0), tmp_path / name)
             for writer, name in ((write_gltf, "poses.gltf"), (write_glb, "poses.glb"))]
    command = library.table[["v", "omega", "v_l"]].mean().to_numpy()
    for name in ("blend.gltf", "blend.glb"):
        assert main(["query", str(path), *map(str, command), "--gltf",
                     str(tmp_path / name)]) == 0
        files.append(tmp_path / name)
    entry = next(e for e in library.table.index if e.startswith("walk_straight_normal_"))
    files.append(retarget(library, entry, skeleton=Skeleton.from_height(1.9), rate=50.0)
                 .write(tmp_path / "tall.glb"))

    done = subprocess.run(["node", "-e", _VALIDATE, str(KHRONOS_VALIDATOR), *map(str, files)],
                          capture_output=True, text=True, timeout=120, check=True)
    for file, issues in zip(files, json.loads(done.stdout)):
        assert issues["numErrors"] == issues["numWarnings"] == 0, (file.name, issues)
        # its one note: the skin no mesh binds (the skeleton and its animation, no body)
        assert [(m["code"], m["pointer"]) for m in issues["messages"]] == [
            ("UNUSED_OBJECT", "/skins/0")], (file.name, issues["messages"])


def test_a_retargeted_cycle_as_gltf_loops_without_its_closing_frame(walks, tmp_path):
    library, path = walks
    entry = next(e for e in library.table.index if e.startswith("walk_straight_normal_"))
    result = retarget(library, entry, skeleton=Skeleton.from_height(1.6), rate=50.0)
    out = result.write(tmp_path / "short.glb")
    check_structure(out)
    times, positions, names = animated_positions(out)
    n = len(result.q) - 1                     # the cycle's samples, both ends included
    assert len(times) == n
    np.testing.assert_array_equal(times, (np.arange(n) / result.rate).astype(np.float32))
    np.testing.assert_allclose(result.time_s[-1], n / result.rate)   # the loop closes at T
    np.testing.assert_allclose(_joints(positions, names),
                               result.skeleton.forward(result.q[:-1])[:, :, :3, 3],
                               atol=TOLERANCE_M)
