"""The synthetic walker's motion: pelvis, spine, head and arm patterns, and leg inverse
kinematics, on the generator's own body (:mod:`.bones`).

Gait phase ``phi = 2 pi (t - t_L) / T`` is 0 at a left heel strike. Patterns (amplitudes from
:class:`~mocaplib.synth.gait.GaitParameters`), written as the angles a fit would report
(:mod:`mocaplib.skeleton`'s DOF names, in the conventions of :mod:`.truth`): the pelvis turns
forward on the swing side (``pelvis_rotation`` = heading − A cos phi), drops on the swing side
after heel strike (``pelvis_list``), tilts twice a stride; it sways towards the stance foot and
bounces (lowest in double support when walking, at mid-stance when running). The thorax
counter-rotates, the trunk bends against the pelvic list, the head stays level and looks ahead,
the arms swing opposite the legs with the elbows flexing as the arm comes forward.

Those patterns drive the generator's joints: the pelvis bone carries the pelvis pattern's
frame; the trunk's flexion, bending and rotation are shared by the lumbar (L5/S1,
:data:`LUMBAR_SHARE`) and thoracic (T12/L1) joints; the shoulder girdle protracts with arm
flexion and elevates with abduction (:data:`GIRDLE_GAIN`), and the glenohumeral joint turns so
that the humerus keeps the arm pattern relative to the thorax; the elbows flex about their own
oblique axes, the wrists flex with the swing.

The legs reach the planned rear-foot poses (:mod:`.gait`) by inverse kinematics of the
generator's leg: a ball hip at Bell's centre, the rolling knee, the oblique talocrural,
subtalar and midtarsal axes: seven angles for the six coordinates of the rear foot's pose; of
the poses that reach it, the one with the smallest subtalar and midtarsal turns, to 1e-11 m.
The pelvis height is the highest that keeps every stance hip–ankle distance within the reach of
a knee flexed by :data:`STANCE_KNEE` (walking 8.9°, running 20°, as at a runner's foot
strike). A swing leg planned straighter than that (or beyond reach: the planned
swing path is only a target, the truth is what the leg does) is saturated smoothly (C2) towards
the reach of a knee flexed by :data:`SWING_KNEE_FLOOR`, so the knee slows down as it extends
instead of stopping dead.

The horizontal offset of the pelvis from the reference frame is chosen so that the shoulder
midpoint (the generator's glenohumeral centres), averaged over a stride in the reference
frame, is exactly the reference point: the commanded (v_f, v_l, omega) are then those of the
shoulder midpoint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SynthError
from ..library.command import Command
from ..skeleton import SEGMENT_NAMES, axis_rotation
from .bones import SIDES, Body, BodyPose, ball_angles, turn_vector
from .command import frame_to_world, reference_path, world_to_frame
from .gait import DEG, FLAT, SWING, GaitParameters, foot_trajectory, plan_footprints
from .truth import convention, neutral_pose

#: Knee flexion (rad) of the longest stance leg, per gait: the pelvis is the highest that keeps
#: every stance leg within that knee's reach.
STANCE_KNEE = {"walk": 8.9 * DEG, "run": 20.0 * DEG}
#: Knee flexion a swing leg approaches but never reaches, rad, per gait: walking terminal
#: swing 0–5°, running late swing 10–20°.
SWING_KNEE_FLOOR = {"walk": 3.0 * DEG, "run": 12.0 * DEG}
#: Share of the trunk's flexion, bending and rotation taken at L5/S1 (the rest at T12/L1).
LUMBAR_SHARE = 0.4
#: Shoulder-girdle protraction per radian of arm flexion and elevation per radian of arm
#: abduction (the glenohumeral centre moves ~1.4 cm forward as the arm swings 30° forward).
GIRDLE_GAIN = (0.15, 0.1)
#: Period of the postural sway of a standing subject, s.
SWAY_PERIOD_S = 4.5
#: Amplitude of a standing subject's fore-aft sway about the ankles, rad (quiet standing:
#: a few millimetres at the centre of mass).
SWAY_ANGLE = 0.25 * DEG
#: The leg's joints in the order of the seven angles the leg's inverse kinematics solves.
LEG_JOINTS = (("femur", 3), ("tibia", 1), ("talus", 1), ("foot", 2))
#: The leg's angles (indices into its seven) the redundancy is resolved on: of the poses that
#: reach the foot, the one with the smallest subtalar and midtarsal turns (:func:`_leg_ik`).
_ANKLE_COMPLEX = [5, 6]
#: The leg's solve stops when the rear foot is within this of its pose (m, and m for the
#: orientation weighted by :data:`_TURN_WEIGHT`).
LEG_TOLERANCE = 1e-11
#: ... once the ankle complex's share moves by less than this (rad; the null direction is known
#: to the finite differences' precision)...
SPLIT_TOLERANCE = 1e-8
#: ... and it is an error when the foot is left further than this from its pose (m; a knee
#: near straight converges slowly, and a C3D stores 1/8 mm).
LEG_REACHED = 1e-5
#: Damping of the leg's least-squares steps (a straight knee makes them singular).
_DAMPING = 1e-6
#: Largest change of any leg angle (rad) in one step of Newton's method.
MAX_STEP = 0.2
#: Weight (m/rad) of the rear foot's orientation against its position in the leg's solve.
_TURN_WEIGHT = 0.1


@dataclass
class BodyMotion:
    """The generator's body over time.

    Attributes
    ----------
    time : (F,) s.  pose : :class:`~mocaplib.synth.bones.BodyPose`, every joint of the body.
    contact : (F, 2) foot contact states (see :mod:`.gait`), columns (left, right).
    shoulders : (F, 2, 3) true glenohumeral centres (left, right), m.
    footprints : dict side -> Footprints (empty when standing).
    reference : ((F, 2) m, (F,) rad) the commanded frame.
    """

    time: np.ndarray
    pose: BodyPose
    contact: np.ndarray
    shoulders: np.ndarray
    footprints: dict
    reference: tuple


def _phase(params: GaitParameters, t: np.ndarray) -> np.ndarray:
    return 2 * np.pi * (t - params.t_left) / params.stride


def _patterns(params: GaitParameters, t: np.ndarray, xy: np.ndarray, theta: np.ndarray,
              offset: np.ndarray) -> dict[str, np.ndarray]:
    """The upper body's motion (F,) each, as a fit would report it: the pelvis frame's origin
    (``pelvis_tx/ty``; ``pelvis_tz`` its bounce alone) and angles, the trunk, neck, shoulder and
    elbow DOFs (:mod:`mocaplib.skeleton` names), and ``wrist_l`` / ``wrist_r`` flexion."""
    phi = _phase(params, t)
    run = params.gait == "run"
    mid_stance = np.pi * params.duty
    local = offset + np.stack([np.zeros_like(t), params.sway * np.cos(phi - mid_stance)], -1)
    low = mid_stance if run else np.pi * (params.duty - 0.5)
    bounce = -params.bounce * np.cos(2 * (phi - low))
    pos = frame_to_world(xy, theta, local)
    tilt0 = (8.0 if run else 4.0) * DEG
    A_pr, A_th, A_arm = params.pelvis_rotation, params.thorax_rotation, params.arm_swing
    pelvis_list = params.pelvis_list * np.sin(phi + 0.5)
    tilt_wave = 1.5 * DEG * np.cos(2 * phi)
    out = {
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
    for side, sign in (("l", -1.0), ("r", 1.0)):
        swing = sign * A_arm * np.cos(phi - 0.3)
        out[f"shoulder_flexion_{side}"] = arm_mean + swing
        out[f"shoulder_abduction_{side}"] = ((11.0 if run else 7.0) * DEG
                                             + 1.5 * DEG * np.sin(2 * phi))
        out[f"shoulder_rotation_{side}"] = np.full_like(t, 5.0 * DEG)
        out[f"elbow_flexion_{side}"] = params.elbow + 0.4 * swing
        out[f"wrist_{side}"] = 8.0 * DEG + 0.3 * swing
    return out


def _euler(letters: str, *columns: np.ndarray) -> np.ndarray:
    """Rotations (F, 3, 3) turning about ``letters``' axes (intrinsic) by ``columns`` (F,)."""
    out = np.broadcast_to(np.eye(3), (len(columns[0]), 3, 3))
    for letter, angle in zip(letters, columns):
        out = out @ axis_rotation(np.eye(3)["XYZ".index(letter.upper())] *
                                  (-1.0 if letter.islower() else 1.0), angle)
    return out


