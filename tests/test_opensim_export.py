"""OpenSim exports: the .osim reproduces our kinematics; .trc and .mot are what OpenSim reads."""

import numpy as np
import pytest
from conftest import REPO
from fk_data import fk_trial, true_model

from mocaplib.cli import main
from mocaplib.errors import MocapError
from mocaplib.export.opensim import opensim_name, osim_text, write_mot, write_osim, write_trc
from mocaplib.io.c3d import read_c3d
from mocaplib.model.anthropometry import DEFAULT_BODY_MASS
from mocaplib.model.fitting import fit_capture
from mocaplib.model.motion import Motion
from mocaplib.skeleton import DOF_NAMES, TRANSLATION
from mocaplib.trial import Trial


def test_opensim_places_markers_where_we_do(tmp_path, monkeypatch):
    osim = pytest.importorskip("opensim")
    monkeypatch.chdir(tmp_path)                      # OpenSim writes opensim.log here
    cap = fk_trial(n_frames=4)
    path = write_osim(true_model(cap), tmp_path / "subject.osim")
    model = osim.Model(str(path))
    state = model.initSystem()
    coords = model.getCoordinateSet()
    markers = model.getMarkerSet()
    rng = np.random.default_rng(0)
    for q in cap.q + rng.normal(0, 0.3, cap.q.shape):      # arbitrary poses, not only gait
        for j, name in enumerate(DOF_NAMES):
            coords.get(name).setValue(state, float(q[j]), False)
        model.realizePosition(state)
        theirs = np.array([[markers.get(i).getLocationInGround(state).get(k) for k in range(3)]
                           for i in range(markers.getSize())])
        ours = cap.skeleton.points(q[None], cap.segments, cap.offsets)[0]
        # same kinematic chain in double precision: equal to round-off
        np.testing.assert_allclose(theirs, ours, atol=1e-6)


def test_osim_lists_every_dof_with_ranges_and_locks():
    cap = fk_trial(n_frames=2)
    text = osim_text(true_model(cap, locked=["neck_rotation"]))
    for name in DOF_NAMES:
        assert f'<Coordinate name="{name}">' in text
    neck = text[text.index('<Coordinate name="neck_rotation">'):]
    assert neck[:neck.index("</Coordinate>")].count("<locked>true</locked>") == 1
    assert text.count("<Marker ") == len(cap.segments)
    assert "<gravity>0 0 -9.80665</gravity>" in text


def test_trc_in_millimetres_with_missing_samples(tmp_path):
    markers = np.array([[[0.1, 0.2, 0.3], [np.nan, np.nan, np.nan]],
                        [[0.4, 0.5, 0.6], [1.0, 2.0, 3.0]]])
    path = write_trc(Trial(markers, ["A", "B"], 50.0), tmp_path / "m.trc")
    lines = path.read_text().splitlines()
    assert lines[2].split("\t")[:5] == ["50", "50", "2", "2", "mm"]
    assert lines[3].split("\t")[2] == "A" and lines[3].split("\t")[5] == "B"
    first = lines[6].split("\t")
    assert first[:2] == ["1", "0.000000"] and first[5:] == ["NaN"] * 3
    np.testing.assert_allclose([float(v) for v in lines[7].split("\t")[2:]],
                               [400, 500, 600, 1000, 2000, 3000])  # exact decimal mm


def test_mot_in_degrees_translations_in_metres(tmp_path):
    q = np.zeros((3, len(DOF_NAMES)))
    q[:, DOF_NAMES.index("knee_flexion_r")] = np.pi / 2
    q[:, DOF_NAMES.index("pelvis_tx")] = 1.5
    cap = fk_trial(n_frames=2)
    motion = Motion(q, cap.skeleton, 100.0)
    lines = write_mot(motion, tmp_path / "a.mot").read_text().splitlines()
    assert "inDegrees=yes" in lines and "nRows=3" in lines
    head = lines[lines.index("endheader") + 1].split("\t")
    row = dict(zip(head, map(float, lines[-1].split("\t"))))
    assert row["time"] == pytest.approx(0.02)
    assert row["knee_flexion_r"] == pytest.approx(90.0)
    assert row["pelvis_tx"] == pytest.approx(1.5)


