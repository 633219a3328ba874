"""Checks that make a draft protocol's guesses agree with each other and with the markers'
measured places (used by :func:`mocaplib.markersets.draft.draft_protocol`).

Every guess (a landmark, or the segment of a tracking marker) is checked, in this order:

Sides
    A guess's side (``L_``/``R_`` landmark, ``_l``/``_r`` segment) follows the label's side
    when the label has one, else the side the marker sits on (its lateral coordinate in the
    body frame beyond :data:`SIDE_MARGIN`): a guess on the other side is mirrored. A label
    whose side disagrees with where the marker sits is kept by its label and flagged (a swapped
    label, which ``mocaplib inspect`` reports too).
Mirrored pairs
    Two labels of one stem and opposite sides (``LKNE``/``RKNE``, ``l bar 1``/``r bar 1``) go
    to mirrored landmarks or segments, the pair's better-placed guess deciding, or to none.
Distances
    A marker is never mapped to a landmark whose catalogue place lies farther than
    :data:`FAR_LIMIT` from the marker's measured place (nor a tracking marker to a segment none
    of whose landmarks lies that close). The lateral distance is taken between the sides'
    magnitudes (the side is the first check's business), and arm landmarks are compared by
    their reach from the same side's acromion, which no arm pose changes.

Places are in the body frame of the catalogue's 1.75 m subject (m; forward, left, up from
mid-hips on the floor), as :func:`catalogue_places` gives the landmarks'.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..skeleton import SEGMENT_NAMES, Skeleton
from ..trial import normalise_label
from .protocols import REFERENCE_HEIGHT, load_landmarks, protocol_folders

#: A marker farther than this (m) from the midline, in the body frame, sits on that side
#: (the real files' heel and toe markers of narrow gaits sit up to 4 cm from it).
SIDE_MARGIN = 0.05
#: The farthest (m, weighted as the draft's cost) a marker may sit from its landmark's
#: catalogue place: the real files' correct guesses lie within 0.22 m (a runner's flexed legs),
#: a marker on another segment 0.4 m and more away.
FAR_LIMIT = 0.35
#: Segments whose landmarks are compared by their reach from the shoulder: an arm raised in a
#: static trial puts a wrist 0.85 m from its standing place.
ARM_SEGMENTS = ("humerus", "forearm", "hand")
#: Confidence of a guess its checks changed (a mirrored side or pair).
CHECKED_CONFIDENCE = 0.4


def _standing_catalogue() -> tuple[tuple[str, ...], np.ndarray, tuple[str, ...]]:
    """:func:`catalogue_places` of the catalogue the protocol folders give now."""
    return _standing_places(tuple(os.fspath(f) for f in protocol_folders()))


@lru_cache(maxsize=8)
def _standing_places(folders: tuple[str, ...]) -> tuple[tuple[str, ...], np.ndarray,
                                                       tuple[str, ...]]:
    catalogue = load_landmarks()
    skeleton = Skeleton.from_height(REFERENCE_HEIGHT)
    origins = skeleton.forward(np.zeros((1, len(skeleton.bounds()[0]))))[0, :, :3, 3]
    floor = origins[SEGMENT_NAMES.index("foot_l"), 2] + min(
        lm.position[2] for lm in catalogue.values() if lm.segment.startswith("foot")) - 0.01
    names, places, segments = [], [], []
    for name, lm in catalogue.items():
        place = origins[SEGMENT_NAMES.index(lm.segment)] + np.asarray(lm.position)
        place[:2] -= origins[0, :2]
        place[2] -= floor
        names.append(name)
        places.append(place)
        segments.append(lm.segment)
    return tuple(names), np.array(places), tuple(segments)


def catalogue_places() -> tuple[list[str], np.ndarray, list[str]]:
    """Every catalogue landmark, its place (L, 3) m on the standing 1.75 m skeleton in the
    body frame (origin mid-hips at floor level, X forward, Y left, Z up) and its segment."""
    names, places, segments = _standing_catalogue()
    return list(names), places.copy(), list(segments)


def guess_side(entry) -> str | None:
    """``"L"``, ``"R"`` or None: the side of an entry's landmark or tracking segment."""
    if entry.landmark:
        return entry.landmark[0] if entry.landmark[:2] in ("L_", "R_") else None
    if entry.segment and entry.segment[-2:] in ("_l", "_r"):
        return entry.segment[-1].upper()
    return None


