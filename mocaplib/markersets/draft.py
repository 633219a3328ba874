"""A draft protocol for a marker set mocaplib does not know (``mocaplib protocol draft``).

Each label of a capture (and of its static trial, when given) is matched to a landmark of the
catalogue (``landmarks.toml``) by two kinds of evidence, then the draft is written as a
protocol TOML file in which every guess carries a comment with its evidence and a confidence:

By name
    The label's stem (:func:`label_stem`: subject prefix, spaces, side and trailing digits
    taken off) is looked up in ``label_names.toml``, the names labs give each landmark
    (``SHO``, ``SAJ`` and ``A`` for the acromion...). A side is read from the label (a leading
    or trailing L/R, LEFT/RIGHT).
By place
    Where the marker sits on the body: its median position over the frames in a body frame
    (:func:`body_positions`: origin the median of the markers at pelvis height, forward the
    pelvis's front (ASIS and PSIS found by name) or else the direction of travel, up +Z, the
    floor the lowest markers), scaled to the catalogue's 1.75 m subject; compared with each
    landmark's place on the standing catalogue skeleton.
Which markers move together
    Markers whose distances stay constant over the motion ride on one rigid body (the rigid
    clusters of :func:`mocaplib.markersets.draft_motion.rigid_clusters`): a cluster of three or
    more that no landmark fits is a marker cluster, its markers tracking markers on the segment
    nearest to it. The motion also finds the head: a compact rigid cluster above every other
    one, whose markers are then kept off the trunk's landmarks.

The labels and landmarks are paired by one assignment (Hungarian, ``scipy``) of least total
cost: the distance between the marker and the landmark, less :data:`NAME_BONUS` when the name
points to that landmark, plus :data:`SIDE_PENALTY` when the label's side is the other one; a
label farther than :data:`NONE_COST` from every landmark stays unmatched (a tracking marker if
it belongs to a cluster, else listed as unknown). A label whose name points to a landmark that
another label within :data:`SECOND_MARKER_GAP` of it takes is a second label of that marker
(two marker sets' names exported at once): a tracking marker on the landmark's segment, before
the checks of :mod:`~mocaplib.markersets.draft_checks` and after them for a label they left
without a guess. Required landmarks are marked as the pipeline
needs them: both acromions, both ASIS, a back pelvis marker (PSIS or sacrum, ``[any_of]``),
each heel and a toe or forefoot marker (``[any_of]``). A marker seen on the static only is
``static_only``.
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ..errors import ProtocolError
from ..numeric import nanmedian
from ..statics import STANDING_EXTENT
from ..trial import Trial, normalise_label, require_markers, written_side
from .draft_checks import catalogue_places, check_draft
from .draft_motion import head_cluster, motion_cost, rigid_clusters
from .matching import computed_points, is_model_output, numbered_candidates
from .protocols import (REFERENCE_HEIGHT, load_landmarks, protocol_folders, read_protocol_toml,
                        role_landmarks)
from .sides import forward_direction

#: Cost (m) a name that points to a landmark takes off the distance to it...
NAME_BONUS = 0.20
#: ...and adds to the distance to the landmarks it does not point to.
NAME_MISMATCH = 0.05
#: Cost (m) added when the label says the other side than the landmark's.
SIDE_PENALTY = 0.30
#: A label farther than this (m, after the name's bonus) from every landmark stays unmatched.
NONE_COST = 0.12
#: A name counts the distance to its landmarks up to this (m): a static with the arms raised
#: leaves the wrists far from the catalogue's standing body, yet their names hold...
NAMED_CAP = 0.30
#: ...and a named label stays unmatched only beyond NONE_COST + NAME_BONUS + this (m).
NAMED_SLACK = 0.10
#: A label whose name points to a landmark another label takes, placed within this (m) of that
#: label, is a second label of the marker or a second marker on the landmark (two marker sets'
#: names exported at once, e.g. Plug-in Gait's LANK beside a CAST set's LLM on one marker): a
#: tracking marker on the landmark's segment, of this confidence. Two markers of one set are
#: farther apart (BTS's knee markers on the epicondyle and the fibula's head: 3 cm and more).
SECOND_MARKER_GAP, SECOND_MARKER_CONFIDENCE = 0.02, 0.6
#: A rigid group of at least this many unmatched markers is a cluster.
CLUSTER_SIZE = 3
#: Weights of the forward, lateral and vertical distances in the cost: the side is the surest
#: cue, the forward place the least sure (limbs swing).
AXIS_WEIGHTS = np.array([0.7, 1.2, 1.0])
#: A guess under this confidence (0-1) is called low: written so in the draft and warned of.
LOW_CONFIDENCE = 0.45
#: Landmarks the pipeline needs, required when found: both acromions, both ASIS, each heel.
REQUIRED = ("ACROMION", "ASIS", "HEEL")
#: ``[any_of]`` groups written when one of their landmarks is found: group -> (catalogue role,
#: side) (:func:`mocaplib.markersets.protocols.role_landmarks`).
ANY_OF = {"pelvis_back": ("pelvis_back", None), "left_forefoot": ("forefoot", "left"),
          "right_forefoot": ("forefoot", "right")}


@dataclass
class DraftEntry:
    """One label of the draft: its landmark (None for a tracking marker or an unknown label),
    the segment a tracking marker rides on, ``static_only``, ``required``, the confidence
    (0-1), the evidence in words, whether the label's name points to its landmark, where the
    marker sits (``place``: (3,) m in the body frame of the 1.75 m catalogue body, forward,
    left, up; NaN unseen) and how far (m, weighted as :data:`AXIS_WEIGHTS`) from its
    landmark's catalogue place."""

    label: str
    landmark: str | None
    segment: str | None = None
    static_only: bool = False
    required: bool = False
    confidence: float = 0.0
    evidence: list[str] = field(default_factory=list)
    by_name: bool = False
    place: np.ndarray | None = None
    distance: float | None = None