def test_labels_opensim_refuses_are_written_as_names_it_accepts(tmp_path, monkeypatch):
    # BTS labels hold spaces ("l should"): OpenSim refuses such a marker name, so the .osim
    # and the .trc both write it "l_should"
    from dataclasses import replace

    osim = pytest.importorskip("opensim")
    monkeypatch.chdir(tmp_path)
    cap = fk_trial(n_frames=3)
    model = true_model(cap)
    labels = [f"m {i}" if i % 2 else f"m/{i}*+" for i in range(len(model.labels))]
    path = write_osim(replace(model, labels=labels), tmp_path / "spaced.osim")
    opened = osim.Model(str(path))                  # referenced while its markers are read
    markers = opened.getMarkerSet()
    names = [markers.get(i).getName() for i in range(markers.getSize())]
    assert names == [label.replace(" ", "_").replace("/", "_").replace("*", "_")
                     .replace("+", "_") for label in labels]
    trc = write_trc(Trial(cap.trial.markers, labels, 100.0), tmp_path / "spaced.trc")
    assert list(osim.TimeSeriesTableVec3(str(trc)).getColumnLabels()) == names


# ------------------------------------------------------------------ masses and inertias
#: de Leva (1996), Table 4, males, as the paper prints them: mass fraction of each of our
#: segments (the trunk's lower part rides on the pelvis, the hand on the forearm), and for the
#: long bones the centre of mass (fraction of the length from the proximal joint) and the
#: radii of gyration (sagittal, transverse, longitudinal; fractions of the length).
DE_LEVA_MASS = {"pelvis": 0.1117, "torso": 0.1596 + 0.1633, "head": 0.0694,
                "humerus": 0.0271, "forearm": 0.0162 + 0.0061, "femur": 0.1416,
                "tibia": 0.0433, "foot": 0.0137}
DE_LEVA_LONG_BONES = {"humerus": ("upper_arm", 0.5772, (0.285, 0.269, 0.158)),
                      "femur": ("thigh", 0.4095, (0.329, 0.329, 0.149)),
                      "tibia": ("shank", 0.4395, (0.251, 0.246, 0.102))}


def _opensim_bodies(osim, path):
    """Per body: mass (kg), centre of mass (3,), inertia tensor about it (3, 3), as OpenSim
    reads the file; and the model's total mass."""
    model = osim.Model(str(path))
    state = model.initSystem()
    out = {}
    for i in range(model.getBodySet().getSize()):
        body = model.getBodySet().get(i)
        moments, products = body.getInertia().getMoments(), body.getInertia().getProducts()
        (xx, yy, zz), (xy, xz, yz) = ([v.get(k) for k in range(3)] for v in (moments, products))
        out[body.getName()] = (body.getMass(),
                               np.array([body.getMassCenter().get(k) for k in range(3)]),
                               np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]))
    return out, model.getTotalMass(state)


def test_the_model_s_masses_are_de_leva_s_for_the_subject(tmp_path, monkeypatch):
    osim = pytest.importorskip("opensim")
    monkeypatch.chdir(tmp_path)
    cap = fk_trial(n_frames=2)
    path = write_osim(true_model(cap), tmp_path / "subject.osim", body_mass=63.0)
    bodies, total = _opensim_bodies(osim, path)
    assert total == pytest.approx(63.0, rel=1e-12)
    lengths = cap.skeleton.lengths
    for name, (mass, com, inertia) in bodies.items():
        kind = name[:-2] if name.endswith(("_l", "_r")) else name
        assert mass == pytest.approx(63.0 * DE_LEVA_MASS[kind], rel=1e-9), name
        principal = np.linalg.eigvalsh(inertia)
        assert principal[0] > 0, name                              # positive definite
        assert principal[0] + principal[1] >= principal[2], name   # a real body's moments
        if kind in DE_LEVA_LONG_BONES:
            length_name, at, radii = DE_LEVA_LONG_BONES[kind]
            length = lengths[length_name]
            np.testing.assert_allclose(com, [0.0, 0.0, -at * length], atol=1e-12)
            np.testing.assert_allclose(np.diag(inertia), mass * (np.array(radii) * length) ** 2,
                                       rtol=1e-9)
            np.testing.assert_allclose(inertia - np.diag(np.diag(inertia)), 0.0, atol=1e-12)
    with pytest.raises(MocapError, match="body mass must be > 0 kg"):
        osim_text(true_model(cap), body_mass=0.0)


