"""OpenSim exports: the .osim reproduces our kinematics; .trc and .mot are what OpenSim reads."""

import numpy as np
import pytest
from fk_data import fk_trial, true_model

from mocaplib.export.opensim import osim_text, write_mot, write_osim, write_trc
from mocaplib.model.motion import Motion
from mocaplib.skeleton import DOF_NAMES
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
