"""How well a control space covers the velocities a controller will ask for: the target
:class:`Envelope` of (v̂, ω̂, v̂_l) commands and the :func:`coverage` of it (the share of its
points inside, the largest holes and what to capture next).

Velocities are SI (m/s, rad/s); points ``(N, 3)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from ..errors import MocapError
from ..io.tomlfile import read_toml
from .controlspace import AXES, AXIS_UNITS, SLIVER_QUALITY, ControlSpace
from .triangulation import degeneracy, delaunay_tetrahedra, locate


# --------------------------------------------------------------------------- coverage
@dataclass
class Envelope:
    """The target region of the control space: convex hull of ``vertices`` (P, 3), SI units.

    Build one with :meth:`box`, :meth:`from_toml` or :meth:`from_commands`.
    """

    vertices: np.ndarray
    axes: tuple[str, str, str] = AXES["tangential"]
    source: str = "explicit"

    @classmethod
    def box(cls, ranges: dict[str, tuple[float, float]], *, source: str = "box") -> "Envelope":
        """Axis-aligned box, e.g. ``{"v": (0, 1.8), "omega": (-1.5, 1.5), "v_l": (-.5, .5)}``."""
        axes = AXES["frontal"] if "v_f" in ranges else AXES["tangential"]
        missing = [k for k in axes if k not in ranges]
        if missing:
            raise MocapError(f"envelope box needs ranges for {', '.join(missing)}", path=source)
        lo = np.array([min(ranges[k]) for k in axes], float)
        hi = np.array([max(ranges[k]) for k in axes], float)
        corners = np.array([[(lo, hi)[(c >> i) & 1][i] for i in range(3)] for c in range(8)])
        return cls(corners, axes, source)

    @classmethod
    def from_commands(cls, commands: pd.DataFrame, *, source: str = "commands") -> "Envelope":
        """Hull of commanded velocities: a DataFrame with columns v_f, omega, v_l (SI)."""
        v = np.hypot(commands["v_f"].to_numpy(float), commands["v_l"].to_numpy(float))
        pts = np.column_stack([v, commands["omega"].to_numpy(float),
                               commands["v_l"].to_numpy(float)])
        return cls(pts, AXES["tangential"], source)

    @classmethod
    def from_toml(cls, path) -> "Envelope":
        """Read an ``[envelope]`` table: either ``points = [[v, omega, v_l], ...]`` (optionally
        ``axes = ["v_f", "omega", "v_l"]``) or one ``[lo, hi]`` range per axis name. Values
        must be finite numbers (:class:`MocapError` naming the file and key otherwise)."""
        path = Path(path)
        table = read_toml(path, what="envelope file",
                          hint="give a TOML file with an [envelope] table").get("envelope")
        if not isinstance(table, dict):
            raise MocapError("no [envelope] table", path=path,
                             hint="add [envelope] with v/omega/v_l ranges or points")
        try:
            if "points" in table:
                axes = tuple(table.get("axes", AXES["tangential"]))
                if axes not in AXES.values():
                    raise ValueError(f"axes must be one of {list(AXES.values())}")
                pts = _finite_numbers("points", table["points"], "triples of finite numbers")
                if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4:
                    raise ValueError("points must be at least 4 triples")
                return cls(pts, axes, str(path))
            ranges = {}
            for k, v in table.items():
                if k in AXIS_UNITS:
                    ranges[k] = tuple(_finite_numbers(k, v, "[lo, hi], two finite numbers"))
                    if len(ranges[k]) != 2:
                        raise ValueError(f"{k} must be [lo, hi], two finite numbers, got {v!r}")
            return cls.box(ranges, source=str(path))
        except (ValueError, TypeError) as exc:
            raise MocapError(f"bad [envelope] table: {exc}", path=path,
                             hint="ranges are [lo, hi] in m/s or rad/s") from exc

    def sample(self, scale: np.ndarray, *, n: int = 25) -> np.ndarray:
        """Regular grid of about n³ points over the bounding box, the points inside the hull
        (S, 3). An axis whose range straddles 0 is gridded through 0 (steps of
        (hi - lo)/(n - 1) from 0; with odd n on a symmetric range that is linspace), so straight
        walks, no turning and no side-step are sampled exactly, not ± half a step away."""
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        axes = [_grid_through_zero(a, b, n) for a, b in zip(lo, hi)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        x = self.vertices / scale
        if degeneracy(x) is not None:
            return grid  # a flat envelope: its bounding box is the envelope
        inside = locate(delaunay_tetrahedra(x, source=self.source), grid / scale)[0] >= 0
        return grid[inside]


def _finite_numbers(key: str, value, expected: str) -> np.ndarray:
    """``value`` (a list of numbers, or of lists of numbers, from a TOML file) as a float
    array; ValueError naming ``key`` and what was ``expected`` for text, booleans, NaN or
    infinity."""
    def bad(x) -> bool:
        if isinstance(x, list):
            return any(bad(y) for y in x)
        return isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x)
    if not isinstance(value, list) or bad(value):
        raise ValueError(f"{key} must be {expected}, got {repr(value)[:80]}")
    return np.asarray(value, dtype=float)


def _grid_through_zero(lo: float, hi: float, n: int) -> np.ndarray:
    """n (about) evenly spaced values over [lo, hi]; through 0 when lo < 0 < hi."""
    if not hi > lo:
        return np.array([lo])
    if not lo < 0.0 < hi:
        return np.linspace(lo, hi, n)
    step = (hi - lo) / (n - 1)
    k = np.arange(np.ceil(lo / step - 1e-9), np.floor(hi / step + 1e-9) + 1)
    return np.clip(k * step, lo, hi)


@dataclass
class Coverage:
    """Coverage of an :class:`Envelope` by a :class:`ControlSpace` (distances normalised).

    Attributes
    ----------
    fraction_inside : share of envelope samples blended at themselves in a gait's cell
        (:meth:`ControlSpace.contains`; the gap between the cells is not covered).
    n_samples : number of envelope samples.
    largest_hole : (3,) the envelope sample farthest from every entry, SI.
    largest_hole_distance : its normalised distance to the nearest entry.
    slivers : DataFrame of tetrahedra with quality < threshold: ``entries`` (ids), ``quality``.
    entries_per_class : counts of entries by locomotion class ("unknown" when None).
    capture_next : DataFrame of suggested velocity triples (axes columns, SI) and the
        normalised ``gap`` each one fills (greedy farthest point).
    axes : the control-space axes of every triple above.
    samples : (S, 3) the envelope samples, SI; samples_inside : (S,) bool, in a cell.
    """

    fraction_inside: float
    n_samples: int
    largest_hole: np.ndarray
    largest_hole_distance: float
    slivers: pd.DataFrame
    entries_per_class: dict[str, int]
    capture_next: pd.DataFrame
    axes: tuple[str, str, str] = AXES["tangential"]
    samples_inside: np.ndarray = field(default=None, repr=False)
    samples: np.ndarray = field(default=None, repr=False)


def coverage(cs: ControlSpace, envelope: Envelope, *, n_grid: int = 25, n_next: int = 5,
             sliver_quality: float = SLIVER_QUALITY) -> Coverage:
    """How well the entries cover ``envelope`` (see :class:`Coverage`).

    Samples equally far from the entries (mirror images on a symmetric library) are told
    apart by their distance to the envelope's centre, nearest first, so ties do not fall to
    whichever side the grid lists first."""
    if tuple(envelope.axes) != tuple(cs.axes):
        raise MocapError(f"envelope axes {envelope.axes} differ from the control space's "
                         f"{cs.axes}", path=envelope.source)
    samples = envelope.sample(cs.scale, n=n_grid)
    inside = cs.contains(samples)
    xs = cs.normalise(samples)
    dist, _ = cKDTree(cs.normalise(cs.points)).query(xs)
    centre = cs.normalise(envelope.vertices).mean(axis=0)
    off_centre = np.linalg.norm(xs - centre, axis=1)
    hole = _farthest(dist, off_centre)
    picks, gaps = [], []
    d = dist.copy()
    for _ in range(min(n_next, len(xs))):
        j = _farthest(d, off_centre)
        if d[j] <= 0:
            break
        picks.append(samples[j])
        gaps.append(d[j])
        d = np.minimum(d, np.linalg.norm(xs - xs[j], axis=1))
    nxt = pd.DataFrame(np.reshape(picks, (-1, 3)), columns=list(cs.axes))
    nxt["gap"] = gaps
    quality = cs.tetra_quality()
    bad = np.flatnonzero(quality < sliver_quality)
    slivers = pd.DataFrame({"entries": [[cs.ids[k] for k in cs.tri.simplices[s]] for s in bad],
                            "quality": quality[bad]})
    classes = pd.Series([c if c is not None and c == c else "unknown" for c in cs.classes])
    return Coverage(fraction_inside=float(inside.mean()) if len(inside) else float("nan"),
                    n_samples=len(samples), largest_hole=samples[hole],
                    largest_hole_distance=float(dist[hole]), slivers=slivers,
                    entries_per_class={str(k): int(v) for k, v in
                                       classes.value_counts().sort_index().items()},
                    capture_next=nxt, axes=cs.axes, samples_inside=inside, samples=samples)


def _farthest(distance: np.ndarray, off_centre: np.ndarray, *, tol: float = 1e-9) -> int:
    """Index of the largest ``distance``; among ties (within ``tol``) the smallest
    ``off_centre``, then the first."""
    ties = np.flatnonzero(distance >= distance.max() - tol)
    return int(ties[np.argmin(off_centre[ties])])
