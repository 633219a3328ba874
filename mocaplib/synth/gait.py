"""Gait timing, footprints and foot trajectories of the synthetic walker.

Timing
    Stride period ``T`` (left heel strike to left heel strike) from cadence relations, stance
    fraction (duty factor) ``beta``. Left heel strikes at ``t_L + kT``, left toe-offs
    ``beta T`` later; the right foot is half a stride later. ``t_L`` puts the first left toe-off
    at ``lead`` seconds, so every cycle [left toe-off, next left toe-off) starting at
    ``lead + kT`` is steady (the command is constant and the walker starts in steady state, as
    on a lab walkway).
Footprints
    Each stance's flat-foot pose (the rear foot's origin, the ankle centre, over the floor, and
    its heading) is the pelvis' nominal frame at the moment ``plant`` of the stance (a little
    before mid-stance), shifted sideways by half the step width (plus a quarter of the stride's
    lateral displacement, so side-steps open and close without crossing the feet) and toed out.
Feet
    The foot is the generator's (:class:`~mocaplib.synth.bones.FootShape`): a rear foot and
    toes hinged at the metatarsophalangeal (MTP) axis. In stance it lands pitched toes-up about
    the heel, lies flat (not moving at all) from ``loading`` to ``heel_rise`` of the stance,
    then rolls over the forefoot: the heel rises about the MTP axis while the toes stay flat
    (the MTP joint dorsiflexes), and for the last ``toe_roll_time`` of stance the metatarsal
    heads lift too, the foot turning about the tips of its toes, until the tips leave the
    floor: the toe-off, as a force plate sees it. The heel rises ever faster, its pitch rate
    peaking ``pitch_peak`` of the stance before toe-off, as measured on the lab files (the foot's
    pitch rate peaks ~50 ms before their Foot Off at normal speed and is still ~60 % of the
    peak at it; their toe marker starts rising ~40 ms before it: docs/results/event_accuracy.md).
    In swing the foot's pose is a cubic Hermite curve from the toe-off pose to the heel-strike
    pose with the rates of both (the foot's motion has no velocity step at toe-off), its
    horizontal path drawn in the moving body frame, its height set so that the lowest sole
    point follows a clearance profile that leaves the floor with zero velocity.

Angles in radians, lengths in metres, times in seconds. World frame Z up, floor at z = 0.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..library.command import Command
from ..skeleton import axis_rotation
from .bones import FootShape, vector_turn
from .command import frame_to_world, world_to_frame

DEG = np.pi / 180.0
Y_AXIS, Z_AXIS = (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
#: Where the first left toe-off falls, seconds after the first frame.
LEAD_S = 0.25
#: Contact states returned by :func:`foot_trajectory`: swing, on the heel, flat, on the
#: metatarsal heads (heel rising), on the toes' tips.
SWING, HEEL_CONTACT, FLAT, FOREFOOT, TOES = 0, 1, 2, 3, 4
#: Height difference (m) within which the swing foot's lowest point passes smoothly from one
#: sole point to another (:func:`_smooth_min`).
SOLE_BLEND = 0.008
#: Exponent m of the heel rise's pitch rate, w^m (1 - c w) over the rise (w from 0 to 1).
RISE_EXPONENT = 4.0
#: Share of the swing, from toe-off, over which the sole blend and the toes' release grow.
RELEASE = 0.3
#: Time constant (s) of the toes' return to straight after toe-off.
TOES_RETURN_S = 0.04
#: The last share of stance a foot stands on its toes' tips (58 ms of a 0.65 s stance).
TOE_ROLL_TIME = 0.09
#: How long before toe-off, as a share of stance, the heel rises fastest (50 ms of 0.65 s).
PITCH_PEAK = 0.077


@dataclass(frozen=True)
class GaitParameters:
    """Everything the generator derives from the command and the subject (SI units).

    Attributes (timing) ``stride`` s, ``duty`` stance fraction; (feet) ``step_width`` m,
    ``lateral_shift`` m added to both feet's sideways offset, ``toe_out`` rad, ``heel_pitch``
    rad (toes up) at heel strike, ``rise`` the rear foot's turn about the MTP axis at toe-off
    and ``toe_roll`` the toes' turn about their tips at toe-off (rad), ``loading`` and
    ``heel_rise`` fractions of stance (flat between them), ``toe_roll_time`` the fraction of
    stance the foot stands on its toes' tips, ``pitch_peak`` the fraction of stance before
    toe-off at which the heel's rise is fastest, ``plant`` the fraction of stance at which the
    pelvis passes over the footprint, ``clearance`` m; (body) ``bounce`` and ``sway`` m, ``pelvis_rotation``,
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
    rise: float
    toe_roll: float
    loading: float
    heel_rise: float
    toe_roll_time: float
    pitch_peak: float
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
            "run", stride, duty, step_width=0.05 * height, lateral_shift=0.0,
            toe_out=5 * DEG, heel_pitch=8 * DEG, rise=45 * DEG, toe_roll=12 * DEG, loading=0.2,
            heel_rise=0.45, toe_roll_time=TOE_ROLL_TIME, pitch_peak=PITCH_PEAK, plant=0.42, clearance=(0.11 + 0.02 * (v - 2.5)) * scale,
            bounce=0.015 * scale,
            sway=0.01 * scale, pelvis_rotation=7 * DEG, pelvis_list=5 * DEG, lean=9 * DEG,
            thorax_rotation=6 * DEG, arm_swing=30 * DEG, elbow=85 * DEG)
    if command.gait == "stand":
        return GaitParameters(
            "stand", np.inf, 1.0, step_width=0.12 * scale, lateral_shift=0.0, toe_out=8 * DEG,
            heel_pitch=0.0, rise=0.0, toe_roll=0.0, loading=0.0, heel_rise=1.0,
            toe_roll_time=TOE_ROLL_TIME, pitch_peak=PITCH_PEAK, plant=0.5, clearance=0.0,
            bounce=0.0, sway=0.004 * scale, pelvis_rotation=0.0, pelvis_list=0.0,
            lean=2 * DEG, thorax_rotation=0.0, arm_swing=0.0, elbow=12 * DEG)
    # walking: cadence from the step-length relation, raised when turning or stepping sideways
    turning = 80.0 + 30.0 * abs(command.omega)
    sideways = 80.0 + 75.0 * abs(command.v_l)     # short, quick steps when stepping sideways
    walking = 60.0 * v / step_length_walk(v, height) if v > 0 else 0.0
    cadence = float(np.clip(max(walking, turning, sideways), 80.0, 140.0))
    stride = 120.0 / cadence
    roll = 0.6 + 0.4 * forward             # a smaller roll when not moving forwards
    return GaitParameters(
        "walk", stride, duty=0.62 - 0.03 * max(v - 0.6, 0.0),
        # turning, the feet stand wider apart so they do not overlap as they pivot (on the spot)
        # and the swing leg clears the stance leg (on tight curves)
        step_width=0.065 * height + abs(command.omega) * (0.12 - 0.07 * min(v / 0.6, 1.0)),
        lateral_shift=abs(command.v_l) * stride / 4.0,
        toe_out=7 * DEG, heel_pitch=(10 + 8 * v) * DEG * roll, rise=(35 + 12 * v) * DEG * roll,
        toe_roll=18 * DEG, loading=0.2, heel_rise=0.52, toe_roll_time=TOE_ROLL_TIME,
        pitch_peak=PITCH_PEAK, plant=0.44,
        clearance=(0.02 + 0.01 * v) * scale, bounce=(0.006 + 0.012 * v * forward) * scale,
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
#: The swing's clearance profile (:func:`clearance_profile`): how soon the lowest sole point
#: rises (a) and how it comes down (b), shares of the swing.
LIFT_RISE, LIFT_FALL = 0.22, 0.35


def _about(axis, angle) -> np.ndarray:
    return axis_rotation(axis, np.atleast_1d(angle))


def clearance_profile(s: np.ndarray) -> np.ndarray:
    """The swing foot's lowest sole point's height over the swing, as a share of the
    clearance, at ``s`` (F,) from 0 (toe-off) to 1 (heel strike): s²/(s² + a²) ·
    (1 − s)/(1 − s + b) scaled to a peak of 1 (a, b = :data:`LIFT_RISE`, :data:`LIFT_FALL`).
    It leaves the floor with no velocity but fast (the lab files' toe marker rises at
    0.4-0.5 m/s for the 40 ms after Foot Off, as the knee flexes), holds near its peak through
    mid-swing and lands with a downward velocity."""
    grid = np.linspace(0.0, 1.0, 2001)
    peak = np.max(_unscaled_clearance(grid))
    return _unscaled_clearance(np.asarray(s, float)) / peak


def _unscaled_clearance(s: np.ndarray) -> np.ndarray:
    return s ** 2 / (s ** 2 + LIFT_RISE ** 2) * (1 - s) / (1 - s + LIFT_FALL)


def _turned(points: np.ndarray, axis, angle: np.ndarray, pivot) -> np.ndarray:
    """Points (F, 3) turned by ``angle`` (F,) about ``axis`` (3,) through ``pivot`` (3,)."""
    return pivot + np.einsum("fij,fj->fi", _about(axis, angle), points - pivot)


def _rise(w: np.ndarray, w_peak: float) -> tuple[np.ndarray, np.ndarray]:
    """The heel rise's share (F,) of its whole at ``w`` (F,) in [0, 1] of the rise, and its
    rate per unit w: the rate is w^m (1 − c w) (m = :data:`RISE_EXPONENT`), fastest at
    ``w_peak`` (c = m / ((m + 1) w_peak), at most 1 so that the rate is never negative)."""
    m = RISE_EXPONENT
    c = min(m / ((m + 1) * w_peak), 1.0)

    def whole(x):
        return x ** (m + 1) / (m + 1) - c * x ** (m + 2) / (m + 2)

    return whole(w) / whole(1.0), w ** m * (1 - c * w) / whole(1.0)


def _stance(fp: Footprints, k: np.ndarray, t: np.ndarray, params: GaitParameters,
            shape: FootShape):
    """Stance pose at times ``t`` of stances ``k``: rear-foot origin (F, 3), heading (F,), the
    rear foot's turn from flat as a rotation vector in the heading frame (F, 3) and its rate
    (F, 3) /s, MTP dorsiflexion (F,) and its rate (F,) /s, and the contact state (F,)."""
    duration = fp.toe_off[k] - fp.heel_strike[k]
    u = np.clip((t - fp.heel_strike[k]) / duration, 0.0, 1.0)
    a, b = params.loading, params.heel_rise
    roll = 1.0 - params.toe_roll_time
    ul = np.clip(u / a, 0.0, 1.0) if a > 0 else np.ones_like(u)
    heel = params.heel_pitch * 0.5 * (1 + np.cos(np.pi * ul))
    heel_rate = (-params.heel_pitch * 0.5 * np.pi * np.sin(np.pi * ul) / (a * duration)
                 if a > 0 else np.zeros_like(u))
    w = np.clip((u - b) / (1.0 - b), 0.0, 1.0) if b < 1 else np.zeros_like(u)
    share, share_rate = _rise(w, 1.0 - params.pitch_peak / (1.0 - b) if b < 1 else 1.0)
    rise = params.rise * share
    rise_rate = params.rise * share_rate / ((1.0 - b) * duration) * (u > b)
    v = np.clip((u - roll) / (1.0 - roll), 0.0, 1.0)
    tip = params.toe_roll * v ** 3
    tip_rate = 3 * params.toe_roll * v ** 2 / ((1.0 - roll) * duration)
    landing = u < a
    state = np.where(landing, HEEL_CONTACT, np.where(u <= b, FLAT, np.where(
        u < roll, FOREFOOT, TOES)))
    lift_axis = -shape.mtp_axis                         # the heel rises turning about it
    on_mtp = _turned(np.zeros((len(u), 3)), lift_axis, rise - tip, shape.mtp_point)
    origin = np.where(landing[:, None],
                      _turned(np.zeros((len(u), 3)), -np.asarray(Y_AXIS), heel, shape.heel),
                      _turned(on_mtp, lift_axis, tip, shape.toe_tip))
    turn = np.where(landing[:, None], -np.asarray(Y_AXIS) * heel[:, None],
                    lift_axis * rise[:, None])
    turn_rate = np.where(landing[:, None], -np.asarray(Y_AXIS) * heel_rate[:, None],
                         lift_axis * rise_rate[:, None])
    heading = fp.heading[k]
    world = np.zeros((len(u), 3))
    world[:, :2] = fp.position[k]
    world[:, 2] = shape.ankle_height
    world += np.einsum("fij,fj->fi", _about(Z_AXIS, heading), origin)
    return world, heading, turn, turn_rate, rise - tip, rise_rate - tip_rate, state


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


def _toes_release(mtp: np.ndarray, rate: np.ndarray, elapsed: np.ndarray, s: np.ndarray
                  ) -> np.ndarray:
    """The toes' dorsiflexion (F,) ``elapsed`` (F,) s after toe-off, from ``mtp`` (F,) rad
    turning at ``rate`` (F,) rad/s then: a critically damped return to straight toes with
    time constant :data:`TOES_RETURN_S` (no overshoot, as the real toes spring back in ~0.1 s),
    brought exactly to 0 by heel strike (``s`` (F,) the share of the swing) by a smoothstep."""
    decay = 1.0 / TOES_RETURN_S
    relax = (mtp + (rate + decay * mtp) * elapsed) * np.exp(-decay * elapsed)
    return relax * (1.0 - s ** 3 * (10 - 15 * s + 6 * s ** 2))


def _in_frame(fp: Footprints, k: np.ndarray, t: np.ndarray, h: float, params, shape):
    """Horizontal rear-foot origin of stances ``k`` at ``t`` and ``t + h`` in the body frame."""
    out = []
    for when in (t, t + h):
        xy, theta = fp.frame(when)
        out.append(world_to_frame(xy, theta, _stance(fp, k, when, params, shape)[0][:, :2]))
    return out


def sole_heights(shape: FootShape, R: np.ndarray, mtp: np.ndarray) -> np.ndarray:
    """Heights (F, K) above the rear-foot origin of the foot's sole points: heel, the
    :attr:`FootShape.sole` points, and the toe tip with the toes dorsiflexed by ``mtp`` (F,)
    rad; ``R`` (F, 3, 3) the rear foot's orientation."""
    tip = _turned(np.broadcast_to(shape.toe_tip, (len(mtp), 3)), shape.mtp_axis, mtp,
                  shape.mtp_point)
    local = np.concatenate([np.broadcast_to(np.vstack([shape.heel, shape.sole]),
                                            (len(mtp), 1 + len(shape.sole), 3)),
                            tip[:, None]], axis=1)
    return np.einsum("fj,fkj->fk", R[:, 2], local)


def foot_trajectory(fp: Footprints, t: np.ndarray, params: GaitParameters, shape: FootShape
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rear-foot pose of one foot at times ``t`` (F,).

    Returns the rear foot's origin (the ankle centre; F, 3) m, its orientation (F, 3, 3), the
    MTP dorsiflexion (F,) rad and the contact state (F,) (:data:`SWING`,
    :data:`HEEL_CONTACT`, :data:`FLAT`, :data:`FOREFOOT`, :data:`TOES`).
    """
    t = np.asarray(t, float)
    k = np.searchsorted(fp.heel_strike, t, side="right") - 1
    if (k < 0).any() or (k + 1 >= len(fp.heel_strike)).any():
        raise ValueError("times outside the planned footprints")
    in_stance = t <= fp.toe_off[k]
    origin, heading, turn, _, mtp, _, state = _stance(fp, k, t, params, shape)

    sw = ~in_stance
    if sw.any():
        ks, ts = k[sw], t[sw]
        t0, t1 = fp.toe_off[ks], fp.heel_strike[ks + 1]
        duration = t1 - t0
        s = (ts - t0) / duration
        h = 1e-4
        # the swing is drawn in the moving body frame, so the foot keeps its side of the body
        # on curves and turns instead of cutting across the other leg
        _, hd0, w0, r0, m0, mr0, _ = _stance(fp, ks, t0, params, shape)
        _, hd1, w1, r1, _, _, _ = _stance(fp, ks + 1, t1, params, shape)
        b0, b0h = _in_frame(fp, ks, t0, -h, params, shape)
        b1, b1h = _in_frame(fp, ks + 1, t1, h, params, shape)
        # the foot still moves (a quarter of its mean swing speed) when the heel strikes
        arrive = (b1h - b1) / h + 0.25 * (b1 - b0) / duration[:, None]
        local = _hermite(b0, (b0 - b0h) / h, b1, arrive, s, duration)
        fxy, fth = fp.frame(ts)
        rel0, rel1 = hd0 - fp.frame(t0)[1], hd1 - fp.frame(t1)[1]
        change = np.angle(np.exp(1j * (rel1 - rel0)))
        hd = fth + rel0 + change * (3 * s ** 2 - 2 * s ** 3)
        w = _hermite(w0, r0, w1, r1, s, duration)
        m = _toes_release(m0, mr0, ts - t0, s)
        release = np.clip(s / RELEASE, 0.0, 1.0)
        blend = SOLE_BLEND * release ** 2 * (3 - 2 * release)
        heights = sole_heights(shape, vector_turn(w), m)
        lowest = heights[:, 0]
        for column in heights.T[1:]:
            lowest = _smooth_min(lowest, column, blend)
        lift = params.clearance * clearance_profile(s)
        origin[sw, :2] = frame_to_world(fxy, fth, local)
        origin[sw, 2] = lift - lowest
        heading[sw], turn[sw], mtp[sw], state[sw] = hd, w, m, SWING
    R = _about(Z_AXIS, heading) @ vector_turn(turn)
    return origin, R, mtp, state
