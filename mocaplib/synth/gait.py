"""Gait timing, footprints and foot trajectories of the synthetic walker.

Timing
    Stride period ``T`` (left heel strike to left heel strike) from cadence relations, stance
    fraction (duty factor) ``beta``. Left heel strikes at ``t_L + kT``, left toe-offs
    ``beta T`` later; the right foot is half a stride later. ``t_L`` puts the first left toe-off
    at ``lead`` seconds, so every cycle [left toe-off, next left toe-off) starting at
    ``lead + kT`` is steady (the command is constant and the walker starts in steady state, as
    on a lab walkway).
Footprints
    Each stance's flat-foot pose (ankle centre over the floor, heading) is the pelvis' nominal
    frame at the moment ``plant`` of the stance (a little before mid-stance), shifted sideways
    by half the step width (plus a quarter of the stride's lateral displacement, so side-steps
    open and close without crossing the feet) and toed out.
Feet
    The rear foot (the fitting skeleton's ``foot`` segment) rolls heel to toe: it lands pitched
    toes-up about the heel contact point, lies flat (not moving at all) from ``loading`` to
    ``heel_rise`` of the stance, then rotates about the metatarsal heads while the toe joint
    (a joint the fitting skeleton does not have) keeps the toes flat, until toe-off. In swing
    the ankle follows a cubic Hermite curve, drawn in the moving body frame, between the
    toe-off and heel-strike poses, and is
    lifted so that the lowest sole point (heel, metatarsal heads or toe tip) follows a
    clearance profile; where the heel and the forefoot are nearly level the lowest point is a
    smooth minimum, so the ankle height has no kink when the foot tips from toes-down to
    toes-up.

Angles in radians, lengths in metres, times in seconds. World frame Z up, floor at z = 0.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..skeleton import Skeleton, axis_rotation
from .command import Command, frame_to_world, world_to_frame

DEG = np.pi / 180.0
Y_AXIS, Z_AXIS = (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
SIDES = ("l", "r")
#: Where the first left toe-off falls, seconds after the first frame.
LEAD_S = 0.25
#: Contact states returned by :func:`foot_trajectory`.
SWING, HEEL_CONTACT, FLAT, TOE_CONTACT = 0, 1, 2, 3
#: Height difference (m) within which the swing foot's lowest point passes smoothly from toe
#: tip to metatarsal heads to heel (:func:`_smooth_min`, twice: each lowers the minimum by at
#: most a sixth of it and the two stack, so the ankle rises at most a third of it).
SOLE_BLEND = 0.008


@dataclass(frozen=True)
class FootGeometry:
    """Sole points of the rear foot, in the foot frame (metres), and the toe-joint position.

    ``heel``, ``mtp`` and ``toe`` are x coordinates of the heel contact, metatarsal heads (the
    toe joint) and toe tip; the sole lies at z = ``-ankle_height``.
    """

    heel: float
    mtp: float
    toe: float
    ankle_height: float

    @classmethod
    def from_skeleton(cls, skeleton: Skeleton) -> "FootGeometry":
        length = skeleton.lengths["foot_length"]
        return cls(-0.20 * length, 0.50 * length, 0.76 * length,
                   skeleton.lengths["ankle_height"])

    def sole_points(self, toe_angle: np.ndarray) -> np.ndarray:
        """Heel, metatarsal-head and toe-tip points (F, 3, 3) with toes dorsiflexed by
        ``toe_angle`` (F,) rad, in the rear-foot frame."""
        toe_angle = np.asarray(toe_angle, float)
        lever = self.toe - self.mtp
        z = -self.ankle_height
        out = np.zeros(toe_angle.shape + (3, 3))
        out[..., 0, :] = (self.heel, 0.0, z)
        out[..., 1, :] = (self.mtp, 0.0, z)
        out[..., 2, 0] = self.mtp + lever * np.cos(toe_angle)
        out[..., 2, 2] = z + lever * np.sin(toe_angle)
        return out


@dataclass(frozen=True)
class GaitParameters:
    """Everything the generator derives from the command and the subject (SI units).

    Attributes (timing) ``stride`` s, ``duty`` stance fraction; (feet) ``step_width`` m,
    ``lateral_shift`` m added to both feet's sideways offset, ``toe_out`` rad, ``heel_pitch`` and
    ``toe_pitch`` rad at heel strike and toe-off, ``loading`` and ``heel_rise`` fractions of
    stance, ``plant`` the fraction of stance at which the pelvis passes over the footprint,
    ``clearance`` m; (body) ``bounce`` and ``sway`` m, ``pelvis_rotation``,
    ``pelvis_list``, ``lean`` (trunk flexion), ``thorax_rotation``, ``arm_swing`` and
    ``elbow`` (mean elbow flexion) rad.
    """

    gait: str
    stride: float
    duty: float
    step_width: float
    lateral_shift: float
    toe_out: float
    heel_pitch: float
    toe_pitch: float
    loading: float
    heel_rise: float
    plant: float
    clearance: float
    bounce: float
    sway: float
    pelvis_rotation: float
    pelvis_list: float
    lean: float
    thorax_rotation: float
    arm_swing: float
    elbow: float

    @property
    def cadence(self) -> float:
        """Steps per minute."""
        return 120.0 / self.stride

    @property
    def t_left(self) -> float:
        """Time of a left heel strike such that the first left toe-off is at :data:`LEAD_S`."""
        return LEAD_S - self.duty * self.stride

    def heel_strikes(self, side: str, t0: float, t1: float) -> np.ndarray:
        """Heel-strike times of ``side`` from one stride before ``t0`` to one after ``t1``."""
        start = self.t_left + (0.5 * self.stride if side == "r" else 0.0)
        k0 = np.floor((t0 - start) / self.stride) - 1
        k1 = np.ceil((t1 - start) / self.stride) + 1
        return start + np.arange(k0, k1 + 1) * self.stride


def step_length_walk(speed: float, height: float) -> float:
    """Walking step length in metres: 0.374 h (v / 1.2)^0.6.

    A power law through typical adult values (about 110 steps/min at 1.2 m/s, 84 at 0.6 and
    129 at 1.8; cf. Grieve 1968, Oberg et al. 1993, whose normal ranges contain them).
    """
    return 0.374 * height * (speed / 1.2) ** 0.6


def gait_parameters(command: Command, height: float) -> GaitParameters:
    """Timing, foot and body-pattern parameters for ``command`` and a subject ``height`` m."""
    v = command.speed
    scale = height / 1.75
    forward = max(command.v_f, 0.0) / v if v > 0 else 0.0   # 1 straight ahead, 0 sideways
    if command.gait == "run":
        cadence = 150.0 + 6.0 * v          # 162-171 steps/min at 2-3.5 m/s (Cavanagh & Kram 1989)
        stride = 120.0 / cadence
        duty = 0.40 - 0.05 * (v - 2.0)      # stance 0.30-0.23 s: a flight phase each step
        return GaitParameters(
            "run", stride, duty, step_width=0.04 * height, lateral_shift=0.0,
            toe_out=5 * DEG, heel_pitch=8 * DEG, toe_pitch=40 * DEG, loading=0.2,
            heel_rise=0.45, plant=0.42, clearance=(0.11 + 0.02 * (v - 2.5)) * scale,
            bounce=0.015 * scale,
            sway=0.01 * scale, pelvis_rotation=7 * DEG, pelvis_list=5 * DEG, lean=9 * DEG,
            thorax_rotation=6 * DEG, arm_swing=30 * DEG, elbow=85 * DEG)
    if command.gait == "stand":
        return GaitParameters(
            "stand", np.inf, 1.0, step_width=0.12 * scale, lateral_shift=0.0, toe_out=8 * DEG,
            heel_pitch=0.0, toe_pitch=0.0, loading=0.0, heel_rise=1.0, plant=0.5, clearance=0.0,
            bounce=0.0, sway=0.004 * scale, pelvis_rotation=0.0, pelvis_list=0.0,
            lean=2 * DEG, thorax_rotation=0.0, arm_swing=0.0, elbow=12 * DEG)
    # walking: cadence from the step-length relation, raised when turning or stepping sideways
    turning = 80.0 + 30.0 * abs(command.omega)
    sideways = 80.0 + 75.0 * abs(command.v_l)     # short, quick steps when stepping sideways
    walking = 60.0 * v / step_length_walk(v, height) if v > 0 else 0.0
    cadence = float(np.clip(max(walking, turning, sideways), 80.0, 140.0))
    stride = 120.0 / cadence
    roll = 0.3 + 0.7 * forward             # heel-to-toe roll only when moving forwards
    return GaitParameters(
        "walk", stride, duty=0.62 - 0.03 * max(v - 0.6, 0.0),
        # turning, the feet stand wider apart so they do not overlap as they pivot (on the spot)
        # and the swing leg clears the stance leg (on tight curves)
        step_width=0.065 * height + abs(command.omega) * (0.12 - 0.07 * min(v / 0.6, 1.0)),
        lateral_shift=abs(command.v_l) * stride / 4.0,
        toe_out=7 * DEG, heel_pitch=(10 + 8 * v) * DEG * roll,
        toe_pitch=(35 + 12 * v) * DEG * roll, loading=0.2, heel_rise=0.55, plant=0.44,
        clearance=(0.03 + 0.01 * v) * scale, bounce=(0.006 + 0.012 * v * forward) * scale,
        sway=(0.012 + 0.01 * forward * (1.0 - v / 3.0)) * scale,
        pelvis_rotation=(1.5 + 3.0 * v * forward) * DEG, pelvis_list=(2.0 + 2.0 * v) * DEG,
        lean=(2.0 + 2.0 * v * forward) * DEG, thorax_rotation=(1.0 + 2.0 * v * forward) * DEG,
        arm_swing=(4.0 + 12.0 * v * forward) * DEG, elbow=(15.0 + 8.0 * v) * DEG)


# ------------------------------------------------------------------------ footprints
@dataclass(frozen=True)
class Footprints:
    """One foot's stances: heel-strike and toe-off times (K,), flat-foot ankle ground point
    (K, 2) m and heading (K,) rad, and the body frame ``frame(t) -> (xy, heading)`` they were
    planned in (swings are drawn in it)."""

    side: str
    heel_strike: np.ndarray
    toe_off: np.ndarray
    position: np.ndarray
    heading: np.ndarray
    frame: "Frame"


Frame = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def plan_footprints(params: GaitParameters, frame: Frame, side: str, t0: float, t1: float
                    ) -> Footprints:
    """Footprints of ``side`` covering [t0, t1] for the pelvis' nominal ``frame(t)``."""
    hs = params.heel_strikes(side, t0, t1)
    stance = params.duty * params.stride
    xy, theta = frame(hs + params.plant * stance)
    sign = 1.0 if side == "l" else -1.0
    offset = np.array([0.0, sign * (0.5 * params.step_width + params.lateral_shift)])
    position = frame_to_world(xy, theta, np.broadcast_to(offset, xy.shape))
    return Footprints(side, hs, hs + stance, position, theta - sign * params.toe_out, frame)


