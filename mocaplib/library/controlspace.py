"""The library's control space: Delaunay tetrahedra of the entries' velocities, blending, coverage.

Axes and normalisation
----------------------
Each entry is a point ``(v̂, ω̂, v̂_l)`` (m/s, rad/s, m/s; the paper's section III), or with
``axes="frontal"`` ``(v̂_f, ω̂, v̂_l)``. Points are stored in SI units; the triangulation, the
hull distances and the coverage distances use **normalised** coordinates ``x / scale`` with one
scale per axis (:data:`DEFAULT_SCALE`, or the ``control_space.scale`` stored in the library), so
that 1 normalised unit is "a lot" of each velocity: 1.5 m/s of walking speed, π/2 rad/s of
turning, 0.5 m/s of side-stepping. Queries are normalised the same way. Barycentric weights are
affine invariant, so they do not depend on the scales; which tetrahedra Delaunay chooses, the
distances and the coverage figures do.

Triangulation of degenerate (gridded) libraries
-----------------------------------------------
Libraries are often gridded: many entries share v̂_l = 0 or a speed, and four or more lie on a
common plane or sphere. Their Delaunay subdivision then has cells that are not tetrahedra
(a grid's cube cell has 8 cospherical corners), and Qhull's triangulated output (``Qt``, which
``scipy.spatial.Delaunay`` always uses) splits such cells into fans that include **zero-volume
tetrahedra** (34 of 178 on a grid of 4×5×3 points, cells 0.33×0.5×0.5). Joggling the input
(``QJ``) is worse here: the tetrahedra are flat only after the joggle is undone, and it gives
156 flat ones of 296 on the same grid. Dropping the flat ones leaves a non-conforming mesh
(100 interior faces of that grid had no neighbour), so blending would jump across faces.
:func:`delaunay_tetrahedra` instead lifts the normalised points onto the paraboloid ``|x|²`` plus a
tiny deterministic height per point (:data:`LIFT_PERTURBATION` times a hash of the point, so the
same entry gets the same height in every sub-library) and keeps the lower hull of the lifted points:
a *regular* triangulation that refines the Delaunay subdivision. Every tetrahedron is a Delaunay
tetrahedron of the original points, has positive volume, the mesh is conforming (each interior face
shared by exactly two tetrahedra) and the tetrahedra tile the convex hull exactly (142 on that grid,
smallest radius ratio 0.54). Thin tetrahedra that remain are genuine slivers of the point set, which
is what the sliver count reports: on the sample library, side-steps within ~1e-5 (normalised) of the
cone |v̂_l| = v̂ with spot turns on its edge, and 60°/120° diagonal walks that share v̂ and v̂_l
(:func:`close_entries` finds such pairs; the frontal axes separate them).

Blending (Truong et al. 2010, equations (4)-(6))
------------------------------------------------
A command is blended in the tetrahedra of one gait (:mod:`mocaplib.library.cells`: one cell
per gait, the side-step cone a facet of the walk cell, the boundary within a stated tolerance,
a command between the walks and the runs served by the nearest cell). On the tangential axes
the cells say whether and by which gait a command is served, and its weights are computed on
the frontal axes (v̂_f, ω̂, v̂_l) in that gait's frontal tetrahedra (``Cell.frontal``; module
docstring of :mod:`mocaplib.library.cells`), so that the blend moves at the frontal and
lateral speeds and turns at the rate the command asks: barycentric weights reproduce a
quantity linear in the axes exactly, and v̂_f is not linear in (v̂, v̂_l) near the side-step
cone. The point blended lies in one tetrahedron; its barycentric weights ``w`` (four,
summing to 1, reproducing the point) blend the four entries' Fourier coefficients and periods:
``a_d = Σ w_i a_i``, ``b_d = Σ w_i b_i``, ``T_d = Σ w_i T_i`` (entries with fewer harmonics are
padded with zeros), and the joint angles are synthesised with the team's convention
``q(t) = a_0 + Σ_k a_k cos(2πkt/T_d) + b_k sin(2πkt/T_d)``, ``t ∈ [0, T_d)``.

Coverage
--------
A target :class:`~mocaplib.library.coverage.Envelope` (the convex hull of a few points, SI units; by default the commanded
velocities of a capture plan) is sampled on a regular grid; :func:`~mocaplib.library.coverage.coverage` reports the
fraction of those samples blended at themselves in a gait's cell (:meth:`ControlSpace.contains`),
the largest hole (the sample farthest from
every entry), sliver tetrahedra, entries per class and a greedy farthest-point "capture next" list.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from ..errors import LibraryError, MocapError
from ..gait.fourier import RootDrift, synthesize
from ..skeleton import ROOT_Z
from .entry import DRIFT_VELOCITIES
from .cells import (HULL_TOLERANCE, build_cells, cell_tetrahedra, frontal_tetrahedra, onto_cone,
                    serve, to_frontal, weigh_on_frontal_axes)
from .phase import from_left_toe_off
from .triangulation import (DEGENERACY_HINT, Triangulation, degeneracy, delaunay_tetrahedra,
                            outside_planes, stack_padded, tetra_quality)

#: Axis names of the two control-space variants.
AXES = {"tangential": ("v", "omega", "v_l"), "frontal": ("v_f", "omega", "v_l")}
#: Units of each axis.
AXIS_UNITS = {"v": "m/s", "v_f": "m/s", "omega": "rad/s", "v_l": "m/s"}
#: Normalisation scale of each axis (normalised = SI / scale): brisk walking speed, a 90°/s
#: turn, a brisk side-step.
DEFAULT_SCALE = {"v": 1.5, "v_f": 1.5, "omega": np.pi / 2, "v_l": 0.5}
#: Tetrahedra whose radius ratio 3·r_in/R_circ (1 = regular, 0 = flat) is below this are slivers.
SLIVER_QUALITY = 0.1
#: Entries closer than this (normalised: 30 mm/s of v̂, 1.8°/s, 10 mm/s of v̂_l) are hard to tell
#: apart in the control space: blending between them switches motions over a tiny distance.
CLOSE_DISTANCE = 0.02


# --------------------------------------------------------------------------- results
@dataclass
class QueryResult:
    """Answer to :meth:`ControlSpace.query` for Q points.

    Attributes
    ----------
    points : (Q, 3) the query points, SI units.
    inside : (Q,) bool, True when the point is served: inside a gait's cell (within
        :data:`~mocaplib.library.cells.HULL_TOLERANCE`), or between cells (``clamped``).
    entries : (Q, 4) int, row numbers (in :attr:`ControlSpace.ids`) of the entries of the
        tetrahedron the weights are computed in (on the tangential axes, a frontal one of the
        serving cell); -1 when outside.
    weights : (Q, 4) barycentric weights (sum 1, reproduce the point blended, on the tangential
        axes its (v̂_f, ω̂, v̂_l)); NaN when outside.
    nearest : (Q, 3) SI units: the point blended when ``clamped``, the nearest point of the
        nearest cell when outside, else the query point itself.
    distance : (Q,) normalised distance from the point to ``nearest`` (0 inside a cell).
    gait : (Q,) the gait of the cell that serves the point (or, outside, of the nearest cell).
    clamped : (Q,) bool, served at ``nearest`` on its gait's cell, not at the point itself.
    """

    points: np.ndarray
    inside: np.ndarray
    entries: np.ndarray
    weights: np.ndarray
    nearest: np.ndarray
    distance: np.ndarray
    gait: np.ndarray
    clamped: np.ndarray


@dataclass
class Blend:
    """Blended cycles (equation (5)): coefficients (Q, D, N+1), periods T (Q,) in seconds and,
    when the entries have one, the blended root drift velocities (Q, 3) (:data:`~mocaplib.library.entry.DRIFT_VELOCITIES`)."""

    a: np.ndarray
    b: np.ndarray
    T: np.ndarray
    drift: np.ndarray | None = None

    def synthesize(self, i: int = 0, *, rate: float = 100.0,
                   cycles: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Blend ``i`` sampled at ``rate`` Hz over ``cycles`` cycles: times (F,) s, angles (F, D).

        Root channels are in the path frame, as stored in the library (see :meth:`world`).
        """
        t = np.arange(self.frames(i, rate=rate, cycles=cycles)) / rate
        return t, synthesize(self.a[i], self.b[i], self.T[i], t)

    def frames(self, i: int = 0, *, rate: float = 100.0, cycles: int = 1) -> int:
        """How many frames :meth:`synthesize` samples: k / ``rate`` s before the end of the
        last of ``cycles`` periods."""
        return int(np.ceil(cycles * self.T[i] * rate - 1e-9))

    def looped(self, rate: float) -> Blend:
        """The blends played in whole frames at ``rate`` Hz: each period T (s) becomes
        n / rate, n = round(T × rate) (at least 1), so that a clip of whole cycles loops with
        every step one frame long; the joint angles are the same cycle played n / (T × rate)
        times slower (at most half a frame per cycle) and the drift velocities are scaled by
        the same factor, so each cycle still covers its path."""
        played = np.maximum(np.round(self.T * rate), 1.0) / rate
        drift = None if self.drift is None else self.drift * (self.T / played)[:, None]
        return Blend(self.a, self.b, played, drift)

    def world(self, i: int = 0, *, rate: float = 100.0,
              cycles: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Like :meth:`synthesize` with the root moved into the world frame by the blended drift.

        The path frame starts at the origin facing +X and moves with the blended constant
        velocity and turn rate (:class:`mocaplib.gait.fourier.RootDrift`: a line or circular arc);
        ``pelvis_tx/ty`` and ``pelvis_rotation`` are composed with it. Without drift, the same
        as :meth:`synthesize` (the cycle stays in place).
        """
        t, q = self.synthesize(i, rate=rate, cycles=cycles)
        if self.drift is None:
            return t, q
        return t, RootDrift(0.0, 0.0, 0.0, *(float(v) for v in self.drift[i])).restore(q, t)


# --------------------------------------------------------------------------- control space
class ControlSpace:
    """Delaunay tetrahedralisation of library entries in the normalised control space.

    Parameters
    ----------
    points : (E, 3) entries' velocities on ``axes``, SI units.
    a, b : E Fourier coefficient arrays (D, N_i+1) (zero-padded to the largest N), or None.
    T : (E,) periods, s, or None.
    drift : (E, 3) root drift velocities (:data:`~mocaplib.library.entry.DRIFT_VELOCITIES`), or None.
    ids : E entry ids; classes : E locomotion classes (None when unknown), which give each
        entry's gait (:func:`mocaplib.gait.gaits.class_gait`).
    v_f : (E,) frontal speeds, m/s, or None: on the tangential axes, entries moving backwards
        stay out of the cells (:mod:`mocaplib.library.cells`).
    axes : "tangential" (v, ω, v_l) or "frontal" (v_f, ω, v_l).
    scale : (3,) normalisation scales, default :data:`DEFAULT_SCALE` for those axes.
    body_scales : (E,) factors that put each entry's pelvis height on the body blends are
        posed on (:meth:`on_body`; ``Library.body_scales``), or None: all 1.
    source : the library file, for error messages.

    Raises
    ------
    LibraryError
        Fewer than 4 distinct entries, or entries that span only a plane or a line.
    """

    def __init__(self, points, *, a=None, b=None, T=None, drift=None, ids=None, classes=None,
                 v_f=None, axes: str = "tangential", scale=None, body_scales=None, source=None):
        if axes not in AXES:
            raise MocapError(f"unknown control-space axes {axes!r}; use one of {', '.join(AXES)}")
        self.variant = axes
        self.axes = AXES[axes]
        self.source = source
        self.points = np.asarray(points, dtype=float).reshape(-1, 3)
        n = len(self.points)
        self.ids = [str(i) for i in (ids if ids is not None else range(n))]
        self.classes = list(classes) if classes is not None else [None] * n
        self.v_f = None if v_f is None else np.asarray(v_f, dtype=float)
        self.scale = (np.array([DEFAULT_SCALE[k] for k in self.axes]) if scale is None
                      else np.asarray(scale, dtype=float))
        if not np.all(np.isfinite(self.points)):
            raise LibraryError("control-space points must be finite", path=source,
                               hint="drop entries without velocities before building")
        self.tri = self._triangulate()
        self.cells, self.cell_problems = build_cells(
            self.points, self.scale, classes=self.classes, v_f=v_f,
            tangential=axes == "tangential", source=source, whole=self.tri)
        self.a = None if a is None else stack_padded(a)
        self.b = None if b is None else stack_padded(b)
        self.T = None if T is None else np.asarray(T, dtype=float)
        self.drift = None if drift is None else np.asarray(drift, dtype=float)
        self.body_scales = None if body_scales is None else np.asarray(body_scales, float)

    @classmethod
    def from_library(cls, library, *, axes: str = "tangential", chosen_only: bool = True,
                     mirrored: bool = True, source=None) -> "ControlSpace":
        """Control space of a :class:`mocaplib.library.format.Library`.

        Uses the entries with finite velocities and period (only those marked ``chosen`` when
        ``chosen_only``; without the mirror images unless ``mirrored``), their Fourier
        coefficients and root drift, the library's stored ``control_space.scale`` (for the
        frontal variant the same scales, v̂_f taking v̂'s) and their :attr:`body_scales`
        (:meth:`on_body`). Blending takes phase 0 as the
        left toe-off: an entry whose cycle starts at another event (``cycle_start``) is
        expressed from its left toe-off (:func:`mocaplib.library.phase.from_left_toe_off`).

        Parameters
        ----------
        library : Library
            A loaded library.
        axes : {"tangential", "frontal"}
            (v̂, ω̂, v̂_l), or (v̂_f, ω̂, v̂_l), which tells walking backwards from forwards.
        chosen_only : bool
            Only the entries marked ``chosen`` (one per capture).
        mirrored : bool
            With the mirror images.
        source : str, optional
            The library's file, for error messages.

        Returns
        -------
        ControlSpace

        Raises
        ------
        LibraryError
            The entries span no 3-D control space, or one lacks a finite root drift.
        """
        entries = [from_left_toe_off(e) for e in library.entries]
        # (E, 4): the axes' velocities and the period, NaN where null
        values = np.array([[getattr(e, key) for key in (*AXES[axes], "T")] for e in entries],
                          dtype=np.float64).reshape(-1, 4)
        usable = ~np.isnan(values).any(axis=1)
        if chosen_only:
            usable &= np.array([e.chosen for e in entries], dtype=bool)
        if not mirrored:
            usable &= ~np.array([e.mirrored for e in entries], dtype=bool)
        a, b = library.coefficient_arrays()
        for i, (entry, stored) in enumerate(zip(entries, library.entries)):
            if entry is not stored:
                a[i], b[i] = entry.fourier.a, entry.fourier.b
        kept = [e for e, use in zip(entries, usable) if use]
        ids = [e.id for e in kept]
        drift = np.array([e.root_drift.velocities for e in kept],
                         dtype=np.float64).reshape(-1, 3)
        lacking = [i for i, row in zip(ids, drift) if not np.isfinite(row).all()]
        if lacking:  # blending without it would drop every entry's root motion
            raise LibraryError(f"entries without a finite root_drift "
                               f"{'/'.join(DRIFT_VELOCITIES)}: {', '.join(lacking[:5])}"
                               + (" …" if len(lacking) > 5 else ""), path=source,
                               hint="build the library again with mocaplib build (run "
                                    "`mocaplib validate` on it for every problem)")
        return cls(values[usable, :3], a=a[usable], b=b[usable], T=values[usable, 3],
                   drift=drift, ids=ids, classes=[e.locomotion_class for e in kept],
                   v_f=np.array([e.v_f for e in kept], dtype=np.float64), axes=axes,
                   scale=library.control_scale, body_scales=library.body_scales()[usable],
                   source=source)

    def normalise(self, x) -> np.ndarray:
        """SI points (…, 3) to normalised coordinates."""
        return np.asarray(x, dtype=float) / self.scale

    def _triangulate(self) -> Triangulation:
        x = self.normalise(self.points)
        reason = degeneracy(x)
        if reason:
            raise LibraryError(f"no control space: the control space of the {len(x)} entries' "
                               f"({', '.join(self.axes)}) is degenerate: it {reason}",
                               path=self.source, hint=DEGENERACY_HINT)
        return delaunay_tetrahedra(x, source=self.source)

    # ----------------------------------------------------------------- queries
    @property
    def hull_facets(self) -> np.ndarray:
        """Triangles of the hull, (H, 3) row numbers of entries."""
        return self.tri.convex_hull

    def query(self, points, *, gait: str | None = None) -> QueryResult:
        """Enclosing tetrahedra and barycentric weights (equation (4)) of query points, in the
        cells of one gait (:mod:`mocaplib.library.cells`), the weights on the frontal axes.

        Parameters
        ----------
        points : array_like, shape (Q, 3) or (3,)
            Velocities on :attr:`axes`, SI units (m/s, rad/s, m/s).
        gait : {"walk", "run"}, optional
            Blend in this gait's cell only (a point outside it but inside the hull of all the
            entries is clamped onto it); default: the cell holding the point, else the nearest.

        Returns
        -------
        QueryResult
            Per point: served or not, the gait, the four entries (rows of :attr:`ids`) and
            their weights, and the point blended with its normalised distance.

        Raises
        ------
        MocapError
            Points of another shape, or a gait without a cell.
        """
        p = np.atleast_2d(np.asarray(points, dtype=float))
        if p.ndim != 2 or p.shape[1] != 3:
            raise MocapError(f"query points must have shape (Q, 3), got {np.shape(points)}")
        cells = self._cells(gait)
        x = self.normalise(p)
        coned = onto_cone(p) if self.variant == "tangential" else p
        on_cone = self.normalise(coned)
        served = serve(cells, on_cone, outside_planes(self.tri, x) <= HULL_TOLERANCE)
        if self.variant == "tangential":     # the SI point served: exactly on the cone there
            at = np.all(served.point == on_cone, axis=1)[:, None]
            weigh_on_frontal_axes(cells, served, self.normalise(to_frontal(
                np.where(at, coned, served.point * self.scale))))
        inside = served.simplex[:, 0] >= 0
        weights = np.full((len(p), 4), np.nan)
        w = np.clip(served.weights[inside], 0.0, None)
        weights[inside] = w / w.sum(axis=1, keepdims=True)
        moved = served.clamped | ~inside
        nearest = np.where(moved[:, None], served.point * self.scale, p)
        return QueryResult(p, inside, served.simplex, weights, nearest,
                           np.where(moved, served.distance, 0.0), served.gait,
                           served.clamped)

    def _cells(self, gait: str | None) -> dict:
        """The cells a query may use: all of them, or the one of ``gait``; raises MocapError
        naming the gaits there are when there is none."""
        have = ", ".join(self.cells) or "none"
        if gait is None and self.cells:
            return self.cells
        if gait in self.cells:
            return {gait: self.cells[gait]}
        why = self.cell_problems.get(gait) or self.cell_problems.get("walk")
        raise MocapError(f"the control space has no {gait or 'gait'} cell to blend in "
                         f"(cells: {have})" + (f": its entries {why}" if why else ""),
                         path=self.source, hint=DEGENERACY_HINT)

    def nearest_ids(self, point, *, k: int = 3) -> list[str]:
        """Ids of the ``k`` entries of the cells nearest to an SI point (3,), in normalised
        distance."""
        rows = np.unique(np.concatenate([c.rows for c in self.cells.values()]))
        d = np.linalg.norm(self.normalise(self.points[rows]) - self.normalise(point), axis=1)
        return [self.ids[rows[i]] for i in np.argsort(d, kind="stable")[:k]]

    def outside_text(self, result: QueryResult, i: int = 0) -> str:
        """What a person needs about query ``i`` of ``result`` that no cell serves: how far it
        is (normalised), the nearest point and gait, the nearest entries and, when there is
        one, :meth:`impossible_text`."""
        def point(x) -> str:
            return "(" + ", ".join(f"{float(v):.4g}" for v in x) + ")"

        text = (f"{point(result.points[i])} is outside the control space by "
                f"{result.distance[i]:.3g} (normalised); the nearest point of the "
                f"{result.gait[i]} cell is {point(result.nearest[i])}, the "
                f"nearest entries {', '.join(self.nearest_ids(result.points[i]))}")
        why = self.impossible_text(result.points[i])
        return text + (f"; {why}" if why else "")

    def impossible_text(self, point) -> str | None:
        """Why no motion does the SI command ``point`` (3,) on the tangential axes when it
        moves faster sideways than its speed (``|v̂_l| > v̂``), and where such commands are
        asked; None for any other command."""
        v, _, v_l = (float(x) for x in point)
        if self.variant != "tangential" or abs(v_l) <= v * (1 + 1e-9):
            return None
        return (f"no motion moves faster sideways than its speed: v̂ is the speed along the "
                f"path and v̂_l its lateral part, so |v̂_l| <= v̂ (here |{v_l:.4g}| > {v:.4g} "
                f"m/s); to ask a forward and a sideways speed, use the frontal axes "
                f"(v̂_f, ω̂, v̂_l): --axes frontal")

    def contains(self, points) -> np.ndarray:
        """(Q,) bool: SI points (Q, 3) blended at themselves by :meth:`query`: inside a gait's
        cell, not clamped onto one."""
        res = self.query(np.atleast_2d(points))
        return res.inside & ~res.clamped

    # ----------------------------------------------------------------- blending
    def blend(self, result: QueryResult) -> Blend:
        """Weighted coefficients and periods (equation (5)) of every query point.

        Parameters
        ----------
        result : QueryResult
            The answer of :meth:`query`; every point must be inside the hull.

        Returns
        -------
        Blend
            Fourier coefficients (Q, D, N+1), periods (Q,) s and, when the entries have one,
            root drift velocities (Q, 3); :meth:`Blend.synthesize` samples them.

        Raises
        ------
        MocapError
            A point outside the hull (the message gives the nearest point on it), or a
            control space without Fourier coefficients.
        """
        if self.a is None or self.T is None:
            raise MocapError("this control space has no Fourier coefficients to blend",
                             path=self.source)
        if not result.inside.all():
            bad = np.flatnonzero(~result.inside)
            raise MocapError(f"{len(bad)} query point(s) are outside: "
                             + self.outside_text(result, int(bad[0])), path=self.source,
                             hint="query the nearest point instead")
        e, w = result.entries, result.weights
        return Blend(np.einsum("qk,qkdn->qdn", w, self.a[e]),
                     np.einsum("qk,qkdn->qdn", w, self.b[e]),
                     np.einsum("qk,qk->q", w, self.T[e]),
                     None if self.drift is None else np.einsum("qk,qkj->qj", w, self.drift[e]))

    def on_body(self, blend: Blend, result: QueryResult) -> Blend:
        """``blend`` of ``result`` (:meth:`blend`) posed on the library's body: its pelvis height
        (``pelvis_tz``'s coefficients) scaled by its entries' :attr:`body_scales`, weighted as
        they are (a blend of subjects of other sizes stands on that body's feet; unchanged
        without scales)."""
        if self.body_scales is None:
            return blend
        factor = np.einsum("qk,qk->q", result.weights, self.body_scales[result.entries])
        a, b = blend.a.copy(), blend.b.copy()
        a[:, ROOT_Z] *= factor[:, None]
        b[:, ROOT_Z] *= factor[:, None]
        return Blend(a, b, blend.T, blend.drift)

    def tetra_quality(self) -> np.ndarray:
        """Radius ratio of every tetrahedron in normalised coordinates, shape (nsimplex,)."""
        return tetra_quality(self.tri.points[self.tri.simplices])


def stored_tetrahedra(library) -> dict | None:
    """The tetrahedra ``mocaplib query`` locates a command in, as the library file stores them
    (``control_space.tetrahedra``) for readers in other languages, or None when the entries
    span no 3-D control space (or no gait has a cell).

    Keys: ``ids`` (the control space's entries: chosen, with finite velocities and period, in
    the file's order), ``simplices`` (S, 4) row numbers of ``ids``: the tetrahedra of each
    gait's cell (:mod:`mocaplib.library.cells`), walks first, ``gaits`` (S,) the gait of each
    tetrahedron's cell, ``hull`` (H, 3) row numbers of ``ids``: the boundary triangles of
    all the entries' points, which tell a command between the cells from one outside, and
    ``frontal_simplices`` (S', 4) with ``frontal_gaits`` (S',): each cell's frontal
    tetrahedra, where a served command's weights are computed. A point's normalised
    coordinates are its (v, omega, v_l) / ``control_space.scale``, in the cells with the
    side-steps put on the cone (:meth:`ControlSpace.from_library`, tangential axes), and in
    the frontal tetrahedra those points' (v_f, omega, v_l) / scale
    (:func:`~mocaplib.library.cells.to_frontal`).
    """
    try:
        cs = ControlSpace.from_library(library)
    except LibraryError:
        return None
    if not cs.cells:
        return None
    simplices, gaits = cell_tetrahedra(cs.cells)
    frontal, frontal_gaits = frontal_tetrahedra(cs.cells)
    return {"ids": list(cs.ids), "simplices": simplices.tolist(), "gaits": gaits,
            "hull": cs.tri.convex_hull.tolist(), "frontal_simplices": frontal.tolist(),
            "frontal_gaits": frontal_gaits}


def close_entries(cs: ControlSpace, *, within: float = CLOSE_DISTANCE) -> pd.DataFrame:
    """Pairs of entries closer than ``within`` (normalised distance): columns ``a``, ``b`` (ids)
    and ``distance``, nearest first. E.g. 60° and 120° diagonal walks have the same v̂ and v̂_l,
    so they coincide on the tangential axes but not on the frontal ones."""
    x = cs.normalise(cs.points)
    pairs = np.array(sorted(cKDTree(x).query_pairs(within)), dtype=int).reshape(-1, 2)
    d = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    order = np.argsort(d, kind="stable")
    return pd.DataFrame({"a": [cs.ids[i] for i in pairs[order, 0]],
                         "b": [cs.ids[j] for j in pairs[order, 1]], "distance": d[order]})
