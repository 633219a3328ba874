"""One subject's calibrated model: the skeleton, the markers' offsets on its segments and what
the calibration found (:class:`SubjectModel`, made by :func:`mocaplib.model.calibration.calibrate`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..markersets.protocols import Protocol
from ..skeleton import DOF_NAMES, Skeleton


@dataclass
class SubjectModel:
    """One subject's calibrated model, what :func:`mocaplib.model.ik.fit` needs.

    Attributes
    ----------
    skeleton : Skeleton with this subject's segment lengths (metres).
    protocol : Protocol the labels come from.
    labels : list[str], length M. Protocol labels of the markers used, in model order.
    marker_segments : int ndarray, shape (M,). Segment index of each marker.
    marker_offsets : ndarray, shape (M, 3). Each marker in its segment's frame, metres.
    locked_dofs : list[str]. DOFs held at 0 because too few markers see them.
    left_out : list[str]. Segments with no marker on them or below them.
    rms : float. Marker RMS of the calibration fit, metres.
    history : list[float]. Marker RMS after each refinement round, metres.
    source : str or None. The calibration trial's file (the static one when given).
    swapped : list of (label, label). Pairs whose labels the calibration trial exchanges (in
        all or part of its frames, :func:`mocaplib.model.repairs.find_repairs`); calibration read them
        exchanged back. A fit finds the motion's own (``Motion.repairs``).
    centre_methods : dict[str, str]. How each joint centre was found (``"knee_l"``: ``"chord,
        knee width from the measurements"``...), see :func:`joint_centres`.
    unobservable : dict[str, float]. DOFs the markers cannot see well enough, held at 0 (also
        in ``locked_dofs``), with the standard deviation (radians) one frame's markers would
        leave them at (:func:`unobservable_dofs`).
    static_window_s : (start, end) or None. Seconds from the static's first frame of the
        stretch of it used (:func:`standing_part`); None without a static.
    knee_axis_turns : dict[str, float]. Per side ("l", "r") whose knee has a functional axis,
        its turn about the femur's long axis from the anatomical one, radians, in the sense
        of ``hip_rotation`` (:func:`functional_knee_turns`).
    """

    skeleton: Skeleton
    protocol: Protocol
    labels: list[str]
    marker_segments: np.ndarray
    marker_offsets: np.ndarray
    locked_dofs: list[str] = field(default_factory=list)
    left_out: list[str] = field(default_factory=list)
    rms: float = float("nan")
    history: list[float] = field(default_factory=list)
    source: str | None = None
    swapped: list[tuple[str, str]] = field(default_factory=list)
    centre_methods: dict[str, str] = field(default_factory=dict)
    unobservable: dict[str, float] = field(default_factory=dict)
    static_window_s: tuple[float, float] | None = None
    knee_axis_turns: dict[str, float] = field(default_factory=dict)

    @property
    def marker_weights(self) -> np.ndarray:
        """Each marker's weight in the fit (M,), from the protocol
        (:attr:`mocaplib.markersets.protocols.ProtocolMarker.weight`)."""
        return np.array([self.protocol.marker(label).weight for label in self.labels])

    @property
    def free(self) -> np.ndarray:
        """DOFs the fit may move, bool (D,)."""
        return np.array([name not in self.locked_dofs for name in DOF_NAMES])

    @property
    def swap_warnings(self) -> list[str]:
        """One sentence per pair in :attr:`swapped`, for the user."""
        return [f"calibration trial {self.source or ''}: labels {a} and {b} look exchanged "
                "(each marker lies where the other belongs); calibration exchanged them back: "
                "check the labelling" for a, b in self.swapped]