def _upper_pose(body: Body, patterns: dict[str, np.ndarray]) -> BodyPose:
    """The body's pose for the upper body's ``patterns`` (:func:`_patterns`), pelvis at the
    bounce's height, the legs at their zero angles (set by :func:`_leg_ik`)."""
    n = len(patterns["pelvis_list"])
    conv = convention(body)
    p = patterns
    pose = BodyPose.zero(body, n)
    pelvis = _euler("ZXY", p["pelvis_rotation"], p["pelvis_list"], p["pelvis_tilt"])
    pose.root_R = pelvis @ conv.turns[0].T
    origin = np.column_stack([p["pelvis_tx"], p["pelvis_ty"], p["pelvis_tz"]])
    pose.root_t = origin - np.einsum("fij,j->fi", pose.root_R, conv.pelvis_origin)
    trunk = np.column_stack([p["trunk_flexion"], p["trunk_bending"], p["trunk_rotation"]])
    pose.angles["lumbar"] = LUMBAR_SHARE * trunk
    pose.angles["thorax"] = (1.0 - LUMBAR_SHARE) * trunk
    pose.angles["head"] = np.column_stack([p["neck_flexion"], p["neck_bending"],
                                           p["neck_rotation"]])
    for side in SIDES:
        flexion, abduction = p[f"shoulder_flexion_{side}"], p[f"shoulder_abduction_{side}"]
        girdle = np.column_stack([GIRDLE_GAIN[0] * flexion, GIRDLE_GAIN[1] * abduction])
        pose.angles[f"girdle_{side}"] = girdle
        bone = body.bones[body.index(f"girdle_{side}")]
        girdle_turn, _ = body.joint_motion(bone, girdle)
        arm = _euler("yxZ" if side == "r" else "yXz", flexion, abduction,
                     p[f"shoulder_rotation_{side}"])
        thorax, humerus = (conv.turns[SEGMENT_NAMES.index(name)]
                           for name in ("torso", f"humerus_{side}"))
        pose.angles[f"humerus_{side}"] = ball_angles(
            np.swapaxes(girdle_turn, 1, 2) @ thorax @ arm @ humerus.T, "humerus", side)
        pose.angles[f"forearm_{side}"] = p[f"elbow_flexion_{side}"][:, None]
        pose.angles[f"hand_{side}"] = p[f"wrist_{side}"][:, None]
    return pose


