"""Poulaines: the path of each ankle centre over a cycle, seen from the pelvis (Pronost et al.).

**Frame.** Origin at the pelvis centre (the skeleton's root, midway between the hip joint
centres), x along the direction of travel, z up, y = z × x (to the left of the travel). The
ankle centre is the origin of the foot segment's frame (:meth:`Skeleton.forward`). The direction
of travel is the cycle's path frame (:class:`mocaplib.gait.fourier.RootDrift`, which moves with
velocity (u_f, u_l) in its own axes while turning at ω) turned by β = atan2(u_l, u_f): the
direction of that velocity, constant in the path frame; β = 0 (the path frame's heading, the
pelvis's at the cycle start) when the speed is below :data:`MIN_TRAVEL_SPEED` (turning on the
spot). A poulaine therefore follows from the cycle's joint coordinates in the path frame
alone, as the library stores them: pelvis translation set to 0, heading minus β, forward
kinematics (:func:`travel_coordinates`, :func:`ankle_centres`).

**Model** of each ankle's path, four characteristic points:

1. ``highest``: the highest ankle position (largest z);
2. ``foremost``: the largest x (the leg stretched forward);
3. ``under_pelvis``: x closest to 0 among the samples from ``foremost`` to ``rearmost`` (the
   ankle passing under the pelvis in support);
4. ``rearmost``: the smallest x (the leg furthest behind).

Taken in the order they occur, consecutive points P_k, P_k+1 are joined by cubic Hermite
(Coons) curves with their own end tangents A_k, B_k (m per unit parameter),

    C_k(s) = (2s³ − 3s² + 1) P_k + (s³ − 2s² + s) A_k + (−2s³ + 3s²) P_k+1 + (s³ − s²) B_k,

s ∈ [0, 1]; the curve parameter is u = k + s ∈ [0, 4). The tangents minimise the distance from
the measured samples to the curve: each sample first gets the fraction of its segment's
duration as parameter, the tangents are solved by linear least squares (the curve is linear in
them), each sample's parameter moves to its closest point on its segment (Newton steps, within
±:data:`PROJECTION_WINDOW`), and the two steps repeat :data:`FIT_ITERATIONS` times; after the
first :data:`POINT_ITERATIONS`, the least squares weigh each residual's component along the
curve by :data:`ALONG_WEIGHT` only (the distance across the curve is the one to minimise; the
whole distance converges slowly, the across part alone is unstable). **Speed profile**: within segment k, s = f_k(r), r the
fraction of the segment's duration, f_k monotone from 0 to 1, stored at
:data:`TIMING_KNOTS` evenly spaced r and interpolated by PCHIP; so the model gives the ankle at
any phase φ = t/T of the cycle (:meth:`AnklePath.__call__`), passing through each
characteristic point at its phase.

**Fit errors** (m): ``fit_rms`` / ``fit_max``, the RMS / largest distance from the measured
samples to the curve (its geometry); ``timed_rms``, the RMS distance between each sample and
the model at the sample's phase (what retargeting follows).

**Parameters** (m), from the characteristic points: step length = the mean over both ankles of
x(foremost) − x(rearmost), the ankle's fore-aft excursion relative to the pelvis (Pronost et
al.'s step length, not the distance between footprints); foot spacing = y_left(under_pelvis) −
y_right(under_pelvis); stance = −mean z(under_pelvis), the pelvis-to-ankle height in support.
:class:`Blend` builds a poulaine with requested parameters from the library's (per axis, the
closest in that parameter, then corrected exactly).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..errors import MocapError
from ..io.jsonvalues import float_or_nan
from ..skeleton import ROOT_HEADING, ROOT_X, ROOT_Y, ROOT_Z, SEGMENT_NAMES, Skeleton
from .fourier import RootDrift

#: The characteristic points, in the paper's numbering (1 to 4).
KINDS = ("highest", "foremost", "under_pelvis", "rearmost")
SIDES = ("left", "right")
#: The foot segments whose origins are the ankle centres, in :data:`SIDES` order.
FEET = (SEGMENT_NAMES.index("foot_l"), SEGMENT_NAMES.index("foot_r"))
#: Below this speed (m/s) of the path frame the direction of travel is its heading.
MIN_TRAVEL_SPEED = 0.1
#: Speed-profile knots per segment.
TIMING_KNOTS = 5
#: Alternations of tangent solving and parameter correction; how far (in s) a sample's parameter
#: may move in one correction; Newton steps of each correction (:func:`_closest`).
FIT_ITERATIONS, PROJECTION_WINDOW, NEWTON_STEPS = 20, 0.1, 3
#: The first iterations solve the tangents on the whole distance to each sample's point of the
#: curve, the others on its part across the curve and ALONG_WEIGHT of its part along it (much
#: faster than the whole distance; the across part alone diverges on some real walks).
POINT_ITERATIONS, ALONG_WEIGHT = 3, 0.3
#: Curve points per segment among which the closest to a sample is refined into its distance to
#: the curve.
DISTANCE_SAMPLES = 50


def travel_angle(u_f: float, u_l: float) -> float:
    """β (rad, > 0 to the left): the direction of travel in the path frame, from its velocity
    (u_f forward, u_l left, m/s); 0 below :data:`MIN_TRAVEL_SPEED`."""
    if np.hypot(u_f, u_l) < MIN_TRAVEL_SPEED:
        return 0.0
    return float(np.arctan2(u_l, u_f))


def travel_coordinates(q_path: np.ndarray, travel: float, /) -> np.ndarray:
    """Joint coordinates (n, D) in the path frame (as the library stores them) re-expressed in
    the travel frame of a pelvis at the origin: ``pelvis_t*`` 0, heading minus ``travel``
    (rad)."""
    q = np.array(q_path, dtype=np.float64)
    q[:, [ROOT_X, ROOT_Y, ROOT_Z]] = 0.0
    q[:, ROOT_HEADING] -= travel
    return q


def ankle_centres(skeleton: Skeleton, q: np.ndarray, /) -> np.ndarray:
    """Left and right ankle centres (the foot segments' origins) in poses ``q`` (n, D):
    (n, 2, 3) m, in the frame ``q`` places the root in."""
    return skeleton.forward(q)[:, list(FEET)][..., :3, 3]


def _hermite(s: np.ndarray, derivative: int = 0) -> np.ndarray:
    """The four cubic Hermite basis functions (or their first or second derivative) at ``s``:
    shape (*s.shape, 4)."""
    s2, s3, one = s * s, s * s * s, np.ones_like(s)
    if derivative == 1:
        return np.stack([6 * s2 - 6 * s, 3 * s2 - 4 * s + one, -6 * s2 + 6 * s, 3 * s2 - 2 * s],
                        axis=-1)
    if derivative == 2:
        return np.stack([12 * s - 6 * one, 6 * s - 4 * one, -12 * s + 6 * one, 6 * s - 2 * one],
                        axis=-1)
    return np.stack([2 * s3 - 3 * s2 + one, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2], axis=-1)


@dataclass(frozen=True)
class AnklePath:
    """One ankle's modelled poulaine (see the module docstring); points in the order they occur.

    Attributes
    ----------
    kinds : tuple[str, ...], length 4
        The characteristic point each of ``points`` is (:data:`KINDS`).
    phases : ndarray, shape (4,)
        Their phases t/T in [0, 1), increasing.
    points : ndarray, shape (4, 3)
        The characteristic points, m.
    tangents : ndarray, shape (4, 2, 3)
        Segment k's start and end tangents A_k, B_k (segment k joins point k to point k + 1,
        the last to the first), m per unit parameter.
    timing : ndarray, shape (4, J)
        Segment k's speed profile: its parameter s at the fractions j / (J + 1), j = 1..J, of
        its duration (J = :data:`TIMING_KNOTS` when fitted here).
    fit_rms, fit_max, timed_rms : float
        Fit errors, m (module docstring).
    """

    kinds: tuple[str, ...]
    phases: np.ndarray
    points: np.ndarray
    tangents: np.ndarray
    timing: np.ndarray
    fit_rms: float = float("nan")
    fit_max: float = float("nan")
    timed_rms: float = float("nan")

    def point(self, kind: str) -> np.ndarray:
        """The characteristic point ``kind`` (:data:`KINDS`), (3,) m."""
        return self.points[self.kinds.index(kind)]

    def curve(self, u, derivative: int = 0) -> np.ndarray:
        """Curve points (or their first or second derivative along u) at parameters ``u`` (any
        shape; wraps modulo 4): (*u.shape, 3) m."""
        u = np.mod(np.asarray(u, dtype=np.float64), 4.0)
        k = np.minimum(np.floor(u).astype(int), 3)
        h = _hermite(u - k, derivative)
        return (h[..., 0, None] * self.points[k] + h[..., 1, None] * self.tangents[k, 0]
                + h[..., 2, None] * self.points[(k + 1) % 4] + h[..., 3, None]
                * self.tangents[k, 1])

    @cached_property
    def _profiles(self) -> list:
        from scipy.interpolate import PchipInterpolator

        r = np.arange(self.timing.shape[1] + 2) / (self.timing.shape[1] + 1)
        return [PchipInterpolator(r, np.concatenate([[0.0], row, [1.0]])) for row in self.timing]

    def parameter(self, phase) -> np.ndarray:
        """Curve parameter u in [0, 4) at cycle phases ``phase`` (t/T; wraps modulo 1)."""
        phase = np.asarray(phase, dtype=np.float64)
        k, r = _segment_fractions(self.phases, np.mod(phase, 1.0))
        out = np.empty(phase.shape)
        for segment, profile in enumerate(self._profiles):
            inside = k == segment
            out[inside] = segment + profile(r[inside])
        return out

    def __call__(self, phase) -> np.ndarray:
        """The modelled ankle centre at cycle phases ``phase``: (*phase.shape, 3) m."""
        return self.curve(self.parameter(phase))

    def to_dict(self) -> dict:
        return {"kinds": list(self.kinds), "phases": self.phases.tolist(),
                "points_m": self.points.tolist(), "tangents_m": self.tangents.tolist(),
                "timing": self.timing.tolist(), "fit_rms_m": self.fit_rms,
                "fit_max_m": self.fit_max, "timed_rms_m": self.timed_rms}

    @classmethod
    def from_dict(cls, data: dict) -> "AnklePath":
        return cls(tuple(data["kinds"]), np.asarray(data["phases"], float),
                   np.asarray(data["points_m"], float), np.asarray(data["tangents_m"], float),
                   np.asarray(data["timing"], float), *(float_or_nan(data.get(key)) for key in
                                                        ("fit_rms_m", "fit_max_m",
                                                         "timed_rms_m")))


def _segment_fractions(phases: np.ndarray, phase: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For ``phase`` (any shape, in [0, 1)): the segment k between ``phases[k]`` and the next
    (cyclically) it falls in, and the fraction r in [0, 1] of that segment's duration."""
    k = np.mod(np.searchsorted(phases, phase, side="right") - 1, 4)
    duration = np.mod(np.roll(phases, -1) - phases, 1.0)
    elapsed = np.mod(phase - phases[k], 1.0)
    span = duration[k]
    return k, np.clip(np.divide(elapsed, span, out=np.zeros_like(elapsed), where=span > 0),
                      0.0, 1.0)


