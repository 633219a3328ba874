"""A stair made from a sample walk, for the tests of events and of non-level cycles: each
stance a tread lower (or higher) than the one before."""

from __future__ import annotations

import dataclasses

import numpy as np

SIDES = {"left": "L", "right": "R"}
#: A stair's riser (m): each stance stands this much lower than the one before.
RISER = 0.17


def _smoothstep(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def stairs(trial, truth, riser):
    """``trial`` (a sample walk) on a stair: every stance, of either foot, ``riser`` m lower
    (higher for a negative riser) than the one before it. A foot's markers step from one tread
    to the next in the middle half of each swing, so that it leaves and lands as on the level
    (the kinematic marks of its release and landing stay where they were: what changes is
    the floor); the rest of the body follows the mean of the feet."""
    rate, n = trial.rate, trial.n_frames
    frames = np.arange(n)
    events = sorted((e["time_s"] * rate, e["side"], e["kind"]) for e in truth["events"])
    offs = {side: [t for t, s, k in events if s == side and k == "toe_off"] for side in SIDES}
    # the stances after a swing, in time order: the k-th stands on the k-th tread down
    steps = [(t, side) for t, side, kind in events
             if kind == "heel_strike" and any(off < t for off in offs[side])]
    level = {side: np.zeros(n) for side in SIDES}
    for tread, (strike, side) in enumerate(steps, start=1):
        off = max(t for t in offs[side] if t < strike)
        previous = level[side][int(off)]
        swing = (frames - off) / (strike - off)
        level[side] = np.where(frames > off, previous + (-riser * tread - previous)
                               * _smoothstep((swing - 0.25) / 0.5), level[side])
    markers = trial.markers.copy()
    body = 0.5 * (level["left"] + level["right"])
    for i, label in enumerate(trial.labels):
        side = next((s for s, letter in SIDES.items() if label[:1] == letter and label[1:]
                     in ("HEE", "TOE", "MT5", "ANK")), None)
        markers[:, i, 2] += level[side] if side else body
    return dataclasses.replace(trial, markers=markers)
