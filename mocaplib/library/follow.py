"""Following a path with the library: continuous motion synthesised cycle after cycle (the
on-line stage of Truong et al. 2010, as a reference for the tools that read a library).

Paths
-----
A :class:`Path` is either a **polyline** (x, y in metres in the world frame, Z up; the times
``t`` in seconds optional, else a constant speed) or a **timeline** of velocity commands
(t s, v̂ m/s, ω̂ rad/s, v̂_l m/s: the control space's tangential axes, held linear between
rows). :func:`read_path` reads either from a CSV file by its header.

Algorithm (:func:`follow`)
--------------------------
The walker starts on the path (its first point, facing along it; a timeline starts at the
origin facing +X). Cycle after cycle, at the pose the previous cycle ended at:

1. **Command.** Polyline: the speed v̂ (the segment's, from ``t``, or the constant one) and the
   turn rate ω̂ that turns the blended path frame's travel direction over one cycle onto the
   path's direction one stride ahead (the blend's stride, ``|u|·T`` along the path from the
   walker's projection onto it), plus ``atan(e / stride)`` towards the path for a walker ``e``
   metres beside it (which halves the offset every cycle); two iterations put the blend's own
   turn rate (not the command's) on that value. The path's direction at arc length s is that
   of its chord from s − w to s + w, w = :data:`TANGENT_WINDOW` strides: a polyline sampled
   from a curve turns in steps at its vertices (4.5° on a 3 m half circle of 40 points),
   which the chord smooths, so the commands follow the curve, not the steps (on the 68-entry
   sample library, 3 m half circle: root 3.4 cm and heading 4.0° from the path, against 7.0 cm
   and 6.4° with the segments' own directions). v̂_l = 0 (the walker faces along the path).
   Timeline: the command at the cycle's start time, ω̂ corrected by the error of the body's
   heading (the path frame's plus the blend's mean ``pelvis_rotation`` in it) at the cycle's
   end, plus ``atan(e / stride)`` towards the reference for a walker ``e`` metres beside it
   across its direction of travel; the reference is the commands integrated (the body facing
   +X at the start, the heading the integral of ω̂).
2. **Blend** at that command in one gait's cell (:meth:`ControlSpace.query` and
   :meth:`~ControlSpace.blend`): coefficients, period T and root drift. A command the cell
   serves only clamped (at its nearest point) is served at that point's turn rate; the turn
   rate it lacks, up to :data:`MAX_TURN_WARP`, turns the cycle's path frame (the *turn
   warp*, as a game engine's orientation warping turns a clip's root): a run cell whose
   captured runs are all straight still steers a run back onto its path.
3. **Stitch.** Each cycle starts at a left toe-off, where the previous one ended (phase
   continuity). Its path frame starts at the pose the previous one ended at and moves with
   its blended drift (:class:`mocaplib.gait.fourier.RootDrift`); the joint angles and the root
   in the path frame are the series at phase τ/T, the coefficients cross-faded (smoothstep)
   from the previous cycle's over the first :data:`FADE` of the cycle, so no frame jumps.

Frames are sampled at exactly ``rate`` Hz from t = 0 (frame k at k/rate s), whatever the
periods. The result carries each cycle's start, period, command, gait, entries and weights,
so that stance intervals and foot planting can be computed per cycle from its entries.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field

import numpy as np

from ..errors import MocapError
from ..gait.fourier import RootDrift
from ..skeleton import JOINT_ANGLES, ROOT_HEADING, ROOT_X, ROOT_Y

#: Share of a cycle (phase) over which its coefficients are cross-faded from the previous one's.
FADE = 0.5
#: Half the chord (in strides) whose direction is the path's direction for the commands
#: (module docstring, 1.); measured on the 68-entry sample library, 0.15 to 0.25 keep the 3 m
#: half circle and the S-curve within 5 cm and 5°, 0.5 cuts the S-curve's corners (8.8 cm).
TANGENT_WINDOW = 0.2
#: How far (s) beyond a timeline's last time its reference is integrated (a cycle starting
#: before the end ends after it).
REFERENCE_BEYOND_S = 5.0
#: Most cycles one path may take (a typing mistake in a timeline's times, not a walk).
MAX_CYCLES = 2000
#: The largest turn rate (rad/s, about 6 deg/s) a clamped cycle's path frame is turned beyond
#: its blend's (module docstring, 2.): the heading and offset corrections of a straight path
#: need a few hundredths.
MAX_TURN_WARP = 0.1
#: Headers of the two path forms.
POLYLINE_COLUMNS, TIMELINE_COLUMNS = ("x", "y"), ("t", "v", "omega", "v_l")


@dataclass(frozen=True)
class Path:
    """A path to follow: ``kind`` "polyline" with ``xy`` (P, 2) m and optional ``t`` (P,) s, or
    "timeline" with ``t`` (P,) s and ``commands`` (P, 3) (v̂, ω̂, v̂_l); ``source`` the file."""

    kind: str
    xy: np.ndarray | None = None
    t: np.ndarray | None = None
    commands: np.ndarray | None = None
    source: str | None = None


def read_path(path, /) -> Path:
    """A :class:`Path` from a CSV file whose header names its columns: ``x, y`` (optionally
    ``t``) for a polyline, ``t, v, omega, v_l`` for a timeline. Raises MocapError naming the
    file, the row and what to do."""
    name = str(path)
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as exc:
        raise MocapError(f"cannot read the path: {exc}", path=name) from exc
    rows = [r for r in rows if any(c.strip() for c in r)]
    if len(rows) < 3:
        raise MocapError("a path needs a header and at least two rows", path=name)
    header = [c.strip().lower() for c in rows[0]]
    kind = ("timeline" if set(TIMELINE_COLUMNS) <= set(header) else
            "polyline" if set(POLYLINE_COLUMNS) <= set(header) else None)
    if kind is None:
        raise MocapError(f"the header {rows[0]} names neither a polyline nor a timeline",
                         path=name, hint="use the columns x,y (optionally t) in metres and "
                                         "seconds, or t,v,omega,v_l (s, m/s, rad/s, m/s)")
    wanted = TIMELINE_COLUMNS if kind == "timeline" else POLYLINE_COLUMNS + (
        ("t",) if "t" in header else ())
    values = np.empty((len(rows) - 1, len(wanted)))
    for i, row in enumerate(rows[1:], start=2):
        try:
            values[i - 2] = [float(row[header.index(c)]) for c in wanted]
        except (ValueError, IndexError):
            raise MocapError(f"row {i} is not {len(wanted)} numbers ({', '.join(wanted)})",
                             path=name) from None
    if not np.isfinite(values).all():
        raise MocapError("the path holds a value that is not finite", path=name)
    t = values[:, wanted.index("t")] if "t" in wanted else None
    if t is not None and not (np.diff(t) > 0).all():
        raise MocapError("the times t must increase from row to row", path=name)
    if kind == "timeline":
        return Path(kind, t=t, commands=values[:, 1:], source=name)
    if (np.linalg.norm(np.diff(values[:, :2], axis=0), axis=1) == 0).any():
        raise MocapError("two consecutive points of the polyline are equal", path=name,
                         hint="remove the repeated row")
    return Path(kind, xy=values[:, :2], t=t, source=name)


@dataclass
class Cycle:
    """One synthesised cycle: ``start_s`` (from the first frame), ``T`` s, ``command``
    (v̂, ω̂, v̂_l), its ``gait``, blended ``entries`` (ids) and ``weights``, ``clamped``, and
    ``turn_warp`` (rad/s) its path frame turns beyond the blend's."""

    start_s: float
    T: float
    command: tuple
    gait: str
    entries: list
    weights: list
    clamped: bool
    turn_warp: float = 0.0


