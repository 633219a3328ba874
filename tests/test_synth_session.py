"""Synthetic sessions: marker placement shared by a session's captures; a neutral static trial."""

from __future__ import annotations

import numpy as np

from mocaplib.protocols import load_protocol
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES
from mocaplib.synth import Command, MarkerSettings, synthesize_capture
from mocaplib.synth.body import SWAY_ANGLE

#: Placement only: no soft tissue, no noise, so a marker's segment-frame position is exact.
PLACEMENT_ONLY = MarkerSettings(soft_tissue=0.0, noise_sd=0.0)
#: Segments whose markers the generator's extra joints (toes, girdle, wrist) never move (the
#: acromions, on the torso, follow the shoulder girdle and are left out).
RIGID = ("pelvis", "torso", "femur_l", "femur_r", "tibia_l", "tibia_r")


def _local_markers(cap) -> tuple[np.ndarray, np.ndarray]:
    """Markers on :data:`RIGID` segments in their segment frames (F, M, 3), and the nominal."""
    protocol = load_protocol("fullbody38")
    segments, nominal = protocol.nominal_offsets(1.75)
    keep = np.isin(segments, [SEGMENT_NAMES.index(s) for s in RIGID]) & np.array(
        [not m.landmark.name.endswith("_ACROMION") for m in protocol.markers])
    T = cap.skeleton.forward(cap.body.q)[:, segments[keep]]
    x = cap.trial.markers[:, keep]
    return np.einsum("fmji,fmj->fmi", T[..., :3, :3], x - T[..., :3, 3]), nominal[keep]


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
    q = cap.body.q
    root = [DOF_NAMES.index(n) for n in ("pelvis_tx", "pelvis_ty", "pelvis_tz",
                                         "pelvis_rotation", "pelvis_tilt")]
    sway = [DOF_NAMES.index(n) for n in ("ankle_dorsiflexion_l", "ankle_dorsiflexion_r")]
    others = np.setdiff1d(np.arange(len(DOF_NAMES)), root + sway)
    assert np.all(q[:, others] == 0.0), "every joint but the ankles' sway is exactly neutral"
    # the sway tilts the rigid body about the ankles: pelvis tilt = ankle angle, both small
    np.testing.assert_allclose(q[:, sway], q[:, [root[4]] * 2], atol=1e-15)
    assert 0.5 * SWAY_ANGLE < np.abs(q[:, sway]).max() <= SWAY_ANGLE
    assert not cap.truth["events"] and not cap.truth["cycles"]