@dataclass
class Draft:
    """A drafted protocol: its name, the source files, one :class:`DraftEntry` per label and
    how the body frame was found (``frame``)."""

    name: str
    sources: list[str]
    entries: list[DraftEntry]
    frame: str = ""

    def warnings(self) -> list[str]:
        """One sentence per guess of low confidence (under :data:`LOW_CONFIDENCE`), with its
        evidence: what to check before the draft is used."""
        return [f"{e.label}: low confidence ({e.confidence:.0%}) in "
                f"{e.landmark or e.segment}: {'; '.join(e.evidence)}"
                for e in self.entries if (e.landmark or e.segment)
                and e.confidence < LOW_CONFIDENCE]

    @property
    def landmarks(self) -> dict[str, str]:
        """``{normalised label: landmark name}`` of the entries matched to a landmark."""
        return {normalise_label(e.label): e.landmark for e in self.entries if e.landmark}

    def to_toml(self) -> str:
        """The draft as a protocol file, each entry commented with its evidence."""
        lines = [f"# Draft protocol written by `mocaplib protocol draft` from "
                 f"{', '.join(self.sources)}.",
                 "# Every entry is a guess: check each against your lab's marker placement, then "
                 "run `mocaplib inspect --protocol THIS_FILE CAPTURE.c3d`.",
                 f"# Body frame: {self.frame}.",
                 f"name = {_toml_string(self.name)}",
                 "# Delete the next line once you have checked every entry: builds then report "
                 "the protocol as yours.",
                 "drafted = true",
                 "description = " + _toml_string(
                     f"Drafted from {os.path.basename(self.sources[0])}"),
                 "",
                 "[markers]"]
        unknown = []
        for e in self.entries:
            key = _toml_key(e.label)
            if e.landmark is None and e.segment is None:
                unknown.append(e)
                continue
            spec = f'landmark = "{e.landmark}"' if e.landmark else _segment_spec(e.segment)
            flags = (", required = true" if e.required else "") + (
                ", static_only = true" if e.static_only else "")
            lines.append(f"# {_confidence_word(e.confidence)} ({e.confidence:.0%}): "
                         f"{'; '.join(e.evidence)}")
            lines.append(f"{key} = {{ {spec}{flags} }}")
        groups = {g: [e.label for e in self.entries
                      if e.landmark in role_landmarks(role, side=side)]
                  for g, (role, side) in ANY_OF.items()}
        groups = {g: labels for g, labels in groups.items() if labels}
        if groups:
            lines += ["", "[any_of]"]
            lines += [f"{g} = [{', '.join(_toml_string(x) for x in labels)}]"
                      for g, labels in groups.items()]
        if unknown:
            lines += ["", "# Labels matched to no landmark and in no cluster (add them by hand "
                          "if they are markers):"]
            lines += [f"#   {e.label}: {'; '.join(e.evidence)}" for e in unknown]
        return "\n".join(lines) + "\n"


