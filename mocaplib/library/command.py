"""A locomotion command: what a controller asks of the library, and what a capture plan asks a
subject (or the synthetic walker) to do.

The command is the paper's model (2): forward speed ``v_f`` (m/s), lateral speed ``v_l`` (m/s,
> 0 to the person's left) and turn rate ``omega`` (rad/s, > 0 turns left) of the
shoulder-midpoint frame, held constant, plus the gait (``walk``, ``run`` or ``stand``).
:meth:`Command.from_kind` builds one from a locomotion type, a speed and a radius or path
direction, the way a capture plan is written; :func:`plan_command` reads a plan's table.
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


#: The two forms of a plan's ``command`` table: the velocities, or a kind and its parameters.
_COMMAND_KEYS = {"v_f", "v_l", "omega", "gait"}
_KIND_KEYS = {"kind", "speed", "radius", "direction", "side"}


def plan_command(spec, /) -> Command:
    """A command from a plan's inline table (either form); raises SynthError."""
    if not isinstance(spec, dict):
        raise SynthError("command must be a table")
    keys = set(spec)
    if keys <= _COMMAND_KEYS:
        return Command(**{k: (v if k == "gait" else float(v)) for k, v in spec.items()})
    if "kind" in keys and keys <= _KIND_KEYS:
        options = {k: (v if k == "side" else float(v)) for k, v in spec.items() if k != "kind"}
        return Command.from_kind(spec["kind"], **options)
    raise SynthError(f"command keys {sorted(keys)} mix or miss the two forms",
                     hint="use { kind, speed, radius|direction, side } or "
                          "{ v_f, v_l, omega, gait }")
