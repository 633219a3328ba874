"""Matching a capture's labels to a protocol: which points are markers and which are a model's
outputs or computed points (:func:`computed_points`), which protocol a capture uses
(:func:`detect_protocol`), and the columns of the trial each protocol marker is
(:class:`ProtocolMatch`, :func:`match_trial`).

Labels are matched after :func:`mocaplib.trial.normalise_label` (case, spaces, subject
prefixes); markers are ``(F, M, 3)`` arrays in metres.
"""

from __future__ import annotations

import os
import re
import warnings
from collections import Counter
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from ..errors import ProtocolError
from ..numeric import distinct, median
from ..trial import Trial, normalise_label, require_markers, subject_prefixes
from .protocols import Protocol, list_protocols, load_protocol, protocols_dir, read_protocol_toml
from .sides import forward_direction


@lru_cache(maxsize=None)
def _model_output_regex(path: str, key: str) -> re.Pattern:
    patterns = read_protocol_toml(path).get(key)
    if not isinstance(patterns, list) or not all(isinstance(p, str) for p in patterns):
        raise ProtocolError(f"needs {key} = [\"REGEX\", ...]", path=path)
    try:
        return re.compile("|".join(f"(?:{p})" for p in patterns) or "(?!)")
    except re.error as exc:
        raise ProtocolError(f"invalid regular expression: {exc}", path=path) from None


@lru_cache(maxsize=4096)
def _matches(label: str, key: str) -> bool:
    regex = _model_output_regex(os.fspath(protocols_dir() / "model_outputs.toml"), key)
    return regex.fullmatch(normalise_label(label)) is not None


def is_model_output(label: str) -> bool:
    """True when ``label`` names a model output stored as a point (``LHipAngles``, ``PELO``,
    ``*12``...), after normalisation, by the ``patterns`` of ``model_outputs.toml``."""
    return _matches(label, "patterns")


def is_numbered_point(label: str) -> bool:
    """True when ``label`` has the form of a model's numbered virtual point (``LFEM12``,
    ``LTIB1``, ``PEL0``: the ``numbered`` patterns of ``model_outputs.toml``), which labs
    also give cluster markers: :func:`computed_points` tells them apart."""
    return _matches(label, "numbered")


#: Two points whose distance varies less than this (m, standard deviation over the frames)
#: while the body moves are rigid to a file's precision: one was computed from a model
#: (measured: 0-0.03 mm between CMU's and the Oxford Foot Model's virtual points in walks;
#: 0.24-4.8 mm between two markers of one segment in the real walks at hand). A file that
#: stores its coordinates as integers adds their rounding: the bound is then at least the
#: storage step (:func:`storage_step`; rounding to it varies a distance by 0.41 of it, SD).
RIGID_SD = 5e-5
#: At most this many coordinates are looked at to find their :func:`storage_step`.
STEP_SAMPLES = 1_000_000


#: A point moves with the body when it travels more than this (m, the diagonal of the box its
#: path fills); in a standing trial nothing tells a marker from a virtual point (real statics
#: hold marker pairs rigid to 3 µm), so the name decides there.
MOVING_EXTENT = 0.05


#: Frames a pair must be seen together in to be judged.
RIGID_FRAMES = 10


#: Frames, spread over the trial, of the quick first look at every pair (:func:`computed_points`).
SCREEN_FRAMES = 8


def numbered_candidates(trial: Trial) -> list[int]:
    """Trial marker indices whose labels have a model's numbered form
    (:func:`is_numbered_point`) and are not plain model outputs."""
    return [i for i, label in enumerate(trial.labels)
            if not is_model_output(label) and is_numbered_point(label)]


def storage_step(points: np.ndarray, /) -> float:
    """The step (m) the coordinates of ``points`` (F, N, 3) are stored at: the smallest gap
    between two of their distinct values, of at most :data:`STEP_SAMPLES` (an integer C3D's
    POINT:SCALE, in metres; a float file's is far below a micrometre)."""
    values = points[np.isfinite(points)]
    if values.size > STEP_SAMPLES:
        values = values[np.linspace(0, values.size - 1, STEP_SAMPLES).astype(int)]
    gaps = np.diff(np.unique(values))
    return float(gaps.min()) if gaps.size else 0.0


