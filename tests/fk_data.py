"""Forward-kinematics walking data with known joint angles, for the fit tests and benchmark.

A gait-like pose sequence (pelvis travelling along +X, sinusoidal hips, knees, ankles, arms
and trunk) drives a skeleton whose lengths differ from the nominal ones by a few per cent.
Markers sit at the protocol's nominal landmarks moved by a random placement error, then get
soft-tissue-like artefact (smooth displacements of several mm, in the segment's frame, that
follow the motion of the joint driving the segment) and white measurement noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocaplib.model.subject import SubjectModel
from mocaplib.markersets.protocols import load_protocol
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton, SEGMENTS
from mocaplib.trial import Trial

DEG = np.pi / 180
_LIMBS = {"femur": "thigh", "tibia": "shank", "humerus": "upper_arm", "forearm": "forearm"}


def neutral_q(skeleton: Skeleton, n_frames: int = 1) -> np.ndarray:
    """The all-zero pose of ``skeleton`` standing on the floor at the origin, shape (F, D)."""
    q = np.zeros((n_frames, len(DOF_NAMES)))
    q[:, DOF_NAMES.index("pelvis_tz")] = (
        skeleton.lengths["thigh"] + skeleton.lengths["shank"] + skeleton.lengths["ankle_height"])
    return q


def gait_angles(n_frames: int, rate: float, *, speed: float = 1.2, cadence_hz: float = 0.9,
                seed: int = 0) -> np.ndarray:
    """Joint coordinates (F, D) of a steady gait-like motion (radians, metres)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) / rate
    w = 2 * np.pi * cadence_hz
    q = np.zeros((n_frames, len(DOF_NAMES)))

    def put(name, value):
        q[:, DOF_NAMES.index(name)] = value

    phase = rng.uniform(0, 2 * np.pi)
    put("pelvis_tx", speed * t)
    put("pelvis_ty", 0.02 * np.sin(w * t + phase))
    put("pelvis_tz", 0.92 + 0.02 * np.sin(2 * w * t + phase))
    put("pelvis_rotation", 0.1 + 0.08 * np.sin(w * t + phase))
    put("pelvis_list", 4 * DEG * np.sin(w * t + phase + 0.3))
    put("pelvis_tilt", 8 * DEG + 2 * DEG * np.sin(2 * w * t + phase))
    put("trunk_flexion", 3 * DEG + 2 * DEG * np.sin(2 * w * t + phase))
    put("trunk_bending", 2 * DEG * np.sin(w * t + phase))
    put("trunk_rotation", -6 * DEG * np.sin(w * t + phase))
    put("neck_flexion", 5 * DEG * np.sin(w * t + phase + 1.0))
    put("neck_bending", 3 * DEG * np.sin(w * t + phase + 2.0))
    put("neck_rotation", 6 * DEG * np.sin(w * t + phase + 0.5))
    for side, shift in (("r", 0.0), ("l", np.pi)):
        ph = w * t + phase + shift
        put(f"hip_flexion_{side}", 10 * DEG + 25 * DEG * np.sin(ph))
        put(f"hip_adduction_{side}", 3 * DEG * np.sin(ph + 1.0))
        put(f"hip_rotation_{side}", 5 * DEG * np.sin(ph + 0.5))
        put(f"knee_flexion_{side}", 30 * DEG + 28 * DEG * np.sin(ph - 1.2))
        put(f"ankle_dorsiflexion_{side}", 3 * DEG + 12 * DEG * np.sin(ph + 2.0))
        put(f"ankle_inversion_{side}", 4 * DEG * np.sin(ph + 0.7))
        put(f"shoulder_flexion_{side}", -20 * DEG * np.sin(ph))
        put(f"shoulder_abduction_{side}", 8 * DEG + 3 * DEG * np.sin(ph))
        put(f"shoulder_rotation_{side}", 5 * DEG * np.sin(ph + 0.4))
        put(f"elbow_flexion_{side}", 25 * DEG + 12 * DEG * np.sin(ph - 0.5))
    return q


@dataclass
class FKCapture:
    """A synthetic trial and its truth: q (F, D), skeleton, marker segments (M,), offsets (M, 3)."""

    trial: Trial
    q: np.ndarray
    skeleton: Skeleton
    segments: np.ndarray
    offsets: np.ndarray