def shoulder_centres(body: Body, pose: BodyPose) -> np.ndarray:
    """The glenohumeral centres (F, 2, 3) (left, right) of ``pose``, metres."""
    _, t = body.forward(pose)
    return np.stack([t[:, body.index("humerus_l")], t[:, body.index("humerus_r")]], axis=1)


def _stride_grid(params: GaitParameters, samples: int = 200) -> np.ndarray:
    """Times covering one stride uniformly."""
    return params.t_left + params.stride * np.arange(samples) / samples


def _shoulder_offset(params, body, command, t_mid) -> np.ndarray:
    """Mean shoulder midpoint over one stride, in the reference frame, with a centred pelvis."""
    grid = _stride_grid(params)
    xy, theta = reference_path(command, grid, t_mid=t_mid)
    pose = _upper_pose(body, _patterns(params, grid, xy, theta, np.zeros(2)))
    mid = shoulder_centres(body, pose).mean(axis=1)[:, :2]
    return world_to_frame(xy, theta, mid).mean(axis=0)


def leg_reach(body: Body, side: str, knee: float) -> float:
    """Distance (m) from the hip centre to the ankle centre with the knee flexed by ``knee``
    rad (the rolling knee's reach, whatever the hip's angles)."""
    tibia = body.bones[body.index(f"tibia_{side}")]
    talus = body.bones[body.index(f"talus_{side}")]
    turn, shift = body.joint_motion(tibia, np.array([[knee]]))
    return float(np.linalg.norm(tibia.origin + shift[0] + turn[0] @ talus.origin))