def computed_points(trial: Trial, candidates, /) -> set[int]:
    """The ``candidates`` (trial marker indices) that a model computed: each stays rigid, to
    :data:`RIGID_SD` or the coordinates' :func:`storage_step`, with some other point of the
    trial seen with it in :data:`RIGID_FRAMES` frames or more while it moves
    (:data:`MOVING_EXTENT`); a point
    that does not move is taken to be what its name says. A point that moves with the body
    otherwise is a marker.

    Every pair is first looked at on :data:`SCREEN_FRAMES` frames: their squared deviations
    from their own mean, over the frames the pair is seen together in, bound the pair's
    variance from below, so a pair the bound already rules out is not rigid, and only the
    others are measured on every frame (the same result as measuring all, at a fraction of
    the cost for the hundreds of virtual points some files hold).
    """
    X = trial.markers
    candidates = list(dict.fromkeys(candidates))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)            # never seen: NaN
        extent = np.linalg.norm(np.nanmax(X[:, candidates], axis=0)
                                - np.nanmin(X[:, candidates], axis=0), axis=1)
    out = {i for i, e in zip(candidates, extent) if not e > MOVING_EXTENT}
    moving = np.array([i for i in candidates if i not in out], dtype=int)
    if not moving.size:
        return out
    rigid_sd = max(RIGID_SD, storage_step(X[:, moving]))
    seen = np.isfinite(X).all(axis=2).astype(float)                           # (F, N)
    together = seen[:, moving].T @ seen                                       # (c, N) frames
    screen = distinct(np.linspace(0, len(X) - 1, min(len(X), SCREEN_FRAMES)).round()
                      .astype(int))
    Z = np.ascontiguousarray(X[screen].transpose(0, 2, 1))                    # (k, 3, N)
    spread = np.concatenate([_squared_deviations(Z[:, :, chunk, None] - Z[:, :, None])
                             for chunk in np.array_split(moving, -(-moving.size // 64))])
    possible = (spread < rigid_sd ** 2 * together) & (together >= RIGID_FRAMES)
    possible[np.arange(moving.size), moving] = False
    rows, partners = np.nonzero(possible)
    rigid = np.zeros(moving.size, dtype=bool)
    Z = np.ascontiguousarray(X.transpose(0, 2, 1))                            # (F, 3, N)
    while rows.size:                    # each unsettled point's next possible partner
        first = np.r_[True, rows[1:] != rows[:-1]]
        row, partner = rows[first], partners[first]
        total, count = _squared_deviations(Z[:, :, partner] - Z[:, :, moving[row]],
                                           counts=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            rigid[row[(total / count < rigid_sd ** 2) & (count >= RIGID_FRAMES)]] = True
        rows, partners = rows[~first & ~rigid[rows]], partners[~first & ~rigid[rows]]
    return out | {int(i) for i in moving[rigid]}


def _squared_deviations(differences: np.ndarray, *, counts: bool = False):
    """For point differences ``differences`` (F, 3, ...), metres: the sum over the frames of
    the squared deviations of their lengths from the mean length over the frames they are seen
    in, shape (...), m²; with ``counts``, also those frames' numbers (...)."""
    x, y, z = differences[:, 0], differences[:, 1], differences[:, 2]
    d = np.sqrt(x * x + y * y + z * z)
    seen = np.isfinite(d)
    count = seen.sum(axis=0)
    d[~seen] = 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        d -= d.sum(axis=0) / count
    d[~seen] = 0.0
    total = (d * d).sum(axis=0)
    return (total, count) if counts else total


@dataclass(frozen=True)
class ProtocolMatch:
    """How a trial's markers map onto a protocol.

    ``indices[j]`` is the trial marker index of protocol marker ``j`` or -1 when absent.
    ``missing_any_of`` names the ``[any_of]`` groups with no label present. ``ignored`` holds
    the trial labels set aside as model outputs, ``unknown`` the labels that are neither in the
    protocol nor model outputs, ``duplicates`` the protocol labels found more than once (the
    copy seen in most frames is used). ``subject`` is the subject prefix matched when the
    labels name several people (None otherwise). ``warnings`` says all of that, plus
    left/right swaps, in words.
    """

    protocol: Protocol
    indices: tuple[int, ...]
    missing: tuple[str, ...]
    missing_required: tuple[str, ...]
    missing_any_of: tuple[str, ...] = ()
    ignored: tuple[str, ...] = ()
    unknown: tuple[str, ...] = ()
    duplicates: tuple[str, ...] = ()
    swaps: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    subject: str | None = None

    @property
    def subject_note(self) -> str | None:
        """Which person the match took, when the labels name several (None otherwise)."""
        if self.subject is None:
            return None
        return f"matched on subject {self.subject}'s labels, the other subjects' left aside"

    @property
    def found(self) -> int:
        return sum(i >= 0 for i in self.indices)

    @property
    def columns(self) -> list[int]:
        """The trial's marker indices of the protocol's markers found, in protocol order."""
        return [i for i in self.indices if i >= 0]

    @property
    def complete(self) -> bool:
        """True when every required marker and one marker of each ``any_of`` group is present."""
        return not self.missing_required and not self.missing_any_of

    @property
    def missing_landmarks(self) -> list[str]:
        """Missing required landmarks by name (``L_ACROMION``); an empty group as ``A|B|C``."""
        by_label = {m.label: m.landmark.name for m in self.protocol.markers}
        groups = dict(self.protocol.any_of)
        return ([by_label[label] for label in self.missing_required]
                + ["|".join(by_label[label] for label in groups[g]) for g in self.missing_any_of])

    @property
    def present_landmarks(self) -> dict[str, str]:
        """``{landmark name: protocol label}`` of the markers found in the trial (the label is
        what :meth:`marker` takes)."""
        return {m.landmark.name: m.label for m, i in zip(self.protocol.markers, self.indices)
                if i >= 0}

    def markers(self, trial: Trial) -> np.ndarray:
        """The trial's markers in protocol order, shape (F, P, 3), NaN for absent ones."""
        out = np.full((trial.n_frames, len(self.indices), 3), np.nan)
        present = [j for j, i in enumerate(self.indices) if i >= 0]
        out[:, present] = trial.markers[:, [self.indices[j] for j in present]]
        return out

    def marker(self, trial: Trial, label: str) -> np.ndarray:
        """One protocol marker's trajectory, shape (F, 3), all NaN when absent."""
        j = self.protocol.labels.index(label)
        i = self.indices[j]
        return trial.markers[:, i] if i >= 0 else np.full((trial.n_frames, 3), np.nan)


def needs_draft(match: ProtocolMatch | None) -> bool:
    """True when ``match`` (the best protocol's, None when no protocol matches a label) cannot
    serve its capture: a required landmark is missing, or more of the capture's labels are
    unknown to the protocol than it finds; a build then drafts a protocol for the capture's
    marker set (:mod:`mocaplib.build.drafting`)."""
    return match is None or not match.complete or len(match.unknown) > match.found


def match_protocol(trial: Trial, protocol: Protocol, *, check_swaps: bool = True,
                   computed: set[int] | None = None, classify: bool = True) -> ProtocolMatch:
    """Map ``protocol``'s markers to ``trial``'s by normalised label: of a label found more
    than once, the copy seen in most frames (the first of equals); a label never seen counts
    as missing (the fit could do nothing with it).

    With ``classify``, labels the protocol does not list are sorted into model outputs
    (ignored: by name, or numbered points a model computed, :func:`computed_points`, which
    ``computed`` gives when already known) and unknown ones; without, ``ignored``,
    ``unknown`` and their warnings stay empty (the calibration and the fit need the mapping
    only). With ``check_swaps``, left/right label swaps of the shoulder and pelvis markers are
    looked for (:func:`find_side_swaps`) and reported in ``swaps`` and ``warnings``, never
    corrected.
    """
    names = trial.names
    seen = np.isfinite(trial.markers[..., 0]).sum(axis=0)             # (N,) frames seen in
    subjects = subject_prefixes(trial.labels)
    subject = _matched_subject(protocol, names, subjects, seen)
    mine = [not subject or s in (subject, "") for s in subjects]       # the labels matched
    chosen: dict[str, int] = {}               # each name's copy seen in most frames, if any
    for i, name in enumerate(names):
        if seen[i] and mine[i] and (name not in chosen or seen[i] > seen[chosen[name]]):
            chosen[name] = i
    indices = tuple(next((chosen[k] for k in m.keys if k in chosen), -1)
                    for m in protocol.markers)
    missing = tuple(m.label for m, i in zip(protocol.markers, indices) if i < 0)
    missing_required = tuple(m.label for m, i in zip(protocol.markers, indices)
                             if i < 0 and m.required)
    present = {m.label for m, i in zip(protocol.markers, indices) if i >= 0}
    missing_any_of = tuple(g for g, labels in protocol.any_of if not present & set(labels))
    claimed = {k for m in protocol.markers for k in m.keys}
    ignored, unknown = [], []
    if classify and computed is None:
        computed = computed_points(trial, [i for i in numbered_candidates(trial)
                                           if names[i] not in claimed])
    for i, (label, name) in enumerate(zip(trial.labels, names)):
        if classify and name not in claimed:
            (ignored if is_model_output(label) or i in computed else unknown).append(label)
    copies = Counter(name for name, m in zip(names, mine) if m)
    duplicates = tuple(trial.labels[chosen[k]] for m in protocol.markers for k in m.keys
                       if k in chosen and copies[k] > 1)
    match = ProtocolMatch(protocol, indices, missing, missing_required, missing_any_of,
                          tuple(ignored), tuple(dict.fromkeys(unknown)), duplicates,
                          subject=subject or None)
    swaps = find_side_swaps(trial, match) if check_swaps else ()
    return replace(match, swaps=swaps, warnings=_match_warnings(match, swaps))


def _matched_subject(protocol: Protocol, names: list[str], subjects: list[str],
                     seen: np.ndarray) -> str:
    """With labels of several subjects (``subjects``: each label's prefix, ``""`` for none), the
    prefix whose labels seen in some frame (``seen`` (N,) frame counts; ``names`` normalised),
    with the unprefixed ones, give the most of ``protocol``'s markers, the first in the file of
    equals: a file holding several people is matched on one. ``""`` with one subject or none
    (every label is matched)."""
    prefixes = list(dict.fromkeys(s for s in subjects if s))
    if len(prefixes) < 2:
        return ""

    def found(subject):
        have = {n for n, s, k in zip(names, subjects, seen) if s in (subject, "") and k}
        return sum(bool(have.intersection(m.keys)) for m in protocol.markers)

    return max(prefixes, key=found)


def label_match(trial: Trial, protocol: Protocol, /) -> ProtocolMatch:
    """``protocol``'s markers mapped to ``trial``'s labels and nothing more (no swap check, no
    sorting of the other labels, :func:`match_protocol`): what the calibration and the fit
    need, the labels' warnings being said once, by the match of the capture."""
    return match_protocol(trial, protocol, check_swaps=False, classify=False)


def _match_warnings(match: ProtocolMatch, swaps: tuple[str, ...]) -> tuple[str, ...]:
    out = list(swaps)
    if match.subject_note:
        out.append(match.subject_note)
    if match.duplicates:
        out.append(f"duplicate labels {', '.join(match.duplicates)}: the copy of each seen in "
                   "most frames is used, the others are ignored")
    if match.ignored:
        out.append(f"ignored {len(match.ignored)} model-output points ({_few(match.ignored)})")
    if match.unknown:
        plural = "s" if len(match.unknown) > 1 else ""
        out.append(f"{len(match.unknown)} label{plural} not in protocol {match.protocol.name} "
                   f"({_few(match.unknown)})")
    if match.missing_landmarks:
        out.append(f"missing required landmarks for {match.protocol.name}: "
                   f"{', '.join(match.missing_landmarks)}")
    return tuple(out)


def _few(labels, limit: int = 8) -> str:
    labels = list(labels)
    more = f", ... {len(labels) - limit} more" if len(labels) > limit else ""
    return ", ".join(labels[:limit]) + more


def detect_protocol(trial: Trial, /, *, protocols: list[Protocol] | None = None
                    ) -> ProtocolMatch:
    """The best match of ``trial`` among ``protocols`` (default: every shipped protocol).

    Ranking: protocols with every required marker (and one of each ``any_of`` group) present
    come first; then the most markers found; then the largest fraction of the protocol's
    markers found (so a 30-marker subset beats the 42-marker set it is part of when both find
    the same 30); then the name, alphabetically. Raises :class:`ProtocolError` when no
    protocol matches a single label.
    """
    if protocols is None:
        protocols = [load_protocol(name) for name in list_protocols()]
    computed = computed_points(trial, numbered_candidates(trial))
    matches = [match_protocol(trial, p, check_swaps=False, computed=computed)
               for p in protocols]
    if not matches:
        raise ProtocolError("no protocols to choose from", path=trial.source)
    best = min(matches, key=lambda m: (not m.complete, -m.found,
                                       -m.found / len(m.indices), m.protocol.name))
    if best.found == 0:
        raise ProtocolError(
            "no protocol matches any marker label", path=trial.source,
            hint=f"labels are {_few(trial.labels)}; write a protocol for this marker set "
                 "(see docs/guide/protocols.md) and pass it with --protocol")
    return match_protocol(trial, best.protocol, computed=computed)


def match_trial(trial: Trial, protocol: Protocol | str | os.PathLike = "auto", /
                ) -> ProtocolMatch:
    """The match of ``trial`` with ``protocol``: a :class:`Protocol`, a shipped name, a TOML
    path, or ``"auto"`` (:func:`detect_protocol` among the shipped ones). A trial without
    markers is refused (:func:`~mocaplib.trial.require_markers`)."""
    require_markers(trial)
    if isinstance(protocol, Protocol):
        return match_protocol(trial, protocol)
    if protocol == "auto":
        return detect_protocol(trial)
    return match_protocol(trial, load_protocol(protocol))


def missing_landmarks_error(match, source: str | os.PathLike | None) -> ProtocolError | None:
    """The error for a capture (``source``) whose protocol ``match``
    (:class:`mocaplib.markersets.matching.ProtocolMatch`) misses required landmarks, naming each with
    the labels the protocol expects for it and saying what to do; None when none is missing.

    ``mocaplib build`` and ``mocaplib cycles`` fail such a capture (its calibration, fit and
    cycles would quietly lose what the pipeline needs), ``fit`` and ``events`` warn.
    """
    protocol = match.protocol

    def expected(labels):
        markers = [protocol.marker(label) for label in labels]
        keys = [key for m in markers for key in (m.label, *m.aliases)]
        either = ", ".join(keys[:-1]) + " or " + keys[-1] if len(keys) > 1 else keys[0]
        return f"{'|'.join(m.landmark.name for m in markers)} (expects {either})"

    groups = dict(protocol.any_of)
    missing = ([expected([label]) for label in match.missing_required]
               + [f"one of {expected(groups[group])}" for group in match.missing_any_of])
    if not missing:
        return None
    return ProtocolError(
        f"the capture has no label for required landmark{'s' if len(missing) > 1 else ''} of "
        f"protocol {protocol.name!r}: {'; '.join(missing)}", path=source,
        hint="rename the capture's label to the one the protocol expects, add the capture's "
             "label to the protocol as an alias, or pass --protocol with a protocol for this "
             "marker set (`mocaplib inspect` lists the capture's labels and their gaps: a label "
             "missing in every frame counts as absent)")


#: Sided landmarks whose left/right labels are checked for swaps.
SWAP_CHECKED = ("ACROMION", "ASIS", "PSIS")


#: Lateral distance (m) beyond which a left marker found on the right is called a swap:
#: well above skin-marker noise, well below shoulder (>= 0.1 m) or ASIS (>= 0.2 m) widths.
SWAP_MARGIN = 0.02


def find_side_swaps(trial: Trial, match: ProtocolMatch, /) -> tuple[str, ...]:
    """Warnings for left-labelled shoulder/pelvis markers that lie on the subject's right.

    The subject's right is taken per frame from a direction the swap cannot corrupt: forward
    = mean of the anterior markers minus mean of the posterior ones (ASIS vs PSIS/sacrum,
    else sternum vs spine, else front vs back of the head; a left/right swap leaves both means
    unchanged), up = +Z, right = forward x up. So it works whichever way the subject faces,
    turns or walks, and on standing trials. A pair is called swapped when the median, over
    frames where both markers and the forward direction are known, of (left - right) along
    the subject's left is below ``-SWAP_MARGIN``.
    """
    by_landmark: dict[str, np.ndarray] = {}
    for m, i in zip(match.protocol.markers, match.indices):
        if i >= 0:
            by_landmark.setdefault(m.landmark.name, trial.markers[:, i])
    forward = forward_direction(by_landmark, trial.n_frames)
    left = np.stack([-forward[:, 1], forward[:, 0]], axis=1)  # up x forward, horizontal
    label_of = {m.landmark.name: m.label for m, i in zip(match.protocol.markers, match.indices)
                if i >= 0}
    out = []
    for name in SWAP_CHECKED:
        lm, rm = f"L_{name}", f"R_{name}"
        if lm not in by_landmark or rm not in by_landmark:
            continue
        lateral = np.einsum("fi,fi->f", by_landmark[lm][:, :2] - by_landmark[rm][:, :2], left)
        lateral = lateral[np.isfinite(lateral)]
        if lateral.size and median(lateral) < -SWAP_MARGIN:
            out.append(f"left/right swap suspected: {label_of[lm]} (labelled left) lies "
                       f"{-median(lateral) * 100:.0f} cm to the subject's RIGHT of "
                       f"{label_of[rm]} in {np.mean(lateral < 0):.0%} of {lateral.size} frames; "
                       "check the labelling (not corrected)")
    return tuple(out)