def _segment_spec(segment: str) -> str:
    """A tracking marker's TOML entry for a skeleton segment (``femur_l``: bare name, side)."""
    bare, _, side = segment.rpartition("_")
    if side in ("l", "r"):
        return f'segment = "{bare}", side = "{"left" if side == "l" else "right"}"'
    return f'segment = "{segment}"'


def _confidence_word(value: float) -> str:
    return "high" if value >= 0.75 else "medium" if value >= LOW_CONFIDENCE else "low"


def _toml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _toml_key(label: str) -> str:
    return label if re.fullmatch(r"[A-Za-z0-9_-]+", label) else _toml_string(label)


# ----------------------------------------------------------------------------- names
@lru_cache(maxsize=None)
def _name_table(folders: tuple[str, ...]) -> dict[str, tuple[str, ...]]:
    """Stem -> unsided landmark keys, from the ``label_names.toml`` of ``folders``."""
    table: dict[str, list[str]] = {}
    for folder in folders:
        path = os.path.join(folder, "label_names.toml")
        if not os.path.isfile(path):
            continue
        for key, stems in read_protocol_toml(path).items():
            if not isinstance(stems, list) or not all(isinstance(x, str) for x in stems):
                raise ProtocolError(f"{key!r} must list name stems", path=path)
            for stem in stems:
                table.setdefault(normalise_label(stem), []).append(key)
    return {stem: tuple(dict.fromkeys(keys)) for stem, keys in table.items()}


def names() -> dict[str, tuple[str, ...]]:
    """The name stems labs use, each with the landmarks (unsided keys) it points to."""
    return _name_table(tuple(os.fspath(f) for f in protocol_folders()))


def label_stem(label: str) -> tuple[str | None, str]:
    """The side (``"L"``, ``"R"`` or None) and the stem of a label, as the module describes:
    a whole label that names a central landmark keeps no side (``"L5"``, ``"SACR"``); a side
    written as a word of its own (``"l bar 1"``, ``"L_SAJ"``, ``"ASIS_R"``, ``"Left Knee"``)
    is taken first, then a leading L or R, then a trailing one (``SCR1``)."""
    text = normalise_label(label)
    table = names()
    catalogue = load_landmarks()
    if any(key in catalogue for key in table.get(text, ())):      # a central landmark
        return None, text
    side, stem = written_side(label)
    if side:
        return side, stem

    def known(stem):
        return stem in table or stem.rstrip("0123456789") in table

    bare = text.rstrip("0123456789")
    leading = (text[0], text[1:]) if len(text) > 1 and text[0] in "LR" else None
    trailing = (bare[-1], bare[:-1] + text[len(bare):]) if len(bare) > 1 and \
        bare[-1] in "LR" else None
    if trailing and known(trailing[1]) and not (leading and known(leading[1])):
        return trailing
    return leading or trailing or (None, text)


def name_landmarks(label: str) -> tuple[str | None, tuple[str, ...]]:
    """The label's side and the unsided landmark keys its name points to (none when
    unknown): its stem, then the stem without trailing digits."""
    side, stem = label_stem(label)
    table = names()
    keys = table.get(stem) or table.get(stem.rstrip("0123456789")) or ()
    return side, keys


