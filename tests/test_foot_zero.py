"""The foot's zero without a static: the sole's orientation from the frames in which each foot
stands flat on the floor (:func:`mocaplib.model.floor.foot_flat_frames`,
:func:`mocaplib.model.anatomy.flat_soles`), checked against the synthetic captures' true events
and against the fit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mocaplib.io.c3d import read_c3d
from mocaplib.model.fitting import fit_capture
from mocaplib.model.floor import foot_flat_frames
from mocaplib.skeleton import DOF_NAMES

SIDES = {"left": "L", "right": "R"}


def _stances(truth, side, n_frames, rate):
    """(F,) bool: between each true heel-strike of ``side`` and its next toe-off (before
    the first toe-off and after the last heel-strike: the foot is down)."""
    events = sorted((e["time_s"], e["kind"]) for e in truth["events"] if e["side"] == side)
    bounds = [(0.0, "heel_strike")] + events + [(n_frames / rate, "toe_off")]
    inside = np.zeros(n_frames, dtype=bool)
    for (t0, k0), (t1, k1) in zip(bounds, bounds[1:]):
        if (k0, k1) == ("heel_strike", "toe_off"):
            inside[int(np.ceil(t0 * rate)):int(np.floor(t1 * rate)) + 1] = True
    return inside


@pytest.mark.parametrize("name", ["walk_straight_slow", "walk_curve_r2_left_normal",
                                  "side_left_normal", "turn_spot_right_normal"])
def test_a_foot_stands_flat_only_inside_its_stances(sample_dir, name):
    trial = read_c3d(sample_dir / f"{name}.c3d")
    truth = json.loads((sample_dir / f"{name}.truth.json").read_text())
    for side, s in SIDES.items():
        flat = foot_flat_frames(trial.marker(f"{s}HEE"), trial.marker(f"{s}TOE"), trial.rate)
        stance = _stances(truth, side, trial.n_frames, trial.rate)
        assert flat.sum() >= 10, (side, int(flat.sum()))
        # never in a swing, and in the middle of the stances: a fifth of their frames at
        # least (21-27 % measured; the heel rises and the forefoot comes down in the rest)
        assert not (flat & ~stance).any(), (side, np.flatnonzero(flat & ~stance))
        assert flat.sum() >= 0.2 * stance.sum(), (side, int(flat.sum()), int(stance.sum()))


def test_a_foot_in_the_air_or_on_a_moving_belt_never_stands_flat():
    rate, n = 100.0, 200
    t = np.arange(n) / rate
    heel = np.column_stack([0.3 * t, np.zeros(n), 0.03 + 0.05 * (1 + np.sin(6 * t))])
    toe = heel + [0.2, 0.0, -0.01]
    assert not foot_flat_frames(heel, toe, rate).any()           # swinging all the time
    assert not foot_flat_frames(heel[:1], toe[:1], rate).any()   # one frame: nothing to say


@pytest.fixture(scope="module")
def self_calibrated(sample_dir):
    """Four samples fitted without a static, with their true angles."""
    out = {}
    for name in ("walk_straight_normal", "walk_straight_slow", "walk_curve_r2_left_normal",
                 "side_left_normal"):
        truth = json.loads((sample_dir / f"{name}.truth.json").read_text())
        out[name] = (fit_capture(read_c3d(sample_dir / f"{name}.c3d")),
                     np.asarray(truth["angles"]["values"]))
    return out


def test_calibrated_from_itself_the_ankle_reads_the_true_zero(self_calibrated):
    # the samples' left heel and toe markers sit at other heights above the sole, their line
    # rising 1.3° over it where the foot stands flat: along that line the left ankle read
    # 1.3-3.4° more dorsiflexion than the truth (median 1.9°); along the sole 0.1-2.1°
    ankle = DOF_NAMES.index("ankle_dorsiflexion_l")
    errors = [np.degrees(np.mean(fitted.motion.q[:, ankle] - truth[:, ankle]))
              for fitted, truth in self_calibrated.values()]
    assert np.median(np.abs(errors)) <= 1.0, errors
    for fitted, _ in self_calibrated.values():
        zero = [w for w in fitted.warnings if "zero" in w]
        assert len(zero) == 1 and "left flat on the floor in" in zero[0], fitted.warnings
        assert "right flat on the floor in" in zero[0], zero


def test_with_a_static_the_feet_are_flat_on_it_and_no_zero_is_warned(sample_dir):
    fitted = fit_capture(read_c3d(sample_dir / "walk_straight_normal.c3d"),
                         static=read_c3d(sample_dir / "rest.c3d"))
    assert fitted.model.centre_methods["sole_l"] == "flat on the floor in the static"
    assert not [w for w in fitted.warnings if "zero" in w]
