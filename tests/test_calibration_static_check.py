"""Step 0 of calibration: a static trial must show the motion's subject with the same markers."""

import re

import numpy as np
import pytest
from conftest import SAMPLES, plan_capture

import mocaplib.model.calibration as calibration
from mocaplib.model.calibration import calibrate
from mocaplib.model.calibration_checks import SAME_SUBJECT_LIMIT, check_same_subject
from mocaplib.errors import CalibrationError
from mocaplib.io.c3d import read_c3d
from mocaplib.markersets.protocols import load_protocol
from mocaplib.markersets.matching import match_protocol
from mocaplib.skeleton import SEGMENT_NAMES

REPO = SAMPLES.parent


def _session_rest(tmp_path, height):
    """The sample session's static (same seeds, same marker placement) for a subject of
    ``height`` m, written and read back as a C3D file."""
    return read_c3d(plan_capture("rest", height, tmp_path)[0])


def _distance_gap(static, motion):
    proto = load_protocol("fullbody38")
    segments = np.array([SEGMENT_NAMES.index(m.landmark.segment) for m in proto.markers])
    return check_same_subject(match_protocol(static, proto).markers(static),
                              match_protocol(motion, proto).markers(motion), segments,
                              list(proto.labels), static=static, trial=motion)


@pytest.mark.usefixtures("sample_dir")
def test_the_sessions_own_static_is_accepted():
    motion = read_c3d(SAMPLES / "run_3p5.c3d")
    rest = read_c3d(SAMPLES / "rest.c3d")
    # same subject, same markers: only soft tissue and 0.7 mm noise separate the distances
    # (measured 0.2 mm at most over the 68 captures); the limit is 5 mm
    assert _distance_gap(rest, motion) < 0.001
    model = calibrate(motion, static=rest, static_pose="neutral")
    assert model.source == rest.source


@pytest.mark.usefixtures("sample_dir")
def test_regenerated_static_matches_the_shipped_one(tmp_path):
    # the helper reproduces the session's static: same subject, same placement, accepted
    assert _distance_gap(_session_rest(tmp_path, 1.75), read_c3d(SAMPLES / "run_3p5.c3d")) < 0.001


@pytest.mark.usefixtures("sample_dir")
@pytest.mark.parametrize("height", [1.65, 1.85])
def test_a_static_of_a_differently_sized_subject_is_refused(tmp_path, height):
    # the same session's markers on a subject 10 cm shorter or taller (±6 %): within-segment
    # distances differ by 11 mm (median), over twice the 5 mm limit
    static = _session_rest(tmp_path, height)
    motion = read_c3d(SAMPLES / "walk_straight_normal.c3d")
    with pytest.raises(CalibrationError, match=r"does not match the motion trial .*"
                       r"walk_straight_normal\.c3d.*size ratio") as info:
        calibrate(motion, static=static, static_pose="neutral")
    assert f"rest_{height:.2f}.c3d" in str(info.value)          # both files are named
    assert "leave out --static" in str(info.value)              # and what to do


@pytest.mark.usefixtures("sample_dir")
def test_check_is_skipped_without_enough_pairs():
    # one marker per segment: no within-segment distance to compare, nothing is checked
    X = np.random.default_rng(0).normal(size=(5, 3, 3))
    trial = read_c3d(SAMPLES / "rest.c3d")
    assert np.isnan(check_same_subject(X, 2 * X, np.array([0, 1, 2]), ["A", "B", "C"],
                                       static=trial, trial=trial))


def test_real_static_of_the_same_session_is_accepted(real_c3d):
    motion = read_c3d(real_c3d("motonms_unipd/Walking1.c3d"))
    static = read_c3d(real_c3d("motonms_unipd/Static1.c3d"))
    model = calibrate(motion, static=static)          # measured: 0.7 mm median difference
    assert model.source == static.source


def test_real_static_of_another_person_is_refused(real_c3d):
    # btkdata's PiG static is another subject than PiG_Motion-FlatFoot-Full (ASIS-ASIS 227 mm
    # against 200 mm): within-segment distances differ by 24 mm (median)
    motion = read_c3d(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    static = read_c3d(real_c3d("btkdata/PiG_Calibration2-NoOption.c3d"))
    with pytest.raises(CalibrationError, match="PiG_Calibration2-NoOption.*does not match the "
                                               "motion trial .*PiG_Motion-FlatFoot-Full"):
        calibrate(motion, static=static)


def test_the_quoted_limit_is_the_constant():
    # the module docstring and the user guide state the limit in mm next to the constant's name
    docstring = re.search(r"SAME_SUBJECT_LIMIT`\s+\(([\d.]+) mm\)", calibration.__doc__)
    readme = re.search(r"above\s+\*\*([\d.]+) mm\*\*\s+\(`SAME_SUBJECT_LIMIT`\)",
                       (REPO / "docs" / "guide" / "fitting.md").read_text(encoding="utf-8"))
    assert docstring and readme                       # still quoted where they were
    assert float(docstring.group(1)) / 1000 == pytest.approx(SAME_SUBJECT_LIMIT, abs=1e-12)
    assert float(readme.group(1)) / 1000 == pytest.approx(SAME_SUBJECT_LIMIT, abs=1e-12)