# ----------------------------------------------------------------------------- places
def body_positions(X: np.ndarray, cues: dict[str, np.ndarray]) -> tuple[np.ndarray, str]:
    """Each marker's median position (M, 3) in the body frame over the frames of X (F, M, 3),
    metres, and how the forward direction was found. The origin is the median of the markers
    at pelvis height (45-72 % of the highest marker's height), on the floor (the lowest 1 % of
    the samples). ``cues`` maps landmark names found by name to their trajectories (F, 3): the
    pelvis's front (:func:`mocaplib.markersets.sides.forward_direction`) sets forward where it can;
    else the direction of travel."""
    n = len(X)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        floor = np.nanpercentile(X[..., 2], 1)
        heights = nanmedian(X[..., 2], axis=0) - floor
        band = (heights > 0.45 * np.nanmax(heights)) & (heights < 0.72 * np.nanmax(heights))
        origin = nanmedian(X[:, band if band.any() else slice(None), :2], axis=1)   # (F, 2)
    forward = forward_direction(cues, n)
    how = "the pelvis's front (ASIS and PSIS or sacrum, by name)"
    if np.isnan(forward[:, 0]).mean() > 0.5:
        travel = np.gradient(origin, axis=0) if n > 2 else np.zeros_like(origin)
        mean = np.nanmean(travel, axis=0)
        if np.isfinite(mean).all() and np.linalg.norm(mean) > 0:
            forward = np.broadcast_to(mean / np.linalg.norm(mean), (n, 2))
            how = "the direction of travel"
        else:
            forward = np.broadcast_to([1.0, 0.0], (n, 2))
            how = "the file's +X (no pelvis cue, no travel)"
    forward = np.where(np.isnan(forward), np.nanmean(forward, axis=0), forward)
    left = np.stack([-forward[:, 1], forward[:, 0]], axis=1)
    d = X[..., :2] - origin[:, None]
    local = np.stack([np.einsum("fmi,fi->fm", d, forward), np.einsum("fmi,fi->fm", d, left),
                      X[..., 2] - floor], axis=2)
    return nanmedian(local, axis=0), how