def _leg_chain(body: Body, side: str, pelvis_R, pelvis_t, x) -> tuple[np.ndarray, np.ndarray]:
    """The rear foot's rotation (F, 3, 3) and origin (F, 3) for the leg's angles ``x`` (F, 6)
    (:data:`LEG_JOINTS` order) from the pelvis pose."""
    R, t, start = pelvis_R, pelvis_t, 0
    for name, count in LEG_JOINTS:
        bone = body.bones[body.index(f"{name}_{side}")]
        R, t = body.child_pose(bone, R, t, x[:, start:start + count])
        start += count
    return R, t


def _leg_guess(body: Body, side: str, pelvis_R, hip, foot_t, foot_R) -> np.ndarray:
    """A first guess (F, 7) of the leg's angles: the knee from the hip–ankle distance as a
    hinge would have it, the hip turned so that the foot's long axis lies in the knee's plane,
    the talocrural and subtalar angles from the rear foot's turn from the tibia."""
    thigh = float(np.linalg.norm(body.bones[body.index(f"tibia_{side}")].origin))
    talus = body.bones[body.index(f"talus_{side}")]
    shank = float(np.linalg.norm(talus.origin))
    foot_R = foot_R @ talus.zero.T                   # the foot turned back onto the tibia
    p = foot_t - hip
    d = np.linalg.norm(p, axis=1)
    cos_inner = np.clip((thigh ** 2 + shank ** 2 - d ** 2) / (2 * thigh * shank), -1.0, 1.0)
    knee = np.pi - np.arccos(cos_inner)
    u = np.stack([-shank * np.sin(knee), -thigh - shank * np.cos(knee)], axis=1) / d[:, None]
    e = p / d[:, None]
    y = np.cross(foot_R[:, :, 0], p)
    y /= np.linalg.norm(y, axis=1)[:, None]
    y *= np.sign(np.einsum("fi,fi->f", y, pelvis_R[:, :, 1]))[:, None]
    w = np.cross(y, e)
    femur = np.stack([u[:, :1] * e + u[:, 1:] * w, y, u[:, 1:] * e - u[:, :1] * w], axis=2)
    hip_angles = ball_angles(np.swapaxes(pelvis_R, 1, 2) @ femur, "femur", side)
    tibia = femur @ axis_rotation((0.0, 1.0, 0.0), knee)
    relative = np.swapaxes(tibia, 1, 2) @ foot_R
    s = 1.0 if side == "r" else -1.0
    ankle = np.arctan2(relative[:, 2, 0], relative[:, 0, 0])       # toes up
    inversion = s * np.arctan2(relative[:, 2, 1], relative[:, 2, 2])
    return np.column_stack([hip_angles, knee, ankle, -inversion, np.zeros_like(knee)])