def fk_trial(*, protocol: str = "fullbody38", n_frames: int = 200, rate: float = 100.0,
             height: float = 1.70, placement_mm: float = 4.0, sta_mm: float = 6.0,
             noise_mm: float = 1.0, seed: int = 0, static: bool = False):
    """An FKCapture: a Trial of noisy FK markers and the truth that made it.

    placement_mm: SD of each marker's fixed placement error; sta_mm: amplitude of the
    soft-tissue artefact; noise_mm: SD of white noise per coordinate.
    """
    rng = np.random.default_rng(seed)
    proto = load_protocol(protocol)
    nominal = Skeleton.from_height(height)
    skeleton = Skeleton({k: v * rng.uniform(0.96, 1.04) for k, v in nominal.lengths.items()})
    q = gait_angles(n_frames, rate, seed=seed)
    if static:
        sway = np.random.default_rng(seed + 1).normal(0, 0.2 * DEG, (n_frames, len(DOF_NAMES)))
        q = neutral_q(skeleton, n_frames) + sway
    segments, offsets = proto.nominal_offsets(height)
    # landmarks on a long bone scale with that bone (the malleolus stays at the ankle)
    for segment, length in _LIMBS.items():
        for side in ("_l", "_r"):
            on = segments == SEGMENT_NAMES.index(segment + side)
            offsets[on] *= skeleton.lengths[length] / nominal.lengths[length]
    offsets = offsets + rng.normal(0, placement_mm / 1000, offsets.shape)
    # soft tissue: a displacement in the segment frame driven by the last DOF of its joint
    driver = np.array([DOF_NAMES.index(SEGMENTS[s].dofs[-1]) for s in segments])
    direction = rng.normal(size=(len(segments), 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    angle = q[:, driver]
    swing = (angle - angle.mean(axis=0)) / (np.ptp(angle, axis=0) + 1e-9)
    sta = (sta_mm / 1000) * swing[..., None] * direction[None]
    T = skeleton.forward(q)[:, segments]
    local = offsets[None] + sta
    X = np.einsum("fmij,fmj->fmi", T[..., :3, :3], local) + T[..., :3, 3]
    X = X + rng.normal(0, noise_mm / 1000, X.shape)
    trial = Trial(X, proto.labels, rate, source=f"fk_{protocol}_{seed}.c3d")
    return FKCapture(trial, q, skeleton, segments, offsets)


def true_model(cap: FKCapture, *, locked=()):
    """The model that generated a fullbody38 ``cap`` (exact skeleton and offsets), as
    :func:`mocaplib.model.calibration.calibrate` returns it."""
    proto = load_protocol("fullbody38")
    return SubjectModel(cap.skeleton, proto, proto.labels, cap.segments, cap.offsets,
                        locked_dofs=list(locked))


def turn_knee_axis(skeleton: Skeleton, segments: np.ndarray, offsets: np.ndarray, side: str,
                   angle: float) -> tuple[Skeleton, np.ndarray]:
    """The model with one knee's flexion axis turned by ``angle`` (radians, the sense of
    ``hip_rotation_<side>``: positive turns it as internal rotation turns the thigh) about the
    femur's long axis, the leg itself unchanged.

    The femur's, tibia's and foot's frames of ``side`` ("l", "r") are turned together about
    the femur's Z axis (all three are parallel in the neutral pose): their markers' offsets
    (M, 3) and the knee and ankle centres (joint shifts) are turned the other way in them, so
    a pose with ``hip_rotation`` larger by ``angle`` puts every marker where it was, while
    the knee (and the ankle, whose frame takes the tibia's flexion axis) now flexes about the
    turned axis. Returns the new skeleton and offsets; ``offsets`` is not modified.
    """
    sign = -1.0 if side == "l" else 1.0         # hip_rotation's axis: -Z left, +Z right
    c, s = np.cos(sign * angle), np.sin(sign * angle)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])      # frame turned by it
    names = [f"{name}_{side}" for name in ("femur", "tibia", "foot")]
    on = np.isin(segments, [SEGMENT_NAMES.index(name) for name in names])
    out = offsets.copy()
    out[on] = offsets[on] @ turn                                      # turn.T @ offset
    joints = skeleton.joint_offsets()
    nominal = Skeleton(skeleton.lengths).joint_offsets()
    shifts = dict(skeleton.shifts)
    for name in names[1:]:
        i = SEGMENT_NAMES.index(name)
        shifts[name] = tuple((joints[i] @ turn - nominal[i]).tolist())
    return Skeleton(skeleton.lengths, shifts), out