def test_fit_takes_the_body_mass_from_the_user_or_the_file_or_says_what_it_assumes(
        sample_dir, tmp_path, monkeypatch, capsys):
    osim = pytest.importorskip("opensim")
    monkeypatch.chdir(tmp_path)
    walk = str(sample_dir / "walk_straight_normal.c3d")
    assert main(["fit", walk, "-o", "a.csv", "--osim", "assumed.osim"]) == 0
    assert f"assume {DEFAULT_BODY_MASS:g} kg" in capsys.readouterr().err
    assert main(["fit", walk, "-o", "a.csv", "--osim", "given.osim",
                 "--subject", "body_mass=81.5"]) == 0
    assert "assume" not in capsys.readouterr().err
    assert _opensim_bodies(osim, tmp_path / "assumed.osim")[1] == pytest.approx(DEFAULT_BODY_MASS)
    assert _opensim_bodies(osim, tmp_path / "given.osim")[1] == pytest.approx(81.5)


# ------------------------------------------------------------------ OpenSim's own IK
#: Largest RMS difference (degrees; pelvis translations mm) per DOF group between OpenSim's
#: InverseKinematicsTool on `mocaplib fit`'s .osim and .trc and mocaplib's own angles. The two
#: solve the same weighted least squares; mocaplib adds a robust loss and a continuity term.
#: Measured: sample walk_straight_normal (static rest.c3d) / PiG_Motion-FlatFoot-Full.
IK_AGREEMENT = {
    "pelvis translation (mm)": (("pelvis_t",), 0.5),        # measured 0.06 / 0.18 mm
    "pelvis, trunk, neck": (("pelvis_r", "pelvis_l", "pelvis_ti", "trunk", "neck"), 0.5),
    #                                                          measured 0.09 / 0.32°
    "hips and knees": (("hip", "knee"), 1.0),                 # measured 0.33 / 0.73°
    "ankles": (("ankle",), 1.6),                              # measured 1.34 / 0.91°
    "shoulders and elbows": (("shoulder", "elbow"), 1.6),     # measured 0.32 / 1.31°
}


@pytest.mark.parametrize("capture, static, body_mass", [
    ("sample:walk_straight_normal.c3d", "sample:rest.c3d", DEFAULT_BODY_MASS),
    ("btkdata/PiG_Motion-FlatFoot-Full.c3d", None, 47.5),        # PROCESSING Bodymass
])
def test_opensim_s_inverse_kinematics_on_fit_s_files_agrees_with_the_fit(
        sample_dir, real_c3d, tmp_path, monkeypatch, capture, static, body_mass):
    osim = pytest.importorskip("opensim")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(REPO / "benchmarks"))
    from opensim_tools import inverse_kinematics, read_mot

    def find(name):
        return sample_dir / name[7:] if name.startswith("sample:") else real_c3d(name)

    path, static_path = find(capture), static and find(static)
    options = ["--static", str(static_path), "--static-pose", "neutral"] if static else []
    assert main(["fit", str(path), *options, "-o", "a.csv", "--osim", "model.osim",
                 "--trc", "markers.trc"]) == 0
    trial = read_c3d(path)
    fitted = fit_capture(trial, static=[read_c3d(static_path)] if static else None,
                         static_pose="neutral" if static else "free")   # as the command did
    model = fitted.model
    rotations = list(np.flatnonzero(~TRANSLATION))
    inverse_kinematics(tmp_path / "model.osim", tmp_path / "markers.trc",
                       [opensim_name(label) for label in model.labels], model.marker_weights,
                       trial.duration, tmp_path / "ik.mot")
    theirs = read_mot(tmp_path / "ik.mot", list(DOF_NAMES), rotations)
    ours = fitted.motion.q
    assert theirs.shape == ours.shape and not fitted.motion.failed.any()
    difference = theirs - ours
    difference[:, rotations] = np.angle(np.exp(1j * difference[:, rotations]))  # a turn apart
    rms = np.sqrt(np.mean(difference ** 2, axis=0))
    rms = np.where(TRANSLATION, rms * 1e3, np.degrees(rms))
    for group, (prefixes, bound) in IK_AGREEMENT.items():
        columns = [j for j, name in enumerate(DOF_NAMES) if name.startswith(prefixes)]
        assert rms[columns].max() < bound, (group, dict(zip(np.array(DOF_NAMES)[columns],
                                                            rms[columns].round(3))))
    assert _opensim_bodies(osim, tmp_path / "model.osim")[1] == pytest.approx(body_mass)