def _leg_ik(body: Body, side: str, pelvis_R, pelvis_t, foot_t, foot_R, *,
            guess: np.ndarray | None = None) -> np.ndarray:
    """The leg's seven angles (F, 7) (:data:`LEG_JOINTS` order) that put the rear foot at
    ``foot_t`` (F, 3) turned to ``foot_R`` (F, 3, 3), the pelvis at ``pelvis_R``,
    ``pelvis_t``, with the subtalar and midtarsal turns closest to the ``guess``'s (F, 7)
    (the one redundant angle: Gauss-Newton steps on the foot's pose, each followed by the
    move along the solutions that brings those turns closest), or, without a guess, the
    smallest ones, starting from :func:`_leg_guess`'s. Raises
    :class:`SynthError` when the solve leaves the foot more than :data:`LEG_REACHED` from its
    pose (a pose the leg cannot reach)."""
    hip = body.child_pose(body.bones[body.index(f"femur_{side}")], pelvis_R, pelvis_t,
                          np.zeros((len(foot_t), 3)))[1]
    x = (_leg_guess(body, side, pelvis_R, hip, foot_t, foot_R) if guess is None
         else guess.copy())
    preferred = np.zeros_like(x) if guess is None else guess
    target_T = np.swapaxes(foot_R, 1, 2)
    step = 1e-7
    size = x.shape[1]
    weight = np.zeros(size)
    weight[_ANKLE_COMPLEX] = 1.0

    def residual(angles):
        R, t = _leg_chain(body, side, pelvis_R, pelvis_t, angles)
        return np.concatenate([t - foot_t, _TURN_WEIGHT * turn_vector(target_T @ R)], axis=1)

    for _ in range(100):
        r = residual(x)
        jacobian = np.empty((len(x), 6, size))
        for k in range(size):
            moved = x.copy()
            moved[:, k] += step
            jacobian[:, :, k] = (residual(moved) - r) / step
        # damped: a straight knee makes the leg's length singular
        inverse = np.swapaxes(jacobian, 1, 2) @ np.linalg.inv(
            jacobian @ np.swapaxes(jacobian, 1, 2) + _DAMPING * np.eye(6))
        move = -np.einsum("fij,fj->fi", inverse, r)
        # along the solutions (the Jacobian's null direction), the smallest ankle turns
        null = np.linalg.svd(jacobian)[2][:, -1]                              # (F, 7)
        along = -(np.sum(null * weight * (x + move - preferred), axis=1)
                  / np.maximum(np.sum(null * weight * null, axis=1), 1e-12))
        move += along[:, None] * null
        if np.abs(r).max() < LEG_TOLERANCE and np.abs(along).max() < SPLIT_TOLERANCE:
            return x
        # far from the solution a full step may overshoot: at most MAX_STEP rad per angle
        x += move * (MAX_STEP / np.maximum(np.abs(move).max(axis=1, keepdims=True), MAX_STEP))
    if np.abs(residual(x)).max() < LEG_REACHED:       # a knee near straight converges slowly
        return x
    raise SynthError(f"the {side} leg cannot reach its planned foot pose "
                     f"(off by {np.abs(r).max() * 1000:.2g} mm)")


def _place_legs(body: Body, pose: BodyPose, feet: dict, stance: dict, gait: str) -> None:
    """Raise the pelvis to the highest that keeps every ``stance`` (side -> (F,) bool) leg
    within reach, saturate the swing legs planned too straight, and set the legs' angles of
    ``pose`` (in place) for the rear-foot poses ``feet`` (side -> (origin (F, 3), R))."""
    R, t = body.forward(pose)
    reach = {side: leg_reach(body, side, STANCE_KNEE[gait]) for side in SIDES}
    floor = {side: leg_reach(body, side, SWING_KNEE_FLOOR[gait]) for side in SIDES}
    lift = np.inf
    for side in SIDES:
        gap = (feet[side][0] - t[:, body.index(f"femur_{side}")])[stance[side]]
        lift = min(lift, float(np.min(np.sqrt(reach[side] ** 2 - (gap[:, :2] ** 2).sum(1))
                                      + gap[:, 2])))
    lift -= 2e-4   # the stride grid samples the reach limit; keep 0.2 mm in hand between samples
    pose.root_t[:, 2] += lift
    for side in SIDES:
        hip = t[:, body.index(f"femur_{side}")] + np.array([0.0, 0.0, lift])
        target, foot_R = feet[side]
        p = target - hip
        d = np.linalg.norm(p, axis=1)
        d0, d1 = reach[side], floor[side]
        beyond = d > d0
        reached = d0 + (d1 - d0) * np.tanh((d[beyond] - d0) / (d1 - d0))
        target = target.copy()
        target[beyond] = hip[beyond] + p[beyond] * (reached / d[beyond])[:, None]
        _set_leg(pose, side, _leg_ik(body, side, pose.root_R, pose.root_t, target, foot_R))


def _set_leg(pose: BodyPose, side: str, angles: np.ndarray) -> None:
    """Set the leg's joint angles of ``pose`` from the seven ``angles`` (F, 7) of
    :data:`LEG_JOINTS`."""
    start = 0
    for name, count in LEG_JOINTS:
        pose.angles[f"{name}_{side}"] = angles[:, start:start + count]
        start += count


def shoulder_path(command: Command, params: GaitParameters, body: Body, t: np.ndarray, *,
                  t_mid: float) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """The glenohumeral centres' horizontal path (F, 2, 2) (left, right; x, y, metres) of a
    walking or running ``command`` at times ``t`` (F,) s, and the commanded frame ((F, 2) m,
    (F,) rad), as :func:`body_motion` has them: the upper body alone, which is all they need
    (the legs set the pelvis's height only)."""
    offset = -_shoulder_offset(params, body, command, t_mid)
    xy, theta = reference_path(command, np.asarray(t, float), t_mid=t_mid)
    pose = _upper_pose(body, _patterns(params, np.asarray(t, float), xy, theta, offset))
    return shoulder_centres(body, pose)[..., :2], (xy, theta)


