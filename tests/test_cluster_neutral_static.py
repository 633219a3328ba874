"""A cluster set with a static in the neutral pose, fitted as every command does
(:func:`mocaplib.model.fitting.fit_capture`): the legs' joints on the static's landmarks,
the leg flexions against the generator's truth, and the anatomical set left as it is."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.library.command import Command
from mocaplib.markersets.protocols import load_protocol
from mocaplib.model.calibration import NEUTRAL_LEG_CENTRES, neutral_joints
from mocaplib.model.fitting import fit_capture
from mocaplib.model.ik import fit, fit_quality
from mocaplib.model.joint_centres import NEUTRAL_CENTRES
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES
from mocaplib.synth.capture import synthesize_capture

SESSION = 2010
#: name -> (command, duration s, seed), as benchmarks/cluster_accuracy.py makes them.
CAPTURES = {"walk": (Command.from_kind("straight", speed=1.2), 3.0, 2),
            "run": (Command.from_kind("run", speed=2.5), 1.95, 65)}
LEG_FLEXION = [f"{joint}_{side}" for joint in ("hip_flexion", "knee_flexion",
                                               "ankle_dorsiflexion") for side in ("l", "r")]


def _static(protocol: str):
    return synthesize_capture(Command.from_kind("rest"), duration=2.0, seed=8,
                              protocol=protocol, session_seed=SESSION)


@pytest.fixture(scope="module")
def fitted():
    """name -> (capture, with the neutral static, without a static), both by fit_capture,
    and "static" -> the static."""
    static = _static("cluster_fullbody")
    out = {}
    for name, (command, duration, seed) in CAPTURES.items():
        capture = synthesize_capture(command, duration=duration, seed=seed,
                                     protocol="cluster_fullbody", session_seed=SESSION)
        out[name] = (capture, fit_capture(capture.trial, static=static.trial,
                                          static_pose="neutral"), fit_capture(capture.trial))
    return {**out, "static": static}


def _leg_errors(capture, done) -> dict[str, float]:
    """RMS error (degrees) of each leg flexion DOF against the generator's truth."""
    error = np.degrees(done.motion.q - capture.truth["angles"]["values"])
    return {dof: float(np.sqrt(np.mean(error[:, DOF_NAMES.index(dof)] ** 2)))
            for dof in LEG_FLEXION}


@pytest.mark.parametrize("name", sorted(CAPTURES))
def test_a_neutral_static_fits_a_cluster_capture_better_than_none(fitted, name):
    capture, with_static, without = fitted[name]
    errors = _leg_errors(capture, with_static)
    # measured 0.9° (walk) and 1.6° (run) at most; with the legs' nominal layout 4.3° and
    # 9.0° (the run's ankle), more than the 2.1° and 4.6° without a static
    assert max(errors.values()) <= 2.0, errors
    assert max(errors.values()) <= max(_leg_errors(capture, without).values()), errors
    # measured 4.2 and 6.5 mm; with the legs' nominal layout 6.7 and 10.0 mm
    assert fit_quality(with_static.motion)["marker_rms_mm"] <= 7.5


def test_a_neutral_static_puts_the_cluster_legs_joints_on_their_landmarks(fitted):
    (_, with_static, _), static = fitted["run"], fitted["static"]
    model = with_static.model
    T = model.skeleton.forward(fit(static.trial, model).q)
    X, labels = static.trial.markers, static.trial.labels
    for segment, (lateral, medial) in {"tibia_l": ("LKNE", "LKNM"), "tibia_r": ("RKNE", "RKNM"),
                                       "foot_l": ("LANK", "LMED"),
                                       "foot_r": ("RANK", "RMED")}.items():
        midpoint = 0.5 * (X[:, labels.index(lateral)] + X[:, labels.index(medial)])
        off = np.linalg.norm(T[:, SEGMENT_NAMES.index(segment), :3, 3] - midpoint, axis=1)
        # measured 1-3 mm (the two sides' shifts are mirrored means); at the nominal layout
        # 24-27 mm above
        assert np.median(off) <= 0.006, (segment, np.median(off))


@pytest.mark.parametrize("protocol, legs", [("cluster_fullbody", True), ("fullbody38", False)])
def test_only_a_set_that_follows_the_legs_by_clusters_moves_their_joints(protocol, legs):
    # the anatomical set's knee and ankle markers stay on for the motion: its legs keep the
    # nominal layout (ankle inversion's error grows as the pivot drops, NEUTRAL_CENTRES)
    proto = load_protocol(protocol)
    command, duration, seed = CAPTURES["walk"]
    motion = synthesize_capture(command, duration=duration, seed=seed, protocol=protocol,
                                session_seed=SESSION).trial
    static = _static(protocol).trial
    markers = [m for m in proto.markers if m.label in static.labels]
    segments = np.array([SEGMENT_NAMES.index(m.landmark.segment) for m in markers])
    X_motion = np.full((motion.n_frames, len(markers), 3), np.nan)
    for j, m in enumerate(markers):
        if m.label in motion.labels:
            X_motion[:, j] = motion.markers[:, motion.labels.index(m.label)]
    expected = NEUTRAL_CENTRES + (NEUTRAL_LEG_CENTRES if legs else ())
    assert neutral_joints(markers, segments, X_motion) == expected
