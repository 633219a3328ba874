"""One capture workflow: ``mocaplib fit`` and ``mocaplib build`` calibrate and fit a capture
through the same :func:`mocaplib.model.fitting.fit_capture`, with the same warnings."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.errors import CalibrationError
from mocaplib.model.fitting import fit_capture
from mocaplib.io.c3d import read_c3d
from mocaplib.build.settings import BuildSettings
from mocaplib.markersets.matching import match_trial
from mocaplib.trial import Trial
from mocaplib.build.workflow import process_capture


def test_the_build_fits_a_capture_as_fit_capture_does_and_says_what_it_says(real_c3d):
    # PiG_Motion-FlatFoot-Full: a real walk whose foot markers cannot see the ankle inversion
    path = real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d")
    fitted = fit_capture(read_c3d(path))
    assert any("cannot see" in note and "ankle_inversion" in note for note in fitted.warnings)
    result = process_capture(path, BuildSettings())
    assert result.ok, result.error
    for note in fitted.warnings:
        assert note in result.warnings


def test_points_outside_the_protocol_neither_sway_the_cutoff_nor_change_the_fit(sample_dir):
    # a model's virtual points or another subject's markers (here 12 points jittering at
    # 20 Hz, which judged with the markers would raise the cutoff) are left out from the start
    trial = read_c3d(sample_dir / "walk_straight_normal.c3d")
    t = trial.time[:, None, None]
    jitter = 0.01 * np.sin(2 * np.pi * 20.0 * t + np.arange(36).reshape(1, 12, 3))
    wide = Trial(np.concatenate([trial.markers, 1.0 + jitter], axis=1),
                 trial.labels + [f"V{i:03d}" for i in range(12)], trial.rate,
                 source=trial.source)
    alone, among = fit_capture(trial), fit_capture(wide)
    assert among.cutoff == alone.cutoff
    np.testing.assert_array_equal(among.motion.q, alone.motion.q)


def test_a_static_of_another_subject_fails_unless_the_caller_falls_back(real_c3d):
    walk = read_c3d(real_c3d("motonms_unipd/Walking1.c3d"))
    other = read_c3d(real_c3d("biomechzoo/HC030A01.c3d"))        # another lab, another subject
    own = read_c3d(real_c3d("motonms_unipd/Static1.c3d"))
    with pytest.raises(CalibrationError, match="HC030A01.c3d"):
        fit_capture(walk, static=[other])
    fell_back = fit_capture(walk, static=[other], fallback=True)
    assert fell_back.static is None and fell_back.model.source in (None, walk.source)
    assert fell_back.warnings[0].startswith("calibrated from the capture itself: no static "
                                            "shows its subject")
    chosen = fit_capture(walk, static=[other, own], fallback=True)
    assert chosen.static == 1 and chosen.model.source == own.source
    assert not any(n.startswith("calibrated from the capture itself") for n in chosen.warnings)


def test_a_neutral_model_kept_by_the_caller_is_the_one_calibrated_here(sample_dir):
    walk = read_c3d(sample_dir / "walk_straight_normal.c3d")
    rest = read_c3d(sample_dir / "rest.c3d")
    here = fit_capture(walk, static=rest, static_pose="neutral")
    kept = fit_capture(rest, static=rest, static_pose="neutral").model
    calls = []

    def neutral_model(i):
        calls.append(i)
        return kept

    given = fit_capture(walk, protocol=match_trial(walk), static=rest, static_pose="neutral",
                        neutral_model=neutral_model)
    assert calls == [0] and given.static == 0 and given.match.protocol.name == \
        here.match.protocol.name
    np.testing.assert_array_equal(given.motion.q, here.motion.q)