@dataclass
class Followed:
    """The motion following a path: ``q`` (F, D) joint coordinates at ``rate`` Hz (root in the
    world frame), ``frame`` (F, 3) the path frame's x, y (m) and the body's mean heading (rad:
    the path frame's plus the cycle's mean ``pelvis_rotation`` in it) at each frame,
    the ``cycles`` and their ``blends`` (:class:`~mocaplib.library.controlspace.Blend`)."""

    q: np.ndarray
    rate: float
    frame: np.ndarray
    cycles: list = field(default_factory=list)
    blends: list = field(default_factory=list)


class _Polyline:
    """Arc-length geometry of a polyline (P, 2)."""

    def __init__(self, xy):
        self.xy = np.asarray(xy, dtype=float)
        self.seg = np.diff(self.xy, axis=0)
        self.length = np.linalg.norm(self.seg, axis=1)
        self.s = np.concatenate([[0.0], np.cumsum(self.length)])

    def project(self, p) -> float:
        """Arc length of the point of the polyline nearest to p (2,)."""
        u = np.clip(np.einsum("si,si->s", p - self.xy[:-1], self.seg) / self.length ** 2, 0, 1)
        d = np.linalg.norm(self.xy[:-1] + u[:, None] * self.seg - p, axis=1)
        k = int(np.argmin(d))
        return float(self.s[k] + u[k] * self.length[k])

    def at(self, s) -> np.ndarray:
        """Point (2,) at arc length s (clipped to the polyline; extended along the last
        segment beyond its end)."""
        k = int(np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, len(self.length) - 1))
        return self.xy[k] + (s - self.s[k]) / self.length[k] * self.seg[k]

    def heading(self, s) -> float:
        """Direction (rad) of the segment at arc length s."""
        k = int(np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, len(self.length) - 1))
        return float(np.arctan2(self.seg[k, 1], self.seg[k, 0]))

    def chord_heading(self, s, half) -> float:
        """Direction (rad) of the chord from arc length s − half to s + half (m)."""
        d = self.at(s + half) - self.at(s - half)
        return float(np.arctan2(d[1], d[0]))