# ----------------------------------------------------------------------------- the draft
def draft_protocol(trial: Trial, /, *, static: Trial | None = None, name: str = "mylab",
                   use_names: bool = True) -> Draft:
    """Draft a protocol for ``trial``'s labels (and those of ``static``, a standing trial of
    the same session, whose positions are then used), as the module describes.
    ``use_names=False`` matches by place and rigid groups alone. A trial (or static) without
    markers is refused (:func:`~mocaplib.trial.require_markers`)."""
    for given in (trial, static) if static is not None else (trial,):
        require_markers(given)

    labels = marker_labels(trial)
    static_labels = []
    if static is not None:
        static_labels = [x for x in marker_labels(static)
                         if normalise_label(x) not in {normalise_label(y) for y in labels}]
    every = labels + static_labels
    if not every:
        raise ProtocolError("no marker is seen in 10 % of the frames: nothing to draft from",
                            path=trial.source, hint="draft from a capture whose markers were "
                                                    "tracked (`mocaplib inspect` shows the gaps)")
    told = [name_landmarks(x) if use_names else (label_stem(x)[0], ()) for x in every]
    raw, how = _places(trial, every, told)
    if static is not None:                      # the static shows the standing body
        standing, how = _places(static, every, told)
        raw = np.where(np.isfinite(standing), standing, raw)
    lm_names, lm_places, lm_segments = catalogue_places()
    catalogue = load_landmarks()
    named = np.array([[_names_it(side, keys, lm) for lm in lm_names] for side, keys in told],
                     dtype=bool).reshape(len(every), len(lm_names))
    penalty = np.array([[SIDE_PENALTY * _other_side(side, lm) for lm in lm_names]
                        for side, _ in told]).reshape(len(every), len(lm_names))
    has_name = np.array([bool(keys) for _, keys in told])
    none = np.where(has_name, NONE_COST + NAME_BONUS + NAMED_SLACK, NONE_COST)
    mismatch = NAME_MISMATCH * has_name[:, None]
    heads = any(k in ("FRONT_HEAD", "BACK_HEAD") for _, keys in told for k in keys)
    # the top marker is the head's when a head marker is named or the motion finds the head
    # (else C7's or the shoulders'): without either both are tried, the least cost is kept
    moving = _motion_markers(trial, every)
    clusters, weights = rigid_clusters(moving) if _moves(moving) else ([], None)
    head = head_cluster(moving, clusters)
    tops = (0.95,) if heads or head is not None else (0.83,) if use_names else (0.95, 0.83)
    extra = 0.0
    if head is not None:
        segments = [None] * len(clusters)
        segments[head] = "head"
        extra = motion_cost(weights, clusters, segments, lm_segments)
    trials = [_assign(raw, np.nanmax(raw[:, 2]) / top, lm_places, named, mismatch,
                      penalty + extra, none) for top in tops]
    chosen, place, delta, used, _ = min(trials, key=lambda t: t[-1])
    n_landmarks = len(lm_names)
    # a label given no landmark its name points to, beside the label that takes one
    seconds = _second_markers([k for k, j in chosen.items()
                               if not (j < n_landmarks and named[k, j])],
                              {j: k for k, j in chosen.items() if j < n_landmarks}, named, place)
    in_group = {k: g for g in clusters for k in g}
    entries = []
    for k, label in enumerate(every):
        j = chosen.get(k, len(lm_names))
        e = DraftEntry(label, None, static_only=label in static_labels, place=place[k])
        side, keys = told[k]
        if use_names:
            e.evidence.append(f"name {label_stem(label)[1]!r}"
                              + (f" points to {'/'.join(keys)}" if keys else " is not a known "
                                 "landmark name") + (f", side {side}" if side else ""))
        e.evidence.append(_where(place[k]))
        if j < len(lm_names):
            lm = lm_names[j]
            distance = float(np.linalg.norm(delta[k, j]))
            e.landmark, e.distance = lm, distance
            e.evidence.append(f"{distance * 100:.0f} cm from where {lm} sits on the standing "
                              f"catalogue body ({catalogue[lm].description})")
            e.by_name = bool(named[k, j])
            closeness = float(np.clip(1.0 - distance / 0.15, 0.05, 1.0))
            e.confidence = 0.6 + 0.4 * closeness if named[k, j] else 0.7 * closeness
        if k in seconds:
            first, j = seconds[k]
            _make_second(e, every[first], lm_names[j], lm_segments[j],
                         float(np.linalg.norm(place[k] - place[first])))
        group = in_group.get(k)
        if group is not None:
            mates = [every[i] for i in group if i != k]
            e.evidence.append(f"moves rigidly with {', '.join(mates[:4])}"
                              + (" ..." if len(mates) > 4 else ""))
        entries.append(e)
    _clusters(entries, clusters, told, place, lm_places, lm_segments)
    check_draft(entries, [label_stem(x) for x in every], AXIS_WEIGHTS)
    # a label the checks left without a guess (its mirror took another guess) and its landmark
    # to a label beside it
    column = {name: j for j, name in enumerate(lm_names)}
    for k, (first, j) in _second_markers(
            [k for k, e in enumerate(entries) if not (e.landmark or e.segment)],
            {column[e.landmark]: k for k, e in enumerate(entries) if e.landmark},
            named, place).items():
        _make_second(entries[k], every[first], lm_names[j], lm_segments[j],
                     float(np.linalg.norm(place[k] - place[first])))
    for e in entries:
        bare = e.landmark[2:] if e.landmark and e.landmark[:2] in ("L_", "R_") else e.landmark
        e.required = bool(bare in REQUIRED and not e.static_only)
    sources = [trial.source or "capture"] + ([static.source or "static"] if static else [])
    return Draft(name, sources, entries, f"forward from {how}; the subject about "
                                         f"{used:.2f} m tall")


def _assign(raw: np.ndarray, height: float, lm_places: np.ndarray, named: np.ndarray,
            mismatch: np.ndarray, penalty: np.ndarray, none: np.ndarray):
    """Pair the markers at ``raw`` (M, 3) m with the landmarks at ``lm_places`` (L, 3) by one
    least-cost assignment (module docstring), starting from a subject ``height`` tall (m) and
    taking the height again from the markers matched, three times. Returns ``{marker:
    column}`` (a column past the landmarks: unmatched), the places (M, 3) scaled to the 1.75 m
    body, the weighted differences (M, L, 3), the height used and the total cost."""
    from scipy.optimize import linear_sum_assignment

    n_landmarks = len(lm_places)
    for _ in range(3):                          # the height from the markers matched
        used = height
        place = raw * (REFERENCE_HEIGHT / height)
        delta = (place[:, None] - lm_places[None]) * AXIS_WEIGHTS
        distance = np.where(np.isfinite(delta).all(axis=2), np.linalg.norm(delta, axis=2), 1.0)
        cost = np.where(named, np.minimum(distance, NAMED_CAP) - NAME_BONUS,
                        distance + mismatch) + penalty
        padded = np.hstack([cost, np.where(np.eye(len(raw), dtype=bool), none[:, None],
                                           np.inf)])
        rows, cols = linear_sum_assignment(padded)
        chosen = dict(zip(rows, cols))
        pairs = [(k, j) for k, j in chosen.items() if j < n_landmarks
                 and lm_places[j, 2] > 0.3 and np.isfinite(raw[k, 2])]
        if len(pairs) < 3:
            break
        height = REFERENCE_HEIGHT * float(np.median([raw[k, 2] / lm_places[j, 2]
                                                     for k, j in pairs]))
    return chosen, place, delta, used, float(padded[rows, cols].sum())


