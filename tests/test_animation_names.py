"""Marker sets labelled with descriptive camel-case names (``WaistLFront``, ``LKneeOut``), as
animation studios' systems write them (and OpenSim's example models' dotted ones): read by name,
side included, by the draft and by a build that has no protocol for them."""

from __future__ import annotations

import dataclasses
import re

import pytest
from animation_names import PROTOCOL_NAME, protocol_labels, write_protocol, write_session
from test_zero_config import VELOCITY_TOLERANCE

from mocaplib.build.drafting import DRAFTS_FOLDER
from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
from mocaplib.io.c3d import read_c3d
from mocaplib.markersets.draft import draft_protocol, name_landmarks
from mocaplib.markersets.draft_checks import draft_agreement
from mocaplib.markersets.inspection import format_summary, inspect_c3d
from mocaplib.markersets.matching import detect_protocol, match_protocol
from mocaplib.markersets.protocols import FOLDERS_VARIABLE, load_protocol
from mocaplib.trial import normalise_label, written_side


@pytest.mark.parametrize("label, side, rest", [
    ("WaistLFront", "L", "WAISTFRONT"), ("Actor:WaistRBack", "R", "WAISTBACK"),
    ("Waist_L_Front", "L", "WAISTFRONT"), ("WaistLeftFront", "L", "WAISTFRONT"),
    # a side in front or nowhere is read as before
    ("LKneeOut", None, "LKNEEOUT"), ("SpineThoracic10", None, "SPINETHORACIC10"),
    ("LFArm", None, "LFARM"), ("CentreOfMass", None, "CENTREOFMASS"), ("RTHIa", None, "RTHIA"),
])
def test_a_side_inside_a_camel_case_label(label, side, rest):
    assert written_side(label) == (side, rest)


def test_the_normalised_label_puts_the_side_in_front():
    assert normalise_label("Actor:WaistLFront") == normalise_label("LWaistFront") == "LWAISTFRONT"


@pytest.mark.parametrize("label, side, landmarks", [
    ("WaistLFront", "L", {"ASIS"}), ("WaistRBack", "R", {"PSIS", "SACRUM"}),
    ("LKneeOut", "L", {"KNEE_LAT"}), ("RKneeIn", "R", {"KNEE_MED"}),
    ("LAnkleOut", "L", {"ANKLE_LAT"}), ("LShoulderTop", "L", {"ACROMION"}),
    ("RShoulderBack", "R", {"SCAPULA"}), ("LElbowOut", "L", {"ELBOW_LAT"}),
    ("LToeIn", "L", {"MT1"}), ("RToeOut", "R", {"MT5"}), ("LToeTip", "L", {"TOE2"}),
    ("LHeelBack", "L", {"HEEL"}), ("RForefoot5", "R", {"MT5"}), ("LForefootIn", "L", {"MT1"}),
    ("LUArmHigh", "L", {"UPPER_ARM"}),
    ("LShinFrontHigh", "L", {"SHIN"}), ("RThighFrontLow", "R", {"THIGH"}),
    ("SpineThoracic12", None, {"T12"}),
    # full words for Plug-in Gait's markers
    ("LeftWristA", "L", {"WRIST_RAD"}), ("RightWristB", "R", {"WRIST_ULN"}),
    ("RightFrontWaist", "R", {"ASIS"}), ("LeftBackWaist", "L", {"PSIS"}),
    ("LeftFinger", "L", {"FINGER"}), ("Clavicle", None, {"CLAV"}),
    # the dotted names of OpenSim's example models
    ("R.Knee.Lat", "R", {"KNEE_LAT"}), ("L.Ankle.Med", "L", {"ANKLE_MED"}),
    ("R.Acromium", "R", {"ACROMION"}), ("V.Sacral", None, {"SACRUM"}),
    ("L.Shank.Front", "L", {"SHANK"}), ("R.Thigh.Upper", "R", {"THIGH"}),
    # where a name is used both ways, the marker's place decides
    ("LWristOut", "L", {"WRIST_RAD", "WRIST_ULN"}), ("RHandIn", "R", {"FINGER", "HAND_MC5"}),
])
def test_descriptive_names_point_to_their_landmarks(label, side, landmarks):
    assert name_landmarks(label)[0] == side
    assert set(name_landmarks(label)[1]) == landmarks


@pytest.fixture
def session(tmp_path, monkeypatch):
    """The animation-named session's protocol in a user folder and its captures on disk."""
    protocols = tmp_path / "protocols"
    protocols.mkdir()
    write_protocol(protocols)
    monkeypatch.setenv(FOLDERS_VARIABLE, str(protocols))
    captures = tmp_path / "captures"
    captures.mkdir()
    return captures, write_session(captures)


def test_every_label_is_drafted_on_its_landmark(session):
    _, (walk, _, rest) = session
    trial, static = read_c3d(walk), read_c3d(rest)
    draft = draft_protocol(trial, static=static, name="anim")
    got = {entry.label.split(":")[-1]: entry for entry in draft.entries}
    wrong = {label: got[label].landmark for label, landmark in protocol_labels().items()
             if got[label].landmark != landmark}
    assert not wrong                                    # 46 of 46
    assert not draft.warnings()                         # no guess of low confidence
    # the names carry it: by place and motion alone 4 of the 46 land on their landmark
    match = match_protocol(trial, load_protocol(PROTOCOL_NAME))
    alone = draft_agreement(draft_protocol(trial, static=static, use_names=False).entries,
                            trial, match)
    assert alone.total == 46 and alone.landmark <= 10


