"""The synthetic walker's body: pelvis, trunk, head and arm patterns, and leg inverse kinematics.

Gait phase ``phi = 2 pi (t - t_L) / T`` is 0 at a left heel strike. Patterns (amplitudes from
:class:`~mocaplib.synth.gait.GaitParameters`): the pelvis turns forward on the swing side
(``pelvis_rotation`` = heading − A cos phi), drops on the swing side after heel strike
(``pelvis_list``), tilts twice a stride; it sways towards the stance foot and bounces (lowest
in double support when walking, at mid-stance when running). The thorax counter-rotates, the
trunk bends against the pelvic list, the head stays level and looks ahead, the arms swing
opposite the legs with the elbows flexing as the arm comes forward.

The legs reach the planned rear-foot poses by analytic inverse kinematics: the knee angle from
the hip-ankle distance, the hip rotation from the rule that the foot's long axis lies in the
knee's plane, then hip and ankle angles by Euler decomposition in the skeleton's DOF order. The
pelvis height is the highest that keeps every stance hip-ankle distance within
:data:`STANCE_REACH` of the leg length (knee flexed 8.9° or more walking, 20° running). A swing
leg planned straighter than that (or beyond reach: the planned swing path is only a target, the
truth is what the leg does) is saturated smoothly (C2) towards :data:`SWING_KNEE_FLOOR`, so the
knee slows down as it extends instead of stopping dead.

The body is richer than the fitting skeleton: it also has a toe joint (see
:mod:`~mocaplib.synth.gait`), a shoulder girdle that moves the glenohumeral centre (protraction
with arm flexion, elevation with abduction) and wrists. Those are returned apart from ``q``,
which holds the fitting skeleton's 32 DOFs (:data:`mocaplib.skeleton.DOF_NAMES`) exactly.

The horizontal offset of the pelvis from the reference frame is chosen so that the shoulder
midpoint, averaged over a stride in the reference frame, is exactly the reference point: the
commanded (v_f, v_l, omega) are then those of the shoulder midpoint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton, axis_rotation
from .command import Command, frame_to_world, reference_path, world_to_frame
from .gait import (DEG, FLAT, SIDES, SWING, FootGeometry, GaitParameters, foot_trajectory,
                   plan_footprints)

_Q = {name: j for j, name in enumerate(DOF_NAMES)}
_SEG = {name: s for s, name in enumerate(SEGMENT_NAMES)}
#: Longest stance hip–ankle distance, as a fraction of thigh + shank, per gait: the pelvis is
#: the highest that keeps every stance leg within it (knee flexed by at least 8.9° walking,
#: 20° running, as at a runner's foot strike, 15–20°).
STANCE_REACH = {"walk": 0.997, "run": 0.985}
#: Knee flexion a swing leg approaches but never reaches, rad, per gait: walking terminal
#: swing 0–5°, running late swing 10–20°.
SWING_KNEE_FLOOR = {"walk": 3.0 * DEG, "run": 12.0 * DEG}
_LEG_DOFS = ("hip_flexion", "hip_adduction", "hip_rotation", "knee_flexion",
             "ankle_dorsiflexion", "ankle_inversion")
#: Shoulder-girdle motion of the glenohumeral centre in the torso frame, metres for a 1.75 m
#: subject: forward per unit sin(shoulder flexion), up per unit sin(shoulder abduction).
GIRDLE_PROTRACTION, GIRDLE_ELEVATION = 0.02, 0.012
#: Period of the postural sway of a standing subject, s.
SWAY_PERIOD_S = 4.5
#: Amplitude of a standing subject's fore-aft sway about the ankles, rad (quiet standing:
#: a few millimetres at the centre of mass).
SWAY_ANGLE = 0.25 * DEG


@dataclass
class BodyMotion:
    """The generator's body over time.

    Attributes
    ----------
    time : (F,) s.  q : (F, 32) fitting-skeleton DOFs (rad; pelvis_t* m).
    toe : (F, 2) toe-joint dorsiflexion, rad, columns (left, right).
    wrist : (F, 2) wrist flexion, rad.  girdle : (F, 2, 3) glenohumeral-centre shift in the
    torso frame, m.  contact : (F, 2) foot contact states (see :mod:`.gait`).
    shoulders : (F, 2, 3) true glenohumeral centres (left, right), m.
    footprints : dict side -> Footprints (empty when standing).
    reference : ((F, 2) m, (F,) rad) the commanded frame.
    """

    time: np.ndarray
    q: np.ndarray
    toe: np.ndarray
    wrist: np.ndarray
    girdle: np.ndarray
    contact: np.ndarray
    shoulders: np.ndarray
    footprints: dict
    reference: tuple


def _phase(params: GaitParameters, t: np.ndarray) -> np.ndarray:
    return 2 * np.pi * (t - params.t_left) / params.stride


def _upper_body(params: GaitParameters, t: np.ndarray, xy: np.ndarray, theta: np.ndarray,
                offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pelvis (without its height), trunk, head and arm DOFs (F, 32) and wrist angles (F, 2)."""
    phi = _phase(params, t)
    run = params.gait == "run"
    q = np.zeros((len(t), len(DOF_NAMES)))
    mid_stance = np.pi * params.duty
    local = offset + np.stack([np.zeros_like(t), params.sway * np.cos(phi - mid_stance)], -1)
    low = mid_stance if run else np.pi * (params.duty - 0.5)
    bounce = -params.bounce * np.cos(2 * (phi - low))
    pos = frame_to_world(xy, theta, local)
    tilt0 = (8.0 if run else 4.0) * DEG
    A_pr, A_th, A_arm = params.pelvis_rotation, params.thorax_rotation, params.arm_swing
    pelvis_list = params.pelvis_list * np.sin(phi + 0.5)
    tilt_wave = 1.5 * DEG * np.cos(2 * phi)
    set_ = {
        "pelvis_tx": pos[:, 0], "pelvis_ty": pos[:, 1], "pelvis_tz": bounce,
        "pelvis_rotation": theta - A_pr * np.cos(phi),
        "pelvis_list": pelvis_list,
        "pelvis_tilt": tilt0 + tilt_wave,
        "trunk_flexion": params.lean - tilt0 - 0.7 * tilt_wave,
        "trunk_bending": 0.8 * pelvis_list,
        "trunk_rotation": (A_pr + A_th) * np.cos(phi),
        "neck_flexion": -0.6 * params.lean + 1.0 * DEG * np.cos(2 * phi),
        "neck_bending": 0.2 * pelvis_list,
        "neck_rotation": -0.9 * A_th * np.cos(phi),
    }
    arm_mean = (15.0 if run else 2.0) * DEG
    wrist = np.zeros((len(t), 2))
    for col, (side, sign) in enumerate((("l", -1.0), ("r", 1.0))):
        swing = sign * A_arm * np.cos(phi - 0.3)
        set_[f"shoulder_flexion_{side}"] = arm_mean + swing
        set_[f"shoulder_abduction_{side}"] = ((11.0 if run else 7.0) * DEG
                                              + 1.5 * DEG * np.sin(2 * phi))
        set_[f"shoulder_rotation_{side}"] = np.full_like(t, 5.0 * DEG)
        set_[f"elbow_flexion_{side}"] = params.elbow + 0.4 * swing
        wrist[:, col] = 8.0 * DEG + 0.3 * swing
    for name, value in set_.items():
        q[:, _Q[name]] = value
    return q, wrist


