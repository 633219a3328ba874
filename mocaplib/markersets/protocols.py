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
import stat
from collections import Counter
from dataclasses import dataclass, replace
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np

from ..errors import ProtocolError
from ..io import read_regular
from ..io.tomlfile import read_toml
from ..skeleton import SEGMENT_NAMES
from ..trial import CYCLE_STARTS, Trial, normalise_label

#: Height of the subject the catalogue's nominal positions are written for, metres.
REFERENCE_HEIGHT = 1.75

#: Farthest (m) a catalogue landmark's coordinate may lie from its segment's origin: the
#: shipped catalogue's farthest is 0.44 m (C7 above the torso's), a segment of a tall adult is
#: under 1 m, and a position in millimetres (440) is refused.
MAX_LANDMARK_OFFSET = 1.0


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
    workers inherit). Raises :class:`ProtocolError` naming a folder that does not exist, a
    TOML entry that is not a regular file, or a ``landmarks.toml`` that cannot be used."""
    for folder in folders:
        if not Path(folder).is_dir():
            raise ProtocolError("protocol folder not found", path=folder,
                                hint="give a folder holding your protocols (*.toml) and, if "
                                     "you add landmarks, a landmarks.toml")
        if Path(folder) / "landmarks.toml" in toml_files(Path(folder)):
            _catalogue_file(os.path.join(folder, "landmarks.toml"))
    added = [os.path.abspath(f) for f in folders]
    os.environ[FOLDERS_VARIABLE] = os.pathsep.join(dict.fromkeys(_env_folders() + added))


def toml_files(folder: Path, /) -> list[Path]:
    """The ``*.toml`` entries of ``folder``, sorted; :class:`ProtocolError` naming the first
    that is not a regular file (a pipe, a device, a folder, a dangling link or a link loop),
    before any is opened: a pipe would block its reader forever."""
    files = sorted(folder.glob("*.toml"))
    for path in files:
        try:
            mode = path.stat().st_mode
        except OSError as exc:
            raise ProtocolError(f"cannot read it: {exc.strerror or exc}", path=path,
                                hint="remove it from the protocol folder or repair it") from None
        if not stat.S_ISREG(mode):
            raise ProtocolError("not a regular file (a folder, a pipe or a device)", path=path,
                                hint="protocols, landmarks and plans are TOML files: move it "
                                     "out of the protocol folder")
    return files


def _definitions(kind: str) -> tuple[dict[str, Path], list[str]]:
    """``{name: file}`` of every protocol (``kind="protocols"``) or capture plan
    (``"plans"``) in :func:`protocol_folders`, a later folder's winning, and a note per name
    a user folder redefines."""
    found: dict[str, Path] = {}
    notes = []
    for folder in protocol_folders():
        for path in toml_files(folder):
            data = read_protocol_toml(os.fspath(path))
            if kind != ("protocols" if "markers" in data else
                        "plans" if "capture" in data else None):
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
        for path in toml_files(folder):
            digest.update(os.fspath(path.resolve()).encode() + b"\0" + read_regular(path))
    return digest.hexdigest() if folders else ""


def _folder_key() -> tuple[str, ...]:
    return tuple(os.fspath(f) for f in protocol_folders())


#: What the code reads a landmark for (``role`` in the catalogue): the front and back cues of
#: the subject's forward direction (:mod:`mocaplib.markersets.sides`), and the heel and
#: forefoot points of the gait events (:func:`mocaplib.gait.feet.foot_landmarks`).
LANDMARK_ROLES = ("pelvis_front", "pelvis_back", "chest_front", "spine", "head_front",
                  "head_back", "heel", "forefoot")


@dataclass(frozen=True)
class Landmark:
    """One anatomical landmark: sided name (``L_ASIS``), segment, nominal position (3,) m, the
    weight a marker on it gets in the fit by default (:attr:`ProtocolMarker.weight`), and the
    role the code reads it for, if any (:data:`LANDMARK_ROLES`).

    A tracking marker's "landmark" (:func:`tracking_landmark`) has no position (None): it is
    named ``<segment>:<label>`` and its offset is measured, never looked up.
    """

    name: str
    segment: str
    position: tuple[float, float, float] | None
    description: str
    weight: float = 1.0
    role: str | None = None

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
    ``drafted``: the file says ``drafted = true`` (``mocaplib protocol draft`` and the build
    write it; a technician who has checked the entries deletes the line).
    """

    name: str
    description: str
    markers: tuple[ProtocolMarker, ...]
    path: str
    any_of: tuple[tuple[str, tuple[str, ...]], ...] = ()
    fallback_starts: tuple[str, ...] = ()
    drafted: bool = False

    @property
    def origin(self) -> str:
        """Where the protocol comes from: ``"drafted"`` (:attr:`drafted`), ``"shipped"`` (the
        package's folder) or ``"user"`` (a user's folder or path)."""
        if self.drafted:
            return "drafted"
        return "shipped" if Path(self.path).parent == SHIPPED_PROTOCOLS else "user"

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
def read_protocol_toml(path: str) -> dict:
    """The parsed TOML of a protocol folder's file ``path`` (a protocol, the landmark catalogue,
    the label names); raises :class:`ProtocolError` naming it."""
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
    for key, spec in read_protocol_toml(path).items():
        try:
            segment, position = spec["segment"], _position(spec["position"], key, path)
            sided, description = bool(spec.get("sided", False)), str(spec.get("description", ""))
            weight = _weight(spec.get("weight", 1.0), f"landmark {key!r}", path)
            role = spec.get("role")
        except (KeyError, TypeError, ValueError) as exc:
            raise ProtocolError(f"landmark {key!r} needs segment, position [x, y, z] ({exc})",
                                path=path) from None
        if role is not None and role not in LANDMARK_ROLES:
            raise ProtocolError(f"landmark {key!r}: unknown role {role!r}", path=path,
                                hint=f"roles are {', '.join(LANDMARK_ROLES)}")
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
                                         weight, role)
    return out


