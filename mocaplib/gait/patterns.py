"""Geometric pattern of a cycle (line, circular arc or point) and its velocities
(v̂, ω̂, v̂_l, v̂_f).

The pattern is fitted to the horizontal path of the shoulder midpoint over one cycle:

* **line**: total least squares (principal direction of the centred points);
* **arc**: the Hyper algebraic circle fit (Al-Sharadqah & Chernov 2009, *Electron. J. Stat.* 3,
  886), which has no essential bias, refined by geometric Levenberg-Marquardt
  (:func:`scipy.optimize.least_squares`) on the point-to-circle distances. The Kåsa fit is not
  used: on short arcs it shrinks the radius (tests measure it);
* **point**: turning on the spot, where the path shrinks to a point: the RMS distance of the
  path from its centroid is below ``point_radius``.

The shoulders sway from side to side once per cycle. Over one cycle a sine correlates with the
time trend, so a plain fit tilts the line (by ~1.5° for 2 cm of sway, i.e. a false v̂_l of
0.03 m/s). Both fits therefore carry the stride-periodic sway as nuisance terms: the distance to
the pattern may vary as Σ_{k=1,2} (c_k cos 2πkt/T + s_k sin 2πkt/T) (:func:`sway_basis`).

Choice (documented criterion): the arc is kept when it is better by the Bayesian information
criterion, ``n·ln(RSS_arc/n) + 3·ln n < n·ln(RSS_line/n) + 2·ln n``, **and** it turns through at
least ``min_arc_angle`` over the cycle; otherwise the line. On short arcs the circle's curvature
is ill-conditioned, and a slightly bent straight walk (body sway) must not become an arc; the arc
angle is always reported.

Velocities, for a cycle of period ``T``, with DESIGN.md's conventions:

* v̂ = path length along the pattern between the projections of the cycle's first and last
  positions, divided by T (0 for a point);
* θ_T = tangent of the pattern at each sample's projection, oriented along the motion;
* θ_S = θ_lr + π/2, θ_lr the direction left shoulder → right shoulder (facing +X gives 0);
* ω̂ = (θ_S(T) − θ_S(0)) / T with θ_S unwrapped (> 0 turns left);
* v̂_l = time average over the cycle of v̂·sin(θ_T − θ_S) (> 0 moves to the person's left,
  model (2) of the paper; the paper prints sin(θ_S − θ_T), the opposite sign of its own model);
  v̂_f = time average of v̂·cos(θ_T − θ_S) (< 0 walking backwards). Both are 0 for a point.
  Time averages are trapezoidal over the cycle's samples (:func:`time_mean`).

Units: metres, seconds, radians; positions (F, 3) Z up or (F, 2) horizontal.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..errors import EventError
from ..io.jsonvalues import json_values
from ..model.filtering import resample
from ..runs import frames_within


@dataclass(frozen=True)
class Pattern:
    """A line, arc or point fitted to a horizontal path.

    Attributes
    ----------
    kind : ``"line"``, ``"arc"`` or ``"point"``
    params : dict
        line: ``point`` (x, y) m and unit ``direction`` (x, y) along the motion;
        arc: ``centre`` (x, y) m, ``radius`` m, ``turn`` +1 counter-clockwise / −1 clockwise;
        point: ``point`` (x, y) m.
    residual : float
        RMS distance of the path's points from the pattern, m.
    arc_angle : float
        Signed angle turned along the pattern over the path, rad (> 0 counter-clockwise; 0 for
        line and point).
    length : float
        Length along the pattern between the projections of the first and last points, m.
    """

    kind: str
    params: dict = field(default_factory=dict)
    residual: float = 0.0
    arc_angle: float = 0.0
    length: float = 0.0

    def tangent(self, xy: np.ndarray) -> np.ndarray:
        """Direction of motion θ_T (rad) at the projection of each point (F, 2); NaN for a point."""
        xy = np.asarray(xy, dtype=np.float64)
        if self.kind == "line":
            ux, uy = self.params["direction"]
            return np.full(len(xy), np.arctan2(uy, ux))
        if self.kind == "arc":
            cx, cy = self.params["centre"]
            phi = np.arctan2(xy[:, 1] - cy, xy[:, 0] - cx)
            return phi + self.params["turn"] * np.pi / 2
        return np.full(len(xy), np.nan)

    def to_dict(self) -> dict:
        """JSON-ready description, as the library stores it (docs/library-format.md):
        ``type``, ``parameters`` (the fit's, m / rad, and the path ``length`` along it, m),
        ``residual_m`` and ``arc_angle_rad``."""
        return {"type": self.kind,
                "parameters": json_values({**self.params, "length": float(self.length)}),
                "residual_m": float(self.residual), "arc_angle_rad": float(self.arc_angle)}


@dataclass(frozen=True)
class CycleVelocities:
    """Average velocities of one cycle (SI units) and the pattern they were measured on."""

    pattern: Pattern
    period: float
    v: float
    omega: float
    v_l: float
    v_f: float


# ----------------------------------------------------------------------------------- line
def sway_basis(time_s: np.ndarray, period: float, /, *, harmonics: int = 2) -> np.ndarray:
    """cos/sin of 2πkt/T, k = 1..harmonics, at ``time_s`` (n,): the (n, 2·harmonics) basis of
    the stride-periodic lateral sway of the shoulders, fitted together with the pattern."""
    phase = 2 * np.pi * np.outer(np.asarray(time_s, dtype=np.float64),
                                 np.arange(1, harmonics + 1)) / period
    return np.column_stack([np.cos(phase), np.sin(phase)])


def fit_line(xy: np.ndarray, /, *, sway: np.ndarray | None = None) -> Pattern:
    """Total-least-squares line through points (F, 2), oriented from the first to the last point.

    With ``sway`` (F, m) (see :func:`sway_basis`) the distance to the line may also vary along
    that basis: the sway is projected out before the principal direction is taken, so a
    periodic side-to-side sway does not tilt the line. ``residual`` excludes the sway.
    """
    xy = _horizontal(xy)
    basis = np.ones((len(xy), 1)) if sway is None else np.column_stack([np.ones(len(xy)), sway])
    q, _ = np.linalg.qr(basis)
    centred = xy - q @ (q.T @ xy)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    direction = vt[0]
    centroid = xy.mean(axis=0)
    along = (xy - centroid) @ direction
    if along[-1] < along[0]:
        direction, along = -direction, -along
    normal = centred @ np.array([-direction[1], direction[0]])
    return Pattern("line", {"point": centroid, "direction": direction},
                   residual=float(np.sqrt(np.mean(normal ** 2))),
                   length=float(along[-1] - along[0]))


# ----------------------------------------------------------------------------------- circle
def fit_circle(xy: np.ndarray, /, *, sway: np.ndarray | None = None) -> Pattern | None:
    """Hyper algebraic circle fit refined by geometric Levenberg-Marquardt; None if collinear.

    ``xy`` (F, 2) metres, F >= 3. With ``sway`` (F, m) the radial distance may also vary along
    that basis (fitted jointly in the LM step). The result is an ``"arc"`` whose ``turn`` and
    ``arc_angle`` follow the order of the points; ``residual`` excludes the sway.
    """
    xy = _horizontal(xy)
    start = _hyper_circle(xy)
    if start is None:
        return None
    centre, radius = start
    sway = np.zeros((len(xy), 0)) if sway is None else np.asarray(sway, dtype=np.float64)

    def residuals(p):
        return np.hypot(xy[:, 0] - p[0], xy[:, 1] - p[1]) - p[2] - sway @ p[3:]

    x0 = np.concatenate([centre, [radius], np.zeros(sway.shape[1])])
    scale = np.concatenate([np.full(3, max(radius, 1e-9)), np.full(sway.shape[1], 0.01)])
    if len(xy) <= len(x0):
        return None
    solution = least_squares(residuals, x0, method="lm", x_scale=scale)
    cx, cy, radius = solution.x[:3]
    radius = abs(radius)
    if not np.isfinite(radius) or radius > 1e6:
        return None
    phi = np.unwrap(np.arctan2(xy[:, 1] - cy, xy[:, 0] - cx))
    angle = float(phi[-1] - phi[0])
    residual = float(np.sqrt(np.mean(residuals(solution.x) ** 2)))
    return Pattern("arc", {"centre": np.array([cx, cy]), "radius": float(radius),
                           "turn": 1.0 if angle >= 0 else -1.0},
                   residual=residual, arc_angle=angle, length=float(radius * abs(angle)))


def _hyper_circle(xy: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Hyper fit (Al-Sharadqah & Chernov 2009, SVD form): centre (2,), radius; None if a line."""
    centroid = xy.mean(axis=0)
    x, y = (xy - centroid).T
    z = x * x + y * y
    design = np.column_stack([z, x, y, np.ones_like(x)])
    _, s, vt = np.linalg.svd(design, full_matrices=False)
    v = vt.T
    if s[-1] / s[0] < 1e-12:
        coef = v[:, -1]
    else:
        mean = design.mean(axis=0)
        constraint = np.array([[8 * mean[0], 4 * mean[1], 4 * mean[2], 2],
                               [4 * mean[1], 1, 0, 0],
                               [4 * mean[2], 0, 1, 0],
                               [2, 0, 0, 0]])
        w = v @ np.diag(s) @ v.T
        eigval, eigvec = np.linalg.eig(w @ np.linalg.inv(constraint) @ w)
        order = np.argsort(eigval.real)
        coef = np.linalg.solve(w, eigvec[:, order[1]].real)
    if abs(coef[0]) < 1e-12 * np.abs(coef).max():
        return None
    centre = -coef[1:3] / coef[0] / 2 + centroid
    radius2 = coef[1] ** 2 + coef[2] ** 2 - 4 * coef[0] * coef[3]
    if radius2 <= 0:
        return None
    return centre, float(np.sqrt(radius2) / abs(coef[0]) / 2)


# ----------------------------------------------------------------------------------- choice
def fit_pattern(xy: np.ndarray, /, *, sway: np.ndarray | None = None,
                point_radius: float = 0.05, min_arc_angle: float = np.deg2rad(10.0)) -> Pattern:
    """Line, arc or point for a horizontal path (F, 2) or (F, 3), by the module's criterion.

    ``sway`` (F, m): optional periodic sway basis fitted with both candidates
    (:func:`sway_basis`); it counts as m parameters in both, so the BIC comparison is fair.
    """
    xy = _horizontal(xy)
    centroid = xy.mean(axis=0)
    spread = float(np.sqrt(np.mean(np.sum((xy - centroid) ** 2, axis=1))))
    if spread < point_radius:
        return Pattern("point", {"point": centroid}, residual=spread)
    line = fit_line(xy, sway=sway)
    arc = fit_circle(xy, sway=sway)
    if arc is None or abs(arc.arc_angle) < min_arc_angle:
        return line
    n = len(xy)
    tiny = 1e-12  # keeps the logarithm finite for noise-free paths
    bic_line = n * np.log(line.residual ** 2 + tiny) + 2 * np.log(n)
    bic_arc = n * np.log(arc.residual ** 2 + tiny) + 3 * np.log(n)
    return arc if bic_arc < bic_line else line


def _horizontal(xy) -> np.ndarray:
    xy = np.asarray(xy, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] not in (2, 3) or len(xy) < 3:
        raise EventError(f"a path must have shape (F >= 3, 2 or 3), got {xy.shape}")
    if not np.isfinite(xy[:, :2]).all():
        raise EventError("a path to fit contains missing samples; fill or drop them first")
    return xy[:, :2]


# ----------------------------------------------------------------------------------- velocities
def shoulder_heading(left_shoulder: np.ndarray, right_shoulder: np.ndarray, /) -> np.ndarray:
    """θ_S = θ_lr + π/2 per frame (F,), rad, unwrapped; θ_lr = direction left → right shoulder."""
    lr = np.asarray(right_shoulder, dtype=np.float64) - np.asarray(left_shoulder, dtype=np.float64)
    return np.unwrap(np.arctan2(lr[:, 1], lr[:, 0]) + np.pi / 2)


def cycle_velocities(left_shoulder: np.ndarray, right_shoulder: np.ndarray, rate: float,
                     start_s: float, end_s: float, /, *, ground: np.ndarray | None = None,
                     point_radius: float = 0.05, min_arc_angle: float = np.deg2rad(10.0),
                     min_valid: float = 0.8,
                     source: str | os.PathLike | None = None) -> CycleVelocities:
    """Pattern and average velocities of the cycle [start_s, end_s] (seconds from frame 0).

    ``left_shoulder``, ``right_shoulder``: (F, 3) metres, Z up, NaN where missing. Samples are
    the frames inside the cycle plus both ends interpolated at the exact (sub-frame) times;
    gaps are filled linearly when at least ``min_valid`` of the cycle's frames were measured.
    ``ground`` (3,) m/s: the floor's velocity (a treadmill belt's, see
    :func:`mocaplib.gait.events.ground_velocity`); the path is then measured relative to it.
    """
    times, mid, heading = cycle_samples(left_shoulder, right_shoulder, rate, start_s, end_s,
                                        ground=ground, min_valid=min_valid, source=source)
    return path_velocities(times, mid, heading, point_radius=point_radius,
                           min_arc_angle=min_arc_angle)


def cycle_samples(left_shoulder: np.ndarray, right_shoulder: np.ndarray, rate: float,
                  start_s: float, end_s: float, /, *, ground: np.ndarray | None = None,
                  min_valid: float = 0.8, source: str | os.PathLike | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cycle [start_s, end_s] (s) sampled: times (n,) s (:func:`cycle_times`), shoulder
    midpoint (n, 3) m and θ_S (n,) rad (:func:`sample_shoulders`, same arguments)."""
    if not float(end_s - start_s) > 0:
        raise EventError(f"cycle end {end_s} s is not after its start {start_s} s", path=source)
    times = cycle_times(start_s, end_s, rate)
    mid, heading = sample_shoulders(left_shoulder, right_shoulder, rate, times, ground=ground,
                                    min_valid=min_valid, source=source)
    return times, mid, heading


def path_velocities(times: np.ndarray, mid: np.ndarray, heading: np.ndarray, /, *,
                    point_radius: float = 0.05, min_arc_angle: float = np.deg2rad(10.0)
                    ) -> CycleVelocities:
    """Pattern and average velocities of a cycle from :func:`cycle_samples`' times (n,) s,
    shoulder midpoint (n, 3) m and θ_S (n,) rad; the cycle runs from times[0] to times[-1]."""
    start_s, period = times[0], float(times[-1] - times[0])
    path = mid[:, :2]
    pattern = fit_pattern(path, sway=sway_basis(times - start_s, period),
                          point_radius=point_radius, min_arc_angle=min_arc_angle)
    omega = float((heading[-1] - heading[0]) / period)
    if pattern.kind == "point":
        return CycleVelocities(pattern, period, 0.0, omega, 0.0, 0.0)
    v = pattern.length / period
    relative = pattern.tangent(path) - heading
    return CycleVelocities(pattern, period, float(v), omega,
                           float(v * time_mean(times, np.sin(relative))),
                           float(v * time_mean(times, np.cos(relative))))


def time_mean(times: np.ndarray, values: np.ndarray, /) -> float:
    """Average over time of ``values`` (n,) sampled at increasing ``times`` (n,) s: the
    trapezoidal integral over [times[0], times[-1]] divided by its length.

    Not the plain mean of the samples: a cycle's samples hold both ends, the same phase of the
    stride, and their uneven spacing (sub-frame ends) would weight that phase twice; with the
    trunk's rotation swinging θ_S by a few degrees that is up to 0.006 m/s of v̂_l (measured on
    the synthetic walker's own shoulders against its truth, which averages over time).
    """
    steps = np.diff(times)
    return float(np.sum(0.5 * (values[1:] + values[:-1]) * steps) / np.sum(steps))


def cycle_times(start_s: float, end_s: float, rate: float, /) -> np.ndarray:
    """Sample times of a cycle: ``start_s``, the frame times strictly inside, ``end_s`` (s)."""
    first = int(np.floor(start_s * rate)) + 1
    last = int(np.ceil(end_s * rate)) - 1
    inner = np.arange(first, last + 1) / rate
    return np.concatenate([[start_s], inner[(inner > start_s) & (inner < end_s)], [end_s]])


def sample_shoulders(left_shoulder: np.ndarray, right_shoulder: np.ndarray, rate: float,
                     times: np.ndarray, /, *, ground: np.ndarray | None = None,
                     min_valid: float = 0.8,
                     source: str | os.PathLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Shoulder midpoint (n, 3) m and θ_S (n,) rad unwrapped at ``times`` (n,) s, gaps filled.

    With ``ground`` (3,) m/s the midpoint is relative to the moving floor (``− ground·t``).
    Raises :class:`EventError` when less than ``min_valid`` of the frames within the times'
    span were measured for either shoulder.
    """
    left = np.asarray(left_shoulder, dtype=np.float64)
    right = np.asarray(right_shoulder, dtype=np.float64)
    if left.shape != right.shape or left.ndim != 2 or left.shape[1] != 3:
        raise EventError(f"shoulders must both have shape (F, 3), got {left.shape} and "
                         f"{right.shape}", path=source)
    inside = frames_within(times[0], times[-1], rate, len(left))
    sampled = []
    for name, points in (("left", left), ("right", right)):
        valid = np.isfinite(points[inside]).all(axis=1)
        if not valid.size or valid.mean() < min_valid:
            raise EventError(f"{name} shoulder missing in more than {1 - min_valid:.0%} of "
                             f"{times[0]:.3f}-{times[-1]:.3f} s", path=source,
                             hint="check the shoulder markers or fill the gaps")
        sampled.append(resample(points, rate, times, jointly=True))
    left_s, right_s = sampled
    mid = 0.5 * (left_s + right_s)
    if ground is not None:
        mid = mid - np.outer(times, ground)
    return mid, shoulder_heading(left_s, right_s)