def body_motion(command: Command, params: GaitParameters, body: Body, t: np.ndarray, *,
                t_mid: float) -> BodyMotion:
    """The body at times ``t`` (F,) s for a command; the reference frame is at the origin facing
    +X at ``t_mid``. The pelvis height is set over one whole stride, so it does not depend on
    which times are asked for."""
    if params.gait == "stand":
        return _neutral_stance(command, body, np.asarray(t, float), t_mid=t_mid)
    offset = -_shoulder_offset(params, body, command, t_mid)
    n = len(t)
    tt = np.concatenate([np.asarray(t, float), _stride_grid(params)])
    xy, theta = reference_path(command, tt, t_mid=t_mid)
    pose = _upper_pose(body, _patterns(params, tt, xy, theta, offset))

    def nominal(times):
        fxy, fth = reference_path(command, times, t_mid=t_mid)
        return frame_to_world(fxy, fth, np.broadcast_to(offset, fxy.shape)), fth

    feet, footprints, contact = {}, {}, {}
    for side in SIDES:
        footprints[side] = plan_footprints(params, nominal, side, float(tt.min()),
                                           float(tt.max()))
        origin, R, mtp, state = foot_trajectory(footprints[side], tt, params, body.feet[side])
        feet[side] = (origin, R)
        pose.angles[f"toes_{side}"] = mtp[:, None]
        contact[side] = state
    grid = np.arange(len(tt)) >= n
    _place_legs(body, pose, feet, {s: grid & (contact[s] != SWING) for s in SIDES},
                params.gait)
    pose = pose.take(slice(0, n))
    return BodyMotion(time=np.asarray(t, float), pose=pose,
                      contact=np.stack([contact["l"][:n], contact["r"][:n]], axis=1),
                      shoulders=shoulder_centres(body, pose), footprints=footprints,
                      reference=(xy[:n], theta[:n]))


def _neutral_stance(command: Command, body: Body, t: np.ndarray, *, t_mid: float) -> BodyMotion:
    """Standing still in the neutral pose (:func:`mocaplib.synth.truth.neutral_pose`), as for
    a static calibration trial, with a fore-aft sway of the body about the ankles: the pelvis
    tilts by :data:`SWAY_ANGLE` sin 2πt/:data:`SWAY_PERIOD_S` about the line through the ankle
    centres, the upper body with it, and the legs keep the feet flat and still. The ankle
    centres' midpoint stands on the reference point."""
    n = len(t)
    xy, theta = reference_path(command, t, t_mid=t_mid)
    pose = neutral_pose(body, n)
    R, origin = body.forward(pose)
    feet = {side: (origin[:, body.index(f"foot_{side}")], R[:, body.index(f"foot_{side}")])
            for side in SIDES}
    ankles = 0.5 * (feet["l"][0] + feet["r"][0])
    heading = axis_rotation((0.0, 0.0, 1.0), theta)
    sway = heading @ axis_rotation((0.0, 1.0, 0.0), SWAY_ANGLE * np.sin(2 * np.pi * t /
                                                                         SWAY_PERIOD_S))
    target = np.column_stack([xy, ankles[:, 2]])
    pose.root_R = sway @ pose.root_R
    pose.root_t = target + np.einsum("fij,fj->fi", sway, pose.root_t - ankles)
    for side in SIDES:
        foot_t = target + np.einsum("fij,fj->fi", heading, feet[side][0] - ankles)
        neutral = np.concatenate([pose.angles[f"{name}_{side}"] for name, _ in LEG_JOINTS], 1)
        _set_leg(pose, side, _leg_ik(body, side, pose.root_R, pose.root_t, foot_t,
                                     heading @ feet[side][1], guess=neutral))
    return BodyMotion(time=t, pose=pose, contact=np.full((n, 2), FLAT),
                      shoulders=shoulder_centres(body, pose), footprints={},
                      reference=(xy, theta))