def _wrap(angle):
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def _blend(cs, command, gait):
    """(query result, blend) of one command (3,)."""
    result = cs.query([command], gait=gait)
    if not result.inside[0]:
        raise MocapError("the path asks for a command outside the control space: "
                         + cs.outside_text(result), path=cs.source,
                         hint="follow it more slowly, or with gentler turns")
    return result, cs.on_body(cs.blend(result), result)


def _polyline_command(cs, line: _Polyline, pose, speed, gait):
    """Command, query result and blend of the next cycle from ``pose`` (x, y, heading)."""
    s0 = line.project(pose[:2])
    segment = line.heading(s0)
    # > 0 when the path is to the walker's left
    offset = float(np.dot(line.at(s0) - pose[:2], [-np.sin(segment), np.cos(segment)]))
    omega = 0.0
    for _ in range(3):
        result, blend = _blend(cs, (speed, omega, 0.0), gait)
        u_f, u_l, turn = blend.drift[0]
        turn += _turn_warp((speed, omega, 0.0), result)
        period = float(blend.T[0])
        stride = float(np.hypot(u_f, u_l)) * period
        ahead = line.chord_heading(s0 + stride, TANGENT_WINDOW * stride)
        travel = pose[2] + np.arctan2(u_l, u_f)
        wanted = (float(_wrap(ahead - travel)) + np.arctan2(offset, stride)) / period
        omega += wanted - turn
    result, blend = _blend(cs, (speed, omega, 0.0), gait)
    return (speed, omega, 0.0), result, blend


def _turn_warp(command, result) -> float:
    """The turn rate (rad/s) a cycle served clamped lacks: the command's ω̂ less that of the
    point blended, within ±:data:`MAX_TURN_WARP`; 0 for a command served where it is."""
    if not result.clamped[0]:
        return 0.0
    return float(np.clip(command[1] - result.nearest[0, 1], -MAX_TURN_WARP, MAX_TURN_WARP))


def _speed_at(path: Path, line: _Polyline, s: float, speed: float | None) -> float:
    """Speed (m/s) at arc length s: the given one, else the segment's length over its time."""
    if speed is not None:
        return speed
    k = int(np.clip(np.searchsorted(line.s, s, side="right") - 1, 0, len(line.length) - 1))
    return float(line.length[k] / (path.t[k + 1] - path.t[k]))


