"""Mirror images: the DOF map derived from the skeleton, mirrored motions, entries, libraries."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mocaplib.library.cells import cell_tetrahedra, frontal_tetrahedra
from mocaplib.library.controlspace import ControlSpace
from mocaplib.library.format import assemble_library
from mocaplib.library.mirror import (REFLECTION, mirror_dofs, mirror_id, mirror_library,
                                     MIRROR_INDEX, MIRROR_SIGN)
from mocaplib.library.validation import validate_library
from mocaplib.skeleton import partner_name
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, TRANSLATION, Skeleton

from test_library import entry as library_entry


def test_mirrored_poses_put_every_segment_at_the_mirror_image_of_its_partner():
    """Forward kinematics of the mirrored pose = reflection of the pose, segments exchanged:
    position M p, orientation M R M (each segment frame's image under y -> -y). Random poses
    over the joints' ranges, root anywhere; round-off only (products of ~6 rotations)."""
    skeleton = Skeleton.from_height(1.71)
    lo, hi = skeleton.bounds()
    lo, hi = np.where(np.isfinite(lo), lo, -3.0), np.where(np.isfinite(hi), hi, 3.0)
    lo[TRANSLATION], hi[TRANSLATION] = -2.0, 2.0
    q = np.random.default_rng(23).uniform(lo, hi, (50, len(DOF_NAMES)))
    T, T_mirror = skeleton.forward(q), skeleton.forward(mirror_dofs(q))
    for s, name in enumerate(SEGMENT_NAMES):
        image = T_mirror[:, SEGMENT_NAMES.index(partner_name(name))]
        np.testing.assert_allclose(image[:, :3, 3], T[:, s, :3, 3] @ REFLECTION, atol=1e-12,
                                   err_msg=name)
        np.testing.assert_allclose(image[:, :3, :3], REFLECTION @ T[:, s, :3, :3] @ REFLECTION,
                                   atol=1e-12, err_msg=name)


def test_the_dof_map_follows_the_skeleton_conventions():
    """What the derivation gives for the current skeleton, as its docstring's sign table
    reads: sided DOFs exchange sides with their sign (flexion stays flexion, adduction
    adduction), the root's lateral translation, heading and list and the trunk's and neck's
    bending and rotation change sign, everything sagittal keeps it."""
    mirrored = {name: (DOF_NAMES[i], int(s)) for name, i, s in
                zip(DOF_NAMES, MIRROR_INDEX, MIRROR_SIGN)}
    assert mirrored["hip_adduction_l"] == ("hip_adduction_r", 1)
    assert mirrored["shoulder_rotation_r"] == ("shoulder_rotation_l", 1)
    flipped = {name for name, (_, sign) in mirrored.items() if sign < 0}
    assert flipped == {"pelvis_ty", "pelvis_rotation", "pelvis_list", "trunk_bending",
                       "trunk_rotation", "neck_bending", "neck_rotation"}
    assert all(partner == partner_name(name) for name, (partner, _) in mirrored.items())


def test_mirroring_twice_is_the_identity():
    q = np.random.default_rng(1).normal(size=(7, len(DOF_NAMES)))
    np.testing.assert_array_equal(mirror_dofs(mirror_dofs(q)), q)
    a = np.random.default_rng(2).normal(size=(len(DOF_NAMES), 5))
    np.testing.assert_array_equal(mirror_dofs(mirror_dofs(a, axis=0), axis=0), a)


@pytest.mark.parametrize("entry_id, mirrored", [
    ("walk_curve_r2_left_normal_c0", "walk_curve_r2_left_normal_mirror_c0"),
    ("HC030A22_c3@0123abcd", "HC030A22_mirror_c3@0123abcd"),
    ("walk_01#0", "walk_01#0_mirror"),
])
def test_mirror_ids(entry_id, mirrored):
    assert mirror_id(entry_id) == mirrored
    assert mirror_id(mirrored) == entry_id


# --------------------------------------------------------------------------- entries
def _entry(seed: int = 3, n: int = 6):
    """A library entry with gait-sized random coefficients, a turning drift and a right
    toe-off (its numbers as a build writes them: 10 significant digits)."""
    from entries import plain_entry
    from mocaplib.library.entry import LibraryEntry
    from mocaplib.library.format import to_json_data

    rng = np.random.default_rng(seed)
    a, b = rng.normal(0, 0.1, (2, len(DOF_NAMES), n + 1))
    b[:, 0] = 0.0
    return LibraryEntry.from_json(to_json_data(plain_entry(
        id="walk_curve_r2_left_normal_c1", source_file="walk_curve_r2_left_normal.c3d",
        source_sha256="0" * 64, cycle_index=1, start_s=1.43, end_s=2.6, T=1.17,
        pattern={"type": "arc", "parameters": {"centre": [0.3, 2.1], "radius": 2.0,
                                                "turn": 1.0, "length": 1.17},
                 "residual_m": 0.002, "arc_angle_rad": 0.58},
        v=1.0, omega=0.5, v_l=-0.006, v_f=1.0, a=a, b=b,
        root_drift={"u_f_m_s": 0.98, "u_l_m_s": 0.05, "omega_rad_s": 0.49},
        qc={"marker_rms_m": 0.004}, locomotion_class="nonholonomic",
        right_toe_off_s=0.587).to_json()))


def _numbers(x, y, path=""):
    """(|x - y|, where) over every number of two JSON values of the same shape."""
    if isinstance(x, dict):
        assert sorted(x) == sorted(y), path
        for key in x:
            yield from _numbers(x[key], y[key], f"{path}.{key}")
    elif isinstance(x, list):
        assert len(x) == len(y), path
        for i, (p, q) in enumerate(zip(x, y)):
            yield from _numbers(p, q, f"{path}[{i}]")
    elif isinstance(x, (int, float)) and not isinstance(x, bool):
        yield abs(x - y), path
    else:
        assert x == y, path


def test_mirroring_an_entry_twice_gives_it_back():
    from mocaplib.library.mirror import mirror_entry

    entry = _entry()
    image = mirror_entry(entry)
    assert image.id == "walk_curve_r2_left_normal_mirror_c1"
    assert (image.mirrored, image.mirror_of, image.mirror_method) == (True, entry.id, "series")
    assert image.omega == -0.5 and image.v_l == 0.006 and image.v == 1.0
    np.testing.assert_allclose(image.start_s, 1.43 + 0.587)
    np.testing.assert_allclose(image.right_toe_off_s, 1.17 - 0.587)
    back = mirror_entry(image)
    assert not back.mirrored and back.mirror_method is None and back.id == entry.id
    derived = {".root_drift.dx_m", ".root_drift.dy_m", ".root_drift.dheading_rad"}
    for difference, where in _numbers(entry.to_json(), back.to_json()):
        # The displacement is derived from the drift's velocities; the entry stores it
        # rounded to 10 significant digits, the image recomputes it (1e-10 m apart).
        assert difference <= (1e-9 if where in derived else 1e-12), where


def test_a_series_image_is_the_mirrored_motion_from_the_right_toe_off():
    """Put back in the world (library-format.md's root-drift formula), the image's motion is
    the source's from its right toe-off on, reflected, up to one rigid motion of the floor:
    joints equal, root pose a constant SE(2) transform away."""
    from mocaplib.gait.fourier import RootDrift, synthesize
    from mocaplib.skeleton import ROOT_X, ROOT_Y
    from mocaplib.library.mirror import mirror_entry
    from mocaplib.skeleton import ROOT_HEADING

    def world(entry, t):
        q = synthesize(entry.fourier.a, entry.fourier.b, entry.T, t)
        return RootDrift(0, 0, 0, *entry.root_drift.velocities).restore(q, t)

    entry = _entry(seed=5)
    t = np.linspace(0.0, 2.5, 60)
    source = mirror_dofs(world(entry, t + entry.right_toe_off_s))
    image = world(mirror_entry(entry), t)
    root = [ROOT_X, ROOT_Y, ROOT_HEADING]
    np.testing.assert_allclose(np.delete(image, root, axis=1), np.delete(source, root, axis=1),
                               atol=1e-12)
    turn = image[:, ROOT_HEADING] - source[:, ROOT_HEADING]
    c, s = np.cos(turn), np.sin(turn)
    moved = np.column_stack([image[:, ROOT_X] - (c * source[:, ROOT_X] - s * source[:, ROOT_Y]),
                             image[:, ROOT_Y] - (s * source[:, ROOT_X] + c * source[:, ROOT_Y])])
    assert np.ptp(turn) < 1e-12 and np.ptp(moved, axis=0).max() < 1e-12
    # the image's path frame starts at its root pose, as every entry's (the series' L(0))
    np.testing.assert_allclose(image[0, root] * [1, -1, -1],
                               world(entry, np.zeros(1))[0, root], atol=1e-12)


def test_an_entry_without_its_right_toe_off_cannot_be_mirrored():
    from mocaplib.errors import MocapError
    from mocaplib.library.mirror import mirror_entry

    entry = replace(_entry(), right_toe_off_s=None)
    with pytest.raises(MocapError, match="walk_curve_r2_left_normal_c1 does not record its "
                                         "right toe-off.*build the library again"):
        mirror_entry(entry)


def test_docs_mirroring_states_the_derived_map():
    """docs/mirroring.md's table of the DOF map is what the derivation gives."""
    import re
    from pathlib import Path

    doc = (Path(__file__).parents[1] / "docs" / "mirroring.md").read_text()
    stated = {}
    for names, partner, sign in re.findall(r"^\| (`.*?) \| (itself|its `…_l`, and back) \| "
                                           r"([+−]1) \|$", doc, re.M):
        for name in re.findall(r"`(\w+)`", names):
            stated[name] = (partner, 1 if sign == "+1" else -1)
    unsided = [n for n in DOF_NAMES if partner_name(n) == n]
    assert sorted(stated) == sorted(unsided)
    for k, name in enumerate(DOF_NAMES):
        if name in stated:
            assert (DOF_NAMES[MIRROR_INDEX[k]], MIRROR_SIGN[k]) == (name, stated[name][1]), name
        else:  # the sided row: each side takes its partner's value, sign +1
            assert "every `…_r`" in doc and DOF_NAMES[MIRROR_INDEX[k]] == partner_name(name)
            assert MIRROR_SIGN[k] == 1, name


def test_the_mirror_command_refuses_what_it_cannot_mirror(tmp_path, capsys):
    """An entry without its right toe-off (an older library): exit 1, the entries named,
    nothing written; the output naming the input: a usage error (2) before any work."""
    from mocaplib.cli import main
    from mocaplib.library.format import assemble_library

    old = replace(_entry(), right_toe_off_s=None)
    straight = replace(_entry(seed=4), id="walk_straight_normal_c0", omega=0.001, v_l=0.0)
    path = tmp_path / "old.json"
    assemble_library([old, straight], settings={}).write(path)
    out = tmp_path / "out.json"
    assert main(["mirror", str(path), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "1 entries do not record their right toe-off" in err
    assert "walk_curve_r2_left_normal_c1" in err and "Traceback" not in err
    assert not out.exists()
    assert main(["mirror", str(path), "-o", str(path)]) == 2
    assert "is an input of this command" in capsys.readouterr().err
    assert main(["mirror", str(tmp_path / "none.json"), "-o", str(out)]) == 2


def test_a_mirrored_library_stores_the_tetrahedra_of_its_images_too():
    # the source's tetrahedra would leave the images out of every blend (and fail validation)
    source = assemble_library([library_entry(i, right_toe_off_s=0.5) for i in range(5)],
                              settings={"protocol": "auto"})
    mirrored, _ = mirror_library(source)
    assert len(mirrored) > len(source) and validate_library(mirrored) == []
    stored = mirrored.document["control_space"]["tetrahedra"]
    cs = ControlSpace.from_library(mirrored)
    simplices, gaits = cell_tetrahedra(cs.cells)
    frontal, frontal_gaits = frontal_tetrahedra(cs.cells)
    assert stored == {"ids": cs.ids, "simplices": simplices.tolist(), "gaits": gaits,
                      "hull": cs.tri.convex_hull.tolist(), "frontal_simplices": frontal.tolist(),
                      "frontal_gaits": frontal_gaits}
    assert any(e.mirrored for e in mirrored.entries if e.id in stored["ids"])
