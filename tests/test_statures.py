"""Subjects shorter and taller than the samples' 1.75 m: the subject-scaled skeleton, the fit
and the velocities against their targets (all capture types:
``benchmarks/fit_accuracy.py --only statures``)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import plan_capture

from mocaplib.model.fitting import fit_capture
from mocaplib.io.c3d import read_c3d
from mocaplib.build.settings import BuildSettings
from mocaplib.build.workflow import process_capture
from mocaplib.skeleton import DOF_NAMES

FLEXION = [j for j, n in enumerate(DOF_NAMES)
           if n.startswith(("hip_flexion", "knee_flexion", "ankle_dorsiflexion"))]
OTHER = [j for j, n in enumerate(DOF_NAMES) if j not in FLEXION and not n.startswith("pelvis_t")]


def _stature_fit(tmp_path, height):
    """The straight walk of a subject ``height`` m tall fitted as build does it: the model
    and each DOF's RMS error (deg) against the truth, and the truth's standing hip height."""
    static, rest = plan_capture("rest", height, tmp_path)
    walk, capture = plan_capture("walk_straight_normal", height, tmp_path)
    fitted = fit_capture(read_c3d(walk), static=read_c3d(static), static_pose="neutral")
    motion, model = fitted.motion, fitted.model
    error = motion.q - np.asarray(capture.truth["angles"]["values"])
    standing = rest.truth["angles"]["values"][0][DOF_NAMES.index("pelvis_tz")]
    return model, np.degrees(np.sqrt((error ** 2).mean(axis=0))), standing


@pytest.mark.parametrize("height", [1.55, 1.95])
def test_a_shorter_and_a_taller_subject_get_a_skeleton_of_their_size(tmp_path, height):
    model, _, standing = _stature_fit(tmp_path, height)
    # the calibrated hip height against the generator's (its hip centres as the fit's
    # definitions place them, standing): within 3 %
    assert model.skeleton.lengths["hip_height"] == pytest.approx(standing, rel=0.03)


@pytest.mark.parametrize("height", [
    pytest.param(1.55, marks=pytest.mark.xfail(strict=True, reason=(
        "measured knee flexion 3.26° RMS; other DOFs within 4° (hip rotation 3.15°, "
        "elbow flexion 1.79°; docs/results/fit_accuracy.md)"))),
    pytest.param(1.95, marks=pytest.mark.xfail(strict=True, reason=(
        "measured knee flexion 2.85° RMS; other DOFs within 4° (hip rotation 3.11°, "
        "elbow flexion 1.70°; docs/results/fit_accuracy.md)")))])
def test_a_shorter_and_a_taller_subject_are_fitted_within_the_targets(tmp_path, height):
    # the targets against the independent body's truth, every DOF fitted (not held):
    # flexion within 2°, other DOFs within 4°
    model, rms, _ = _stature_fit(tmp_path, height)
    other = [j for j in OTHER if DOF_NAMES[j] not in model.unobservable]
    assert rms[FLEXION].max() <= 2.0, rms[FLEXION].max()
    assert rms[other].max() <= 4.0, rms[other].max()


#: Measured RMS errors (degrees) of the worst flexion and the worst other DOF per height, the
#: strict xfails' figures: a fit that gets worse fails.
STATURE_MEASURED = {1.55: (3.26, 3.15), 1.95: (2.85, 3.11)}


@pytest.mark.parametrize("height", sorted(STATURE_MEASURED))
def test_a_shorter_and_a_taller_subject_are_fitted_no_worse_than_measured(tmp_path, height):
    model, rms, _ = _stature_fit(tmp_path, height)
    other = [j for j in OTHER if DOF_NAMES[j] not in model.unobservable]
    flexion, others = STATURE_MEASURED[height]
    assert rms[FLEXION].max() <= flexion + 0.2, rms[FLEXION].max()
    assert rms[other].max() <= others + 0.2, rms[other].max()


@pytest.mark.parametrize("height", [1.55, 1.95])
def test_a_shorter_and_a_taller_subject_get_their_velocities(tmp_path, height):
    static, _ = plan_capture("rest", height, tmp_path)
    walk, capture = plan_capture("walk_straight_normal", height, tmp_path)
    # the library entry's velocities against the truth cycle it covers (velocity targets)
    result = process_capture(walk, BuildSettings(static=str(static), static_pose="neutral"))
    assert result.ok, result.error
    (entry,) = result.entries
    truth = min(capture.truth["cycles"], key=lambda c: abs(c["start_s"] - entry.start_s))
    assert entry.v == pytest.approx(truth["v"], rel=0.02)
    assert abs(entry.omega - truth["omega"]) < 0.02
    assert abs(entry.v_l - truth["v_l"]) < 0.02
