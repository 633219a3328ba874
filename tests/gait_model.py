"""Analytic gait trajectories with known answers, shared by the event/cycle/pattern tests.

A walker's shoulder midpoint follows model (2) of the paper with constant body-frame velocity
(v_f, v_l) and turn rate ω; its feet are rigid heel-toe segments that stay put in stance, roll
about the toe tip before toe-off, land heel first and swing along a smooth arc. Toe-off is the
instant the toe tip leaves the ground; heel-strike the instant the heel touches it.
"""

from __future__ import annotations

import numpy as np

FOOT = 0.22      # heel-to-toe-tip length, m
HEEL_Z = 0.02    # heel marker height above the sole in stance, m
TOE_Z = 0.03     # toe marker height above the sole, m
TOE_BACK = 0.04  # toe marker behind the toe tip, m
PEAK_PITCH = 0.6  # heel-up pitch at toe-off, rad


def body_path(t, *, v_f=1.2, v_l=0.0, omega=0.0, heading0=0.0):
    """Shoulder-midpoint reference pose at times t: x, y (m), heading θ_S (rad)."""
    t = np.asarray(t, dtype=float)
    psi = heading0 + omega * t
    if abs(omega) < 1e-12:
        fx, fy = v_f * t, v_l * t
        c, s = np.cos(heading0), np.sin(heading0)
        return c * fx - s * fy, s * fx + c * fy, psi
    x = (v_f * (np.sin(psi) - np.sin(heading0)) + v_l * (np.cos(psi) - np.cos(heading0))) / omega
    y = (-v_f * (np.cos(psi) - np.cos(heading0)) + v_l * (np.sin(psi) - np.sin(heading0))) / omega
    return x, y, psi


def shoulders(t, *, width=0.36, sway=0.02, v_f=1.2, v_l=0.0, omega=0.0, period=1.1,
              noise=0.0, seed=0):
    """Left and right shoulder markers (F, 3) with lateral sway at the stride frequency."""
    x, y, psi = body_path(t, v_f=v_f, v_l=v_l, omega=omega)
    left_dir = np.column_stack([-np.sin(psi), np.cos(psi), np.zeros_like(psi)])
    mid = np.column_stack([x, y, 1.4 + 0.02 * np.cos(4 * np.pi * t / period)])
    mid += left_dir * sway * np.sin(2 * np.pi * t / period)[:, None]
    rng = np.random.default_rng(seed)
    left = mid + left_dir * width / 2 + rng.normal(0, noise, mid.shape)
    right = mid - left_dir * width / 2 + rng.normal(0, noise, mid.shape)
    return left, right


def _smoothstep(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (10 - 15 * u + 6 * u * u)


def foot(t, *, period=1.1, duty=0.62, offset=0.0, step=1.3, direction=0.0, ground=0.0,
         lift=0.12, roll=0.45, land_pitch=0.25, flat_time=0.1, noise=0.0, seed=0):
    """Heel and toe markers (F, 3) of one foot, and its true toe-off / heel-strike times.

    Stance starts at heel-strike ``offset + k·period``; toe-off at ``duty`` of the period.
    The foot rolls about the toe tip during the last ``roll`` of stance (pitch to 50°), lands
    pitched ``land_pitch`` rad toes-up and flattens in ``flat_time`` s. ``step`` is the foot's
    displacement per period along ``direction`` (rad), so side-steps and diagonals are a
    direction away; ``ground`` is the stance height of the sole (a raised treadmill belt).
    """
    t = np.asarray(t, dtype=float)
    u = np.array([np.cos(direction), np.sin(direction), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    stance = duty * period
    k = np.floor((t - offset) / period)
    phase = t - offset - k * period  # time since the last heel-strike
    base = (k * step)[:, None] * u   # heel contact point of this stride
    swing = phase >= stance
    # pitch > 0: heel up (roll about the toe tip); < 0: toes up (rock on the heel)
    pitch = np.zeros_like(t)
    landing = phase < flat_time
    pitch[landing] = -land_pitch * (1 - _smoothstep(phase[landing] / flat_time))
    rolling = (phase >= (1 - roll) * stance) & ~swing
    pitch[rolling] = PEAK_PITCH * ((phase[rolling] - (1 - roll) * stance) / (roll * stance)) ** 2
    # swing pitch leaves the roll at its rate, then goes to -land_pitch
    s = (phase[swing] - stance) / (period - stance)
    rate0 = 2 * PEAK_PITCH / (roll * stance) * (period - stance)
    pitch[swing] = (PEAK_PITCH + rate0 * s * (1 - s) ** 2
                    + (-land_pitch - PEAK_PITCH) * (3 * s ** 2 - 2 * s ** 3))
    along = np.cos(pitch)[:, None] * u - np.sin(pitch)[:, None] * up  # heel -> tip, sole
    normal = np.sin(pitch)[:, None] * u + np.cos(pitch)[:, None] * up
    sole_heel = base.copy()                                   # flat or rocking on the heel
    tip = base + FOOT * u
    heel_up = (pitch > 0) & ~swing
    sole_heel[heel_up] = tip[heel_up] - FOOT * along[heel_up]  # pivot about the toe tip
    end_tip = base[swing] + step * u + FOOT * (
        np.cos(land_pitch) * u + np.sin(land_pitch) * up)
    moving_tip = tip[swing] + (3 * s ** 2 - 2 * s ** 3)[:, None] * (end_tip - tip[swing])
    moving_tip[:, 2] += lift * np.sin(np.pi * (s + 0.3 * s * (1 - s)))  # leaves the floor briskly
    sole_heel[swing] = moving_tip - FOOT * along[swing]
    sole_heel[:, 2] += ground
    heel = sole_heel + HEEL_Z * normal
    toe = sole_heel + (FOOT - TOE_BACK) * along + TOE_Z * normal
    rng = np.random.default_rng(seed)
    heel += rng.normal(0, noise, heel.shape)
    toe += rng.normal(0, noise, toe.shape)
    n = np.arange(-1, int(t[-1] / period) + 2)
    strikes = offset + n * period
    offs = strikes + stance

    def inside(x):
        return x[(x > t[0]) & (x < t[-1])]

    return heel, toe, inside(offs), inside(strikes)