def girdle_shift(q: np.ndarray, height: float) -> np.ndarray:
    """Glenohumeral-centre shift (F, 2, 3) in the torso frame (left, right), metres."""
    scale = height / 1.75
    out = np.zeros((len(q), 2, 3))
    for col, side in enumerate(("l", "r")):
        out[:, col, 0] = GIRDLE_PROTRACTION * scale * np.sin(q[:, _Q[f"shoulder_flexion_{side}"]])
        out[:, col, 2] = GIRDLE_ELEVATION * scale * np.sin(
            q[:, _Q[f"shoulder_abduction_{side}"]])
    return out


def true_shoulder_centres(skeleton: Skeleton, q: np.ndarray,
                          girdle: np.ndarray) -> np.ndarray:
    """True glenohumeral centres (F, 2, 3) (left, right) including the girdle shift, metres."""
    T = skeleton.forward(q)
    torso = T[:, _SEG["torso"], :3, :3]
    out = np.stack([T[:, _SEG["humerus_l"], :3, 3], T[:, _SEG["humerus_r"], :3, 3]], axis=1)
    return out + np.einsum("fij,fsj->fsi", torso, girdle)


def _knee_cosine(d, thigh, shank, start, floor):
    """Cosine of the knee's inner angle for hip–ankle distances ``d`` (F,) m: exact while the
    knee is flexed by ``start`` rad or more; a straighter planned leg (even beyond reach) is
    saturated as cos(knee) = c0 + (c1 − c0) tanh((c − c0) / (c1 − c0)) (c0, c1 the cosines of
    ``start`` and ``floor``), equal to the exact value with its first two derivatives at the
    junction, so the knee slows down smoothly and never extends beyond ``floor`` rad."""
    cos_inner = (thigh ** 2 + shank ** 2 - d ** 2) / (2 * thigh * shank)
    c0, c1 = np.cos(start), np.cos(floor)
    beyond = -cos_inner > c0
    saturated = c0 + (c1 - c0) * np.tanh((-cos_inner[beyond] - c0) / (c1 - c0))
    cos_inner[beyond] = -saturated
    return cos_inner, beyond


