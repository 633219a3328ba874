"""A real capture stored as other labs store it gives the same joint angles.

Each variant is PiG_Motion-FlatFoot-Full written again (``write_c3d``) with one difference a lab
could produce: labels, units, storage, vertical axis, walking direction, distance from the
origin. Its fit is compared with the fit of the file written again unchanged, DOF by DOF,
leaving out the pelvis translation and heading, which follow where the subject walks.
"""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_write import write_c3d
from mocaplib.skeleton import DOF_NAMES
from mocaplib.model.fitting import fit_capture

SOURCE = "btkdata/PiG_Motion-FlatFoot-Full.c3d"
#: DOFs that do not depend on where the subject walks.
POSTURE = [i for i, name in enumerate(DOF_NAMES)
           if name not in ("pelvis_tx", "pelvis_ty", "pelvis_tz", "pelvis_rotation")]


def _turned(markers, degrees):
    """Markers (F, M, 3) turned about the vertical axis."""
    a = np.radians(degrees)
    turn = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    return markers @ turn.T


#: name: (labels from the original's, markers (m, Z up) from the original's, writer options,
#: tolerance in degrees and why)
VARIANTS = {
    "subject prefix, lower case, padded": (
        lambda labels: [f" Subj01:{label.lower()}  " for label in labels], None, {}, 1e-6),
    # float32 in other units rounds otherwise (measured 2.3e-5 deg)
    "units cm": (None, None, {"units": "cm"}, 1e-3),
    "units m": (None, None, {"units": "m"}, 1e-3),
    # 16-bit integers times a power-of-two scale: quantisation of 1/16 mm (measured 0.05 deg)
    "integer storage": (None, None, {"integer": True}, 0.2),
    "Y up": (None, lambda m: np.stack([m[..., 0], m[..., 2], -m[..., 1]], axis=-1), {}, 1e-6),
    "walking along -X": (None, lambda m: _turned(m, 180.0), {}, 1e-6),
    "walking along Y": (None, lambda m: _turned(m, 90.0), {}, 1e-6),
    # float32 in mm 200 m away: steps of 1/64 mm (measured 0.01 deg)
    "200 m from the origin": (None, lambda m: m + [200.0, -150.0, 0.0], {}, 0.1),
}


@pytest.fixture(scope="module")
def reference(real_c3d, tmp_path_factory):
    """The original trial and the fit of it written again unchanged."""
    original = read_c3d(real_c3d(SOURCE))
    path = tmp_path_factory.mktemp("lab") / "same.c3d"
    same = read_c3d(write_c3d(path, original.markers, original.labels, original.rate))
    return original, fit_capture(same).motion.q


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_a_variant_fits_like_the_original(variant, reference, tmp_path):
    original, expected = reference
    relabel, move, options, tolerance = VARIANTS[variant]
    labels = relabel(original.labels) if relabel else original.labels
    markers = move(original.markers) if move else original.markers
    trial = read_c3d(write_c3d(tmp_path / "variant.c3d", markers, labels, original.rate,
                               **options))
    angles = fit_capture(trial).motion.q
    np.testing.assert_allclose(np.degrees(angles[:, POSTURE]), np.degrees(expected[:, POSTURE]),
                               atol=tolerance, err_msg=variant)
