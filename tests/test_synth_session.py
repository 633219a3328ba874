"""Synthetic sessions: marker placement shared by a session's captures; a neutral static trial."""

from __future__ import annotations

import numpy as np

from mocaplib.markersets.protocols import load_protocol
from mocaplib.skeleton import DOF_NAMES
from mocaplib.library.command import Command
from mocaplib.synth.markers import MarkerSettings
from mocaplib.synth.capture import synthesize_capture
from mocaplib.synth.body import SWAY_ANGLE

#: Placement only: no soft tissue, no noise, so a marker's position on its bone is exact.
PLACEMENT_ONLY = MarkerSettings(soft_tissue=0.0, noise_sd=0.0)
#: Bones of the generator's body (mocaplib.synth.bones) whose markers are checked.
RIGID = ("pelvis", "thorax", "femur_l", "femur_r", "tibia_l", "tibia_r")


def _local_markers(cap) -> tuple[np.ndarray, np.ndarray]:
    """Markers on :data:`RIGID` bones in their bones' frames (F, M, 3), and where the body
    puts their landmarks (M, 3)."""
    protocol = load_protocol("fullbody38")
    body = cap.body
    rigid = {body.index(name) for name in RIGID}
    places = [(m.label, body.landmarks[m.landmark.name]) for m in protocol.markers
              if not m.tracking and body.landmarks[m.landmark.name][0] in rigid]
    bones = np.array([bone for _, (bone, _) in places])
    nominal = np.array([local for _, (_, local) in places])
    R, t = body.forward(cap.motion.pose)
    x = cap.trial.markers[:, [cap.trial.labels.index(label) for label, _ in places]]
    return np.einsum("fmji,fmj->fmi", R[:, bones], x - t[:, bones]), nominal


def _capture(command, seed, session_seed):
    return synthesize_capture(command, duration=2.5, seed=seed, markers=PLACEMENT_ONLY,
                              session_seed=session_seed)


def test_one_session_shares_the_placement():
    walk = _capture(Command.from_kind("straight", speed=1.2), 1, session_seed=7)
    turn = _capture(Command.from_kind("spot_turn", speed=0.9, side="left"), 2, session_seed=7)
    rest = _capture(Command(gait="stand"), 3, session_seed=7)
    (a, nominal), (b, _), (c, _) = map(_local_markers, (walk, turn, rest))
    # the same offset in every frame of every capture of the session (1e-9 m: round-off)
    np.testing.assert_allclose(a, np.broadcast_to(a[0], a.shape), atol=1e-9)
    np.testing.assert_allclose(b[0], a[0], atol=1e-9)
    np.testing.assert_allclose(c[0], a[0], atol=1e-9)
    placement = a[0] - nominal
    # and it is a real placement error: 3 mm sd per axis, clipped at 7.5 mm
    assert 0.0015 < placement.std() < 0.0045 and np.abs(placement).max() <= 0.0075 + 1e-12


def test_without_a_session_each_capture_has_its_own_placement():
    cmd = Command.from_kind("straight", speed=1.2)
    a, nominal = _local_markers(_capture(cmd, 1, session_seed=None))
    b, _ = _local_markers(_capture(cmd, 2, session_seed=None))
    # independent 3 mm draws: their difference has an sd near 4 mm, far from 0
    assert np.abs(a[0] - b[0]).mean() > 0.001


def test_rest_is_a_neutral_static_trial():
    cap = synthesize_capture(Command(gait="stand"), duration=2.0, seed=5, session_seed=1)
    q = np.asarray(cap.truth["angles"]["values"])
    rotations = [j for j, n in enumerate(DOF_NAMES) if not n.startswith("pelvis_t")]
    tilt = DOF_NAMES.index("pelvis_tilt")
    # the first frame is the neutral pose: every joint angle 0 in the fit's conventions (the
    # truth file keeps 1 µrad; the neutral pose is solved to 1e-12)
    assert np.abs(q[0, rotations]).max() <= 2e-6, np.abs(q[0, rotations]).max()
    # then the body sways about the ankles: the pelvis tilts, the legs keep the feet flat with
    # hips, knees and ankles turning less than the sway itself
    assert 0.5 * SWAY_ANGLE < np.abs(q[:, tilt]).max() <= SWAY_ANGLE + 1e-6
    assert np.abs(q[:, rotations]).max() <= SWAY_ANGLE + 1e-6
    assert not cap.truth["events"] and not cap.truth["cycles"]
