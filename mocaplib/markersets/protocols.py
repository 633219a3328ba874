"""Marker-set protocols: which lab label is which anatomical landmark, on which segment.

Files
-----
``protocols/landmarks.toml`` is the catalogue of anatomical landmarks: for each, the skeleton
segment it sits on and a nominal position in that segment's frame (metres, for a 1.75 m
subject, left side; the right side mirrors y). ``protocols/<name>.toml`` is one marker set:
``name``, ``description`` and a ``[markers]`` table mapping each label to a landmark::

    [markers]
    LASI = { landmark = "L_ASIS", required = true, aliases = ["L.ASIS", "LASIS"] }

A **tracking marker** names the segment it rides on instead of a landmark (a cluster or wand
marker nobody catalogued): ``LTH1 = { segment = "femur", side = "left" }``. It has no nominal
position: calibration measures its offset in the segment's frame (from the static when there is
one, else from the motion). ``static_only = true`` marks an anatomical marker that is put on for
the static trial only (medial knee, medial malleolus...): it places the joint centres there and
is not expected in the motions.

Labels are compared after :func:`mocaplib.trial.normalise_label` (case, subject prefixes,
spaces, ``_ - .`` ignored).

Folders
-------
The shipped folder comes first; the folders of ``$MOCAPLIB_PROTOCOLS`` (several joined by
``os.pathsep``) and those given to :func:`use_protocol_folders` (``--protocols DIR``) are
added to it, in that order. Each may hold protocols (``*.toml`` with a ``[markers]`` table),
its own ``landmarks.toml`` with extra catalogue entries, and capture plans. A later folder's
protocol or landmark of the same name replaces the earlier one, and :func:`overrides` says
so. Nothing in the installed package is ever edited.

Two optional keys extend the format: ``extends = "plugin_gait"`` starts from another protocol's
markers (an entry with the same label, or on the same landmark, replaces the inherited one,
which ``[any_of]`` groups then name by the new label), and an ``[any_of]`` table names groups
of labels of which at least one must be present (``pelvis_back = ["LPSI", "RPSI", "SACR"]``),
for sets where either of two markers does the job.

Matching (:func:`match_protocol`) maps each protocol marker to the first trial marker with the
same normalised label (repeats are flagged), sets aside model outputs stored as points (the
regular expressions of ``model_outputs.toml``; a point its ``numbered`` patterns match is set
aside only when it is computed, :func:`computed_points`), lists the remaining unknown labels,
and checks
that left-labelled shoulder and pelvis markers lie on the subject's left
(:func:`find_side_swaps`). :func:`detect_protocol` picks the best shipped protocol.
"""

from __future__ import annotations

import os
import re
import warnings
from collections import Counter
from dataclasses import dataclass, replace
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np

from ..errors import ProtocolError
from ..io.tomlfile import read_toml
from ..numeric import distinct, median
from ..skeleton import SEGMENT_NAMES
from ..trial import Trial, normalise_label, subject_prefixes

#: Height of the subject the catalogue's nominal positions are written for, metres.
REFERENCE_HEIGHT = 1.75


#: The shipped protocols: mocaplib/data/protocols links to the repository's protocols/; wheels
#: hold a copy.
SHIPPED_PROTOCOLS = Path(__file__).resolve().parents[1] / "data" / "protocols"


#: The environment variable naming users' protocol folders (``os.pathsep`` between several).
FOLDERS_VARIABLE = "MOCAPLIB_PROTOCOLS"


def protocols_dir() -> Path:
    """The shipped folder holding ``landmarks.toml``, ``model_outputs.toml`` and the protocols."""
    return SHIPPED_PROTOCOLS


def protocol_folders() -> tuple[Path, ...]:
    """Every folder protocols, landmarks and capture plans are read from: the shipped one, then
    those of ``$MOCAPLIB_PROTOCOLS`` (to which :func:`use_protocol_folders` adds). A later
    folder's definition of a name replaces an earlier one's."""
    return tuple(dict.fromkeys([SHIPPED_PROTOCOLS] + [Path(p) for p in _env_folders()]))


def _env_folders() -> list[str]:
    return [p for p in os.environ.get(FOLDERS_VARIABLE, "").split(os.pathsep) if p]