def follow(cs, path: Path, /, *, rate: float = 100.0, speed: float | None = None,
           gait: str | None = None) -> Followed:
    """Synthesise the motion following ``path`` with the control space ``cs`` (module
    docstring); ``speed`` m/s for a polyline without times; ``gait`` to keep to one gait.

    Raises
    ------
    MocapError
        A polyline without times nor speed, a command outside the control space, or a path
        that would take more than :data:`MAX_CYCLES` cycles.
    """
    if path.kind == "polyline" and path.t is None and speed is None:
        raise MocapError("a polyline without times needs a speed", path=path.source,
                         hint="give --speed M/S, or a column t (s) in the path")
    cycles, blends = [], []
    if path.kind == "polyline":
        line = _Polyline(path.xy)
        first = _blend(cs, (_speed_at(path, line, 0.0, speed), 0.0, 0.0), gait)[1]
        # the path frame's heading, which the body faces at its mean pelvis_rotation from
        pose = np.array([*path.xy[0], line.heading(0.0) - first.a[0, ROOT_HEADING, 0]])
    else:
        first = _blend(cs, path.commands[0], gait)[1]
        pose = np.array([0.0, 0.0, -first.a[0, ROOT_HEADING, 0]])     # the body faces +X
        end = float(path.t[-1])
        grid = np.arange(int(np.ceil((end + REFERENCE_BEYOND_S) * rate)) + 1) / rate
        reference = _timeline_reference(path, grid)
    start = 0.0
    while True:
        if len(cycles) >= MAX_CYCLES:
            raise MocapError(f"the path takes more than {MAX_CYCLES} cycles", path=path.source)
        if path.kind == "polyline":
            sp = _speed_at(path, line, line.project(pose[:2]), speed)
            command, result, blend = _polyline_command(cs, line, pose, sp, gait)
        else:
            if start >= end:
                break
            command = np.array([np.interp(start, path.t, path.commands[:, k]) for k in range(3)])
            result, blend = _blend(cs, command, gait)
            period = float(blend.T[0])
            x_ref, y_ref, heading_ref = (np.interp(start, grid, r) for r in reference.T)
            travel_ref = heading_ref + np.arctan2(
                command[2], np.sqrt(max(command[0] ** 2 - command[2] ** 2, 0.0)))
            # > 0 when the reference is to the left of its direction of travel
            offset = float(np.dot([x_ref - pose[0], y_ref - pose[1]],
                                  [-np.sin(travel_ref), np.cos(travel_ref)]))
            stride = float(np.hypot(*blend.drift[0, :2])) * period
            # the body's heading at the cycle's end: the path frame's plus its mean in it
            predicted = pose[2] + blend.a[0, ROOT_HEADING, 0] + blend.drift[0, 2] * period
            turn = (float(_wrap(np.interp(start + period, grid, reference[:, 2]) - predicted))
                    + np.arctan2(offset, stride))
            command = (command[0], command[1] + turn / period, command[2])
            result, blend = _blend(cs, command, gait)
        period = float(blend.T[0])
        warp = _turn_warp(command, result)
        cycles.append(Cycle(start, period, tuple(float(c) for c in command), result.gait[0],
                            [cs.ids[k] for k in result.entries[0]],
                            result.weights[0].tolist(), bool(result.clamped[0]), warp))
        u_f, u_l, turn = (float(v) for v in blend.drift[0])
        drift = RootDrift(*pose, u_f, u_l, turn + warp)
        blends.append((blend, drift))
        x, y, psi = drift.frame(period)
        pose = np.array([float(x), float(y), float(psi)])
        start += period
        if path.kind == "polyline" and line.project(pose[:2]) + sp * period / 2 >= line.s[-1]:
            break
    q, frame = _stitch(blends, [c.start_s for c in cycles], start, rate)
    return Followed(q, rate, frame, cycles, [b for b, _ in blends])


