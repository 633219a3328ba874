"""``mocaplib protocol draft``: a draft protocol for an unknown marker set, by name, by place
and by rigid groups, checked against the shipped protocols on the real files."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import real_files

from mocaplib.cli import main
from mocaplib.markersets.draft import (AXIS_WEIGHTS, LOW_CONFIDENCE, Draft, DraftEntry,
                                       draft_protocol, label_stem, name_landmarks)
from mocaplib.markersets.draft_checks import catalogue_places, check_draft, draft_agreement
from mocaplib.io.c3d import read_c3d
from mocaplib.markersets.protocols import load_landmarks, load_protocol
from mocaplib.markersets.matching import detect_protocol, match_protocol
from mocaplib.synth.capture import synthesize_capture
from mocaplib.library.command import Command

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


def _checked(*guesses):
    """Entries ``(label, landmark, segment, place or landmark name, confidence)`` after
    :func:`check_draft`."""
    names, places, _ = catalogue_places()
    entries = [DraftEntry(label, landmark, segment, confidence=confidence,
                          place=places[names.index(where)] if isinstance(where, str)
                          else np.asarray(where, float))
               for label, landmark, segment, where, confidence in guesses]
    check_draft(entries, [label_stem(e.label) for e in entries], AXIS_WEIGHTS)
    return entries


def test_a_guess_on_the_other_side_goes_to_the_labels_or_the_markers_side():
    knee, thigh = _checked(("LKNX", "R_KNEE_LAT", None, "L_KNEE_LAT", 0.9),
                           ("TH9", None, "femur_r", "L_THIGH", 0.9))
    assert (knee.landmark, thigh.segment) == ("L_KNEE_LAT", "femur_l")
    assert knee.confidence < LOW_CONFIDENCE and "side is L" in knee.evidence[-1]


def test_mirrored_labels_get_mirrored_guesses():
    left, right = _checked(("LKNX", "L_KNEE_LAT", None, "L_KNEE_LAT", 0.9),
                           ("RKNX", "R_FIBULA_HEAD", None, "R_KNEE_LAT", 0.3))
    assert right.landmark == "R_KNEE_LAT" and "mirrors LKNX" in right.evidence[-1]
    bar_l, bar_r = _checked(("l bar 7", None, "tibia_l", "L_SHANK", 0.5),
                            ("r bar 7", None, "femur_r", "R_SHANK", 0.4))
    assert (bar_l.segment, bar_r.segment) == ("tibia_l", "tibia_r")


def test_a_marker_far_from_its_landmark_is_not_mapped_to_it():
    names, places, _ = catalogue_places()
    heel = places[names.index("L_HEEL")] + [0, 0, 0.94]          # 94 cm above the heel
    dropped, kept = _checked(("LHEX", "L_HEEL", None, heel, 0.9),
                             ("LHEY", "L_HEEL_UPPER", None, "L_HEEL_UPPER", 0.9))
    assert dropped.landmark is None and "94 cm" in dropped.evidence[-1]
    assert kept.landmark == "L_HEEL_UPPER"
    # an arm raised sideways (a static's T pose) keeps its wrist: its reach from the shoulder
    shoulder = places[names.index("L_ACROMION")]
    reach = np.linalg.norm(places[names.index("L_WRIST_RAD")] - shoulder)
    (wrist,) = _checked(("LWRX", "L_WRIST_RAD", None, shoulder + [0, reach, 0], 0.9))
    assert wrist.landmark == "L_WRIST_RAD"


def test_a_label_on_the_other_side_is_kept_flagged_and_warned():
    (swapped,) = _checked(("RSHX", "R_ACROMION", None, "L_ACROMION", 0.9))
    assert swapped.landmark == "R_ACROMION"
    warned = Draft("lab", ["x.c3d"], [swapped]).warnings()
    assert len(warned) == 1 and "the label says R but the marker sits" in warned[0]


def test_two_labels_of_one_place_are_one_landmark_and_a_tracking_marker():
    # two marker sets' names exported for the same markers (Plug-in Gait's LANK, LASI, LTOE
    # beside a CAST set's LLM, LASIS, LMT2), 4 mm apart: one label takes the landmark, the
    # other tracks its segment; none is dropped or given a landmark elsewhere
    from dataclasses import replace

    walk = synthesize_capture(Command.from_kind("straight", speed=1.2), duration=2.7, seed=1,
                              protocol="plugin_gait", session_seed=4).trial
    seconds = {"LLM": "LANK", "RLM": "RANK", "LASIS": "LASI", "RASIS": "RASI", "LMT2": "LTOE",
               "RMT2": "RTOE"}
    extra = np.stack([walk.markers[:, walk.labels.index(label)] + [0.003, 0.002, 0.0]
                      for label in seconds.values()], axis=1)
    trial = replace(walk, markers=np.concatenate([walk.markers, extra], axis=1),
                    labels=[*walk.labels, *seconds])
    by_label = {e.label: e for e in draft_protocol(trial).entries}
    catalogue = load_landmarks()
    for second, first in seconds.items():
        pair = sorted((by_label[second], by_label[first]), key=lambda e: e.landmark is None)
        held, tracking = pair
        assert held.landmark and held.landmark[2:] in ("ANKLE_LAT", "ASIS", "TOE"), pair
        assert tracking.landmark is None, pair
        assert tracking.segment == catalogue[held.landmark].segment, pair
        assert "a second marker on " + held.landmark in " ".join(tracking.evidence)
    alone = {e.label: (e.landmark, e.segment) for e in draft_protocol(walk).entries}
    for label, (landmark, segment) in alone.items():      # the other labels as without them
        if label not in seconds.values():
            assert (by_label[label].landmark, by_label[label].segment) == (landmark, segment)


def _shared_names():
    from conftest import SHARED_C3D
    return [p.relative_to(SHARED_C3D).as_posix() for p in real_files()]


#: Per real file, measured by ``benchmarks/draft_yield.py`` (docs/results/draft_yield.md): of
#: the labels the shipped protocol maps, how many the draft gives the same landmark, how many
#: the shipped protocol's segment (same landmark or another on it), how many a wrong segment;
#: by name and place, then by place and motion alone (``use_names=False``). A draft that gets
#: one fewer right or one more wrong fails.
MEASURED = {
    "biomechzoo/HC030A01.c3d": ((65, 65, 0), (2, 14, 4)),
    "biomechzoo/HC030A05.c3d": ((59, 59, 0), (25, 53, 2)),
    "biomechzoo/HC030A22.c3d": ((59, 59, 0), (20, 46, 6)),
    "btkdata/Gait.c3d": ((25, 25, 0), (13, 23, 0)),
    "btkdata/PiG_Calibration-FlatFoot-One.c3d": ((35, 35, 0), (0, 10, 10)),
    "btkdata/PiG_Calibration2-NoOption.c3d": ((35, 35, 0), (0, 3, 4)),
    "btkdata/PiG_Motion-FlatFoot-Full.c3d": ((35, 35, 0), (16, 29, 4)),
    "c3dviewer_examples/running.c3d": ((30, 30, 0), (1, 18, 8)),
    "cmu/07_01.c3d": ((41, 41, 0), (2, 31, 8)),
    "cmu/07_12.c3d": ((41, 41, 0), (10, 33, 8)),
    "cmu/16_07.c3d": ((39, 39, 2), (13, 34, 6)),
    "ezc3d_testfiles/BTS.c3d": ((16, 22, 0), (4, 14, 7)),
    "ezc3d_testfiles/FP_Type1.c3d": ((16, 20, 0), (7, 14, 6)),
    "ezc3d_testfiles/Qualisys.c3d": ((49, 55, 0), (17, 45, 8)),
    "motonms_unipd/Static1.c3d": ((29, 29, 0), (23, 25, 2)),
    "motonms_unipd/Walking1.c3d": ((30, 30, 0), (14, 30, 0)),
    "motonms_unipd/Walking3.c3d": ((30, 30, 0), (18, 28, 0)),
}


def _agreements(path):
    """:func:`draft_agreement` of the file's drafts by name and by place alone with the
    shipped protocol it matches."""
    trial = read_c3d(path)
    match = detect_protocol(trial)
    return [draft_agreement(draft_protocol(trial, use_names=names).entries, trial, match)
            for names in (True, False)]


@pytest.mark.parametrize("name", _shared_names() or ["(no shared files)"])
def test_the_draft_of_each_real_file_puts_its_labels_on_the_shipped_segments(real_c3d, name):
    by_name, by_place = _agreements(real_c3d(name))
    # the target: 90 % of the labels on the shipped protocol's segment, by name and place
    assert by_name.landmark + by_name.segment >= 0.9 * by_name.total, (name, by_name)
    # never a guess on the other side, with names or without
    assert by_name.other_side == by_place.other_side == 0, (name, by_name, by_place)
    for measured, got in zip(MEASURED[name], (by_name, by_place)):
        landmark, right, wrong = measured
        assert got.landmark >= landmark and got.landmark + got.segment >= right, (name, got)
        assert got.wrong <= wrong, (name, got.wrong_labels)


@pytest.mark.xfail(strict=True, reason="by place and motion alone 450 of the 657 labels "
                                       "(68 %) land on the shipped protocol's segment, 83 on "
                                       "a wrong one (elbow, knee and ankle markers on the "
                                       "distal bone, a runner's arms on the legs): target 90 %; "
                                       "MEASURED bounds each file's figures")
def test_drafts_by_place_and_motion_alone_reach_the_target(shared_c3d):
    found = [_agreements(shared_c3d / name)[1] for name in _shared_names()]
    right = sum(a.landmark + a.segment for a in found)
    assert right >= 0.9 * sum(a.total for a in found), right
