"""Marker-set protocols: loading, matching, model outputs, detection and left/right swaps."""

from __future__ import annotations

import warnings
from functools import lru_cache

import numpy as np
import pytest

from conftest import REPO, real_files
from protocol_trials import select, walker_trial

from mocaplib.errors import ProtocolError
from mocaplib.io.c3d import read_c3d
from mocaplib.markersets.protocols import list_protocols, load_protocol
from mocaplib.markersets.matching import detect_protocol, is_model_output, is_numbered_point, match_protocol
from mocaplib.markersets.matching import find_side_swaps
from mocaplib.trial import Trial

#: The protocol each real file must be detected as (see protocols/*.toml and SOURCES.md).
EXPECTED = {
    "biomechzoo/HC030A01.c3d": "plugin_gait_ofm",
    "biomechzoo/HC030A05.c3d": "plugin_gait_ofm",
    "biomechzoo/HC030A22.c3d": "plugin_gait_ofm",
    "btkdata/Gait.c3d": "helen_hayes",
    "btkdata/PiG_Calibration-FlatFoot-One.c3d": "plugin_gait",
    "btkdata/PiG_Calibration2-NoOption.c3d": "plugin_gait",
    "btkdata/PiG_Motion-FlatFoot-Full.c3d": "plugin_gait",
    "c3dviewer_examples/running.c3d": "pig_running30",
    "cmu/07_01.c3d": "plugin_gait",
    "cmu/07_12.c3d": "plugin_gait",
    "cmu/16_07.c3d": "plugin_gait",
    "ezc3d_testfiles/BTS.c3d": "bts_cluster",
    "ezc3d_testfiles/FP_Type1.c3d": "bts_davis",
    "ezc3d_testfiles/Qualisys.c3d": "qualisys_cast",
    "motonms_unipd/Static1.c3d": "padova30",
    "motonms_unipd/Walking1.c3d": "padova30",
    "motonms_unipd/Walking3.c3d": "padova30",
}


@lru_cache(maxsize=None)
def _read(path) -> Trial:
    return read_c3d(path)


# ---------------------------------------------------------------- shipped files
def test_every_shipped_protocol_loads_and_every_required_landmark_set_is_usable():
    names = list_protocols()
    assert set(EXPECTED.values()) | {"fullbody38"} <= set(names)
    for name in names:
        protocol = load_protocol(name)
        assert protocol.name == name
        sides = {m.landmark.name[:2] for m in protocol.markers if m.required}
        # the pipeline needs both sides: shoulders, pelvis, knee, heel on L_ and R_
        assert {"L_", "R_"} <= sides, name
        required = {m.landmark.name for m in protocol.markers if m.required}
        assert {"L_ACROMION", "R_ACROMION", "L_HEEL", "R_HEEL"} <= required, name
        # each knee: its lateral marker, or clusters on the thigh and shank (their static
        # places the knee, cluster_fullbody)
        tracked = {m.landmark.segment for m in protocol.markers if m.tracking}
        for side in "LR":
            assert (f"{side}_KNEE_LAT" in required
                    or {f"femur_{side.lower()}", f"tibia_{side.lower()}"} <= tracked), name


def test_extends_inherits_and_overrides():
    ofm, pig = load_protocol("plugin_gait_ofm"), load_protocol("plugin_gait")
    # OFM labels the 5th metatarsal head D5M: its entry replaces PiG's LMT5 on that landmark
    assert set(pig.labels) - {"LMT5", "RMT5"} <= set(ofm.labels)
    assert {"LMT5", "RMT5"}.isdisjoint(ofm.labels) and ofm.marker("LD5M").landmark.name == "L_MT5"
    assert dict(ofm.any_of)["pelvis_back"] == ("LPSI", "RPSI", "SACR")
    # OFM has its own shin marker, so the overriding LTIB entry drops PiG's LSHN alias
    assert "LSHN" in pig.marker("LTIB").keys and ofm.marker("LTIB").aliases == ()
    assert ofm.marker("LSHN").landmark.name == "L_SHIN"