def mirrored(landmark: str | None, segment: str | None, side: str
             ) -> tuple[str | None, str | None]:
    """The (landmark, segment) of a guess moved to ``side`` (``"L"``/``"R"``)."""
    if landmark:
        return f"{side}_{landmark[2:]}", None
    return None, f"{segment[:-2]}_{side.lower()}"


def placed_side(place: np.ndarray) -> str | None:
    """The side a marker at ``place`` (3,) sits on, or None near the midline or unseen."""
    y = place[1]
    return None if not np.isfinite(y) or abs(y) <= SIDE_MARGIN else ("L" if y > 0 else "R")


def distance_to(place: np.ndarray, landmark: str, weights: np.ndarray) -> float:
    """How far (m, ``weights`` per axis) a marker at ``place`` (3,) sits from ``landmark``'s
    catalogue place, the sides compared by magnitude; an arm landmark by its reach from the
    same side's acromion (the difference of the two distances). NaN where unseen."""
    names, places, segments = _standing_catalogue()
    mine = place * [1, np.sign(place[1]) or 1, 1]           # both sides taken as the left
    target = places[names.index(landmark)] * [1, -1 if landmark.startswith("R_") else 1, 1]
    if segments[names.index(landmark)].rsplit("_", 1)[0] in ARM_SEGMENTS:
        shoulder = places[names.index("L_ACROMION")]
        return float(abs(np.linalg.norm(mine - shoulder) - np.linalg.norm(target - shoulder)))
    return float(np.linalg.norm((mine - target) * weights))


def segment_distance(place: np.ndarray, segment: str, weights: np.ndarray) -> float:
    """The distance (m, :func:`distance_to`) from ``place`` to the nearest catalogue landmark
    of ``segment``; 0 for a segment without landmarks, NaN where unseen."""
    names, _, segments = _standing_catalogue()
    on = [n for n, s in zip(names, segments) if s == segment]
    return min((distance_to(place, n, weights) for n in on), default=0.0)


def check_draft(entries: list, stems: list[tuple[str | None, str]], weights: np.ndarray
                ) -> None:
    """Apply the module's three checks to ``entries`` (the draft's
    :class:`~mocaplib.markersets.draft.DraftEntry` list, in place), ``stems`` holding each
    label's side and stem (:func:`mocaplib.markersets.draft.label_stem`), ``weights`` the
    cost's per-axis weights."""
    for entry, (side, _) in zip(entries, stems):
        _check_side(entry, side)
    _check_pairs(entries, stems, weights)
    for entry in entries:
        _check_distance(entry, weights)


def _check_side(entry, label_side: str | None) -> None:
    where = placed_side(entry.place)
    if label_side and where and where != label_side:
        entry.evidence.append(
            f"the label says {label_side} but the marker sits "
            f"{abs(entry.place[1]) * 100:.0f} cm to the {'left' if where == 'L' else 'right'}: "
            "a swapped label? kept by its label")
        entry.confidence = min(entry.confidence, CHECKED_CONFIDENCE)
    side = guess_side(entry)
    wanted = label_side or where
    if side and wanted and side != wanted:
        old = entry.landmark or entry.segment
        entry.landmark, entry.segment = mirrored(entry.landmark, entry.segment, wanted)
        entry.evidence.append(f"not {old}: the {'label' if label_side else 'marker'}'s side "
                              f"is {wanted}")
        entry.confidence = min(entry.confidence, CHECKED_CONFIDENCE)


