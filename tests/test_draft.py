"""``mocaplib protocol draft``: a draft protocol for an unknown marker set, by name, by place
and by rigid groups, checked against the shipped protocols on the real files."""

from __future__ import annotations

import pytest
from conftest import real_files

from mocaplib.cli import main
from mocaplib.markersets.draft import draft_protocol, label_stem, name_landmarks
from mocaplib.io.c3d import read_c3d
from mocaplib.markersets.protocols import load_protocol
from mocaplib.markersets.matching import detect_protocol, match_protocol
from mocaplib.synth.capture import synthesize_capture
from mocaplib.library.command import Command
from mocaplib.trial import normalise_label

#: Files whose draft misses the 90 % target, with what was measured and why (strict xfails).
BELOW_TARGET = {
    "ezc3d_testfiles/BTS.c3d": "73 %: its shank clusters (SCL1/2, SCR1/2, 'bar 2') are drafted "
                               "as tracking markers on the tibia; the shipped protocol maps them "
                               "to catalogue entries written from this very file",
    "ezc3d_testfiles/FP_Type1.c3d": "73 %: a standing trial (no rigid groups to see), its "
                                    "lateral thigh and shank bars 10-13 cm off the catalogue's "
                                    "thigh and shank markers, and 'l thigh' sits on the "
                                    "trochanter though its name says thigh",
    "ezc3d_testfiles/Qualisys.c3d": "87 %: its WAND1-4 markers are drafted as tracking markers "
                                    "(they are wands: rigid with a segment, on no landmark); the "
                                    "shipped protocol maps them to the catalogue's wand places",
}


@pytest.mark.parametrize("label, side, stem", [
    ("LASI", "L", "ASI"), ("l bar 1", "L", "BAR1"), ("SCR1", "R", "SC1"), ("L_SAJ", "L", "SAJ"),
    ("L5", None, "L5"), ("CV7", None, "CV7"), ("Bastian:RBAK", "R", "BAK"),
    ("Left Knee", "L", "KNEE"), ("ASIS_R", "R", "ASIS"), ("LTH2", "L", "TH2"),
])
def test_label_stems_and_sides(label, side, stem):
    assert label_stem(label) == (side, stem)


def test_names_point_to_landmarks():
    assert name_landmarks("LSHO") == ("L", ("ACROMION",))
    assert set(name_landmarks("LLE")[1]) == {"ELBOW_LAT", "KNEE_LAT"}    # the place decides
    assert name_landmarks("r knee 1") == ("R", ("KNEE_LAT",))
    assert name_landmarks("lbar1") == ("L", ())


def test_a_cluster_set_is_drafted_and_fits(tmp_path, capsys):
    session = dict(protocol="cluster_fullbody", session_seed=4)
    walk = synthesize_capture(Command.from_kind("straight", speed=1.2), duration=2.7, seed=1,
                              **session)
    rest = synthesize_capture(Command.from_kind("rest"), duration=2.0, seed=2, **session)
    draft = draft_protocol(walk.trial, static=rest.trial, name="mylab")
    shipped = load_protocol("cluster_fullbody")
    by_label = {e.label: e for e in draft.entries}
    for marker in shipped.markers:
        entry = by_label[marker.label]
        if marker.tracking:                   # every cluster marker, on its own segment
            assert entry.segment == marker.landmark.segment, (marker.label, entry)
        else:
            assert entry.landmark == marker.landmark.name, (marker.label, entry)
        assert entry.static_only == marker.static_only, marker.label
    # written, it is a protocol inspect and fit take as it is
    from mocaplib.io.c3d_write import write_c3d

    capture = write_c3d(tmp_path / "walk.c3d", walk.trial.markers, walk.trial.labels, 100.0)
    static = write_c3d(tmp_path / "rest.c3d", rest.trial.markers, rest.trial.labels, 100.0)
    out = tmp_path / "mylab.toml"
    assert main(["protocol", "draft", str(capture), "--static", str(static), "-o",
                 str(out)]) == 0
    text = out.read_text()
    assert "# high" in text or "# medium" in text             # each guess says its confidence
    assert 'LTH1 = { segment = "femur", side = "left" }' in text
    assert 'LKNE = { landmark = "L_KNEE_LAT", static_only = true }' in text
    protocol = load_protocol(out)
    assert match_protocol(walk.trial, protocol).complete
    capsys.readouterr()
    assert main(["inspect", "--protocol", str(out), str(capture)]) == 0
    assert "protocol mylab: 48/60 markers; missing required landmarks: none" in \
        capsys.readouterr().out
    assert main(["fit", str(capture), "--static", str(static), "--protocol", str(out), "-o",
                 str(tmp_path / "angles.csv"), "--json"]) == 0


def test_draft_usage_errors(tmp_path, capsys):
    assert main(["protocol", "draft", str(tmp_path / "none.c3d"), "-o",
                 str(tmp_path / "x.toml")]) == 2
    assert "none.c3d" in capsys.readouterr().err


def _shared_names():
    from conftest import SHARED_C3D
    return [p.relative_to(SHARED_C3D).as_posix() for p in real_files()]


#: The agreement measured on the files of BELOW_TARGET: a draft that agrees less fails.
MEASURED_BELOW_TARGET = {"ezc3d_testfiles/BTS.c3d": 0.727, "ezc3d_testfiles/FP_Type1.c3d": 0.727,
                         "ezc3d_testfiles/Qualisys.c3d": 0.873}


def _agreement(path) -> float:
    """The share of the shipped protocol's landmarks (by trial label) the draft names alike."""
    trial = read_c3d(path)
    match = detect_protocol(trial)
    shipped = {}
    for marker, i in zip(match.protocol.markers, match.indices):
        if i >= 0:
            shipped.setdefault(trial.names[i], marker.landmark.name)
    drafted = draft_protocol(trial).landmarks
    return sum(drafted.get(normalise_label(k)) == v for k, v in shipped.items()) / len(shipped)


@pytest.mark.parametrize("name", [
    pytest.param(name, marks=pytest.mark.xfail(strict=True,
                                               reason=f"measured {BELOW_TARGET[name]}"))
    if name in BELOW_TARGET else name for name in _shared_names() or ["(no shared files)"]])
def test_the_draft_of_each_real_file_agrees_with_its_shipped_protocol(real_c3d, name):
    agree = _agreement(real_c3d(name))
    assert agree >= 0.9, (name, agree)


@pytest.mark.parametrize("name", sorted(MEASURED_BELOW_TARGET))
def test_the_drafts_below_target_agree_no_less_than_measured(real_c3d, name):
    # 8 of 11 and 48 of 55 landmarks: a draft that names one landmark fewer fails
    agree = _agreement(real_c3d(name))
    assert agree >= MEASURED_BELOW_TARGET[name] - 0.01, (name, agree)