def use_protocol_folders(folders, /) -> None:
    """Add users' protocol folders (``--protocols DIR``) to the shipped one, for this process
    and the worker processes it starts (they are written into ``$MOCAPLIB_PROTOCOLS``, which
    workers inherit). Raises :class:`ProtocolError` naming a folder that does not exist."""
    for folder in folders:
        if not Path(folder).is_dir():
            raise ProtocolError("protocol folder not found", path=folder,
                                hint="give a folder holding your protocols (*.toml) and, if "
                                     "you add landmarks, a landmarks.toml")
    added = [os.path.abspath(f) for f in folders]
    os.environ[FOLDERS_VARIABLE] = os.pathsep.join(dict.fromkeys(_env_folders() + added))


def _definitions(kind: str) -> tuple[dict[str, Path], list[str]]:
    """``{name: file}`` of every protocol (``kind="protocols"``) or capture plan
    (``"plans"``) in :func:`protocol_folders`, a later folder's winning, and a note per name
    a user folder redefines."""
    found: dict[str, Path] = {}
    notes = []
    for folder in protocol_folders():
        for path in sorted(folder.glob("*.toml")):
            is_plan = "plan" in path.stem
            if kind == "plans" and not is_plan or kind == "protocols" and (
                    is_plan or "markers" not in _read_toml(os.fspath(path))):
                continue
            if path.stem in found:
                notes.append(f"protocol {path.stem!r} of {path} replaces the one of "
                             f"{found[path.stem]}")
            found[path.stem] = path
    return found, notes


def overrides() -> list[str]:
    """One sentence per protocol or landmark a user folder redefines (it wins)."""
    return _definitions("protocols")[1] + _landmark_catalogue(_folder_key())[1]