def role_landmarks(role: str, /, *, side: str | None = None) -> tuple[str, ...]:
    """The catalogue's landmarks with ``role`` (:data:`LANDMARK_ROLES`), in its order (a sided
    one as ``L_`` then ``R_``); with ``side`` ("left" or "right") that side's and the central
    ones only."""
    drop = {"left": "R_", "right": "L_", None: None}[side]
    return tuple(name for name, landmark in load_landmarks().items()
                 if landmark.role == role and not (drop and name.startswith(drop)))


def list_protocols() -> list[str]:
    """Names of the protocols in :func:`protocol_folders` (files with a [markers] table)."""
    return sorted(_definitions("protocols")[0])


def capture_plans() -> list[Path]:
    """The capture plans (TOML files with ``[[capture]]`` tables and no ``[markers]``,
    whatever their name) of :func:`protocol_folders`, a user folder's first, each folder's
    sorted by name: the build's locomotion classes and the report's default target envelope
    come from them."""
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
    it uses), as its TOML is (:func:`read_protocol_toml`): protocol detection loads every protocol
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
    data = read_protocol_toml(os.fspath(path))
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
    labelled = {m.landmark.name: m.label for m in markers.values() if not m.tracking}
    own: set[str] = set()               # the labels this file gave so far
    for label, spec in table.items():
        marker = _protocol_marker(label, spec, landmarks, path)
        own.add(label)
        if marker.tracking:
            markers[label] = marker
            continue
        other = labelled.get(marker.landmark.name)
        if other == label or other not in markers or markers[other].tracking \
                or markers[other].landmark.name != marker.landmark.name:
            other = None                 # none, or a label this file moved elsewhere
        if other in own:
            raise ProtocolError(f"markers {other!r} and {label!r} both label the landmark "
                                f"{marker.landmark.name}: a landmark has one marker",
                                path=path, hint=f"list one as the other's alias: {other} = "
                                                f"{{ landmark = \"{marker.landmark.name}\", "
                                                f"aliases = [\"{label}\"] }}")
        if other is not None:
            # a child's entry on a landmark the parent already labels replaces the parent's
            old = markers.pop(other)
            groups = {g: tuple(label if x == other else x for x in labels)
                      for g, labels in groups.items()}
            if not (isinstance(spec, dict) and "required" in spec):
                marker = replace(marker, required=old.required)
        labelled[marker.landmark.name] = label
        markers[label] = marker
    for group, labels in _table(data, "any_of", path).items():
        if (not isinstance(labels, list) or not labels
                or any(label not in markers for label in labels)):
            raise ProtocolError(f"[any_of] {group!r} must list labels of this protocol's markers",
                                path=path, hint=f"got {labels!r}")
        groups[group] = tuple(labels)
    clashes = sorted(k for k, n in Counter(k for m in markers.values() for k in m.keys).items()
                     if n > 1)
    if clashes:
        raise ProtocolError(f"labels or aliases used twice: {', '.join(clashes)}", path=path)
    drafted = data.get("drafted", False)
    if not isinstance(drafted, bool):
        raise ProtocolError(f"drafted must be true or false, got {drafted!r}", path=path)
    return Protocol(str(data.get("name", path.stem)), str(data.get("description", "")),
                    tuple(markers.values()), os.fspath(path), tuple(groups.items()),
                    _fallback_starts(_table(data, "cycles", path), path, fallback), drafted)


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


def _position(value, key: str, path) -> tuple[float, float, float]:
    """A catalogue landmark's nominal position (x, y, z) m from a TOML file: three finite
    numbers within :data:`MAX_LANDMARK_OFFSET` of the segment's origin."""
    if not (isinstance(value, list) and len(value) == 3 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool)
            and abs(v) <= MAX_LANDMARK_OFFSET for v in value)):   # NaN fails the comparison
        raise ProtocolError(
            f"landmark {key!r}: position must be [x, y, z], three finite numbers in metres "
            f"within {MAX_LANDMARK_OFFSET:g} m of the segment's origin, got {value!r}",
            path=path, hint="write the landmark's place on its segment in metres for a "
                            f"{REFERENCE_HEIGHT:g} m subject, as protocols/landmarks.toml does")
    return tuple(float(v) for v in value)


def _weight(value, what: str, path) -> float:
    """A fit weight from a TOML file: a finite number > 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 1e6:
        raise ProtocolError(f"{what}: weight must be a number > 0, got {value!r}", path=path,
                            hint="1 is a typical skin marker; bony landmarks get more")
    return float(value)


