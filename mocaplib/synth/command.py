"""The locomotion command of a synthetic capture and the reference path it produces.

The command is the paper's model (2): forward speed ``v_f`` (m/s), lateral speed ``v_l`` (m/s,
> 0 to the person's left) and turn rate ``omega`` (rad/s, > 0 turns left) of the
shoulder-midpoint frame, held constant over the capture, plus the gait (``walk``, ``run`` or
``stand``). :meth:`Command.from_kind` builds one from a locomotion type, a speed and a radius or
path direction, the way a capture plan is written.

The *reference frame* is the horizontal frame the command moves: position ``(x, y)`` in metres
and heading ``theta`` (rad, counter-clockwise from +X). Integrated in closed form, so any time
array can be evaluated; the capture's middle instant sits at the origin facing +X.
"""

from __future__ import annotations

import numpy as np

from ..library.command import Command


def reference_path(command: Command, t: np.ndarray, *, t_mid: float = 0.0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Position (F, 2) in metres and heading (F,) in rad of the reference frame at times ``t``.

    The frame is at the origin facing +X at ``t_mid``; its velocity in its own axes is always
    ``(v_f, v_l)`` and it turns at ``omega``.
    """
    s = np.asarray(t, dtype=float) - t_mid
    w = command.omega
    # sin(ws)/w and (1 - cos ws)/w written with sinc so that w -> 0 is exact.
    a = s * np.sinc(w * s / np.pi)
    b = 0.5 * w * s ** 2 * np.sinc(w * s / (2 * np.pi)) ** 2
    x = command.v_f * a - command.v_l * b
    y = command.v_f * b + command.v_l * a
    return np.stack([x, y], axis=-1), w * s


def frame_to_world(xy: np.ndarray, theta: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Points ``local`` (F, 2) given in frames at ``xy`` (F, 2) with heading ``theta`` (F,)."""
    c, s = np.cos(theta), np.sin(theta)
    return xy + np.stack([c * local[..., 0] - s * local[..., 1],
                          s * local[..., 0] + c * local[..., 1]], axis=-1)


def world_to_frame(xy: np.ndarray, theta: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Inverse of :func:`frame_to_world`: world points (F, 2) in the moving frames."""
    d = points - xy
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)