def _check_pairs(entries: list, stems, weights: np.ndarray) -> None:
    index = {(side, stem): k for k, (side, stem) in enumerate(stems) if side}
    taken = {e.landmark for e in entries if e.landmark}
    for (side, stem), k in index.items():
        other = index.get(("R", stem))
        if side != "L" or other is None:
            continue
        left, right = entries[k], entries[other]
        if _kind(left) == _kind(right):
            continue                                       # mirrored already
        best = max((left, right), key=lambda e: e.confidence if guess_side(e) else -1)
        if not guess_side(best):
            continue
        for e, s in ((left, "L"), (right, "R")):
            if e is best:
                continue
            landmark, segment = mirrored(best.landmark, best.segment, s)
            old = e.landmark or e.segment or "nothing"
            free = landmark is None or landmark not in taken or landmark == e.landmark
            if free:
                taken.discard(e.landmark)
                taken.add(landmark)
                e.landmark, e.segment = landmark, segment
                e.evidence.append(f"not {old}: mirrors {best.label}")
            else:
                taken.discard(e.landmark)
                e.landmark = e.segment = None
                taken.discard(best.landmark)
                best.landmark = best.segment = None
                best.evidence.append(f"dropped: its mirror {e.label} cannot take "
                                     f"{landmark}, which another label has")
                e.evidence.append(f"dropped: {landmark} is another label's")
            e.confidence = min(e.confidence, CHECKED_CONFIDENCE)


def _kind(entry) -> tuple[str | None, str | None]:
    """An entry's guess with its side taken off: pairs agree when their kinds are equal."""
    if entry.landmark:
        return (entry.landmark[2:] if entry.landmark[:2] in ("L_", "R_") else entry.landmark,
                None)
    if entry.segment:
        return None, entry.segment.removesuffix("_l").removesuffix("_r")
    return None, None


def _check_distance(entry, weights: np.ndarray) -> None:
    if entry.landmark:
        far = distance_to(entry.place, entry.landmark, weights)
    elif entry.segment:
        far = segment_distance(entry.place, entry.segment, weights)
    else:
        return
    if far > FAR_LIMIT:
        entry.evidence.append(f"not {entry.landmark or entry.segment}: the marker sits "
                              f"{far * 100:.0f} cm from it (more than {FAR_LIMIT * 100:.0f})")
        entry.landmark = entry.segment = None
        entry.confidence = 0.0


@dataclass(frozen=True)
class Agreement:
    """How a draft's guesses compare with a protocol's, over the labels the protocol maps in a
    trial: the same landmark, another guess on the same segment, a guess on another segment
    (``wrong``, with the labels), no guess; ``other_side`` counts the wrong guesses on the
    protocol's other side."""

    landmark: int
    segment: int
    wrong: int
    unassigned: int
    other_side: int
    wrong_labels: tuple[str, ...] = ()

    @property
    def total(self) -> int:
        return self.landmark + self.segment + self.wrong + self.unassigned


def draft_agreement(entries: list, trial, match) -> Agreement:
    """Compare draft ``entries`` with the protocol of ``match`` (a
    :class:`~mocaplib.markersets.matching.ProtocolMatch` of ``trial``): every trial label
    the protocol maps counts once."""
    catalogue = load_landmarks()
    by_label = {normalise_label(e.label): e for e in entries}
    counts = dict(landmark=0, segment=0, wrong=0, unassigned=0, other_side=0)
    wrong, seen = [], set()
    for marker, i in zip(match.protocol.markers, match.indices):
        if i < 0 or i in seen:
            continue
        seen.add(i)
        entry = by_label.get(trial.names[i])
        if entry is None or not (entry.landmark or entry.segment):
            counts["unassigned"] += 1
            continue
        segment = catalogue[entry.landmark].segment if entry.landmark else entry.segment
        if entry.landmark == marker.landmark.name:
            counts["landmark"] += 1
        elif segment == marker.landmark.segment:
            counts["segment"] += 1
        else:
            counts["wrong"] += 1
            wrong.append(f"{entry.label}: {entry.landmark or segment}, not "
                         f"{marker.landmark.name} on {marker.landmark.segment}")
            sides = {s[-1] for s in (segment, marker.landmark.segment) if s[-2:] in ("_l", "_r")}
            counts["other_side"] += len(sides) == 2
    return Agreement(**counts, wrong_labels=tuple(wrong))