def user_fingerprint() -> str:
    """SHA-256 of every ``*.toml`` in the user folders (not the shipped one), "" without any:
    part of a build's cache key, so that editing a user protocol invalidates the cache."""
    import hashlib

    digest = hashlib.sha256()
    folders = protocol_folders()[1:]
    for folder in folders:
        for path in sorted(folder.glob("*.toml")):
            digest.update(os.fspath(path.resolve()).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest() if folders else ""


def _folder_key() -> tuple[str, ...]:
    return tuple(os.fspath(f) for f in protocol_folders())


@dataclass(frozen=True)
class Landmark:
    """One anatomical landmark: sided name (``L_ASIS``), segment, nominal position (3,) m, and
    the weight a marker on it gets in the fit by default (:attr:`ProtocolMarker.weight`).

    A tracking marker's "landmark" (:func:`tracking_landmark`) has no position (None): it is
    named ``<segment>:<label>`` and its offset is measured, never looked up.
    """

    name: str
    segment: str
    position: tuple[float, float, float] | None
    description: str
    weight: float = 1.0

    @property
    def tracking(self) -> bool:
        """True for a tracking marker's landmark (no catalogued position)."""
        return self.position is None


def tracking_landmark(label: str, segment: str) -> Landmark:
    """The landmark of a tracking marker ``label`` on ``segment`` (a skeleton segment name)."""
    return Landmark(f"{segment}:{label}", segment, None,
                    f"tracking marker on {segment}, offset measured in calibration")


@dataclass(frozen=True)
class ProtocolMarker:
    """One marker of a protocol: its label, aliases, landmark, whether it is required, its
    weight in the joint-angle fit (relative to 1; the protocol's ``weight``, else the
    landmark's), and whether it is put on for the static trial only (``static_only``)."""

    label: str
    landmark: Landmark
    required: bool
    aliases: tuple[str, ...]
    weight: float = 1.0
    static_only: bool = False

    @property
    def tracking(self) -> bool:
        """True for a tracking marker (on a segment, no landmark)."""
        return self.landmark.tracking

    @cached_property
    def keys(self) -> tuple[str, ...]:
        """Normalised label and aliases this marker matches."""
        return tuple(dict.fromkeys(normalise_label(x) for x in (self.label, *self.aliases)))


@dataclass(frozen=True)
class Protocol:
    """A marker set: name, description, markers (in file order) and the file it came from.

    ``any_of`` holds ``(group name, labels)`` pairs: at least one label of each group must be
    present for a trial to be usable, on top of the ``required`` markers. ``fallback_starts``
    (``[cycles] fallback_starts``): the events a cycle may start at, in order, when a capture
    shows fewer than two left toe-offs (:mod:`mocaplib.gait.cycles`); empty: none.
    """

    name: str
    description: str
    markers: tuple[ProtocolMarker, ...]
    path: str
    any_of: tuple[tuple[str, tuple[str, ...]], ...] = ()
    fallback_starts: tuple[str, ...] = ()

    @property
    def labels(self) -> list[str]:
        return [m.label for m in self.markers]

    @property
    def required(self) -> list[str]:
        return [m.label for m in self.markers if m.required]

    def labelled_in(self, trial: Trial) -> list[str]:
        """The labels of its markers that ``trial`` names under any of their keys, seen in
        some frame or not (the labels tell the marker set; gaps do not)."""
        names = set(trial.names)
        return [m.label for m in self.markers if names.intersection(m.keys)]

    def marker(self, label: str) -> ProtocolMarker:
        for m in self.markers:
            if m.label == label:
                return m
        raise ProtocolError(f"protocol {self.name!r} has no marker {label!r}", path=self.path)

    def nominal_offsets(self, height: float = REFERENCE_HEIGHT) -> tuple[np.ndarray, np.ndarray]:
        """Segment index (M,) and nominal offset (M, 3) in metres of each marker, scaled; NaN
        rows for tracking markers (their offsets are measured, not catalogued)."""
        segments = np.array([SEGMENT_NAMES.index(m.landmark.segment) for m in self.markers])
        offsets = np.array([(np.nan,) * 3 if m.tracking else m.landmark.position
                            for m in self.markers]) * (height / REFERENCE_HEIGHT)
        return segments, offsets


@lru_cache(maxsize=None)
def _read_toml(path: str) -> dict:
    return read_toml(path, error=ProtocolError, what="protocol file",
                     hint=f"protocols are TOML files like those in {protocols_dir()}")


def load_landmarks(path: str | os.PathLike | None = None) -> dict[str, Landmark]:
    """The landmark catalogue, keyed by sided name (``L_ASIS``, ``R_ASIS``, ``C7``...): the
    ``landmarks.toml`` of every :func:`protocol_folders` folder (a later folder's entry of the
    same name wins), or of ``path`` alone."""
    if path is not None:
        return _catalogue_file(os.fspath(path))
    return dict(_landmark_catalogue(_folder_key())[0])


@lru_cache(maxsize=None)
def _landmark_catalogue(folders: tuple[str, ...]) -> tuple[dict[str, Landmark], list[str]]:
    """The merged catalogue of ``folders`` and a note per landmark a later folder redefines."""
    out: dict[str, Landmark] = {}
    notes = []
    for folder in folders:
        path = Path(folder) / "landmarks.toml"
        if folder != os.fspath(SHIPPED_PROTOCOLS) and not path.is_file():
            continue
        for name, landmark in _catalogue_file(os.fspath(path)).items():
            if name in out and out[name] != landmark:
                notes.append(f"landmark {name} of {path} replaces the shipped one")
            out[name] = landmark
    return out, notes


@lru_cache(maxsize=None)
def _catalogue_file(path: str) -> dict[str, Landmark]:
    """The landmarks of one ``landmarks.toml``."""
    out: dict[str, Landmark] = {}
    for key, spec in _read_toml(path).items():
        try:
            segment, position = spec["segment"], tuple(float(v) for v in spec["position"])
            sided, description = bool(spec.get("sided", False)), str(spec.get("description", ""))
            weight = _weight(spec.get("weight", 1.0), f"landmark {key!r}", path)
        except (KeyError, TypeError, ValueError) as exc:
            raise ProtocolError(f"landmark {key!r} needs segment, position [x, y, z] ({exc})",
                                path=path) from None
        if len(position) != 3:
            raise ProtocolError(f"landmark {key!r}: position must have 3 numbers", path=path)
        variants = ([("L_", "_l", 1.0), ("R_", "_r", -1.0)] if sided else [("", "", 1.0)])
        for prefix, suffix, mirror in variants:
            seg = segment if segment in SEGMENT_NAMES else segment + suffix
            if seg not in SEGMENT_NAMES:
                raise ProtocolError(
                    f"landmark {key!r}: unknown segment {seg!r}", path=path,
                    hint=f"segments are {', '.join(SEGMENT_NAMES)}; sided landmarks use the "
                         "bare name (femur)")
            x, y, z = position
            out[prefix + key] = Landmark(prefix + key, seg, (x, mirror * y, z), description,
                                         weight)
    return out


def list_protocols() -> list[str]:
    """Names of the protocols in :func:`protocol_folders` (files with a [markers] table)."""
    return sorted(_definitions("protocols")[0])


def capture_plans() -> list[Path]:
    """The capture plans (``*plan*.toml``) of :func:`protocol_folders`, a user folder's first,
    each folder's sorted by name: the build's locomotion classes and the report's default
    target envelope come from them."""
    plans = _definitions("plans")[0].values()
    return sorted(plans, key=lambda p: (p.parent == SHIPPED_PROTOCOLS, p.name))


def load_protocol(name_or_path: str | os.PathLike) -> Protocol:
    """Load a protocol by name (``plugin_gait``, shipped or in a user folder) or by path to a
    TOML file."""
    path = _protocol_path(name_or_path)
    return _load_protocol_file(os.path.abspath(path), _folder_key())


@lru_cache(maxsize=None)
def _load_protocol_file(path: str, folders: tuple[str, ...]) -> Protocol:
    """A protocol file read once per process (and set of folders, whose landmark catalogue
    it uses), as its TOML is (:func:`_read_toml`): protocol detection loads every protocol
    for every capture."""
    return _load_protocol(Path(path), ())


def _protocol_path(name_or_path: str | os.PathLike) -> Path:
    path = Path(name_or_path)
    if path.suffix == ".toml":
        return path
    found = _definitions("protocols")[0].get(os.fspath(name_or_path))
    if found is None:
        raise ProtocolError(f"unknown protocol {os.fspath(name_or_path)!r}",
                            hint=f"known protocols: {', '.join(list_protocols())}; "
                                 "or give the path of a .toml file, or the folder holding it "
                                 "with --protocols")
    return found


def _load_protocol(path: Path, parents: tuple[str, ...]) -> Protocol:
    key = os.fspath(path.resolve())
    if key in parents:
        raise ProtocolError("'extends' loops back to this file", path=path)
    data = _read_toml(os.fspath(path))
    table = data.get("markers", {} if "extends" in data else None)
    if not isinstance(table, dict) or not (table or "extends" in data):
        raise ProtocolError("no [markers] table", path=path,
                            hint="map each label to a landmark: LASI = { landmark = \"L_ASIS\" }")
    markers: dict[str, ProtocolMarker] = {}
    groups: dict[str, tuple[str, ...]] = {}
    fallback: tuple[str, ...] = ()
    if "extends" in data:
        base = data["extends"]
        if not isinstance(base, str):
            raise ProtocolError("'extends' must be a protocol name or path", path=path)
        try:  # a relative .toml path is relative to this file's folder
            parent_path = _protocol_path(path.parent / base if base.endswith(".toml") else base)
        except ProtocolError as exc:
            raise ProtocolError(f"extends {base!r}: {exc.message}", path=path,
                                hint=exc.hint) from None
        parent = _load_protocol(parent_path, parents + (key,))
        markers = {m.label: m for m in parent.markers}
        groups = dict(parent.any_of)
        fallback = parent.fallback_starts
    landmarks = load_landmarks()
    for label, spec in table.items():
        marker = _protocol_marker(label, spec, landmarks, path)
        # a child's entry on a landmark the parent already labels replaces the parent's entry
        replaced = [m for m in markers.values() if m.label != label and not m.tracking
                    and m.landmark.name == marker.landmark.name] if not marker.tracking else []
        for old in replaced:
            del markers[old.label]
            groups = {g: tuple(label if x == old.label else x for x in labels)
                      for g, labels in groups.items()}
            if not (isinstance(spec, dict) and "required" in spec):
                marker = replace(marker, required=old.required)
        markers[label] = marker
    for group, labels in _table(data, "any_of", path).items():
        if (not isinstance(labels, list) or not labels
                or any(label not in markers for label in labels)):
            raise ProtocolError(f"[any_of] {group!r} must list labels of this protocol's markers",
                                path=path, hint=f"got {labels!r}")
        groups[group] = tuple(labels)
    keys = [k for m in markers.values() for k in m.keys]
    clashes = sorted({k for k in keys if keys.count(k) > 1})
    if clashes:
        raise ProtocolError(f"labels or aliases used twice: {', '.join(clashes)}", path=path)
    return Protocol(str(data.get("name", path.stem)), str(data.get("description", "")),
                    tuple(markers.values()), os.fspath(path), tuple(groups.items()),
                    _fallback_starts(_table(data, "cycles", path), path, fallback))


def _fallback_starts(table: dict, path: Path, inherited: tuple[str, ...]) -> tuple[str, ...]:
    """``[cycles] fallback_starts`` (or ``inherited``, the parent's): names of the stride's
    events other than the left toe-off (:data:`mocaplib.trial.CYCLE_STARTS`), each once."""
    unknown = sorted(set(table) - {"fallback_starts"})
    if unknown:
        raise ProtocolError(f"[cycles] has no key {unknown[0]!r}", path=path,
                            hint="[cycles] takes fallback_starts only")
    starts = table.get("fallback_starts", list(inherited))
    if starts == []:            # no [cycles]: the library's modules need not be loaded
        return ()
    from ..trial import CYCLE_STARTS

    if (not isinstance(starts, list) or any(s not in CYCLE_STARTS for s in starts)
            or len(set(starts)) != len(starts)):
        raise ProtocolError(f"[cycles] fallback_starts must list events among "
                            f"{', '.join(CYCLE_STARTS)}, each once, got {starts!r}", path=path,
                            hint="a cycle starts at a left toe-off first; list the other "
                                 "events in the order to try them")
    return tuple(starts)


def _table(data: dict, name: str, path: Path) -> dict:
    table = data.get(name, {})
    if not isinstance(table, dict):
        raise ProtocolError(f"{name!r} must be a table ([{name}])", path=path)
    return table


#: How a tracking marker's ``side`` may be written.
_SIDES = {"left": "_l", "l": "_l", "right": "_r", "r": "_r"}


def _protocol_marker(label: str, spec, landmarks: dict[str, Landmark], path: Path
                     ) -> ProtocolMarker:
    spec = {"landmark": spec} if isinstance(spec, str) else spec
    name = spec.get("landmark") if isinstance(spec, dict) else None
    if isinstance(spec, dict) and name is None and "segment" in spec:
        landmark = tracking_landmark(label, _tracking_segment(label, spec, path))
    elif not isinstance(name, str) or name not in landmarks:
        raise ProtocolError(f"marker {label!r}: unknown landmark {name!r}", path=path,
                            hint="landmarks are listed in protocols/landmarks.toml (and a "
                                 "landmarks.toml of your protocol folders); a marker on no "
                                 "landmark names its segment: { segment = \"femur\", "
                                 "side = \"left\" }")
    else:
        landmark = landmarks[name]
    aliases = spec.get("aliases", ())
    if not isinstance(aliases, (list, tuple)) or not all(isinstance(a, str) for a in aliases):
        raise ProtocolError(f"marker {label!r}: aliases must be a list of strings", path=path)
    required, static_only = spec.get("required", False), spec.get("static_only", False)
    if not isinstance(required, bool):
        raise ProtocolError(f"marker {label!r}: required must be true or false", path=path)
    if not isinstance(static_only, bool) or (static_only and required):
        raise ProtocolError(f"marker {label!r}: static_only must be true or false, and a "
                            "marker on the static only cannot be required", path=path)
    weight = _weight(spec.get("weight", landmark.weight), f"marker {label!r}", path)
    return ProtocolMarker(label, landmark, required, tuple(aliases), weight, static_only)


def _tracking_segment(label: str, spec: dict, path: Path) -> str:
    """The skeleton segment of a tracking marker's ``segment`` and ``side`` entries."""
    segment, side = spec.get("segment"), spec.get("side")
    suffix = _SIDES.get(side) if isinstance(side, str) else None
    if side is not None and suffix is None:
        raise ProtocolError(f"marker {label!r}: side must be \"left\" or \"right\", got "
                            f"{side!r}", path=path)
    name = segment + suffix if isinstance(segment, str) and suffix and \
        segment not in SEGMENT_NAMES else segment
    if name not in SEGMENT_NAMES or (suffix and not name.endswith(suffix)):
        raise ProtocolError(
            f"marker {label!r}: unknown segment {segment!r}"
            + (f" on side {side!r}" if side else ""), path=path,
            hint=f"segments are {', '.join(SEGMENT_NAMES)}; a limb's bare name (femur) needs "
                 "side = \"left\" or \"right\"")
    return name


def _weight(value, what: str, path) -> float:
    """A fit weight from a TOML file: a finite number > 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 1e6:
        raise ProtocolError(f"{what}: weight must be a number > 0, got {value!r}", path=path,
                            hint="1 is a typical skin marker; bony landmarks get more")
    return float(value)


@lru_cache(maxsize=None)
def _model_output_regex(path: str, key: str) -> re.Pattern:
    patterns = _read_toml(path).get(key)
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
#: 0.24-4.8 mm between two markers of one segment in the real walks at hand).
RIGID_SD = 5e-5
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


def computed_points(trial: Trial, candidates, /) -> set[int]:
    """The ``candidates`` (trial marker indices) that a model computed: each stays rigid, to
    :data:`RIGID_SD`, with some other point of the trial seen with it in
    :data:`RIGID_FRAMES` frames or more while it moves (:data:`MOVING_EXTENT`); a point
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
    seen = np.isfinite(X).all(axis=2).astype(float)                           # (F, N)
    together = seen[:, moving].T @ seen                                       # (c, N) frames
    screen = distinct(np.linspace(0, len(X) - 1, min(len(X), SCREEN_FRAMES)).round()
                      .astype(int))
    Z = np.ascontiguousarray(X[screen].transpose(0, 2, 1))                    # (k, 3, N)
    spread = np.concatenate([_squared_deviations(Z[:, :, chunk, None] - Z[:, :, None])
                             for chunk in np.array_split(moving, -(-moving.size // 64))])
    possible = (spread < RIGID_SD ** 2 * together) & (together >= RIGID_FRAMES)
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
            rigid[row[(total / count < RIGID_SD ** 2) & (count >= RIGID_FRAMES)]] = True
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
    path, or ``"auto"`` (:func:`detect_protocol` among the shipped ones)."""
    if isinstance(protocol, Protocol):
        return match_protocol(trial, protocol)
    if protocol == "auto":
        return detect_protocol(trial)
    return match_protocol(trial, load_protocol(protocol))


#: Sided landmarks whose left/right labels are checked for swaps.
SWAP_CHECKED = ("ACROMION", "ASIS", "PSIS")
#: Anterior and posterior landmarks giving the subject's forward direction, in order of trust.
#: A side is usable in a frame when its central landmark or both sided ones are present.
_FORWARD_CUES = (
    (("L_ASIS", "R_ASIS"), ("L_PSIS", "R_PSIS", "SACRUM")),
    (("CLAV", "STRN"), ("C7", "T2", "T6", "T8", "T10", "T12")),
    (("L_FRONT_HEAD", "R_FRONT_HEAD"), ("L_BACK_HEAD", "R_BACK_HEAD")),
)
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


def forward_direction(by_landmark: dict[str, np.ndarray], n_frames: int) -> np.ndarray:
    """Unit horizontal forward direction per frame, shape (F, 2), NaN where unknown: the
    first of :func:`forward_cues` known in each frame."""
    forward = np.full((n_frames, 2), np.nan)
    for cue in forward_cues(by_landmark, n_frames):
        todo = np.isnan(forward[:, 0])
        forward[todo] = cue[todo]
    return forward


def forward_cues(by_landmark: dict[str, np.ndarray], n_frames: int) -> list[np.ndarray]:
    """The unit horizontal forward direction per frame (F, 2), NaN where unknown, from each
    front/back cue the landmarks (``by_landmark``: name -> (F, 3)) give, in this order: ASIS
    against PSIS or sacrum, sternum against spine, front against back of the head (each the
    mean of a pair, so an exchange of left and right leaves it)."""
    out = []
    for anterior, posterior in _FORWARD_CUES:
        front, back = _side_mean(by_landmark, anterior), _side_mean(by_landmark, posterior)
        if front is None or back is None:
            continue
        cue = (front - back)[:, :2]
        norm = np.linalg.norm(cue, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            out.append(np.where(norm > 1e-3, cue / norm, np.nan))
    return out


def _side_mean(by_landmark: dict[str, np.ndarray], names: tuple[str, ...]) -> np.ndarray | None:
    """Per-frame mean of balanced landmarks (each central one, or both of a sided pair)."""
    parts = []
    for name in names:
        if name.startswith("L_"):
            pair = [by_landmark.get(name), by_landmark.get("R_" + name[2:])]
            if all(p is not None for p in pair):
                parts.append((pair[0] + pair[1]) / 2)
        elif not name.startswith("R_") and name in by_landmark:
            parts.append(by_landmark[name])
    if not parts:
        return None
    stack = np.stack(parts)
    count = np.isfinite(stack[..., 0]).sum(axis=0)
    mean = np.nansum(stack, axis=0) / np.maximum(count, 1)[:, None]
    mean[count == 0] = np.nan
    return mean


def missing_landmarks_error(match, source: str | os.PathLike | None) -> ProtocolError | None:
    """The error for a capture (``source``) whose protocol ``match``
    (:class:`mocaplib.markersets.protocols.ProtocolMatch`) misses required landmarks, naming each with
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