# ------------------------------------------------------------------------ foot motion
def _about(axis, angle) -> np.ndarray:
    return axis_rotation(axis, np.atleast_1d(angle))


def foot_rotation(heading: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """Rear-foot orientation (F, 3, 3): heading about +Z, then ``pitch`` > 0 toes up."""
    return _about(Z_AXIS, heading) @ _about(Y_AXIS, -np.asarray(pitch))


def _stance(fp: Footprints, k: np.ndarray, t: np.ndarray, params: GaitParameters,
            geom: FootGeometry):
    """Stance pose at times ``t`` of stances ``k``: ankle (F, 3), heading, pitch, toe angle,
    pitch rate and contact state (F,)."""
    duration = fp.toe_off[k] - fp.heel_strike[k]
    u = np.clip((t - fp.heel_strike[k]) / duration, 0.0, 1.0)
    a, b = params.loading, params.heel_rise
    ul = np.clip(u / a, 0.0, 1.0) if a > 0 else np.ones_like(u)
    ur = np.clip((u - b) / (1.0 - b), 0.0, 1.0) if b < 1 else np.zeros_like(u)
    pitch = np.where(u < a, params.heel_pitch * 0.5 * (1 + np.cos(np.pi * ul)),
                     -params.toe_pitch * ur ** 1.3)
    rate = np.where(u < a, -params.heel_pitch * 0.5 * np.pi * np.sin(np.pi * ul) / (a * duration)
                    if a > 0 else 0.0,
                    -params.toe_pitch * 1.3 * ur ** 0.3 / ((1.0 - b) * duration) if b < 1 else 0.0)
    state = np.where(u < a, HEEL_CONTACT, np.where(u <= b, FLAT, TOE_CONTACT))
    pivot = np.zeros(t.shape + (3,))
    pivot[:, 0] = np.where(u < a, geom.heel, geom.mtp)
    pivot[:, 2] = -geom.ankle_height
    heading = fp.heading[k]
    rotated = np.einsum("fij,fj->fi", _about(Y_AXIS, -pitch), pivot)
    ankle = np.zeros(t.shape + (3,))
    ankle[:, :2] = fp.position[k]
    ankle[:, 2] = geom.ankle_height
    ankle += np.einsum("fij,fj->fi", _about(Z_AXIS, heading), pivot - rotated)
    toe = np.maximum(-pitch, 0.0) * (state == TOE_CONTACT)
    return ankle, heading, pitch, toe, rate, state


def _smooth_min(a, b, width):
    """min(a, b) made C2 where ``a`` and ``b`` are within ``width`` (> 0, or an array >= 0)
    of each other: min − max(width − |a − b|, 0)³ / (6 width²), at most width / 6 below."""
    width = np.maximum(width, 1e-12)
    return np.minimum(a, b) - np.maximum(width - np.abs(a - b), 0.0) ** 3 / (6 * width ** 2)


def _hermite(p0, v0, p1, v1, s, duration):
    """Cubic Hermite between values ``p0``→``p1`` with rates ``v0``, ``v1`` (per second)."""
    s2, s3 = s * s, s * s * s
    h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
    expand = (lambda x: x[:, None]) if np.ndim(p0) == 2 else (lambda x: x)
    return (expand(h00) * p0 + expand(h10 * duration) * v0 + expand(h01) * p1
            + expand(h11 * duration) * v1)


def _in_frame(fp: Footprints, k: np.ndarray, t: np.ndarray, h: float, params, geom):
    """Horizontal ankle position of stances ``k`` at ``t`` and ``t + h`` in the body frame."""
    out = []
    for when in (t, t + h):
        xy, theta = fp.frame(when)
        out.append(world_to_frame(xy, theta, _stance(fp, k, when, params, geom)[0][:, :2]))
    return out


def foot_trajectory(fp: Footprints, t: np.ndarray, params: GaitParameters, geom: FootGeometry
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rear-foot pose of one foot at times ``t`` (F,).

    Returns ankle centre (F, 3) m, orientation (F, 3, 3), toe-joint dorsiflexion (F,) rad and
    contact state (F,) (:data:`SWING`, :data:`HEEL_CONTACT`, :data:`FLAT`, :data:`TOE_CONTACT`).
    """
    t = np.asarray(t, float)
    k = np.searchsorted(fp.heel_strike, t, side="right") - 1
    if (k < 0).any() or (k + 1 >= len(fp.heel_strike)).any():
        raise ValueError("times outside the planned footprints")
    in_stance = t <= fp.toe_off[k]
    ankle, heading, pitch, toe, _, state = _stance(fp, k, t, params, geom)

    sw = ~in_stance
    if sw.any():
        ks, ts = k[sw], t[sw]
        t0, t1 = fp.toe_off[ks], fp.heel_strike[ks + 1]
        duration = t1 - t0
        s = (ts - t0) / duration
        h = 1e-4
        # the swing is drawn in the moving body frame, so the foot keeps its side of the body
        # on curves and turns instead of cutting across the other leg
        _, hd0, p0, _, r0, _ = _stance(fp, ks, t0, params, geom)
        _, hd1, p1, _, r1, _ = _stance(fp, ks + 1, t1, params, geom)
        b0, b0h = _in_frame(fp, ks, t0, -h, params, geom)
        b1, b1h = _in_frame(fp, ks + 1, t1, h, params, geom)
        # the foot still moves (a quarter of its mean swing speed) when the heel strikes
        arrive = (b1h - b1) / h + 0.25 * (b1 - b0) / duration[:, None]
        local = _hermite(b0, (b0 - b0h) / h, b1, arrive, s, duration)
        fxy, fth = fp.frame(ts)
        xy = frame_to_world(fxy, fth, local)
        rel0, rel1 = hd0 - fp.frame(t0)[1], hd1 - fp.frame(t1)[1]
        turn = np.angle(np.exp(1j * (rel1 - rel0)))
        hd = fth + rel0 + turn * (3 * s ** 2 - 2 * s ** 3)
        p = _hermite(p0, 0.3 * r0, p1, r1, s, duration)   # the push-off spin fades fast
        release = np.clip(s / 0.35, 0.0, 1.0)
        released = release ** 2 * (3 - 2 * release)
        tq = params.toe_pitch * (1.0 - released)
        skew = s + (0.8 if params.gait == "run" else 0.3) * s * (1 - s)
        lift = params.clearance * np.sin(np.pi * skew)
        sole = np.einsum("fij,fkj->fki", _about(Y_AXIS, -p), geom.sole_points(tq))
        ankle[sw, :2] = xy
        # toes and metatarsal heads are level at toe-off: blend them only as the toes release
        forefoot = _smooth_min(sole[:, 1, 2], sole[:, 2, 2], SOLE_BLEND * released)
        lowest = _smooth_min(sole[:, 0, 2], forefoot, SOLE_BLEND)
        ankle[sw, 2] = lift - lowest
        heading[sw], pitch[sw], toe[sw], state[sw] = hd, p, tq, SWING
    return ankle, foot_rotation(heading, pitch), toe, state