def _stitch(blends, starts, end, rate):
    """Frames at k/rate s in [0, end) of the cycles ``blends`` [(Blend, RootDrift)] starting at
    ``starts`` s: (F, D) coordinates and (F, 3) path-frame poses (module docstring, 3.)."""
    t = np.arange(int(np.ceil(end * rate - 1e-9))) / rate
    which = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(starts) - 1)
    a = np.stack([b.a[0] for b, _ in blends])
    b = np.stack([b.b[0] for b, _ in blends])
    periods = np.array([bl.T[0] for bl, _ in blends])
    tau = t - np.asarray(starts)[which]
    phase = tau / periods[which]
    s = np.clip(phase / FADE, 0.0, 1.0)
    s = s * s * (3 - 2 * s)
    s[which == 0] = 1.0
    before = np.maximum(which - 1, 0)
    mix_a = a[before] + s[:, None, None] * (a[which] - a[before])          # (F, D, N+1)
    mix_b = b[before] + s[:, None, None] * (b[which] - b[before])
    k = np.arange(a.shape[2])
    angle = 2 * np.pi * phase[:, None] * k[None]                            # (F, N+1)
    q = (np.einsum("fdn,fn->fd", mix_a, np.cos(angle))
         + np.einsum("fdn,fn->fd", mix_b, np.sin(angle)))
    frame = np.empty((len(t), 3))
    facing = mix_a[:, ROOT_HEADING, 0]      # the body's mean heading in the path frame
    for c, (_, drift) in enumerate(blends):
        rows = which == c
        x, y, psi = drift.frame(tau[rows])
        frame[rows] = np.column_stack([x, y, psi + facing[rows]])
        lx, ly = q[rows, ROOT_X].copy(), q[rows, ROOT_Y].copy()
        q[rows, ROOT_X] = x + np.cos(psi) * lx - np.sin(psi) * ly
        q[rows, ROOT_Y] = y + np.sin(psi) * lx + np.cos(psi) * ly
        q[rows, ROOT_HEADING] += psi
    return q, frame


def _timeline_reference(path: Path, t) -> np.ndarray:
    """Poses (len(t), 3) (x, y m, heading rad) of a timeline's commands integrated (model (2):
    forward ``sqrt(v̂² − v̂_l²)``, left v̂_l, turn ω̂; Euler steps) at evenly spaced times t
    (from 0 s), starting at the origin facing +X; the last command held beyond its time."""
    cmd = np.column_stack([np.interp(t, path.t, path.commands[:, k]) for k in range(3)])
    v_f = np.sqrt(np.clip(cmd[:, 0] ** 2 - cmd[:, 2] ** 2, 0, None))
    dt = t[1] - t[0] if len(t) > 1 else 0.0
    heading = np.concatenate([[0.0], np.cumsum(cmd[:-1, 1]) * dt])
    vx = v_f * np.cos(heading) - cmd[:, 2] * np.sin(heading)
    vy = v_f * np.sin(heading) + cmd[:, 2] * np.cos(heading)
    return np.column_stack([np.concatenate([[0.0], np.cumsum(vx[:-1]) * dt]),
                            np.concatenate([[0.0], np.cumsum(vy[:-1]) * dt]), heading])


def tracking_errors(path: Path, followed: Followed) -> dict:
    """How well ``followed`` keeps to ``path``: ``root_m`` the largest distance (m) of the root
    (pelvis_tx, pelvis_ty) from the path, ``heading_deg`` the largest difference between the
    path frame's heading and the path's (polyline: its tangent at the nearest point;
    timeline: the integral of ω̂), ``jump_deg`` the largest frame-to-frame change of a joint
    angle and ``own_jump_deg`` the largest of the blended cycles' own (each alone, at the
    same rate)."""
    root = followed.q[:, [ROOT_X, ROOT_Y]]
    if path.kind == "polyline":
        line = _Polyline(path.xy)
        s = np.array([line.project(p) for p in root])
        nearest = np.array([line.at(v) for v in s])
        expected = np.array([line.heading(line.project(p)) for p in followed.frame[:, :2]])
    else:
        reference = _timeline_reference(path, np.arange(len(followed.q)) / followed.rate)
        line = _Polyline(reference[:, :2])
        nearest = np.array([line.at(line.project(p)) for p in root])
        expected = reference[:, 2]
    own = max(np.abs(np.diff(b.synthesize(0, rate=followed.rate)[1][:, JOINT_ANGLES], axis=0)).max()
              for b in followed.blends)
    return {"root_m": float(np.linalg.norm(root - nearest, axis=1).max()),
            "heading_deg": float(np.degrees(np.abs(_wrap(followed.frame[:, 2] - expected)).max())),
            "jump_deg": float(np.degrees(np.abs(np.diff(followed.q[:, JOINT_ANGLES],
                                                        axis=0)).max())),
            "own_jump_deg": float(np.degrees(own))}