def _leg_ik(hip, pelvis_R, ankle, foot_R, thigh, shank, side, *, start, floor):
    """Hip (flexion, adduction, rotation), knee flexion, ankle (dorsiflexion, inversion), each
    (F,) rad, putting the ankle centre at ``ankle`` (F, 3) with rear-foot orientation
    ``foot_R`` (F, 3, 3), for a hip at ``hip`` (F, 3) on a pelvis ``pelvis_R`` (F, 3, 3).
    A leg planned straighter than ``start`` rad of knee flexion is saturated towards ``floor``
    (:func:`_knee_cosine`); its ankle then stops short of the plan along the hip–ankle line."""
    s = 1.0 if side == "r" else -1.0
    p = ankle - hip
    d = np.linalg.norm(p, axis=1)
    cos_inner, beyond = _knee_cosine(d, thigh, shank, start, floor)
    reached = np.sqrt(thigh ** 2 + shank ** 2 - 2 * thigh * shank * cos_inner[beyond])
    p[beyond] *= (reached / d[beyond])[:, None]
    d[beyond] = reached
    knee = np.pi - np.arccos(np.clip(cos_inner, -1.0, 1.0))
    u = np.stack([-shank * np.sin(knee), -thigh - shank * np.cos(knee)], axis=1) / d[:, None]
    e = p / d[:, None]
    y = np.cross(foot_R[:, :, 0], p)
    y /= np.linalg.norm(y, axis=1)[:, None]
    y *= np.sign(np.einsum("fi,fi->f", y, pelvis_R[:, :, 1]))[:, None]
    w = np.cross(y, e)
    x = u[:, :1] * e + u[:, 1:] * w
    z = u[:, 1:] * e - u[:, :1] * w
    femur = np.stack([x, y, z], axis=2)
    hip_angles = Rotation.from_matrix(pelvis_R.transpose(0, 2, 1) @ femur).as_euler("YXZ")
    tibia = femur @ axis_rotation((0.0, 1.0, 0.0), knee)
    ankle_angles = Rotation.from_matrix(tibia.transpose(0, 2, 1) @ foot_R).as_euler("YXZ")
    return (-hip_angles[:, 0], s * hip_angles[:, 1], s * hip_angles[:, 2], knee,
            -ankle_angles[:, 0], s * ankle_angles[:, 1])


def _stride_grid(params: GaitParameters, samples: int = 200) -> np.ndarray:
    """Times covering one stride uniformly."""
    return params.t_left + params.stride * np.arange(samples) / samples


def _shoulder_offset(params, skeleton, command, height, t_mid) -> np.ndarray:
    """Mean shoulder midpoint over one stride, in the reference frame, with a centred pelvis."""
    grid = _stride_grid(params)
    xy, theta = reference_path(command, grid, t_mid=t_mid)
    q, _ = _upper_body(params, grid, xy, theta, np.zeros(2))
    mid = true_shoulder_centres(skeleton, q, girdle_shift(q, height)).mean(axis=1)[:, :2]
    return world_to_frame(xy, theta, mid).mean(axis=0)


