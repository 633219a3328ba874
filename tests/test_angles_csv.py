"""The joint-coordinate CSV (:mod:`mocaplib.export.angles_csv`) has the bytes pandas writes for
``Motion.angles.to_csv(float_format="%.9g")``; ``Motion.angles`` is ``Motion.q`` at
``Motion.time``."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.cli import main
from mocaplib.errors import MocapError
from mocaplib.export.angles_csv import write_angles_csv
from mocaplib.io.c3d import read_c3d
from mocaplib.model.motion import Motion
from mocaplib.skeleton import DOF_NAMES, Skeleton
from mocaplib.model.fitting import fit_capture


def _pandas_csv(motion: Motion) -> bytes:
    return motion.angles.to_csv(float_format="%.9g").encode("utf-8")


def test_the_fit_command_writes_what_pandas_writes_for_a_capture_with_failed_frames(
        real_c3d, tmp_path):
    path = real_c3d("btkdata/Gait.c3d")
    out = tmp_path / "angles.csv"
    assert main(["fit", str(path), "-o", str(out)]) == 0
    motion = fit_capture(read_c3d(path)).motion
    assert motion.failed.any()     # its first frames show no marker of the model
    assert out.read_bytes() == _pandas_csv(motion)
    # the failed frames' angles are interpolated; left as NaN they are empty fields in both
    motion.q[motion.failed] = np.nan
    write_angles_csv(motion, out)
    assert b",," in out.read_bytes() and out.read_bytes() == _pandas_csv(motion)


def test_special_values_are_written_as_pandas_writes_them(tmp_path):
    rng = np.random.default_rng(4)
    q = rng.normal(scale=2.0, size=(7, len(DOF_NAMES))) * 10.0 ** rng.integers(-12, 12, (7, 1))
    q[1, :3] = [np.nan, np.inf, -np.inf]
    q[2] = np.nan                                       # a whole row missing
    q[3, :4] = [-0.0, 0.0, 1e-300, 5e-324]              # signed zero, tiny and subnormal
    q[4, :3] = [123456789.0, 1234567891.0, 0.1 + 0.2]   # 9 digits exactly, one more, rounding
    motion = Motion(q, Skeleton.from_height(1.75), 120.0)
    out = write_angles_csv(motion, tmp_path / "angles.csv")
    assert out.read_bytes() == _pandas_csv(motion)


def test_the_angles_frame_is_q_at_the_frame_times_and_a_copy():
    q = np.arange(3.0 * len(DOF_NAMES)).reshape(3, -1)
    motion = Motion(q, Skeleton.from_height(1.75), 50.0)
    angles = motion.angles
    assert list(angles.columns) == list(DOF_NAMES) and angles.index.name == "time_s"
    np.testing.assert_array_equal(angles.index, [0.0, 0.02, 0.04])
    np.testing.assert_array_equal(angles.to_numpy(), q)
    angles.iloc[0, 0] = -1.0                      # changing the frame leaves the motion as it was
    assert motion.q[0, 0] == 0.0 and motion.n_frames == 3
    with pytest.raises(MocapError, match=r"Motion\.q must have shape \(F, 32\).*\(3, 5\)"):
        Motion(np.zeros((3, 5)), Skeleton.from_height(1.75), 50.0)
