"""The :class:`Motion` container: a fitted capture (root pose and joint angles over time).

Angles are radians, root translation metres, world frame Z up; time on axis 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import MocapError
from ..skeleton import DOF_NAMES, Skeleton

if TYPE_CHECKING:
    import pandas as pd

#: A DOF within this distance (radians or metres) of a joint limit counts as at the limit.
AT_LIMIT = 1e-3
#: A DOF at a limit in more than this share of a capture's frames is warned about.
LIMIT_WARNING_SHARE = 0.02


@dataclass(frozen=True)
class Repair:
    """A labelling error the fit undid: two markers whose labels are exchanged in frames
    ``[start, stop)`` (``kind="swap"``, ``labels`` the two), or a marker that stays far from
    its place and is left out (``kind="drop"``, one label); ``evidence`` says what showed it."""

    kind: str
    labels: tuple[str, ...]
    start: int
    stop: int
    evidence: str

    def as_dict(self, rate: float) -> dict:
        """JSON-ready: kind, markers, first and last frame (0-based, inclusive), the times of
        those frames (s, from the capture's first frame) and the evidence."""
        return {"kind": self.kind, "markers": list(self.labels),
                "frames": [self.start, self.stop - 1],
                "time_s": [self.start / rate, (self.stop - 1) / rate],
                "evidence": self.evidence}

    def sentence(self, rate: float) -> str:
        """The repair in words, for warnings."""
        when = f"frames {self.start}-{self.stop - 1} ({self.start / rate:.2f}-" \
               f"{(self.stop - 1) / rate:.2f} s)"
        if self.kind == "swap":
            return (f"labels {self.labels[0]} and {self.labels[1]} look exchanged in {when}: "
                    f"{self.evidence}; the fit exchanges them back: check the labelling")
        return f"marker {self.labels[0]} left out in {when}: {self.evidence}; check its label"


def apply_repairs(markers: np.ndarray, labels: list[str], repairs) -> np.ndarray:
    """Markers (F, M, 3) in ``labels`` order with the :class:`Repair` s applied (a copy):
    swapped columns exchanged in their frames, dropped ones NaN there."""
    out = np.array(markers, dtype=np.float64, copy=True)
    for r in repairs:
        columns = [labels.index(label) for label in r.labels]
        rows = slice(r.start, r.stop)
        out[rows, columns] = np.nan if r.kind == "drop" else markers[rows, columns[::-1]]
    return out


@dataclass
class Motion:
    """Joint angles of a subject-scaled skeleton fitted to a trial's markers.

    Attributes
    ----------
    q : ndarray, shape (F, D)
        Joint coordinates, one column per DOF in :data:`mocaplib.skeleton.DOF_NAMES` order
        (radians; ``pelvis_t*`` metres); frame ``f`` is at ``f / rate`` seconds from the
        trial's first frame (:attr:`time`). :attr:`angles` gives them as a DataFrame.
    skeleton : Skeleton
        The calibrated skeleton the angles drive.
    rate : float
        Frame rate, Hz.
    marker_labels : list[str], length M
        Labels of the markers used in the fit.
    residuals : ndarray, shape (F, M)
        Distance between each measured marker and its model position, metres; NaN when missing.
    failed : ndarray of bool, shape (F,)
        Frames that could not be fitted (too few markers, no convergence); their angles are
        interpolated and should not be trusted.
    rejected : ndarray of bool, shape (F, M)
        Samples the fit removed as outliers (mislabelled or jumping); their residuals are NaN.
    locked_dofs : list[str]
        DOFs held at zero because the protocol lacks the markers to see them.
    unobservable : dict[str, float]
        Of those, the ones the markers on hand determine too poorly to fit, with the standard
        deviation (radians) they would have had (:func:`mocaplib.model.calibration.unobservable_dofs`).
    marker_weights : ndarray, shape (M,), optional
        Each marker's weight in the fit (the protocol's); markers weighted below 1 only steady
        the fit, and quality figures leave them out (:meth:`trusted`).
    marker_segments, marker_offsets : ndarray, shapes (M,), (M, 3)
        Each marker's segment index and its position in that segment's frame (metres).
    repairs : list of :class:`Repair`
        Labelling errors the fit undid (exchanged labels, a marker far from its place); the
        fit read the markers repaired (:func:`apply_repairs`), and so do the gait events
        (:meth:`repaired_track`).
    source : str or None
        The capture's file.
    """

    q: np.ndarray
    skeleton: Skeleton
    rate: float
    marker_labels: list[str] = field(default_factory=list)
    residuals: np.ndarray | None = None
    failed: np.ndarray | None = None
    rejected: np.ndarray | None = None
    locked_dofs: list[str] = field(default_factory=list)
    marker_segments: np.ndarray | None = None
    marker_offsets: np.ndarray | None = None
    repairs: list[Repair] = field(default_factory=list)
    source: str | None = None
    unobservable: dict[str, float] = field(default_factory=dict)
    marker_weights: np.ndarray | None = None

    def __post_init__(self):
        self.q = np.asarray(self.q, dtype=np.float64)
        if self.q.ndim != 2 or self.q.shape[1] != len(DOF_NAMES):
            raise MocapError(f"Motion.q must have shape (F, {len(DOF_NAMES)}), one column per "
                             f"DOF of the skeleton, got {self.q.shape}", path=self.source)
        n = len(self.q)
        if self.residuals is None:
            self.residuals = np.full((n, len(self.marker_labels)), np.nan)
        if self.failed is None:
            self.failed = np.zeros(n, dtype=bool)
        if self.rejected is None:
            self.rejected = np.zeros(self.residuals.shape, dtype=bool)
        if self.residuals.shape != (n, len(self.marker_labels)):
            raise MocapError(f"residuals must have shape ({n}, {len(self.marker_labels)}), "
                             f"got {self.residuals.shape}", path=self.source)

    @property
    def time(self) -> np.ndarray:
        """Seconds from the first frame, shape (F,): ``arange(F) / rate``."""
        return np.arange(len(self.q)) / float(self.rate)

    @property
    def n_frames(self) -> int:
        return len(self.q)

    @property
    def angles(self) -> "pd.DataFrame":
        """:attr:`q` as a DataFrame (F, D), built on each call from a copy (change :attr:`q`
        to change the motion): DOF columns in :data:`~mocaplib.skeleton.DOF_NAMES` order,
        index ``time_s`` (:attr:`time`)."""
        import pandas as pd  # here: fitting and writing the angles need no pandas

        return pd.DataFrame(self.q, columns=list(DOF_NAMES),
                            index=pd.Index(self.time, name="time_s"), copy=True)

    def trusted(self) -> np.ndarray:
        """Markers (M,) bool the fit follows closely: weight 1 or more (all without weights)."""
        if self.marker_weights is None:
            return np.ones(len(self.marker_labels), dtype=bool)
        return np.asarray(self.marker_weights) >= 1.0

    def frame_rms(self) -> np.ndarray:
        """Root-mean-square marker residual of each frame, shape (F,), metres (NaN if none)."""
        with np.errstate(invalid="ignore"):
            return np.sqrt(np.nanmean(self.residuals ** 2, axis=1))

    def marker_rms(self) -> np.ndarray:
        """Root-mean-square residual of each marker over the capture, shape (M,), metres."""
        with np.errstate(invalid="ignore"):
            return np.sqrt(np.nanmean(self.residuals ** 2, axis=0))

    def limit_shares(self, frames: np.ndarray | slice = slice(None)) -> dict[str, float]:
        """Share of the fitted ``frames`` (default all; :attr:`failed` ones left out, their
        angles copied from the fitted frames beside them) each DOF spends at one of its joint
        limits (within :data:`AT_LIMIT` of it), for the DOFs that reach one: {name: fraction}."""
        lower, upper = self.skeleton.bounds()
        chosen = np.zeros(self.n_frames, dtype=bool)
        chosen[frames] = True
        q = self.q[chosen & ~self.failed]
        at = ((q <= lower + AT_LIMIT) | (q >= upper - AT_LIMIT)).mean(axis=0) if len(q) else \
            np.zeros(len(DOF_NAMES))
        return {name: float(share) for name, share in zip(DOF_NAMES, at) if share > 0}

    def limit_warnings(self) -> list[str]:
        """One sentence per DOF at a joint limit in more than :data:`LIMIT_WARNING_SHARE` of
        the frames: a DOF the fit pushes against its range is not measured there."""
        return [f"{name} sits at a joint limit in {share:.0%} of the frames: its angles there "
                "are not measured; check the markers of that joint"
                for name, share in self.limit_shares().items() if share > LIMIT_WARNING_SHARE]

    def repaired_track(self, label: str, read) -> np.ndarray:
        """The trajectory (F, 3) the fit used for marker ``label``, given ``read(label)``, the
        capture's trajectory of a label: a swap reads the partner's in its frames, a drop
        leaves NaN."""
        out = np.array(read(label), dtype=np.float64, copy=True)
        for r in self.repairs:
            if label in r.labels:
                rows = slice(r.start, r.stop)
                out[rows] = np.nan if r.kind == "drop" else \
                    read(r.labels[1 - r.labels.index(label)])[rows]
        return out

    def repair_warnings(self) -> list[str]:
        """One sentence per :attr:`repairs` entry."""
        return [r.sentence(self.rate) for r in self.repairs]

    def segment_transforms(self) -> np.ndarray:
        """Segment-to-world transforms, shape (F, S, 4, 4)."""
        return self.skeleton.forward(self.q)

    def model_markers(self) -> np.ndarray:
        """Model marker positions for the fitted angles, shape (F, M, 3), metres."""
        if self.marker_segments is None or self.marker_offsets is None:
            raise MocapError("this Motion carries no marker model", path=self.source)
        return self.skeleton.points(self.q, self.marker_segments, self.marker_offsets)
