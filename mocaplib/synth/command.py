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

from dataclasses import dataclass

import numpy as np

from ..errors import SynthError

GAITS = ("walk", "run", "stand")
#: Locomotion types :meth:`Command.from_kind` understands.
KINDS = ("straight", "curve", "spot_turn", "sidestep", "diagonal", "run", "rest")


@dataclass(frozen=True)
class Command:
    """A constant locomotion command of the shoulder-midpoint frame (SI units)."""

    v_f: float = 0.0
    v_l: float = 0.0
    omega: float = 0.0
    gait: str = "walk"

    def __post_init__(self):
        if self.gait not in GAITS:
            raise SynthError(f"gait must be one of {', '.join(GAITS)}, got {self.gait!r}")
        values = (self.v_f, self.v_l, self.omega)
        if not all(np.isfinite(v) for v in values):
            raise SynthError(f"command speeds must be finite, got {values}")
        if self.gait == "stand" and any(values):
            raise SynthError("a standing command has v_f = v_l = omega = 0")
        if self.gait == "run" and self.v_f < 1.5:
            raise SynthError(f"running needs v_f >= 1.5 m/s, got {self.v_f}")
        if self.gait == "walk" and self.speed > 2.2:
            raise SynthError(f"walking faster than 2.2 m/s is not modelled, got {self.speed:.2f}",
                             hint="use gait = \"run\"")
        if self.gait != "stand" and self.speed < 0.05 and abs(self.omega) < 0.05:
            raise SynthError("a moving command needs a speed or a turn rate above 0.05",
                             hint="use gait = \"stand\" for standing still")

    @property
    def speed(self) -> float:
        """Tangential speed of the reference frame, m/s."""
        return float(np.hypot(self.v_f, self.v_l))

    @property
    def direction(self) -> float:
        """Path direction relative to the body, θ_T − θ_S (rad); 0 when not moving."""
        return float(np.arctan2(self.v_l, self.v_f)) if self.speed > 0 else 0.0

    @property
    def radius(self) -> float:
        """Radius of the reference path in metres (inf when straight, 0 on the spot)."""
        return self.speed / abs(self.omega) if self.omega else np.inf

    def as_dict(self) -> dict:
        return {"v_f": self.v_f, "v_l": self.v_l, "omega": self.omega, "gait": self.gait}

    @classmethod
    def from_kind(cls, kind: str, *, speed: float = 0.0, radius: float | None = None,
                  direction: float | None = None, side: str = "left") -> "Command":
        """A command from a locomotion type.

        ``straight`` and ``run``: forward at ``speed`` m/s. ``curve``: forward at ``speed`` on a
        circle of ``radius`` m turning to ``side``. ``spot_turn``: ``speed`` is the turn rate in
        rad/s, towards ``side``. ``sidestep``: ``speed`` m/s towards ``side``. ``diagonal``:
        ``speed`` m/s along ``direction`` rad relative to the body (θ_T − θ_S, > 0 to the left).
        ``rest``: standing still.
        """
        sign = {"left": 1.0, "right": -1.0}.get(side)
        if sign is None:
            raise SynthError(f"side must be 'left' or 'right', got {side!r}")
        if not speed >= 0:
            raise SynthError(f"speed is a magnitude, >= 0, got {speed}",
                             hint="give the way with side = \"left\"/\"right\" or direction")
        if kind in ("straight", "run"):
            return cls(v_f=speed, gait="run" if kind == "run" else "walk")
        if kind == "curve":
            if not radius or radius <= 0:
                raise SynthError(f"a curve needs a radius > 0 m, got {radius}")
            return cls(v_f=speed, omega=sign * speed / radius)
        if kind == "spot_turn":
            return cls(omega=sign * speed)
        if kind == "sidestep":
            return cls(v_l=sign * speed)
        if kind == "diagonal":
            if direction is None:
                raise SynthError("a diagonal walk needs a direction (rad, relative to the body)")
            return cls(v_f=speed * np.cos(direction), v_l=speed * np.sin(direction))
        if kind == "rest":
            return cls(gait="stand")
        raise SynthError(f"unknown locomotion kind {kind!r}; kinds are {', '.join(KINDS)}")


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