# ---------------------------------------------------------------- real files
def test_every_real_file_has_an_expected_protocol(shared_c3d):
    found = {p.relative_to(shared_c3d).as_posix() for p in real_files()}
    assert found == set(EXPECTED)


@pytest.mark.parametrize("relative", sorted(EXPECTED))
def test_real_file_detects_its_protocol_with_all_required_landmarks(relative, real_c3d):
    trial = _read(real_c3d(relative))
    match = detect_protocol(trial)
    assert match.protocol.name == EXPECTED[relative]
    assert match.complete, match.missing_landmarks
    assert match.missing_landmarks == []
    if relative == "motonms_unipd/Walking3.c3d":
        assert len(match.swaps) == 1 and match.swaps[0].startswith(
            "left/right swap suspected: LA (labelled left)")
    else:
        assert match.swaps == (), match.swaps


def test_walking3_swap_is_reported_not_fixed(real_c3d):
    trial = _read(real_c3d("motonms_unipd/Walking3.c3d"))
    before = trial.markers.copy()
    match = detect_protocol(trial)
    assert any("LA (labelled left)" in w and "RA" in w for w in match.warnings)
    # LA is still the marker labelled LA in the file
    assert "LA" in match.protocol.labels
    np.testing.assert_array_equal(match.marker(trial, "LA"), before[:, trial.index("LA")])
    np.testing.assert_array_equal(trial.markers, before)