def _second_markers(candidates, holders: dict[int, int], named: np.ndarray, place: np.ndarray
                    ) -> dict[int, tuple[int, int]]:
    """Of the labels ``candidates``, those whose name points to a landmark (``named`` (M, L)
    bool) that another label placed within :data:`SECOND_MARKER_GAP` of them (``place``
    (M, 3) m) holds (``holders``: landmark column -> label): ``{label: (that label, the
    column)}``."""
    out = {}
    for k in candidates:
        for column in np.flatnonzero(named[k]):
            first = holders.get(int(column))
            if first is not None and first != k and \
                    np.linalg.norm(place[k] - place[first]) <= SECOND_MARKER_GAP:
                out[k] = (first, int(column))
                break
    return out


def _make_second(entry: DraftEntry, first: str, landmark: str, segment: str, gap: float
                 ) -> None:
    """Make ``entry`` a second marker on ``landmark``, which the label ``first`` takes ``gap``
    (m) from it: a tracking marker on ``segment``, by its name."""
    entry.evidence.append(f"a second marker on {landmark}, which {first} takes {gap * 100:.0f} "
                          f"cm from it: a tracking marker on {segment}")
    entry.landmark, entry.segment, entry.by_name, entry.distance = None, segment, True, None
    entry.confidence = SECOND_MARKER_CONFIDENCE


def _names_it(side: str | None, keys: tuple[str, ...], landmark: str) -> bool:
    """True when a label of ``side`` whose name points to ``keys`` names ``landmark``."""
    sided = landmark[:2] in ("L_", "R_")
    return (landmark[2:] if sided else landmark) in keys and (
        not sided or side is None or side == landmark[0])


def _other_side(side: str | None, landmark: str) -> bool:
    """True when the label's ``side`` is not ``landmark``'s."""
    return bool(side) and landmark[:2] in ("L_", "R_") and landmark[0] != side


def _clusters(entries: list[DraftEntry], groups: list[list[int]], told, place: np.ndarray,
              lm_places: np.ndarray, lm_segments: list[str]) -> None:
    """Find the clusters among the rigid groups of :data:`CLUSTER_SIZE` markers or more and
    make their markers tracking markers on the group's segment: the members of a numbered
    family (``LTH1``, ``LTH2``, ``LTH3``: one side and stem, several numbers, not a landmark's
    own name as T10 is), those matched to no
    landmark, and those whose place alone (not their name) matched them to a landmark far off
    or on another segment. The group's segment is the one its family's name, else its
    members' names, else its members' places point to, else that of the landmark nearest the
    group's centre; ``told`` holds each label's side and named landmark keys."""
    catalogue = load_landmarks()
    for group in groups:
        if len(group) < CLUSTER_SIZE:
            continue
        table = names()
        stems = []
        for k in group:
            side, stem = label_stem(entries[k].label)
            numbered = stem != stem.rstrip("0123456789") and stem not in table
            stems.append((side, stem.rstrip("0123456789")) if numbered else None)
        family = {k for k, stem in zip(group, stems) if stem and stems.count(stem) > 1}
        votes = [_named_segment(told[k], catalogue) for k in family] or \
            [entries[k].segment or catalogue[entries[k].landmark].segment for k in group
             if entries[k].by_name] or \
            [catalogue[entries[k].landmark].segment for k in group
             if entries[k].landmark and entries[k].confidence >= LOW_CONFIDENCE]
        votes = [v for v in votes if v]
        centre = np.nanmean(place[group], axis=0)
        gap = np.linalg.norm(lm_places - centre, axis=1)           # (L,) to each landmark

        def nearness(segment):          # ties of votes go to the segment nearest the group
            return -min(g for g, s in zip(gap, lm_segments) if s == segment)

        segment = max(sorted(set(votes)), key=lambda v: (votes.count(v), nearness(v))) \
            if votes else lm_segments[int(np.argmin(gap))]
        for k in group:
            e = entries[k]
            if k not in family and (e.by_name and e.segment or e.landmark and (e.by_name or (
                    e.confidence >= LOW_CONFIDENCE and catalogue[e.landmark].segment == segment))):
                continue
            if e.landmark:
                e.evidence.append(f"not {e.landmark}: " + (
                    "one of a numbered family" if k in family else "too far from it"
                    if e.confidence < LOW_CONFIDENCE else f"its rigid group rides on {segment}"))
            e.landmark, e.segment, e.confidence, e.by_name = None, segment, 0.5, False
            e.evidence.append(f"a tracking marker of a {len(group)}-marker rigid group on "
                              f"{segment}")


