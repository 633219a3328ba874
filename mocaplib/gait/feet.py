"""The feet of a capture: each foot's heel and toe trajectories from the protocol's foot
landmarks (:func:`feet_of`), and how detected events compare with the events a lab recorded
(:func:`event_differences`).

Trajectories are ``(F, 3)`` arrays in metres, NaN where unseen.
"""

from __future__ import annotations

import numpy as np

from ..errors import EventError
from ..markersets.protocols import role_landmarks

#: Labels of lab-recorded events (C3D EVENT group: Vicon, Qualisys, our synthetic captures) and
#: the event kind each marks; the side is the context's first letter (Left/Right), else the
#: label's (LTO).
LAB_EVENT_KINDS = {"Foot Off": "toe_off", "Foot Strike": "heel_strike",
                   "LTO": "toe_off", "RTO": "toe_off", "LHS": "heel_strike", "RHS": "heel_strike"}


def event_differences(detected, reference, /, *, kind: str, start_time: float = 0.0,
                      max_s: float = 0.1) -> np.ndarray:
    """Detected minus reference time (s) of each reference event of ``kind``, shape (R,).

    ``detected`` are :class:`GaitEvent` (seconds from the first frame), ``reference`` the
    trial's lab events (:class:`mocaplib.trial.Event`, on the lab clock whose first frame is at
    ``start_time``). Each reference event is paired with the nearest detected event of the
    same side and kind (placed: :attr:`GaitEvent.placed`); NaN where there is none within
    ``max_s`` (e.g. at the capture's edges).
    """
    out = []
    for lab in reference:
        if LAB_EVENT_KINDS.get(lab.label) != kind:
            continue
        letter = next((text[:1].upper() for text in (lab.context, lab.label)
                       if text[:1].upper() in ("L", "R")), None)
        if letter is None:
            continue
        side = "left" if letter == "L" else "right"
        found = [e.time_s + start_time - lab.time_s for e in detected
                 if e.side == side and e.kind == kind and e.placed]
        nearest = min(found, key=abs, default=np.inf)
        out.append(nearest if abs(nearest) <= max_s else np.nan)
    return np.array(out, dtype=np.float64)


def foot_landmarks() -> dict[str, tuple[str, tuple[str, ...]]]:
    """Each foot's heel landmark and its toe landmarks by preference order, ``{"left":
    ("L_HEEL", ("L_TOE", ...)), "right": ...}``: the catalogue's ``heel`` and ``forefoot``
    roles (:func:`mocaplib.markersets.protocols.role_landmarks`)."""
    return {side: (role_landmarks("heel", side=side)[0],
                   role_landmarks("forefoot", side=side)) for side in ("left", "right")}


def feet_of(trial, match, /, *, motion=None
            ) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], dict[str, np.ndarray]]:
    """The feet of a trial's protocol-matched markers, and where they were measured.

    Returns ``{"left": (heel, toe), "right": ...}`` (F, 3) m and ``{"left": (F,) bool, ...}``,
    the frames where the capture measured both (pass it as :func:`detect_events`'s
    ``measured``). ``match`` is a :class:`mocaplib.markersets.matching.ProtocolMatch`; the toe is the
    first present of :func:`foot_landmarks`. With a fitted ``motion``
    (:class:`mocaplib.Motion`), samples where a marker is missing are taken from the fitted
    skeleton's position of that marker, except in frames the fit flagged as failed and before
    the marker's first measured sample or after its last (they stay missing: nothing measured
    supports an event there), and the labelling errors the fit undid (``motion.repairs``: a
    LHEE/RHEE swap, a marker left out) are undone here too, as the fit read them. Raises
    :class:`EventError` naming
    the landmark the capture has no label for (and the labels the protocol gives for it), or
    the marker the fit left out in every frame.
    """
    present = match.present_landmarks
    modelled = motion.model_markers() if motion is not None else None

    def track(side, label):
        measured = match.marker(trial, label)
        if motion is not None:
            measured = motion.repaired_track(label, lambda other: match.marker(trial, other))
        points = measured
        if modelled is not None and label in motion.marker_labels:
            model_points = modelled[:, motion.marker_labels.index(label)]
            usable = (np.isnan(measured) & ~np.asarray(motion.failed, dtype=bool)[:, None]
                      & _between_samples(np.isfinite(measured).all(axis=1))[:, None])
            points = np.where(usable, model_points, measured)
        if np.isnan(points[:, 2]).all():        # the match takes only labels seen somewhere
            raise EventError(f"{side} foot marker {label} was left out by the fit in every "
                             "frame: it stays far from where the calibrated skeleton puts it",
                             path=trial.source,
                             hint="check its label and its placement: the fit's warnings name "
                                  "the markers it left out")
        return points, np.isfinite(measured).all(axis=1)

    feet, measured = {}, {}
    for side, (heel, toes) in foot_landmarks().items():
        toe = next((name for name in toes if name in present), None)
        if heel not in present:
            _no_foot_marker(trial, match, f"{side} heel", (heel,))
        if toe is None:
            _no_foot_marker(trial, match, f"{side} toe", toes)
        (heel_points, heel_seen), (toe_points, toe_seen) = (track(side, present[heel]),
                                                            track(side, present[toe]))
        feet[side] = (heel_points, toe_points)
        measured[side] = heel_seen & toe_seen
    return feet, measured


def _between_samples(seen: np.ndarray) -> np.ndarray:
    """The frames (F,) bool from the first ``True`` of ``seen`` (F,) bool to its last."""
    frames = np.flatnonzero(seen)
    inside = np.zeros(len(seen), dtype=bool)
    if len(frames):
        inside[frames[0]:frames[-1] + 1] = True
    return inside


def _no_foot_marker(trial, match, what: str, landmarks: tuple[str, ...]) -> None:
    """Raise the :class:`EventError` for a capture without a ``what`` marker (any of
    ``landmarks``), blaming the capture's labels or, when it has none, the protocol."""
    protocol = match.protocol
    labels = [key for m in protocol.markers if m.landmark.name in landmarks
              for key in (m.label, *m.aliases)]
    named = f"{what} ({'/'.join(landmarks)})"
    need = "gait events need a heel and a toe marker on each foot"
    if not labels:
        raise EventError(f"protocol {protocol.name!r} has no {named} marker", path=trial.source,
                         hint=f"{need}: pass --protocol with a protocol that has one, or add "
                              "one to this protocol")
    raise EventError(f"the capture has no {named} marker: none of the labels protocol "
                     f"{protocol.name!r} gives for it ({', '.join(labels)}) is in the file",
                     path=trial.source,
                     hint=f"{need}: rename the capture's {what} label to one of those, add it "
                          "to the protocol as an alias, or pass --protocol (`mocaplib inspect` "
                          "lists the capture's labels and their gaps: a label missing in every "
                          "frame counts as absent)")