def body_motion(command: Command, params: GaitParameters, skeleton: Skeleton, height: float,
                t: np.ndarray, *, t_mid: float) -> BodyMotion:
    """The body at times ``t`` (F,) s for a command; the reference frame is at the origin facing
    +X at ``t_mid``. The pelvis height is set over one whole stride, so it does not depend on
    which times are asked for."""
    if params.gait == "stand":
        return _neutral_stance(command, skeleton, height, np.asarray(t, float), t_mid=t_mid)
    geom = FootGeometry.from_skeleton(skeleton)
    offset = -_shoulder_offset(params, skeleton, command, height, t_mid)
    n = len(t)
    tt = np.concatenate([np.asarray(t, float), _stride_grid(params)])
    xy, theta = reference_path(command, tt, t_mid=t_mid)
    q, wrist = _upper_body(params, tt, xy, theta, offset)

    def nominal(times):
        fxy, fth = reference_path(command, times, t_mid=t_mid)
        return frame_to_world(fxy, fth, np.broadcast_to(offset, fxy.shape)), fth

    feet, footprints = {}, {}
    for side in SIDES:
        footprints[side] = plan_footprints(params, nominal, side, float(tt.min()),
                                           float(tt.max()))
        feet[side] = foot_trajectory(footprints[side], tt, params, geom)

    T = skeleton.forward(q)
    pelvis_R = T[:, _SEG["pelvis"], :3, :3]
    hips = {side: T[:, _SEG[f"femur_{side}"], :3, 3] for side in SIDES}
    thigh, shank = skeleton.lengths["thigh"], skeleton.lengths["shank"]
    reach = STANCE_REACH[params.gait] * (thigh + shank)
    lift = np.inf
    for side in SIDES:
        stance = feet[side][3][n:] != SWING
        gap = (feet[side][0] - hips[side])[n:][stance]
        lift = min(lift, float(np.min(np.sqrt(reach ** 2 - (gap[:, :2] ** 2).sum(1))
                                      + gap[:, 2])))
    lift -= 2e-4   # the stride grid samples the reach limit; keep 0.2 mm in hand between samples
    q[:, _Q["pelvis_tz"]] += lift
    start = np.pi - np.arccos((thigh ** 2 + shank ** 2 - reach ** 2) / (2 * thigh * shank))
    for side in SIDES:
        hip = hips[side] + np.array([0.0, 0.0, lift])
        ankle, foot_R = feet[side][:2]
        angles = _leg_ik(hip, pelvis_R, ankle, foot_R, thigh, shank, side, start=start,
                         floor=SWING_KNEE_FLOOR[params.gait])
        for name, value in zip(_LEG_DOFS, angles):
            q[:, _Q[f"{name}_{side}"]] = value
    q, wrist = q[:n], wrist[:n]
    girdle = girdle_shift(q, height)
    return BodyMotion(
        time=np.asarray(t, float), q=q, toe=np.stack([feet["l"][2][:n], feet["r"][2][:n]], 1),
        wrist=wrist, girdle=girdle,
        contact=np.stack([feet["l"][3][:n], feet["r"][3][:n]], axis=1),
        shoulders=true_shoulder_centres(skeleton, q, girdle), footprints=footprints,
        reference=(xy[:n], theta[:n]))


def _neutral_stance(command: Command, skeleton: Skeleton, height: float, t: np.ndarray, *,
                    t_mid: float) -> BodyMotion:
    """Standing still in the anatomical neutral pose, as for a static calibration trial: every
    joint angle 0 (feet parallel under the hips, arms hanging), except a fore-aft sway of the
    rigid body about the ankles (``pelvis_tilt`` = ``ankle_dorsiflexion`` = :data:`SWAY_ANGLE`
    sin 2πt/:data:`SWAY_PERIOD_S`, which keeps the feet flat and fixed). The ankle midpoint
    stands on the reference point."""
    n = len(t)
    xy, theta = reference_path(command, t, t_mid=t_mid)
    sway = SWAY_ANGLE * np.sin(2 * np.pi * t / SWAY_PERIOD_S)
    q = np.zeros((n, len(DOF_NAMES)))
    q[:, _Q["pelvis_rotation"]] = theta
    q[:, _Q["pelvis_tilt"]] = sway
    for side in SIDES:
        q[:, _Q[f"ankle_dorsiflexion_{side}"]] = sway
    T = skeleton.forward(q)
    ankles = 0.5 * (T[:, _SEG["foot_l"], :3, 3] + T[:, _SEG["foot_r"], :3, 3])
    target = np.column_stack([xy, np.full(n, FootGeometry.from_skeleton(skeleton).ankle_height)])
    q[:, [_Q["pelvis_tx"], _Q["pelvis_ty"], _Q["pelvis_tz"]]] = target - ankles
    girdle = girdle_shift(q, height)
    return BodyMotion(time=t, q=q, toe=np.zeros((n, 2)), wrist=np.zeros((n, 2)), girdle=girdle,
                      contact=np.full((n, 2), FLAT),
                      shoulders=true_shoulder_centres(skeleton, q, girdle), footprints={},
                      reference=(xy, theta))
