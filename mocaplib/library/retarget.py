"""Retargeting a library cycle to another body by inverse kinematics (Pronost et al.).

:func:`retarget` takes one entry of a library and a target skeleton:

1. **Poulaine.** The requested step length, foot spacing and stance (m, as
   :mod:`mocaplib.gait.poulaine` defines them) default to the entry's own, scaled to the target: step
   length and stance by the ratio of leg lengths (thigh + shank), foot spacing by the ratio of
   hip widths. :func:`mocaplib.gait.poulaine.blend` picks, per axis, the poulaine of the library
   closest in that parameter, each first scaled to the target's body by the ratio of leg lengths
   (:meth:`~mocaplib.gait.poulaine.Poulaine.scaled`: compared as if walked by the target, so a
   body scaled as a whole walks the entry's own poulaine), among the entries of the same locomotion class that move (or
   stay on the spot), turn, travel and support themselves like the entry (:data:`SIMILAR_TURN`,
   :data:`SIMILAR_TRAVEL`, :data:`SIMILAR_SUPPORT`; the entry itself wins ties), corrects it exactly to the requested
   values and times it on the entry's characteristic points. Sampled over the cycle, it is
   low-passed at :data:`mocaplib.model.filtering.WALKING_CUTOFF` (:func:`periodic_lowpass`; the
   four Hermite curves meet at corners) and corrected again the same way, so that the ankle
   targets have the requested values exactly where the entry passes its characteristic
   points.
2. **Inverse kinematics** on the target skeleton, frame after frame over the cycle sampled in
   n = ``round(T × rate)`` equal steps (both ends included), played in n / rate s so that the
   output has the requested rate exactly (the period changes by at most half a sample); the
   reference is the entry's closed cycle (its Fourier series without the ramp), so that the
   output loops. The primary task puts both ankle
   centres on the poulaine, in the travel frame of a pelvis at the origin: Δθ = J⁺ΔX over the
   :data:`TASK_DOFS` (the pelvis's orientation, hips and knees; J⁺ damped near a stretched
   leg, :data:`DAMPING`, and steps of at most :data:`MAX_STEP`). In the null space of J (the
   basis Z of its right singular vectors beyond the task's 6), the step minimises a weighted
   sum of three costs (:class:`Weights`), each expanded to second order (a Newton step on the
   projected cost):

   a. distance to the joint limits, Σ_j r_j² / (4 (θ_max − θ)(θ − θ_min)) (Chan & Dubey's
      criterion: 1 per DOF at mid-range, infinite at a limit; r_j the range);
   b. distance to the reference posture, Σ_j (θ_j − θ_ref,j)², rad², the entry's own angles at
      the same phase;
   c. rotational kinetic energy, ½ θ̇ᵀ M(θ) θ̇ per kilogram of body mass (J/kg), θ̇ = (θ −
      θ_previous frame) / Δt, M = Σ_b A_bᵀ R_b I_b R_bᵀ A_b over de Leva's bodies
      (:mod:`mocaplib.model.anthropometry`), A_b the world axes of the task DOFs that turn body b.

   Up to :data:`ITERATIONS` steps per frame, each clamped to the joint limits (the knees at 0
   or more: never hyperextended); the other DOFs
   (trunk, head, arms, ankles) keep the entry's angles, clipped to the joint limits (a Fourier
   series may ring past one by a fraction of a degree).
3. **Root.** The path frame's speed (the entry's root drift) and the pelvis's excursions in it
   are scaled so that the pelvis covers per cycle the stride of the poulaine's x-source times
   its x-correction (the stance ankle then moves back under the pelvis as fast as the pelvis
   moves on: the foot stays where it landed). The pelvis height is the entry's above its ankle
   height, times the ratio of the requested stance to the entry's, plus the target's ankle
   height (smooth: the entry's own rise and fall, scaled).
4. **Feet** planted on the floor through each stance
   (:func:`mocaplib.library.planting.plant_cycles`), and measured with the entry's
   (:attr:`Retargeted.feet`).

The result carries the criteria C1-C3 of the entry (its Fourier series on its own skeleton)
and of the result, computed alike (:func:`cycle_criteria`), and writes it in any motion format of
:data:`mocaplib.export.formats.FORMATS` (CSV, OpenSim ``.mot``, BVH, glTF).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import MocapError
from ..export.formats import write
from ..gait.criteria import closure, internal_power, jerk_rms, segment_energies, third_derivative
from ..gait.fourier import RootDrift, fit_series, synthesize
from ..gait.poulaine import FEET, MIN_TRAVEL_SPEED, ankle_centres, blend, travel_coordinates
from ..model.anthropometry import bodies
from ..model.filtering import WALKING_CUTOFF
from ..model.motion import Motion
from ..skeleton import (DOF_NAMES, JOINT_ANGLES, MOVES, ROOT_HEADING, ROOT_X, ROOT_Y, TRANSLATION,
                        Skeleton, segment_dofs)
from .legs import KNEES
from .planting import ContactMeasures, cycle_contact, plant_cycles

#: The DOFs the inverse kinematics solves: they place the ankle centres relative to the pelvis
#: (the pelvis's rotations, the hips and the knees).
TASK_DOFS = tuple(j for segments in (("pelvis",), ("femur_l", "tibia_l"), ("femur_r", "tibia_r"))
                  for j in segment_dofs(*segments) if not TRANSLATION[j])
#: Damping of the pseudo-inverse J⁺ = V diag(σ / (σ² + λ²)) Uᵀ, which bounds the step where a
#: leg is stretched straight (σ → 0): λ² = DAMPING² (1 − (σ_min / SINGULAR)²) when the smallest
#: singular value σ_min of J is below SINGULAR, else 0 (m/rad; Chiaverini's adaptive damping).
DAMPING, SINGULAR = 0.05, 0.05
#: Largest step of a DOF in one iteration, rad.
MAX_STEP = 0.2
#: Steps per frame at most; a frame is done when the ankles are within TOLERANCE (m) of the
#: poulaine and the step is below 1e-7 rad.
ITERATIONS, TOLERANCE = 10, 1e-6
#: The entries whose poulaines a cycle is retargeted from turn within this (rad/s) of its turn
#: rate ω̂, travel within this (rad) of its direction relative to the pelvis and spend within
#: this share of the cycle in support: walks spend 0.60-0.67 of it, runs 0.49-0.54 (measured
#: on the samples and the shared real files; docs/poulaines.md).
SIMILAR_TURN, SIMILAR_TRAVEL, SIMILAR_SUPPORT = 0.25, np.deg2rad(20.0), 0.04
#: A foot is in support where its ankle centre is within this (m) of its lowest
#: (:func:`foot_skate`; the gait events' contact rule takes 1 cm above the floor too).
SUPPORT_HEIGHT = 0.01
#: Fewest samples over the cycle :func:`retarget` solves (a lower rate is refused).
MIN_STEPS = 8
#: Largest distance (m) between the result's ankles and the requested poulaine that
#: ``mocaplib retarget`` writes: beyond it the body cannot follow the request (measured on the
#: real walks at x0.85: 25.6 mm at worst, docs/results/retarget.md).
ANKLE_TOLERANCE_M = 0.05
#: Default output rate, Hz.
RATE = 100.0
_ROOT_Z = DOF_NAMES.index("pelvis_tz")


@dataclass(frozen=True)
class Weights:
    """Weights of the null-space costs (module docstring): ``joint_limits`` (dimensionless
    cost), ``reference`` (per rad²), ``kinetic`` (per J/kg)."""

    joint_limits: float = 1e-3
    reference: float = 1.0
    kinetic: float = 1e-2

    def __post_init__(self):
        values = (self.joint_limits, self.reference, self.kinetic)
        if not all(np.isfinite(v) and v >= 0 for v in values) or not any(values):
            raise MocapError(f"the weights must be finite and >= 0, not all 0, got "
                             f"{self.joint_limits}, {self.reference}, {self.kinetic}")


@dataclass
class Retargeted:
    """A retargeted cycle.

    Attributes
    ----------
    entry : str
        The library entry it comes from.
    skeleton : Skeleton
        The target body.
    time_s : ndarray, shape (n + 1,)
        Sample times over the cycle, k / rate s: the cycle of n = round(T × rate) samples is
        played in n / rate s (within half a sample of the entry's period T).
    q : ndarray, shape (n + 1, D)
        Joint coordinates in :data:`~mocaplib.skeleton.DOF_NAMES` order (rad; ``pelvis_t*`` m),
        world frame, the pelvis starting at the origin facing +X; the feet planted
        (:mod:`mocaplib.library.planting`).
    requested : tuple[float, float, float]
        Step length, foot spacing and stance, m.
    sources : tuple[str, str, str]
        The entries whose poulaine gave x, y and z.
    ankle_error_m : float
        Largest distance between an ankle centre and its poulaine target over the cycle, m.
    clamped : int
        Inverse-kinematics steps that a joint limit stopped.
    criteria : dict
        ``{"input": {...}, "output": {...}}``, each with ``jerk_rms_rad_s3`` (C1),
        ``cycle_closure_rad`` (C2) and ``internal_power_w_kg`` (C3): :func:`cycle_criteria`.
    drift : RootDrift
        The path frame the pelvis moves along (the entry's, sped up or slowed down).
    weights : Weights
    rate : float
        Samples per second, exactly as requested.
    feet : dict
        ``{"entry": ContactMeasures, "output": ContactMeasures}``: the feet of the entry's closed
        cycle (its Fourier series) on its own body and the output's
        (:func:`mocaplib.library.planting.contact_measures`).
    poulaine_q : ndarray, shape (n + 1, D) or None
        The inverse kinematics' solution before the feet are planted, in the path frame: its
        ankles on the requested poulaine (planting then moves them by a few millimetres).
    """

    entry: str
    skeleton: Skeleton
    time_s: np.ndarray
    q: np.ndarray
    requested: tuple[float, float, float]
    sources: tuple[str, str, str]
    ankle_error_m: float
    clamped: int
    criteria: dict
    drift: RootDrift
    weights: Weights = field(default_factory=Weights)
    rate: float = RATE
    feet: dict[str, ContactMeasures] = field(default_factory=dict)
    poulaine_q: np.ndarray | None = None

    def path_coordinates(self) -> np.ndarray:
        """``q`` (n + 1, D) with the root in the path frame, as the library stores cycles."""
        return self.drift.remove(self.q, self.time_s)

    def summary(self) -> dict:
        """What ``mocaplib retarget --json`` prints: ``entry``, ``requested_m`` (step length,
        foot spacing, stance), ``sources`` (the entries of x, y, z), ``rate_hz``, ``frames``,
        ``ankle_error_m`` (the IK's, before the feet are planted), ``clamped_steps``,
        ``limit_violations``, ``hyperextended_samples`` (knee samples below 0),
        ``feet`` (:class:`~mocaplib.library.planting.ContactMeasures` of the entry and of the
        output: slide, penetration, hover, pelvis vertical acceleration), ``weights`` and
        ``criteria``."""
        return {"entry": self.entry, "requested_m": list(self.requested),
                "sources": list(self.sources), "rate_hz": self.rate, "frames": len(self.q),
                "ankle_error_m": self.ankle_error_m, "clamped_steps": self.clamped,
                "limit_violations": self.limit_violations(),
                "hyperextended_samples": int(np.sum(self.q[:, list(KNEES)] < -1e-9)),
                "feet": {key: value.as_dict() for key, value in self.feet.items()},
                "weights": {"joint_limits": self.weights.joint_limits,
                            "reference": self.weights.reference,
                            "kinetic": self.weights.kinetic},
                "criteria": self.criteria}

    def limit_violations(self) -> int:
        """Samples of a DOF outside its joint limits (rounding aside)."""
        lower, upper = Skeleton.bounds()
        return int(np.sum((self.q < lower - 1e-9) | (self.q > upper + 1e-9)))

    def motion(self) -> Motion:
        """The cycle as a :class:`~mocaplib.model.motion.Motion` (n + 1 frames at :attr:`rate`,
        both ends included), named after its entry."""
        return Motion(self.q, self.skeleton, self.rate, source=self.entry)

    def write(self, path: str | os.PathLike) -> Path:
        """Write the cycle (atomically) in the motion format of the suffix
        (:data:`mocaplib.export.formats.FORMATS`); BVH and glTF, which players loop, leave out
        the closing frame. Returns the path."""
        return write(self.motion(), path, closed=True)


def retarget(library, entry_id: str, /, *, skeleton: Skeleton, step_length: float | None = None,
             foot_spacing: float | None = None, stance: float | None = None,
             weights: Weights = Weights(), rate: float = RATE) -> Retargeted:
    """Retarget the cycle of one library entry to another body (module docstring).

    Parameters
    ----------
    library : Library
        The library (:func:`mocaplib.library.format.load_library`).
    entry_id : str
        The entry whose cycle is retargeted; it needs a poulaine.
    skeleton : Skeleton
        The target body.
    step_length, foot_spacing, stance : float or None
        The requested poulaine parameters, metres; None: the entry's, scaled to the target's
        leg length.
    weights : Weights
        Weights of the secondary tasks in the ankles' null space.
    rate : float
        Output sampling rate, Hz.

    Returns
    -------
    Retargeted
        The output joint coordinates over one cycle, the requested and reached parameters,
        the ankle error and the criteria C1-C3 of the entry and the output.

    Raises
    ------
    MocapError
        An entry without a poulaine (rest, or a library written before poulaines were stored),
        requested values that are not lengths, or a rate that is not > 0.
    """

    entry = library.entry(entry_id)
    own = library.poulaine(entry_id)
    if own is None:
        why = ("a rest entry" if entry.locomotion_class == "rest"
               else "the library was written before poulaines were stored")
        raise MocapError(f"entry {entry_id!r} has no poulaine to retarget ({why})",
                         hint="choose a walking entry, or rebuild the library with this mocaplib")
    period = float(entry.T)
    if not (np.isfinite(rate) and round(period * rate) >= MIN_STEPS):
        raise MocapError(f"an output rate of {rate:g} Hz gives fewer than {MIN_STEPS} samples "
                         f"over the cycle of {entry_id!r} ({period:.3g} s)",
                         hint=f"ask for at least {lowest_rate(period):.3g} Hz")
    source = library.entry_skeleton(entry_id)
    requested = _requested(own.parameters, source, skeleton, step_length, foot_spacing, stance)
    sizes = _body_sizes(library, entry, own, skeleton)
    path = blend({name: library.poulaine(name).scaled(size) for name, size in sizes.items()},
                 step_length=requested[0], foot_spacing=requested[1], stance=requested[2],
                 prefer=entry_id)
    steps = int(round(period * rate))
    played = steps / rate                           # the cycle's period in the output, s
    phase = np.arange(steps + 1) / steps
    captured = library.angles(entry_id, phase * period)                    # path frame
    reference = synthesize(entry.fourier.a, entry.fourier.b, period, phase * period)  # closed
    targets = _targets(path, own, requested, phase, period)
    solved, error, clamped = solve(skeleton, targets,
                                   travel_coordinates(reference, own.travel),
                                   weights=weights, step=1.0 / rate)
    out = np.clip(reference, *Skeleton.bounds())   # a Fourier series may ring past a limit
    out[:, list(TASK_DOFS)] = solved[:, list(TASK_DOFS)]
    out[:, ROOT_HEADING] += own.travel
    scale = _stride_scale(library, entry, path, sizes[path.names[0]])
    out[:, [ROOT_X, ROOT_Y]] *= scale
    out[:, _ROOT_Z] = (skeleton.lengths["ankle_height"] + requested[2] / own.parameters[2]
                       * (reference[:, _ROOT_Z] - source.lengths["ankle_height"]))
    still = library.root_drift(entry_id)
    pace = period / played
    moved = RootDrift(0.0, 0.0, 0.0, still.u_f * scale * pace, still.u_l * scale * pace,
                      still.omega * pace)
    planted = plant_cycles(skeleton, lambda t: out[np.mod(np.rint(t * rate).astype(int), steps)],
                           moved, played, rate, steps + 1)
    times = np.arange(steps + 1) / rate
    feet = {"entry": cycle_contact(source, lambda t: synthesize(entry.fourier.a, entry.fourier.b,
                                                                period, t),
                                   still, period, steps / period, steps + 1),
            "output": planted.after}
    criteria = {"input": cycle_criteria(source, captured, still, period),
                "output": cycle_criteria(skeleton, moved.remove(planted.q, times), moved, played)}
    return Retargeted(entry_id, skeleton, times, planted.q, requested, path.names,
                      float(error.max()), clamped, criteria, moved, weights, rate=float(rate),
                      feet=feet, poulaine_q=out)


def lowest_rate(period: float) -> float:
    """The lowest output rate (Hz) :func:`retarget` delivers for a cycle of ``period`` s:
    :data:`MIN_STEPS` samples over it."""
    return (MIN_STEPS - 0.5) / period


def foot_skate(skeleton: Skeleton, q: np.ndarray, time_s: np.ndarray, /) -> float:
    """How fast the feet slide in support, m/s: per foot, the median speed of its ankle centre
    over the frames where it is within :data:`SUPPORT_HEIGHT` of its lowest over ``q`` (n, D)
    at ``time_s`` (n,) (world frame); the larger of the two feet's."""

    ankles = ankle_centres(skeleton, q)
    speed = np.linalg.norm(np.gradient(ankles, time_s, axis=0), axis=-1)
    height = ankles[..., 2]
    support = height <= height.min(axis=0) + SUPPORT_HEIGHT
    return float(max(np.median(speed[support[:, side], side]) for side in (0, 1)))


def _requested(own: tuple, source: Skeleton, target: Skeleton, step_length, foot_spacing,
               stance) -> tuple[float, float, float]:
    """The requested (step length, foot spacing, stance), m: given, or the entry's ``own``
    scaled to the target (module docstring)."""
    legs = [s.lengths["thigh"] + s.lengths["shank"] for s in (source, target)]
    hips = [s.lengths["hip_width"] for s in (source, target)]
    defaults = (own[0] * legs[1] / legs[0], own[1] * hips[1] / hips[0], own[2] * legs[1] / legs[0])
    out = tuple(float(d if given is None else given)
                for d, given in zip(defaults, (step_length, foot_spacing, stance)))
    if not (out[0] > 0 and out[2] > 0 and np.isfinite(out[1])) or max(map(abs, out)) > 5.0:
        raise MocapError(f"step length {out[0]:.4g} m, foot spacing {out[1]:.4g} m, stance "
                         f"{out[2]:.4g} m: step length and stance must be > 0 m and all within "
                         "5 m of 0 (metres, not centimetres)")
    return out


def _stride_scale(library, entry, path, size: float) -> float:
    """How much faster the retargeted pelvis travels than the entry's: the x-source's stride
    (its path frame's speed times its period) scaled to the target's body (``size``, its
    poulaine's factor) times its x-correction, over the entry's stride: the stance ankle then
    moves back under the pelvis as fast as the pelvis moves on."""
    def stride(e) -> float:
        return float(np.hypot(e.root_drift.u_f_m_s, e.root_drift.u_l_m_s) * e.T)

    own = stride(entry)
    if own < 1e-3:            # turning on the spot: the x-correction alone
        return path.x_scale
    return stride(library.entry(path.names[0])) * size * path.x_scale / own


def _body_sizes(library, entry, own, target: Skeleton) -> dict[str, float]:
    """The entries whose poulaines :func:`~mocaplib.gait.poulaine.blend` chooses from, each
    with the factor that scales its poulaine to the ``target`` body (the ratio of leg lengths,
    thigh + shank: the poulaines are compared as if walked by the target): the library's
    entries with one, of ``entry``'s locomotion class, moving if it moves (v̂ at least
    :data:`~mocaplib.gait.poulaine.MIN_TRAVEL_SPEED`) and on the spot if it does not, turning within
    :data:`SIMILAR_TURN` of its ω̂, travelling within :data:`SIMILAR_TRAVEL` of its direction
    relative to the pelvis and in support within :data:`SIMILAR_SUPPORT` of its share of the
    cycle (``own``: its poulaine; :attr:`~mocaplib.gait.poulaine.Poulaine.duty_factor`)."""
    def leg(skeleton: Skeleton) -> float:
        return skeleton.lengths["thigh"] + skeleton.lengths["shank"]

    return {name: leg(target) / leg(library.entry_skeleton(name))
            for name in _candidates(library, entry, own)}


def _candidates(library, entry, own) -> dict:
    """The poulaines of the entries :func:`_body_sizes` names, by entry id."""

    moving = entry.v >= MIN_TRAVEL_SPEED
    same = [e.id for e in library.entries if e.poulaine is not None
            and e.locomotion_class == entry.locomotion_class
            and (e.v >= MIN_TRAVEL_SPEED) == moving and abs(e.omega - entry.omega) <= SIMILAR_TURN]
    found = {name: library.poulaine(name) for name in same}
    return {name: p for name, p in found.items()
            if abs(np.angle(np.exp(1j * (p.travel - own.travel)))) <= SIMILAR_TRAVEL
            and abs(p.duty_factor - own.duty_factor) <= SIMILAR_SUPPORT}


def _targets(path, own, requested: tuple, phase: np.ndarray, period: float) -> np.ndarray:
    """The ankle targets (n + 1, 2, 3) m at ``phase`` (n + 1,) over [0, 1]: the blended poulaine
    ``path`` low-passed (:func:`periodic_lowpass`), then corrected again, as
    :func:`~mocaplib.gait.poulaine.blend` corrects it, so that at the phases of the entry's (``own``)
    characteristic points it has the ``requested`` step length, foot spacing and stance
    exactly."""
    series = periodic_lowpass(path(phase[:-1]).reshape(len(phase) - 1, 6), period)
    sides = (own.left, own.right)

    def at(kind):        # both ankles where the entry passes its point ``kind``: (2, 3)
        return np.stack([series(p.phases[p.kinds.index(kind)] * period).reshape(2, 3)[s]
                         for s, p in enumerate(sides)])

    foremost, rearmost, under = at("foremost"), at("rearmost"), at("under_pelvis")
    targets = series(phase * period).reshape(-1, 2, 3)
    targets[..., 0] *= requested[0] / np.mean(foremost[:, 0] - rearmost[:, 0])
    shift = (requested[1] - (under[0, 1] - under[1, 1])) / 2
    targets[:, 0, 1] += shift
    targets[:, 1, 1] -= shift
    targets[..., 2] *= requested[2] / -np.mean(under[:, 2])
    return targets


def periodic_lowpass(values: np.ndarray, period: float, /, *, cutoff: float | None = None):
    """One cycle's samples ``values`` (n, C) at n equal steps over [0, T) (``period`` T s)
    without their harmonics above ``cutoff`` Hz (default
    :data:`mocaplib.model.filtering.WALKING_CUTOFF`): the least-squares Fourier series of order
    floor(cutoff·T) (:func:`mocaplib.gait.fourier.fit_series`), a
    :class:`~mocaplib.gait.fourier.FourierSeries` to evaluate at any time."""

    values = np.asarray(values, dtype=np.float64)
    times = np.arange(len(values)) * period / len(values)
    order = min(int(np.floor((WALKING_CUTOFF if cutoff is None else cutoff) * period)),
                (len(values) - 1) // 2)
    return fit_series(values, times, period, order)


def cycle_criteria(skeleton: Skeleton, q_path: np.ndarray, drift: RootDrift,
                   period: float, /) -> dict:
    """C1-C3 (:mod:`mocaplib.gait.criteria`) of one cycle sampled at ``n + 1`` equal steps over
    [0, T] (``q_path`` (n + 1, D), root in the path frame ``drift`` moves along): C1 from
    periodic third differences of the joint angles over the first n samples; C2 between the
    first and last sample; C3 from the world motion (the path frame's drift put back), its
    velocities by centred differences with one more sample each side, taken periodically in
    the path frame."""

    steps = len(q_path) - 1
    rate = steps / period
    unwrapped = q_path.copy()
    unwrapped[:, ~TRANSLATION] = np.unwrap(unwrapped[:, ~TRANSLATION], axis=0)
    smooth = periodic_lowpass(unwrapped[:-1], period)(np.arange(steps) * period / steps)
    third = third_derivative(smooth[:, JOINT_ANGLES], rate, periodic=True)
    padded = np.vstack([smooth[-1], smooth, smooth[:2]])
    times = np.arange(-1, steps + 2) * period / steps
    energies = segment_energies(skeleton, drift.restore(padded, times), rate)[1:-1]
    return {"jerk_rms_rad_s3": jerk_rms(third),
            "cycle_closure_rad": closure(unwrapped[0], unwrapped[-1]),
            "internal_power_w_kg": internal_power(energies, period)}


def solve(skeleton: Skeleton, targets: np.ndarray, reference: np.ndarray, /, *,
          weights: Weights = Weights(), step: float) -> tuple[np.ndarray, np.ndarray, int]:
    """The inverse kinematics of the module docstring, frame after frame.

    ``targets`` (m, 2, 3): left and right ankle centres (m) in the frame of a pelvis at the
    origin; ``reference`` (m, D): the reference postures in that frame (the non-task DOFs are
    kept); ``step``: seconds between frames. Returns the joint coordinates (m, D), each frame's
    largest ankle error (m,) m and the number of steps a joint limit stopped.
    """

    task = np.array(TASK_DOFS)
    lower, upper = (bound[task].copy() for bound in Skeleton.bounds())
    knees = np.isin(task, KNEES)
    lower[knees] = np.maximum(lower[knees], 0.0)             # never hyperextended
    reference = np.clip(reference, *Skeleton.bounds())
    parts = bodies(skeleton)
    feet, offsets = np.array(FEET), np.zeros((2, 3))
    out = reference.copy()
    errors = np.zeros(len(targets))
    clamped = 0
    for k in range(len(targets)):
        pose = reference[k].copy()
        if k:
            pose[task] = out[k - 1, task] + reference[k, task] - reference[k - 1, task]
        previous = out[k - 1, task] if k else None
        inertia = _rotational_inertia(skeleton, pose, parts, task) if k else None
        for _ in range(ITERATIONS):
            points, jacobian = skeleton.marker_jacobian(pose[None], feet, offsets)
            gap = (targets[k] - points[0]).ravel()
            J = jacobian[0].reshape(6, -1)[:, task]
            U, sigma, Vt = np.linalg.svd(J)
            damping = DAMPING ** 2 * max(0.0, 1.0 - (sigma[-1] / SINGULAR) ** 2)
            primary = Vt[:6].T @ (sigma / (sigma ** 2 + damping) * (U.T @ gap))
            null = Vt[6:].T
            gradient, hessian = _costs(pose[task], reference[k, task], previous, inertia,
                                       lower, upper, weights, step)
            reduced = null.T @ hessian @ null + 1e-12 * np.eye(null.shape[1])
            move = primary - null @ np.linalg.solve(reduced,
                                                    null.T @ (gradient + hessian @ primary))
            wanted = pose[task] + move * min(1.0, MAX_STEP / np.abs(move).max(initial=1e-12))
            pose[task] = np.clip(wanted, lower + 1e-9, upper - 1e-9)
            clamped += int(np.any(pose[task] != wanted))
            if np.abs(gap).max() < TOLERANCE and np.abs(move).max() < 1e-7:
                break
        points = skeleton.marker_jacobian(pose[None], feet, offsets)[0][0]
        errors[k] = np.linalg.norm(targets[k] - points, axis=1).max()
        out[k] = pose
    return out, errors, clamped


def _rotational_inertia(skeleton: Skeleton, pose: np.ndarray, parts, task: np.ndarray
                        ) -> np.ndarray:
    """M (T, T) of the rotational kinetic energy ½ θ̇ᵀ M θ̇ (J/kg) of the task DOFs' rates in
    ``pose`` (D,): Σ_b A_bᵀ R_b I_b R_bᵀ A_b (module docstring)."""
    transforms, axes, _ = skeleton.chain(pose[None])
    R = transforms[0, parts.segments, :3, :3]                            # (B, 3, 3)
    world = R @ (parts.inertia[:, :, None] * np.swapaxes(R, 1, 2))       # R I Rᵀ
    A = axes[0][task].T[None] * MOVES[parts.segments][:, None, task]      # (B, 3, T)
    return np.einsum("bit,bij,bju->tu", A, world, A)


def _costs(theta, reference, previous, inertia, lower, upper, weights: Weights,
           step: float) -> tuple[np.ndarray, np.ndarray]:
    """Gradient (T,) and Hessian (T, T) of the weighted null-space costs at ``theta`` (module
    docstring); the kinetic cost only when a ``previous`` frame and its ``inertia`` exist."""
    gradient = 2 * weights.reference * (theta - reference)
    hessian = 2 * weights.reference * np.eye(len(theta))
    bounded = np.isfinite(lower) & np.isfinite(upper)
    a = np.maximum(upper - theta, 1e-6)[bounded]
    b = np.maximum(theta - lower, 1e-6)[bounded]
    span2 = (upper - lower)[bounded] ** 2
    gradient[bounded] += weights.joint_limits * -span2 / 4 * (a - b) / (a * b) ** 2
    hessian[bounded, bounded] += weights.joint_limits * span2 / 2 * (a * b + (a - b) ** 2) \
        / (a * b) ** 3
    if previous is not None:
        gradient += weights.kinetic * inertia @ (theta - previous) / step ** 2
        hessian += weights.kinetic * inertia / step ** 2
    return gradient, hessian