def test_pig_model_outputs_are_ignored_not_unknown(real_c3d):
    trial = _read(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    match = detect_protocol(trial)
    for label in ("PELO", "PELA", "LFEO", "TRXP", "CentreOfMass"):
        assert label in match.ignored
    assert match.unknown == ()
    zoo = detect_protocol(_read(real_c3d("biomechzoo/HC030A22.c3d")))
    assert {"*179", "LHJC", "LHLX0", "LTIB1", "CentreOfMassFloor"} <= set(zoo.ignored)
    # a label we cannot classify stays visible; so does OFM's LD1M0: it moves with the body
    # and is rigid with no single point (measured 0.6-2.6 mm), as a marker would be
    assert zoo.unknown == ("LD1M0", "RD1M0", "JUG")


def test_duplicates_flagged_and_the_copy_seen_in_most_frames_used(real_c3d):
    trial = _read(real_c3d("btkdata/Gait.c3d"))
    match = detect_protocol(trial)
    assert set(match.duplicates) == {"RKNE", "RANK", "LKNE", "LANK", "RFOO", "LFOO"}
    rkne = [i for i, label in enumerate(trial.labels) if label == "RKNE"]
    # both copies seen in 194 frames: the first of equals
    assert match.indices[match.protocol.labels.index("RKNE")] == rkne[0] < rkne[1]
    # LFOO is a real marker in this set even though PiG uses the name for a model output
    assert "LFOO" not in match.ignored
    assert any("duplicate labels" in w and "seen in most frames" in w for w in match.warnings)
    # a stray first copy holding a three-frame ghost loses to the copy that tracks the knee
    seen = np.flatnonzero(np.isfinite(trial.markers[:, rkne[0], 0]))
    trial.markers[seen[3:], rkne[0]] = np.nan
    match = match_protocol(trial, match.protocol)
    assert match.indices[match.protocol.labels.index("RKNE")] == rkne[1]
    assert "RKNE" in match.duplicates
    # the columns a fit reads: one per protocol marker found, the chosen copy's
    assert len(match.columns) == match.found and rkne[1] in match.columns
    assert rkne[0] not in match.columns


def test_cmu_subject_prefix_and_aliases(real_c3d):
    match = detect_protocol(_read(real_c3d("cmu/07_12.c3d")))
    assert match.protocol.name == "plugin_gait" and match.found == 41
    assert match.unknown == ("liu:RWRB-1",)


# ---------------------------------------------------------------- synthetic trials
def test_labels_match_across_prefixes_spaces_and_case():
    protocol = load_protocol("bts_davis")
    labels = [f"Subject 1:{label.upper().replace(' ', '_')}" for label in protocol.labels]
    match = match_protocol(walker_trial(protocol, labels=labels), protocol)
    assert match.found == len(protocol.markers) and match.complete


def _side_styled(label: str, style: str) -> str:
    """``label`` (``L`` or ``R`` then its stem) with its side written as ``style`` writes it."""
    if label[:1] not in ("L", "R") or len(label) < 3 or label in ("L5",):
        return label
    side, stem, word = label[0], label[1:], {"L": "Left", "R": "Right"}[label[0]]
    return {"suffix": f"{stem}_{side}", "dotted suffix": f"{stem.lower()}.{side.lower()}",
            "word": f"{word} {stem}", "joined word": f"{word}{stem}",
            "word suffix": f"{stem}-{word.upper()}"}[style]


@pytest.mark.parametrize("style", ["suffix", "dotted suffix", "word", "joined word",
                                   "word suffix"])
def test_labels_match_whichever_end_and_word_gives_their_side(style):
    # labs write the side after the name (ASI_L), as a word (Left ASI) or joined (LeftASI):
    # each matches the protocol's LASI, no marker taken for another
    from mocaplib.trial import normalise_label

    protocol = load_protocol("plugin_gait")
    labels = [_side_styled(label, style) for label in protocol.labels]
    assert [normalise_label(x) for x in labels] == [normalise_label(x) for x in protocol.labels]
    trial = walker_trial(protocol, labels=labels)
    match = detect_protocol(trial)
    assert match.protocol.name == "plugin_gait" and match.found == len(protocol.markers)
    assert match.indices == match_protocol(walker_trial(protocol), protocol).indices


def test_a_real_capture_with_its_sides_after_the_names_matches_as_itself(real_c3d):
    # PiG_Motion-FlatFoot-Full relabelled LASI -> ASI_L, LFOA -> FOA_L ...: the same markers
    # in the same columns, and Plug-in Gait's virtual points still known as model outputs
    trial = _read(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    before = detect_protocol(trial)
    trial.labels = [_side_styled(label, "suffix") for label in trial.labels]
    after = detect_protocol(trial)
    assert after.protocol.name == before.protocol.name == "plugin_gait"
    assert after.indices == before.indices
    assert len(after.ignored) == len(before.ignored) and "FOA_L" in after.ignored
    assert after.unknown == before.unknown == ()


@pytest.mark.parametrize("heading", [0.0, 2.5, -1.2, np.pi])
def test_swap_found_whichever_way_the_subject_faces(heading):
    protocol = load_protocol("plugin_gait")
    assert find_side_swaps(walker_trial(protocol, heading=heading),
                           match_protocol(walker_trial(protocol), protocol)) == ()
    for left, right in (("LSHO", "RSHO"), ("LASI", "RASI"), ("LPSI", "RPSI")):
        labels = protocol.labels
        i, j = labels.index(left), labels.index(right)
        labels[i], labels[j] = labels[j], labels[i]
        match = match_protocol(walker_trial(protocol, heading=heading, labels=labels), protocol)
        assert len(match.swaps) == 1 and f"{left} (labelled left)" in match.swaps[0]


def test_no_false_swap_when_standing_still_or_walking_backwards():
    protocol = load_protocol("fullbody38")
    for speed in (0.0, -1.0):
        match = match_protocol(walker_trial(protocol, heading=1.0, speed=speed), protocol)
        assert match.swaps == ()


def test_detection_prefers_the_complete_then_tighter_protocol():
    # fullbody38's 38 labels are all in plugin_gait too: the tie goes to the full match
    assert detect_protocol(walker_trial(load_protocol("fullbody38"))).protocol.name == "fullbody38"
    running = load_protocol("pig_running30")
    assert detect_protocol(walker_trial(running)).protocol.name == "pig_running30"
    # without the shoulders no protocol is complete; the best is still returned, flagged
    pig = load_protocol("plugin_gait")
    keep = [i for i, label in enumerate(pig.labels) if label not in ("LSHO", "RSHO")]
    match = detect_protocol(select(walker_trial(pig), keep))
    assert not match.complete and set(match.missing_landmarks) >= {"L_ACROMION", "R_ACROMION"}


def test_model_output_patterns():
    for label in ("LHipAngles", "Bastian:RKneeMoment", "LGroundReactionForce", "PELO", "HEDA",
                  "*12", "CentreOfMass", "LHJC", "RNormalisedGRF"):
        assert is_model_output(label), label
    for label in ("LASI", "T10", "C7", "L_FM1", "r bar 1", "RFHD", "SCR1", "LA", "LFIN"):
        assert not is_model_output(label) and not is_numbered_point(label), label
    # numbered names are what models and labs both use: the data decide (computed_points)
    for label in ("Justin_Nancy:LFEM12", "LTH1", "LTB3", "th12", "PEL0", "LTIB1"):
        assert not is_model_output(label) and is_numbered_point(label), label


def test_numbered_points_that_move_with_the_body_are_markers():
    protocol = load_protocol("fullbody38")
    trial = walker_trial(protocol, speed=1.2)
    X = trial.markers
    rng = np.random.default_rng(0)
    thigh = X[:, protocol.labels.index("LTHI")]
    # a lab's thigh cluster: three markers near the thigh marker, each with its own noise; a
    # model's virtual point: the knee marker moved by a fixed vector (rigid to the precision)
    cluster = [thigh + (0.03 * k, 0.0, 0.0) + rng.normal(0, 0.0007, thigh.shape) for k in (1, 2, 3)]
    virtual = X[:, protocol.labels.index("LKNE")] + (0.0, 0.0, 0.1)
    extra = Trial(np.concatenate([X, np.stack(cluster + [virtual], axis=1)], axis=1),
                  list(trial.labels) + ["LTH1", "LTH2", "LTH3", "LFEM1"], trial.rate)
    match = match_protocol(extra, protocol)
    assert set(match.unknown) == {"LTH1", "LTH2", "LTH3"} and match.ignored == ("LFEM1",)
    # standing still, nothing tells them apart: the name decides
    still = Trial(np.repeat(extra.markers[:1], 20, axis=0), extra.labels, trial.rate)
    assert set(match_protocol(still, protocol).ignored) == {"LTH1", "LTH2", "LTH3", "LFEM1"}


def test_no_protocol_matches_raises():
    trial = Trial(np.zeros((2, 2, 3)), ["foo", "bar"], 100.0, source="x.c3d")
    with pytest.raises(ProtocolError, match=r"x\.c3d: no protocol matches any marker label"):
        detect_protocol(trial)


# ---------------------------------------------------------------- malformed protocol files
@pytest.mark.parametrize("text, message", [
    ("[markers\nLASI = 1", "not valid TOML"),
    ('name = "x"\n', r"no \[markers\] table"),
    ('[markers]\nLASI = { landmark = "L_NOPE" }\n', "unknown landmark 'L_NOPE'"),
    ('[markers]\nLASI = { landmark = "L_ASIS", required = "yes" }\n', "required must be"),
    ('[markers]\nLASI = { landmark = "L_ASIS", aliases = "RASI" }\n', "aliases must be"),
    ('[markers]\nLASI = { landmark = "L_ASIS", aliases = 3 }\n', "aliases must be"),
    ('[markers]\nLASI = { landmark = [1, 2] }\n', "unknown landmark"),
    ('[markers]\nLASI = "L_ASIS"\nRASI = { landmark = "R_ASIS", aliases = ["lasi"] }\n',
     "used twice: LASI"),
    ('[markers]\nLASI = "L_ASIS"\n[any_of]\nback = ["LPSI"]\n', r"\[any_of\] 'back'"),
    ('extends = "nope"\n[markers]\nLASI = "L_ASIS"\n', "extends 'nope': unknown protocol"),
    ('[markers]\nLASI = "L_ASIS"\n[cycles]\nfallback_starts = ["left_toe_off"]\n',
     r"\[cycles\] fallback_starts must list events among left_heel_strike, right_toe_off, "
     r"right_heel_strike, each once, got \['left_toe_off'\]"),
    ('[markers]\nLASI = "L_ASIS"\n[cycles]\nfallback_starts = "right_toe_off"\n',
     "fallback_starts must list"),
    ('[markers]\nLASI = "L_ASIS"\n[cycles]\nstarts = ["right_toe_off"]\n',
     r"\[cycles\] has no key 'starts'"),
])
def test_malformed_protocol_names_the_file(tmp_path, text, message):
    path = tmp_path / "lab_set.toml"
    path.write_text(text)
    with pytest.raises(ProtocolError, match=message) as info:
        load_protocol(path)
    assert str(info.value).startswith(str(path))


def test_fallback_cycle_starts_are_read_and_inherited(tmp_path):
    assert load_protocol("fullbody38").fallback_starts == ()
    (tmp_path / "runs.toml").write_text(
        'extends = "fullbody38"\n[cycles]\n'
        'fallback_starts = ["right_toe_off", "left_heel_strike"]\n')
    (tmp_path / "child.toml").write_text('extends = "runs.toml"\n[markers]\nC7 = "C7"\n')
    runs, child = load_protocol(tmp_path / "runs.toml"), load_protocol(tmp_path / "child.toml")
    assert runs.fallback_starts == child.fallback_starts == ("right_toe_off", "left_heel_strike")
    assert runs.labels == load_protocol("fullbody38").labels   # [markers] may be left out


def test_extends_loop_is_an_error(tmp_path):
    (tmp_path / "a.toml").write_text('extends = "b.toml"\n[markers]\nC7 = "C7"\n')
    (tmp_path / "b.toml").write_text('extends = "a.toml"\n[markers]\nT10 = "T10"\n')
    with pytest.raises(ProtocolError, match="loops back"):
        load_protocol(tmp_path / "a.toml")


def test_a_technicians_protocol_file(tmp_path):
    path = tmp_path / "mylab.toml"
    path.write_text('name = "mylab"\n[markers]\n'
                    'LSHOULDER = { landmark = "L_ACROMION", required = true }\n'
                    'RSHOULDER = { landmark = "R_ACROMION", required = true }\n'
                    'LHIP = { landmark = "L_ASIS", required = true, aliases = ["LASI"] }\n')
    protocol = load_protocol(path)
    trial = walker_trial(protocol, labels=["lab:L_Shoulder", "lab:R shoulder", "LASI"])
    match = match_protocol(trial, protocol)
    assert match.complete and match.found == 3 and match.swaps == ()


def test_the_guide_protocol_example_matches_its_capture(tmp_path):
    readme = (REPO / "docs" / "guide" / "protocols.md").read_text(encoding="utf-8")
    block = readme.split("<!-- protocol-example -->", 1)[1].split("```toml\n", 1)[1]
    path = tmp_path / "mylab_lower16.toml"
    path.write_text(block.split("```", 1)[0])
    protocol = load_protocol(path)
    labels = ["Anna:" + label.replace(" ", "_").upper() for label in protocol.labels]
    labels[labels.index("Anna:SACRUM")] = "Anna:S1"
    trial = walker_trial(protocol, labels=labels)
    keep = [i for i, label in enumerate(labels) if label != "Anna:L_PSIS"]
    match = detect_protocol(select(trial, keep), protocols=[protocol, load_protocol("plugin_gait")])
    assert match.protocol.name == "mylab_lower16" and match.complete
    assert match.missing == ("L PSIS",) and match.found == 15


# ---------------------------------------------------------------- users' folders, extends
def _user_folder(tmp_path, monkeypatch):
    """A user's folder with a landmark, a protocol using it and a protocol named like a
    shipped one; $MOCAPLIB_PROTOCOLS names it (monkeypatched: restored after the test)."""
    folder = tmp_path / "mylab"
    folder.mkdir()
    (folder / "landmarks.toml").write_text(
        '[GLUTEUS]\nsegment = "pelvis"\nposition = [-0.10, 0.10, -0.02]\nsided = true\n'
        '[C7]\nsegment = "torso"\nposition = [-0.085, 0.0, 0.445]\n')
    (folder / "mylab16.toml").write_text(
        'name = "mylab16"\n[markers]\nLGLU = { landmark = "L_GLUTEUS" }\n'
        'LTH1 = { segment = "femur", side = "left" }\nC7 = "C7"\n')
    (folder / "bts_davis.toml").write_text('[markers]\nC7 = "C7"\n')
    monkeypatch.setenv("MOCAPLIB_PROTOCOLS", str(folder))
    return folder


def test_a_users_folder_adds_protocols_and_landmarks_to_the_shipped_ones(tmp_path, monkeypatch):
    from mocaplib.markersets.protocols import load_landmarks, overrides

    folder = _user_folder(tmp_path, monkeypatch)
    names = list_protocols()
    assert "mylab16" in names and "plugin_gait" in names      # added, nothing taken away
    catalogue = load_landmarks()
    assert catalogue["L_GLUTEUS"].segment == "pelvis" and "L_ASIS" in catalogue
    assert catalogue["C7"].position == (-0.085, 0.0, 0.445)   # the user's entry wins
    mine = load_protocol("mylab16")
    assert mine.marker("LGLU").landmark.name == "L_GLUTEUS"
    assert mine.marker("LTH1").tracking and mine.marker("LTH1").landmark.segment == "femur_l"
    assert len(load_protocol("bts_davis").markers) == 1          # the user's bts_davis wins
    notes = " ".join(overrides())
    assert f"protocol 'bts_davis' of {folder}" in notes and "landmark C7" in notes


def test_protocols_option_adds_a_folder_and_inspect_notes_the_override(tmp_path, monkeypatch,
                                                                        capsys):
    from mocaplib.cli import main
    from mocaplib.io.c3d_write import write_c3d

    folder = _user_folder(tmp_path, monkeypatch)
    monkeypatch.delenv("MOCAPLIB_PROTOCOLS")
    capture = tmp_path / "walk.c3d"
    trial = walker_trial(load_protocol("fullbody38"))
    write_c3d(capture, trial.markers, trial.labels, trial.rate)
    assert main(["inspect", str(capture), "--protocol", "mylab16"]) == 2      # not known yet
    assert "unknown protocol 'mylab16'" in capsys.readouterr().err
    assert main(["inspect", str(capture), "--protocol", "mylab16", "--protocols",
                 str(folder), "--json"]) == 0
    out = capsys.readouterr().out
    assert '"protocol": "mylab16"' in out and "replaces the one of" in out
    assert main(["inspect", str(capture), "--protocols", str(tmp_path / "nope")]) == 2
    assert "protocol folder not found" in capsys.readouterr().err


def test_a_tracking_marker_names_its_segment(tmp_path):
    path = tmp_path / "clusters.toml"
    path.write_text('[markers]\nLTH1 = { segment = "femur", side = "left" }\n'
                    'TRK = { segment = "torso" }\nRSH1 = { segment = "tibia_r" }\n'
                    'LMKN = { landmark = "L_KNEE_MED", static_only = true }\n')
    protocol = load_protocol(path)
    assert [m.landmark.segment for m in protocol.markers] == ["femur_l", "torso", "tibia_r",
                                                              "femur_l"]
    assert [m.tracking for m in protocol.markers] == [True, True, True, False]
    assert protocol.marker("LMKN").static_only
    segments, offsets = protocol.nominal_offsets()
    assert np.isnan(offsets[:3]).all() and np.isfinite(offsets[3]).all()   # never invented
    for text, message in [('X = { segment = "femur" }', "needs side"),
                          ('X = { segment = "femur", side = "up" }', "side must be"),
                          ('X = { segment = "tibia_r", side = "left" }', "unknown segment"),
                          ('X = { landmark = "L_ASIS", static_only = true, required = true }',
                           "cannot be required")]:
        path = tmp_path / f"bad{len(list(tmp_path.iterdir()))}.toml"    # files are read once
        path.write_text(f"[markers]\n{text}\n")
        with pytest.raises(ProtocolError, match=message):
            load_protocol(path)


def test_extends_lets_a_child_relabel_a_parents_landmark(tmp_path):
    path = tmp_path / "child.toml"
    path.write_text('extends = "qualisys_cast"\n[markers]\n'
                    'L_SAE = { landmark = "L_ACROMION", required = true }\n'
                    'L_MT5 = { landmark = "L_MT5" }\n')
    child = load_protocol(path)
    assert "L_SAJ" not in child.labels and child.marker("L_SAE").required
    assert dict(child.any_of)["left_forefoot"] == ("L_FM1", "L_MT5")   # the group follows
    cast = load_protocol("qualisys_cast")
    labels = ["L_SAE" if label == "L_SAJ" else label for label in cast.labels]
    match = match_protocol(walker_trial(cast, labels=labels), child)
    assert match.complete and "L_ACROMION" not in match.missing_landmarks


def _computed_by_definition(trial):
    """computed_points' definition, point by point against every other point, all frames."""
    from mocaplib.markersets.matching import MOVING_EXTENT, RIGID_FRAMES, RIGID_SD, storage_step

    X = trial.markers
    expected = set()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # points never seen: NaN
        extent = np.linalg.norm(np.nanmax(X, axis=0) - np.nanmin(X, axis=0), axis=1)  # (N,)
        bound = max(RIGID_SD, storage_step(X[:, extent > MOVING_EXTENT]))
        for i in range(len(trial.labels)):
            d = np.linalg.norm(X - X[:, i:i + 1], axis=2)                       # (F, N)
            rigid = ((np.nanstd(d, axis=0) < bound)
                     & (np.isfinite(d).sum(axis=0) >= RIGID_FRAMES))
            rigid[i] = False
            if not extent[i] > MOVING_EXTENT or rigid.any():
                expected.add(i)
    return expected


@pytest.mark.parametrize("name", ["cmu/16_07.c3d", "biomechzoo/HC030A05.c3d"])
def test_computed_points_are_those_of_their_definition_pair_by_pair(real_c3d, name):
    # every point a candidate: the shortcuts (the screen on a few frames, one rigid pair
    # settling a point) must change nothing
    from mocaplib.markersets.matching import computed_points

    trial = read_c3d(real_c3d(name))
    expected = _computed_by_definition(trial)
    assert 0 < len(expected) < len(trial.labels)
    assert computed_points(trial, range(len(trial.labels))) == expected


def test_computed_points_stay_computed_in_a_file_that_stores_integers():
    # a C3D storing its coordinates as integers (here 1/4 mm steps, as BTS.c3d's rewritten
    # with write_c3d) rounds every point: two virtual points rigid with each other vary by
    # 0.1 mm (SD) once rounded, over RIGID_SD; a marker's partner on its segment varies by
    # 0.24 mm or more on the real walks, over the storage step
    from mocaplib.markersets.matching import RIGID_SD, computed_points, storage_step

    frames, step = 400, 0.00025
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 1.0, frames)[:, None, None]
    X = rng.uniform(-0.1, 0.1, (1, 6, 3)) + t * np.array([1.2, 0.3, 0.05])
    turn = np.linspace(0.0, 2.0, frames)                                  # rad, a turning body
    X[:, 1] = X[:, 0] + 0.04 * np.stack([np.cos(turn), np.sin(turn), 0.3 + 0 * turn], axis=1)
    X[:, 2:] += rng.normal(0.0, 0.0003, (frames, 4, 3))                  # four markers, loose
    X = np.round(X / step) * step
    assert storage_step(X) == pytest.approx(step)
    d = np.linalg.norm(X[:, 1] - X[:, 0], axis=1)
    assert np.std(d) > RIGID_SD                     # rounded, the virtual pair looks loose
    trial = Trial(markers=X, labels=[f"PT{i}" for i in range(6)], rate=100.0)
    assert computed_points(trial, range(6)) == {0, 1}


def test_a_real_capture_stored_as_integers_tells_its_virtual_points_as_it_does(real_c3d,
                                                                               tmp_path):
    from mocaplib.io.c3d_write import write_c3d

    trial = _read(real_c3d("biomechzoo/HC030A22.c3d"))
    path = write_c3d(tmp_path / "integers.c3d", trial.markers, trial.labels, trial.rate,
                     integer=True)
    rounded = read_c3d(path)
    assert np.nanmax(np.abs(rounded.markers - trial.markers)) > 1e-5        # rounded indeed
    before, after = detect_protocol(trial), detect_protocol(rounded)
    assert after.protocol.name == before.protocol.name
    assert (after.ignored, after.unknown) == (before.ignored, before.unknown)


def test_a_point_rigid_over_the_trial_stays_computed_when_it_jumps_on_the_screened_frames():
    # the quick look at every pair sees only SCREEN_FRAMES frames: a point whose one jump
    # falls on one of them looks loose there though it is rigid over the whole trial (SD 0.8
    # times RIGID_SD); a jittering point is loose everywhere
    from mocaplib.markersets.matching import RIGID_SD, SCREEN_FRAMES, computed_points

    frames = 400
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, frames)[:, None, None]
    X = rng.uniform(-0.1, 0.1, (1, 6, 3)) + t * np.array([1.0, 0.2, 0.0])  # six points walk
    screened = np.linspace(0, frames - 1, SCREEN_FRAMES).round().astype(int)
    towards = X[screened[3], 1] - X[screened[3], 0]
    X[screened[3], 0] -= 0.8 * RIGID_SD * frames ** 0.5 * towards / np.linalg.norm(towards)
    X[:, 5] += rng.normal(0.0, 3 * RIGID_SD, (frames, 3))
    trial = Trial(markers=X, labels=[f"PT{i}" for i in range(6)], rate=100.0)
    spread = np.linalg.norm(X[:, 1] - X[:, 0], axis=1)
    assert np.std(spread) < RIGID_SD < np.std(spread[screened])
    assert computed_points(trial, range(6)) == _computed_by_definition(trial) == {0, 1, 2, 3, 4}