def characteristic_indices(path: np.ndarray, /) -> dict[str, int]:
    """The samples of a measured ankle path (n, 3) (one cycle, time order) that are the
    characteristic points, by kind."""
    n = len(path)
    foremost, rearmost = int(np.argmax(path[:, 0])), int(np.argmin(path[:, 0]))
    support = (foremost + np.arange((rearmost - foremost) % n + 1)) % n
    return {"highest": int(np.argmax(path[:, 2])), "foremost": foremost,
            "under_pelvis": int(support[np.argmin(np.abs(path[support, 0]))]),
            "rearmost": rearmost}


def _closest(model: AnklePath, points: np.ndarray, segment: np.ndarray, s: np.ndarray,
             lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Parameters s in [``lower``, ``upper``] of the points of ``model``'s segments ``segment``
    (n,) closest to ``points`` (n, 3): :data:`NEWTON_STEPS` Newton steps on the squared
    distance from ``s`` (n,), each kept inside the bounds."""
    for _ in range(NEWTON_STEPS):
        u = segment + s
        gap = model.curve(u) - points
        first, second = model.curve(u, 1), model.curve(u, 2)
        slope = np.sum(gap * first, axis=1)
        curvature = np.sum(first * first, axis=1) + np.sum(gap * second, axis=1)
        step = np.divide(slope, curvature, out=np.zeros_like(slope), where=curvature > 0)
        s = np.clip(s - step, lower, upper)
    return s


def fit_ankle(path: np.ndarray, phase: np.ndarray, /) -> AnklePath:
    """The model (module docstring) of one ankle's measured path ``path`` (n, 3) m at cycle
    phases ``phase`` (n,) in [0, 1), increasing."""
    path = np.asarray(path, dtype=np.float64)
    phase = np.asarray(phase, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != 3 or len(path) != len(phase) or len(path) < 8:
        raise MocapError(f"a poulaine is fitted to at least 8 samples (n, 3) with their phases, "
                         f"got {path.shape} and {phase.shape}")
    found = characteristic_indices(path)
    order = sorted(KINDS, key=lambda kind: (phase[found[kind]], KINDS.index(kind)))
    samples = [found[kind] for kind in order]
    points, phases = path[samples], phase[samples]
    k, r = _segment_fractions(phases, phase)
    s = r.copy()
    rows = np.arange(len(path))
    model = None
    for iteration in range(FIT_ITERATIONS):
        h = _hermite(s)
        design = np.zeros((len(path), 8))
        design[rows, 2 * k], design[rows, 2 * k + 1] = h[:, 1], h[:, 3]
        rest = path - h[:, 0, None] * points[k] - h[:, 2, None] * points[(k + 1) % 4]
        if model is None or iteration < POINT_ITERATIONS:
            tangents = np.linalg.lstsq(design, rest, rcond=None)[0].reshape(4, 2, 3)
        else:   # the residuals along the curve count ALONG_WEIGHT² as much as across it
            along = model.curve(k + s, 1)
            along /= np.maximum(np.linalg.norm(along, axis=1, keepdims=True), 1e-12)
            across = np.eye(3) - (1 - ALONG_WEIGHT) * along[:, :, None] * along[:, None, :]
            system = np.einsum("nij,nt->nitj", across, design).reshape(3 * len(path), 24)
            tangents = np.linalg.lstsq(system, np.einsum("nij,nj->ni", across, rest).ravel(),
                                       rcond=None)[0].reshape(4, 2, 3)
        model = AnklePath(tuple(order), phases, points, tangents, np.zeros((4, TIMING_KNOTS)))
        s = _closest(model, path, k, s, np.clip(s - PROJECTION_WINDOW, 0.0, 1.0),
                     np.clip(s + PROJECTION_WINDOW, 0.0, 1.0))
    grid = np.arange(4 * DISTANCE_SAMPLES) / DISTANCE_SAMPLES
    start = grid[np.argmin(np.linalg.norm(model.curve(grid)[None] - path[:, None], axis=-1),
                           axis=1)]
    segment = np.minimum(np.floor(start).astype(int), 3)
    nearest = _closest(model, path, segment, start - segment, np.zeros(len(path)),
                       np.ones(len(path)))
    gaps = np.linalg.norm(model.curve(segment + nearest) - path, axis=1)
    knots = np.arange(1, TIMING_KNOTS + 1) / (TIMING_KNOTS + 1)
    timing = np.empty((4, TIMING_KNOTS))
    for segment in range(4):
        inside = np.flatnonzero(k == segment)
        inside = inside[np.argsort(r[inside], kind="stable")]
        fractions = np.concatenate([[0.0], r[inside], [1.0]])
        reached = np.maximum.accumulate(np.concatenate([[0.0], s[inside], [1.0]]))
        timing[segment] = np.interp(knots, fractions, reached)
    fitted = AnklePath(tuple(order), phases, points, tangents, timing)
    timed = np.linalg.norm(fitted(phase) - path, axis=1)
    return AnklePath(tuple(order), phases, points, tangents, timing,
                     float(np.sqrt(np.mean(gaps ** 2))), float(gaps.max()),
                     float(np.sqrt(np.mean(timed ** 2))))


def _parameters(left: AnklePath, right: AnklePath) -> tuple[float, float, float]:
    """(step length, foot spacing, stance), m, of two ankles' characteristic points."""
    step = np.mean([p.point("foremost")[0] - p.point("rearmost")[0] for p in (left, right)])
    spacing = left.point("under_pelvis")[1] - right.point("under_pelvis")[1]
    stance = -np.mean([p.point("under_pelvis")[2] for p in (left, right)])
    return float(step), float(spacing), float(stance)


@dataclass(frozen=True)
class Poulaine:
    """Both ankles' modelled poulaines of one cycle, in the travel frame ``travel`` rad from the
    path frame's heading (module docstring)."""

    travel: float
    left: AnklePath
    right: AnklePath

    @property
    def parameters(self) -> tuple[float, float, float]:
        """(step length, foot spacing, stance), m (module docstring)."""
        return _parameters(self.left, self.right)

    @property
    def duty_factor(self) -> float:
        """The fraction of the cycle an ankle spends moving back from ``foremost`` to
        ``rearmost`` (about heel strike to toe-off: in support), mean of both: above ½ when
        walking, below when running."""
        return float(np.mean([np.mod(p.phases[p.kinds.index("rearmost")]
                                     - p.phases[p.kinds.index("foremost")], 1.0)
                              for p in (self.left, self.right)]))

    def scaled(self, factor: float) -> "Poulaine":
        """The same cycle for a body ``factor`` times as large: points, tangents and fit
        errors times ``factor``, phases and timing unchanged (geometric similarity)."""
        def path(ankle: AnklePath) -> AnklePath:
            return replace(ankle, points=ankle.points * factor, tangents=ankle.tangents * factor,
                           fit_rms=ankle.fit_rms * factor, fit_max=ankle.fit_max * factor,
                           timed_rms=ankle.timed_rms * factor)
        return Poulaine(self.travel, path(self.left), path(self.right))

    def __call__(self, phase) -> np.ndarray:
        """Both modelled ankle centres at phases ``phase`` (n,): (n, 2, 3) m, left then right."""
        return np.stack([self.left(phase), self.right(phase)], axis=-2)

    def to_dict(self) -> dict:
        """As a library entry stores it (``docs/library-format.md``)."""
        step, spacing, stance = self.parameters
        return {"travel_rad": self.travel, "step_length_m": step, "foot_spacing_m": spacing,
                "stance_m": stance, "left": self.left.to_dict(),
                "right": self.right.to_dict()}

    @classmethod
    def from_dict(cls, data: dict) -> "Poulaine":
        return cls(float(data["travel_rad"]), AnklePath.from_dict(data["left"]),
                   AnklePath.from_dict(data["right"]))


def cycle_poulaine(skeleton: Skeleton, q_path: np.ndarray, phase: np.ndarray,
                   drift: RootDrift, /) -> tuple[Poulaine, np.ndarray]:
    """The poulaine of one cycle and its measured ankle paths.

    ``q_path``: the cycle's joint coordinates (n, D) in its path frame (``drift.remove``) at
    phases ``phase`` (n,) in [0, 1); ``drift``: the cycle's :class:`RootDrift`. Returns the
    :class:`Poulaine` and the measured ankle centres (n, 2, 3) m in the travel frame.
    """
    travel = travel_angle(drift.u_f, drift.u_l)
    measured = ankle_centres(skeleton, travel_coordinates(q_path, travel))
    return Poulaine(travel, fit_ankle(measured[:, 0], phase),
                    fit_ankle(measured[:, 1], phase)), measured


# --------------------------------------------------------------------------- blending
def aligned_phases(phase, timing: AnklePath, path: AnklePath) -> np.ndarray:
    """The phases of ``path`` at which it is where ``timing`` is at ``phase``: each segment
    between characteristic points mapped onto the segment between the same points of ``path``,
    in proportion to time. Unchanged when the two meet their points in another order."""
    phase = np.asarray(phase, dtype=np.float64)
    offset = path.kinds.index(timing.kinds[0])
    if path.kinds != timing.kinds[-offset:] + timing.kinds[:-offset]:
        return phase
    k, r = _segment_fractions(timing.phases, np.mod(phase, 1.0))
    k = (k + offset) % 4
    duration = np.mod(np.roll(path.phases, -1) - path.phases, 1.0)
    return np.mod(path.phases[k] + r * duration[k], 1.0)


@dataclass(frozen=True)
class Blend:
    """A poulaine with requested parameters built from others, axis by axis: x from
    ``sources[0]`` scaled by ``x_scale`` about the pelvis, y from ``sources[1]`` with the left
    ankle moved ``y_shift`` m to the left and the right one as far to the right, z from
    ``sources[2]`` scaled by ``z_scale``. Each source is evaluated at the same phase or, with a
    ``timing`` poulaine, at the phases where it passes its characteristic points when
    ``timing`` passes its own (:func:`aligned_phases`): heel strikes and toe-offs then stay
    together across the axes."""

    sources: tuple[Poulaine, Poulaine, Poulaine]
    x_scale: float
    y_shift: float
    z_scale: float
    names: tuple[str, str, str] = field(default=("", "", ""))
    timing: Poulaine | None = None

    def _component(self, axis: int, phase: np.ndarray) -> np.ndarray:
        """Coordinate ``axis`` of both ankles of source ``axis`` at ``phase``: (n, 2)."""
        source = self.sources[axis]
        paths = (source.left, source.right)
        if self.timing is not None:
            return np.stack([p(aligned_phases(phase, t, p))[..., axis] for p, t in
                             zip(paths, (self.timing.left, self.timing.right))], axis=-1)
        return np.stack([p(phase)[..., axis] for p in paths], axis=-1)

    def __call__(self, phase) -> np.ndarray:
        """Both ankle centres at phases ``phase`` (n,): (n, 2, 3) m, left then right."""
        phase = np.asarray(phase, dtype=np.float64)
        out = np.stack([self._component(axis, phase) for axis in range(3)], axis=-1)
        out[..., 0] *= self.x_scale
        out[..., 0, 1] += self.y_shift
        out[..., 1, 1] -= self.y_shift
        out[..., 2] *= self.z_scale
        return out

    @property
    def parameters(self) -> tuple[float, float, float]:
        """(step length, foot spacing, stance), m: the sources' characteristic points after the
        correction."""
        step = self.sources[0].parameters[0] * self.x_scale
        spacing = self.sources[1].parameters[1] + 2 * self.y_shift
        stance = self.sources[2].parameters[2] * self.z_scale
        return step, spacing, stance


def blend(poulaines: dict[str, Poulaine], /, *, step_length: float, foot_spacing: float,
          stance: float, prefer: str | None = None) -> Blend:
    """Pronost et al.'s interpolation: per axis, the poulaine of ``poulaines`` (by name) closest
    in that axis's parameter (x: step length, y: foot spacing, z: stance; ties go to ``prefer``,
    then to the first name in sorted order), corrected exactly to the requested values (m):
    x scaled, y shifted symmetrically, z scaled (:class:`Blend`), timed on ``prefer``'s
    characteristic points when given."""
    if not poulaines:
        raise MocapError("no poulaine to blend from",
                         hint="the library's entries carry none: rebuild it with this mocaplib")
    if not (step_length > 0 and np.isfinite(foot_spacing) and stance > 0):
        raise MocapError(f"step length and stance must be > 0 m and the foot spacing a number, "
                         f"got {step_length}, {stance} and {foot_spacing}")
    names = sorted(poulaines, key=lambda name: (name != prefer, name))
    chosen = []
    for axis, wanted in enumerate((step_length, foot_spacing, stance)):
        usable = [n for n in names if axis == 1 or poulaines[n].parameters[axis] > 1e-3]
        if not usable:
            raise MocapError(f"no poulaine with a {('step length', '', 'stance')[axis]} above "
                             "1 mm to scale from")
        chosen.append(min(usable, key=lambda n: abs(poulaines[n].parameters[axis] - wanted)))
    x, y, z = (poulaines[name] for name in chosen)
    return Blend((x, y, z), step_length / x.parameters[0],
                 (foot_spacing - y.parameters[1]) / 2, stance / z.parameters[2], tuple(chosen),
                 poulaines.get(prefer))