def test_a_build_without_their_protocol_gives_its_entries(session, tmp_path, monkeypatch):
    captures, _ = session
    written = build_library([captures], BuildSettings(), progress=False)
    monkeypatch.setenv(FOLDERS_VARIABLE, "")           # only the shipped protocols: drafted
    drafted = build_library([captures], BuildSettings(), progress=False,
                            drafts_dir=tmp_path / DRAFTS_FOLDER)
    drafts = list((tmp_path / DRAFTS_FOLDER).glob("*.toml"))
    assert len(drafts) == 1 and "low (" not in drafts[0].read_text()
    expected = {c.file: c.entries for c in written.captures}
    assert sum(map(len, expected.values())) >= 2        # the walk's and the curve's cycles
    for capture in drafted.captures:
        assert len(capture.entries) == len(expected[capture.file]), capture.file
        for got, want in zip(capture.entries, expected[capture.file]):
            for name in ("v", "omega", "v_l"):
                assert getattr(got, name) == pytest.approx(getattr(want, name),
                                                           abs=VELOCITY_TOLERANCE), name


def test_inspect_says_a_build_drafts_their_protocol(session, monkeypatch):
    _, (walk, _, _) = session
    served = inspect_c3d(walk)                          # their protocol in a user folder
    assert served["protocol"] == PROTOCOL_NAME
    assert not any("no protocol serves" in w for w in served["warnings"])
    monkeypatch.setenv(FOLDERS_VARIABLE, "")           # only the shipped protocols
    unknown = inspect_c3d(walk)
    hint = [w for w in unknown["warnings"] if "no protocol serves this marker set" in w]
    assert len(hint) == 1 and f"mocaplib protocol draft {walk} -o" in hint[0]
    assert served["draft"] is None and all(m["drafted"] is None for m in served["markers"])
    # what a draft from the walk alone makes of each label, in place of the closest protocol's
    assert unknown["draft"] == {"landmarks": 46, "cluster_markers": 0, "without_guess": 0,
                                "low_confidence": 0}
    truth = {label: served_marker["landmark"] for label, served_marker in
             zip(served["labels"], served["markers"])}
    guessed = {m["label"]: m["drafted"]["landmark"] for m in unknown["markers"]}
    wrong = {label for label in truth if guessed[label] != truth[label]}
    # the hand's outer marker is put on the 2nd metacarpal (both ride on the forearm): the
    # walk's swinging hands do not show which side of the hand it sits on; the static does
    assert wrong == {"Actor:LHandOut", "Actor:RHandOut"}
    table = format_summary(unknown)
    assert "46 labels on a landmark, 0 in a segment's cluster, 0 without a guess" in table
    assert re.search(r"Actor:WaistRBack +R_PSIS \(drafted, \d+%\)", table)


#: Plug-in Gait's label stems written as words (``LKNE`` as ``LeftKnee``).
PIG_WORDS = {"FHD": "FrontHead", "BHD": "BackHead", "SHO": "Shoulder", "UPA": "UpperArm",
             "ELB": "Elbow", "FRM": "Forearm", "WRA": "WristA", "WRB": "WristB",
             "FIN": "Finger", "FWT": "FrontWaist", "BWT": "BackWaist", "THI": "Thigh",
             "KNE": "Knee", "SHN": "Shin", "ANK": "Ankle", "HEE": "Heel", "TOE": "Toe",
             "MT5": "MT5", "BAK": "Back", "CLAV": "Clavicle", "STRN": "Sternum"}


def _in_words(name: str) -> str:
    """A Plug-in Gait label (``LKNE``) in :data:`PIG_WORDS` (``LeftKnee``); others as they are."""
    side = {"L": "Left", "R": "Right"}.get(name[:1])
    if name in PIG_WORDS:
        return PIG_WORDS[name]
    return side + PIG_WORDS[name[1:]] if side and name[1:] in PIG_WORDS else name


def test_a_real_capture_in_full_words_is_drafted_as_in_its_own_names(real_c3d):
    # CMU 07_12 (Plug-in Gait's 41 labels) relabelled LeftKnee, RightWristA, Clavicle...:
    # drafted by its words as by its own labels (41 on their landmark), but for the shank
    # markers, whose word Shin names the tibia's crest (the same segment)
    trial = read_c3d(real_c3d("cmu/07_12.c3d"))
    words = [_in_words(name) for name in trial.names]
    assert sum(w != n for w, n in zip(words, trial.names)) == 38   # not C7, T10, RBAC, RWRB1
    renamed = dataclasses.replace(trial, labels=words)
    back = dict(zip(words, trial.labels))
    entries = [dataclasses.replace(e, label=back[e.label])
               for e in draft_protocol(renamed).entries]
    agreement = draft_agreement(entries, trial, detect_protocol(trial))
    assert (agreement.landmark, agreement.segment, agreement.wrong) == (39, 2, 0)
