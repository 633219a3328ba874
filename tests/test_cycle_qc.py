"""The per-cycle QC metrics of the build (:func:`mocaplib.pipeline.cycle_qc`)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from mocaplib.filtering import WALKING_CUTOFF
from mocaplib.pipeline import cycle_qc
from mocaplib.skeleton import DOF_NAMES, JOINT_ANGLES


def _motion(q: np.ndarray, rate: float):
    return SimpleNamespace(n_frames=len(q), rate=rate, q=q, residuals=np.zeros((len(q), 4)),
                           angles=pd.DataFrame(q, columns=DOF_NAMES))


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
    cycle = SimpleNamespace(start_s=1.0, end_s=3.0, event_quality=1.0, encoding=SimpleNamespace(
        series=SimpleNamespace(rms=np.zeros(len(DOF_NAMES)))))
    jerk = cycle_qc(cycle, _motion(q, rate))["jerk_rms_rad_s3"]
    expected = gain * amplitude * (2 * np.pi * frequency) ** 3 / np.sqrt(2)
    assert jerk == pytest.approx(expected, rel=0.01)


def test_no_jerk_for_a_capture_too_short_to_filter():
    q = np.zeros((12, len(DOF_NAMES)))
    cycle = SimpleNamespace(start_s=0.0, end_s=0.11, event_quality=1.0, encoding=SimpleNamespace(
        series=SimpleNamespace(rms=np.zeros(len(DOF_NAMES)))))
    assert cycle_qc(cycle, _motion(q, 100.0))["jerk_rms_rad_s3"] is None