def test_the_landmarks_the_code_reads_come_from_the_catalogues_roles(tmp_path, monkeypatch):
    from mocaplib.gait.feet import foot_landmarks
    from mocaplib.markersets.protocols import load_landmarks, role_landmarks

    assert foot_landmarks()["left"] == ("L_HEEL", ("L_TOE", "L_MT1", "L_MT5", "L_TOE2"))
    assert role_landmarks("pelvis_back") == ("L_PSIS", "R_PSIS", "SACRUM")
    # a lab's catalogue that names the hallux a forefoot point: the events read it, after TOE2
    shipped = (REPO / "protocols" / "landmarks.toml").read_text(encoding="utf-8")
    (tmp_path / "landmarks.toml").write_text(
        shipped.replace('[HALLUX]\n', '[HALLUX]\nrole = "forefoot"\n'), encoding="utf-8")
    monkeypatch.setenv("MOCAPLIB_PROTOCOLS", str(tmp_path))
    assert foot_landmarks()["right"][1] == ("R_TOE", "R_MT1", "R_MT5", "R_HALLUX", "R_TOE2")
    # a role the code does not read is refused, naming it
    (tmp_path / "bad.toml").write_text('[TOE]\nsegment = "foot"\nposition = [0.1, 0.0, 0.0]\n'
                                       'role = "toe"\n', encoding="utf-8")
    with pytest.raises(ProtocolError, match="TOE.*unknown role 'toe'"):
        load_landmarks(tmp_path / "bad.toml")