def _named_segment(told, catalogue) -> str | None:
    """The segment of the first landmark a label's name points to (its side's), or None."""
    side, keys = told
    for key in keys:
        for name in ((f"{side}_{key}",) if side else (key, f"L_{key}")):
            if name in catalogue:
                return catalogue[name].segment
    return None


def _where(place: np.ndarray) -> str:
    x, y, z = place
    side = f"{abs(y) * 100:.0f} cm {'left' if y > 0 else 'right'}" if abs(y) > 0.02 else \
        "on the midline"
    return (f"sits at {z / REFERENCE_HEIGHT:.0%} of the height, {side}, "
            f"{abs(x) * 100:.0f} cm {'forward' if x > 0 else 'back'} (1.75 m body)")


def marker_labels(trial: Trial) -> list[str]:
    """The labels of ``trial`` that are markers (not model outputs, not computed points, not
    unlabelled, seen in 10 % of the frames), without their subject prefix."""
    computed = computed_points(trial, numbered_candidates(trial))
    seen = np.isfinite(trial.markers[..., 0]).mean(axis=0) if trial.n_frames else []
    out, taken = [], set()
    for i, label in enumerate(trial.labels):
        bare = label.split(":")[-1].strip()
        key = normalise_label(bare)
        if is_model_output(label) or i in computed or not key or key in taken or seen[i] < 0.1:
            continue
        taken.add(key)
        out.append(bare)
    return out


def _places(trial: Trial, labels: list[str], told) -> tuple[np.ndarray, str]:
    """:func:`body_positions` of ``labels`` in ``trial``, the pelvis landmarks found by name
    (``told``: side and landmark keys per label) setting forward."""
    X = _motion_markers(trial, labels)
    cues = {}
    for k, (side, keys) in enumerate(told):
        for key in keys:
            full = f"{side}_{key}" if side else key
            if full in ("L_ASIS", "R_ASIS", "L_PSIS", "R_PSIS", "SACRUM"):
                cues.setdefault(full, X[:, k])
    return body_positions(X, cues)


def _moves(X: np.ndarray) -> bool:
    """True when the markers X (F, M, 3) move more than a standing subject's: in a static
    every marker is rigid with every other, which says nothing of the segments."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        extent = np.linalg.norm(np.nanmax(X, axis=0) - np.nanmin(X, axis=0), axis=1)
        return bool(nanmedian(extent) > STANDING_EXTENT)


def _motion_markers(trial: Trial, labels: list[str]) -> np.ndarray:
    """``trial``'s trajectories (F, M, 3) of ``labels`` (NaN for those it lacks)."""
    index = {normalise_label(x): i for i, x in enumerate(trial.labels)}
    X = np.full((trial.n_frames, len(labels), 3), np.nan)
    for k, label in enumerate(labels):
        if normalise_label(label) in index:
            X[:, k] = trial.markers[:, index[normalise_label(label)]]
    return X
