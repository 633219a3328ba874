"""The biomechanical criteria of a locomotion cycle (Pronost et al.): C1 jerk, C2 closure, C3
internal power.

* **C1**, :func:`jerk_rms`: RMS over frames and joint angles of the third time derivative of the
  joint angles, rad/s³ (centred differences, :func:`third_derivative`).
* **C2**, :func:`closure`: ‖θ(end) − θ(start)‖ over the joint angles, rad.
* **C3**, :func:`internal_power`: the kinetic energy theorem applied to every body segment: over
  each time step, the work done on segment *i* by the forces other than gravity is the change of
  its kinetic energy minus the work of gravity,

      ΔW_i = ΔE_k,i − W_g,i = Δ(½ m_i |v_i|² + ½ ω_iᵀ I_i ω_i) + m_i g Δz_i,

  with translational and rotational kinetic energy, v_i the velocity of its centre of mass and
  ω_i its angular velocity (world frame, Z up); C3 = Σ_steps Σ_i |ΔW_i| / (m T), watts per
  kilogram of body mass over the duration T. Segment masses, centres of mass and inertias are de
  Leva's (1996), laid on the subject's skeleton (:mod:`mocaplib.model.anthropometry`), per kilogram of
  body mass, so the body mass itself is never needed.

"Joint angles" are :data:`mocaplib.skeleton.JOINT_ANGLES`: the rotational DOFs except the root's
heading. Arrays: time on axis 0, radians (``pelvis_t*`` metres), seconds.
"""

from __future__ import annotations

import numpy as np

from ..model.anthropometry import Bodies, bodies
from ..skeleton import JOINT_ANGLES, Skeleton

#: Standard gravity, m/s².
GRAVITY = 9.80665


def third_derivative(values: np.ndarray, rate: float, /, *, periodic: bool = False
                     ) -> np.ndarray:
    """Centred third differences ``(x[k+2] − 2x[k+1] + 2x[k−1] − x[k−2]) / 2h³`` of ``values``
    (F, C) sampled at ``rate`` Hz: (F, C), units per s³. NaN at the two frames of each end, or,
    when ``periodic``, the samples wrap around (one cycle sampled over [0, T))."""
    x = np.asarray(values, dtype=np.float64)
    if periodic:
        return (np.roll(x, -2, axis=0) - 2 * np.roll(x, -1, axis=0) + 2 * np.roll(x, 1, axis=0)
                - np.roll(x, 2, axis=0)) * rate ** 3 / 2
    out = np.full_like(x, np.nan)
    out[2:-2] = (x[4:] - 2 * x[3:-1] + 2 * x[1:-3] - x[:-4]) * rate ** 3 / 2
    return out


def jerk_rms(third: np.ndarray) -> float:
    """C1: RMS of third derivatives (F, C) over every finite value, rad/s³ (NaN when none)."""
    third = np.asarray(third, dtype=np.float64)
    finite = third[np.isfinite(third)]
    return float(np.sqrt(np.mean(finite ** 2))) if finite.size else float("nan")


def closure(q_start: np.ndarray, q_end: np.ndarray) -> float:
    """C2: norm of the change of the joint angles from ``q_start`` to ``q_end`` (each (D,),
    angles unwrapped), rad."""
    return float(np.linalg.norm((np.asarray(q_end) - np.asarray(q_start))[JOINT_ANGLES]))


def segment_energies(skeleton: Skeleton, q: np.ndarray, rate: float, /, *,
                     periodic: bool = False, parts: Bodies | None = None) -> np.ndarray:
    """Each body's mechanical energy (kinetic, translational and rotational, plus potential)
    per kilogram of body mass in poses ``q`` (F, D) sampled at ``rate`` Hz: (F, B) J/kg, bodies
    of :func:`mocaplib.model.anthropometry.bodies` (``parts`` when already computed).

    Velocities are centred differences of the bodies' centres of mass and orientations
    (one-sided at the ends, or wrapping around when ``periodic``). Potential energy counts
    heights from z = 0.
    """
    parts = bodies(skeleton) if parts is None else parts
    q = np.asarray(q, dtype=np.float64)
    if periodic or len(q) <= ENERGY_BLOCK:
        return _energies(skeleton, q, rate, periodic, parts)
    out = np.empty((len(q), len(parts.segments)))
    for start in range(0, len(q), ENERGY_BLOCK):       # a frame of margin for the differences
        lo, hi = max(start - 1, 0), min(start + ENERGY_BLOCK + 1, len(q))
        block = _energies(skeleton, q[lo:hi], rate, False, parts)
        out[start:start + ENERGY_BLOCK] = block[start - lo:start - lo + ENERGY_BLOCK]
    return out


#: Frames whose energies :func:`segment_energies` computes at once (a long take's are taken a
#: block at a time, with one frame of margin on each side for the centred differences: the
#: same numbers, in work arrays near 40 MB whatever the capture's length).
ENERGY_BLOCK = 4096


def _energies(skeleton: Skeleton, q: np.ndarray, rate: float, periodic: bool,
              parts: Bodies) -> np.ndarray:
    """:func:`segment_energies` of all of ``q`` (F, D) at once: (F, B) J/kg."""
    frames = skeleton.forward(q, segments=parts.segments)             # (F, B, 4, 4)
    R = frames[..., :3, :3]
    centre = (R @ parts.com[..., None])[..., 0] + frames[..., :3, 3]  # (F, B, 3)
    h = 1.0 / rate
    if periodic:
        velocity = (np.roll(centre, -1, axis=0) - np.roll(centre, 1, axis=0)) / (2 * h)
        turning = (np.roll(R, -1, axis=0) - np.roll(R, 1, axis=0)) / (2 * h)
    else:
        velocity = np.gradient(centre, h, axis=0)
        turning = np.gradient(R, h, axis=0)
    spin = np.swapaxes(R, -1, -2) @ turning                           # Rᵀ Ṙ = [ω]x, body axes
    omega = 0.5 * np.stack([spin[..., 2, 1] - spin[..., 1, 2], spin[..., 0, 2] - spin[..., 2, 0],
                            spin[..., 1, 0] - spin[..., 0, 1]], axis=-1)
    return (0.5 * parts.mass * np.sum(velocity ** 2, axis=-1)
            + 0.5 * np.sum(parts.inertia * omega ** 2, axis=-1)
            + parts.mass * GRAVITY * centre[..., 2])


def internal_power(energies: np.ndarray, duration: float, /) -> float:
    """C3 (W/kg): the sum over time steps and bodies of the absolute change of each body's
    energy (:func:`segment_energies`, (F, B) J/kg), divided by ``duration`` s."""
    return float(np.sum(np.abs(np.diff(np.asarray(energies), axis=0))) / duration)
