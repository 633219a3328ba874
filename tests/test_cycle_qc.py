"""The per-cycle QC metrics of the build (:func:`mocaplib.gait.qc.cycle_qc`)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mocaplib.model.filtering import WALKING_CUTOFF
from mocaplib.gait.qc import cycle_qc
from mocaplib.skeleton import DOF_NAMES, JOINT_ANGLES, Skeleton


def _motion(q: np.ndarray, rate: float):
    return SimpleNamespace(n_frames=len(q), rate=rate, q=q, residuals=np.zeros((len(q), 4)),
                           rejected=np.zeros((len(q), 4), dtype=bool),
                           trusted=lambda: np.ones(4, dtype=bool),
                           skeleton=Skeleton.from_height(1.75))


@pytest.mark.parametrize("frequency, gain", [
    (2.0, 1.0),                 # well inside the pass band
    (WALKING_CUTOFF, 0.5 ** 0.5),   # the cutoff is the -3 dB point of the whole filter
])
def test_jerk_is_that_of_the_angles_low_passed_at_the_walking_cutoff(frequency, gain):
    rate, amplitude = 500.0, 0.01    # 500 Hz: the centred difference is exact to 0.2 %
    t = np.arange(int(4 * rate)) / rate
    q = np.zeros((len(t), len(DOF_NAMES)))
    q[:, JOINT_ANGLES] = amplitude * np.sin(2 * np.pi * frequency * t)[:, None]
    q[:, DOF_NAMES.index("pelvis_rotation")] = 0.5 * t     # the heading is left out
    cycle = SimpleNamespace(start_s=1.0, end_s=3.0, event_quality=1.0, rise_per_step=0.0, encoding=SimpleNamespace(
        series=SimpleNamespace(rms=np.zeros(len(DOF_NAMES)))))
    jerk = cycle_qc(cycle, _motion(q, rate))["jerk_rms_rad_s3"]
    expected = gain * amplitude * (2 * np.pi * frequency) ** 3 / np.sqrt(2)
    assert jerk == pytest.approx(expected, rel=0.01)


def test_no_jerk_nor_internal_power_for_a_capture_too_short_to_filter():
    q = np.zeros((12, len(DOF_NAMES)))
    cycle = SimpleNamespace(start_s=0.0, end_s=0.11, event_quality=1.0, rise_per_step=0.0, encoding=SimpleNamespace(
        series=SimpleNamespace(rms=np.zeros(len(DOF_NAMES)))))
    qc = cycle_qc(cycle, _motion(q, 100.0))
    assert qc["jerk_rms_rad_s3"] is None and qc["internal_power_w_kg"] is None


def test_internal_power_is_that_of_the_low_passed_motion_relative_to_the_floor():
    from mocaplib.gait.criteria import GRAVITY

    rate, amplitude, w = 200.0, 0.02, 2 * np.pi * 1.0   # 1 Hz bounce: in the pass band
    t = np.arange(int(4 * rate)) / rate
    q = np.zeros((len(t), len(DOF_NAMES)))
    q[:, DOF_NAMES.index("pelvis_tz")] = 0.9 + amplitude * np.sin(w * t)
    cycle = SimpleNamespace(start_s=1.0, end_s=3.0, event_quality=1.0, rise_per_step=0.0, encoding=SimpleNamespace(
        series=SimpleNamespace(rms=np.zeros(len(DOF_NAMES)))))
    fine = np.linspace(0, 2, 100001)
    z_dot, z_ddot = amplitude * w * np.cos(w * fine), -amplitude * w ** 2 * np.sin(w * fine)
    expected = np.mean(np.abs(z_dot * z_ddot + GRAVITY * z_dot))   # W/kg, body mass 1
    assert cycle_qc(cycle, _motion(q, rate))["internal_power_w_kg"] == pytest.approx(
        expected, rel=0.01)
    # on a treadmill belt running backwards at the walking speed, the body stays in place in
    # the lab: its energy is measured relative to the belt, where it moves steadily forwards
    from mocaplib.gait.qc import qc_series

    q[:, DOF_NAMES.index("pelvis_tz")] = 0.9
    q[:, DOF_NAMES.index("hip_flexion_r")] = 0.3 * np.sin(w * t)   # a leg swinging
    motion = _motion(q, rate)
    on_belt = cycle_qc(cycle, motion, qc_series(motion, np.array([-1.3, 0.0, 0.0])))
    q[:, DOF_NAMES.index("pelvis_tx")] = 1.3 * t
    overground = cycle_qc(cycle, _motion(q, rate))
    assert on_belt["internal_power_w_kg"] == pytest.approx(overground["internal_power_w_kg"],
                                                           rel=1e-6)
    assert overground["internal_power_w_kg"] > 0.1



def test_a_marker_qc_failure_names_its_marker_and_when():
    from mocaplib.gait.qc import DEFAULT_QC_THRESHOLDS
    from mocaplib.gait.qc import named_failures

    # 4 markers over 3 s at 100 Hz, the cycle 1-2 s: C's largest residual inside it is at 1.5 s
    # (the 0.09 m at 0.5 s, outside, does not count); D, untrusted, is left out. C stays off
    # for 3 frames, longer than a spike (SPIKE_FRAMES): the marker's, not an outlier's
    residuals = np.full((300, 4), 0.005)
    residuals[149:152, 2], residuals[50, 2], residuals[:, 3] = 0.045, 0.09, 0.2
    residuals[150, 2] = 0.05
    residuals[100:201, 1] = 0.03
    motion = SimpleNamespace(rate=100.0, n_frames=300, residuals=residuals,
                             rejected=np.zeros(residuals.shape, dtype=bool),
                             marker_labels=["A", "B", "C", "D"],
                             trusted=lambda: np.array([True, True, True, False]))
    cycle = SimpleNamespace(start_s=1.0, end_s=2.0)
    qc = {"marker_max_m": 0.05, "marker_rms_m": 0.016, "gap_fraction": 0.0}
    failures = named_failures(cycle, motion, qc, {**DEFAULT_QC_THRESHOLDS, "marker_rms_m": 0.01})
    assert [f.split(": likely ")[0] for f in failures] \
        == ["marker_max_m 0.05 > 0.04 (C at 1.50 s)", "marker_rms_m 0.016 > 0.01 (B)"]
    # each says its likely cause and what to do
    assert all("a marker off its segment for several frames" in f and "check the named "
               "marker's label" in f for f in failures), failures
    # calibrated from the capture itself, that is the likelier cause
    assert "calibrated from the capture itself" in named_failures(
        cycle, motion, qc, DEFAULT_QC_THRESHOLDS, facts={"static": None})[0]
    gaps = named_failures(cycle, motion, {"marker_max_m": 0.01, "gap_fraction": 0.5},
                          {"marker_max_m": 0.04, "gap_fraction": 0.1})
    assert [f.split(": likely ")[0] for f in gaps] == ["gap_fraction 0.5 > 0.1"]


def test_one_bad_marker_sample_is_an_outlier_not_the_cycles_maximum():
    from mocaplib.gait.qc import SPIKE_FRAMES, outlier_samples, qc_series

    # a walk's residuals (2-8 mm, smooth) with one 4.45 cm sample of marker 1 at 1.33 s
    # (the lab file's RANK) and, on marker 2, 5 cm held for 5 frames (a marker knocked)
    rate = 100.0
    t = np.arange(300) / rate
    q = np.zeros((len(t), len(DOF_NAMES)))
    motion = _motion(q, rate)
    motion.residuals = 0.005 + 0.003 * np.sin(2 * np.pi * t)[:, None] * np.ones(4)
    motion.residuals[133, 1] = 0.0445
    motion.residuals[60:65, 2] = 0.05
    outliers = outlier_samples(motion)
    assert np.flatnonzero(outliers.any(axis=1)).tolist() == [133]
    assert SPIKE_FRAMES < 5
    cycle = SimpleNamespace(start_s=1.0, end_s=2.0, event_quality=1.0, rise_per_step=0.0,
                            encoding=SimpleNamespace(series=SimpleNamespace(
                                rms=np.zeros(len(DOF_NAMES)))))
    qc = cycle_qc(cycle, motion, qc_series(motion))
    # the spike left out: the largest residual is the smooth series' own, 8 mm
    assert qc["marker_max_m"] == pytest.approx(0.008, abs=1e-4)
    assert qc["gap_fraction"] == 0.0                   # an outlier is not a gap
    knocked = SimpleNamespace(**{**vars(cycle), "start_s": 0.5, "end_s": 1.0})
    assert cycle_qc(knocked, motion)["marker_max_m"] == pytest.approx(0.05)
    # samples the fit removed (NaN residual, rejected) are outliers too, not gaps
    motion.rejected[150, 0], motion.residuals[150, 0] = True, np.nan
    assert cycle_qc(cycle, motion)["gap_fraction"] == 0.0


def test_a_marker_noisy_throughout_is_not_cleared_as_outliers():
    from mocaplib.gait.qc import SPIKE_SHARE, outlier_samples

    # 25 mm of noise on each coordinate of marker 0's fit: its residuals spike everywhere,
    # and none of them is an outlier; marker 1's one bad sample still is
    rate = 100.0
    motion = _motion(np.zeros((300, len(DOF_NAMES))), rate)
    noise = np.random.default_rng(1).normal(0.0, 0.025, (300, 3))
    motion.residuals = np.full((300, 4), 0.005)
    motion.residuals[:, 0] = np.linalg.norm(noise, axis=1)
    motion.residuals[133, 1] = 0.0445
    spiking = (motion.residuals[:, 0] - np.median(motion.residuals[:, 0]) > 0.01).mean()
    assert spiking > SPIKE_SHARE
    outliers = outlier_samples(motion)
    assert not outliers[:, 0].any() and np.flatnonzero(outliers[:, 1]).tolist() == [133]
    # so are the samples the fit removed from a marker it removes often
    motion.rejected[::10, 2] = True
    assert not outlier_samples(motion)[:, 2].any()
