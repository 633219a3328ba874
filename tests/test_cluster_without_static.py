"""A cluster set fitted without a static: functional knee and elbow joints (SCoRE/SARA), the
ankle from the foot's markers fitted to their catalogue layout, on synthetic cluster captures (walk, run, curve) measured against the
generator's truth; the assumptions stated once; a QC failure names its likely cause."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.build.settings import BuildSettings
from mocaplib.build.workflow import process_capture
from mocaplib.library.command import Command
from mocaplib.model.fitting import fit_capture
from mocaplib.model.ik import fit_quality
from mocaplib.model.motion import LIMIT_WARNING_SHARE
from mocaplib.skeleton import DOF_NAMES
from mocaplib.synth.capture import synthesize_capture, write_capture

#: name -> (command, duration s, seed): the captures of the brief.
CAPTURES = {"walk": (Command.from_kind("straight", speed=1.2), 3.0, 2),
            "run": (Command.from_kind("run", speed=2.5), 1.95, 65),
            "curve": (Command.from_kind("curve", speed=1.0, radius=2.0, side="left"), 3.6, 12)}
LEG_FLEXION = [f"{joint}_{side}" for joint in ("hip_flexion", "knee_flexion",
                                               "ankle_dorsiflexion") for side in ("l", "r")]
#: Target RMS error (degrees) of each leg flexion DOF against the truth, without a static.
LEG_TARGET = 3.0
#: Measured: the largest leg flexion RMS error per capture (degrees) and its DOF.
LEG_MEASURED = {"walk": 2.9, "run": 4.6, "curve": 2.3}


@pytest.fixture(scope="module")
def fitted():
    """name -> (capture, FittedCapture), calibrated from the capture itself."""
    out = {}
    for name, (command, duration, seed) in CAPTURES.items():
        capture = synthesize_capture(command, duration=duration, seed=seed,
                                     protocol="cluster_fullbody", session_seed=2010)
        out[name] = capture, fit_capture(capture.trial)
    return out


def _leg_errors(capture, done) -> dict[str, float]:
    """RMS error (degrees) of each leg flexion DOF against the generator's truth."""
    error = np.degrees(done.motion.q - capture.truth["angles"]["values"])
    return {dof: float(np.sqrt(np.mean(error[:, DOF_NAMES.index(dof)] ** 2)))
            for dof in LEG_FLEXION}


@pytest.mark.parametrize("name", sorted(CAPTURES))
def test_a_cluster_capture_without_static_is_plausible(fitted, name):
    capture, done = fitted[name]
    # marker RMS within QC's 20 mm (measured 3.9 walk, 5.7 run, 2.7 curve); and the tighter
    # 10 mm the cluster set meets with a static
    assert fit_quality(done.motion)["marker_rms_mm"] <= 10.0
    # no DOF pushed against a joint limit (the knee at 149° of a 150° limit, before)
    shares = done.motion.limit_shares()
    assert max(shares.values(), default=0.0) <= LIMIT_WARNING_SHARE, shares
    # the knees are hinged on their functional axes, the ankles placed by the foot's markers
    for side in ("l", "r"):
        assert "SARA" in done.model.centre_methods[f"knee_{side}"]
        assert done.model.centre_methods[f"ankle_{side}"].startswith("the foot's markers")


@pytest.mark.parametrize("name", [
    pytest.param(name, marks=pytest.mark.xfail(strict=True, reason=(
        f"measured largest leg flexion RMS error {LEG_MEASURED[name]}° (target {LEG_TARGET}°): "
        + "the run's left ankle dorsiflexion, 4.3° too little throughout (knees 1.0-1.8°): "
          "its SCoRE knee centre lies 16 mm behind the epicondyles' midpoint, tilting the "
          "shank's axis")) if LEG_MEASURED[name] > LEG_TARGET else ())
    for name in sorted(CAPTURES)])
def test_leg_flexion_without_static_within_target(fitted, name):
    errors = _leg_errors(*fitted[name])
    assert max(errors.values()) <= LEG_TARGET, errors


@pytest.mark.parametrize("name", sorted(CAPTURES))
def test_leg_flexion_without_static_no_worse_than_measured(fitted, name):
    errors = _leg_errors(*fitted[name])
    # the heel's offset turned by the foot's nominal fit places the run's ankles 39 mm off:
    # 7.1° on the run; without the functional axes: knee 10.2°, ankle 15.9° on the walk
    assert max(errors.values()) <= LEG_MEASURED[name] + 0.5, errors


def test_the_assumptions_are_stated_once(fitted):
    _, done = fitted["walk"]
    stated = [w for w in done.warnings if w.startswith("cluster set without a static")]
    assert len(stated) == 1, done.warnings
    assert "segment zero poses are assumed" in stated[0] and "SCoRE" in stated[0]
    assert done.joint_centres_from_motion


def test_a_qc_failure_of_a_cluster_capture_without_static_names_the_cause(tmp_path, fitted):
    capture, _ = fitted["walk"]
    path, _ = write_capture(capture, tmp_path, "walk")
    # a marker RMS limit no fit meets makes every cycle fail QC
    thresholds = {**BuildSettings().qc_thresholds, "marker_rms_m": 1e-4}
    result = process_capture(path, BuildSettings(qc_thresholds=thresholds))
    assert not result.entries
    assert result.provenance["joint_centres"] == "the motion"
    assert "likely a cluster set without a static" in result.no_entry, result.no_entry
    assert "--static" in result.no_entry.split("likely a cluster set")[1]
