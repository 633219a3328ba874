"""Marker-set protocols: which lab label is which anatomical landmark, on which segment.

Files
-----
``protocols/landmarks.toml`` is the catalogue of anatomical landmarks: for each, the skeleton
segment it sits on and a nominal position in that segment's frame (metres, for a 1.75 m
subject, left side; the right side mirrors y). ``protocols/<name>.toml`` is one marker set:
``name``, ``description`` and a ``[markers]`` table mapping each label to a landmark::

    [markers]
    LASI = { landmark = "L_ASIS", required = true, aliases = ["L.ASIS", "LASIS"] }

Labels are compared after :func:`mocaplib.trial.normalise_label` (case, subject prefixes,
spaces, ``_ - .`` ignored). The folder is found at ``$MOCAPLIB_PROTOCOLS`` if set, otherwise the
copy installed with the package.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from .errors import ProtocolError
from .skeleton import SEGMENT_NAMES
from .trial import Trial, normalise_label

#: Height of the subject the catalogue's nominal positions are written for, metres.
REFERENCE_HEIGHT = 1.75


def protocols_dir() -> Path:
    """The folder holding ``landmarks.toml`` and the protocol files."""
    env = os.environ.get("MOCAPLIB_PROTOCOLS")
    if env:
        return Path(env)
    # mocaplib/data/protocols links to the repository's protocols/; wheels hold a copy.
    return Path(__file__).resolve().parent / "data" / "protocols"


@dataclass(frozen=True)
class Landmark:
    """One anatomical landmark: sided name (``L_ASIS``), segment, nominal position (3,) m."""

    name: str
    segment: str
    position: tuple[float, float, float]
    description: str


@dataclass(frozen=True)
class ProtocolMarker:
    """One marker of a protocol: its label, aliases, landmark and whether it is required."""

    label: str
    landmark: Landmark
    required: bool
    aliases: tuple[str, ...]

    @property
    def keys(self) -> tuple[str, ...]:
        """Normalised label and aliases this marker matches."""
        return tuple(dict.fromkeys(normalise_label(x) for x in (self.label, *self.aliases)))


@dataclass(frozen=True)
class Protocol:
    """A marker set: name, description, markers (in file order) and the file it came from."""

    name: str
    description: str
    markers: tuple[ProtocolMarker, ...]
    path: str

    @property
    def labels(self) -> list[str]:
        return [m.label for m in self.markers]

    @property
    def required(self) -> list[str]:
        return [m.label for m in self.markers if m.required]

    def marker(self, label: str) -> ProtocolMarker:
        for m in self.markers:
            if m.label == label:
                return m
        raise ProtocolError(f"protocol {self.name!r} has no marker {label!r}", path=self.path)

    def nominal_offsets(self, height: float = REFERENCE_HEIGHT) -> tuple[np.ndarray, np.ndarray]:
        """Segment index (M,) and nominal offset (M, 3) in metres of each marker, scaled."""
        segments = np.array([SEGMENT_NAMES.index(m.landmark.segment) for m in self.markers])
        offsets = np.array([m.landmark.position for m in self.markers]) * (
            height / REFERENCE_HEIGHT)
        return segments, offsets


@lru_cache(maxsize=None)
def _read_toml(path: str) -> dict:
    try:
        with open(path, "rb") as handle:
            return tomllib.load(handle)
    except FileNotFoundError:
        raise ProtocolError("file not found", path=path,
                            hint=f"protocols live in {protocols_dir()}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ProtocolError(f"not valid TOML: {exc}", path=path) from None


def load_landmarks(path: str | os.PathLike | None = None) -> dict[str, Landmark]:
    """The landmark catalogue, keyed by sided name (``L_ASIS``, ``R_ASIS``, ``C7``...)."""
    path = os.fspath(path or protocols_dir() / "landmarks.toml")
    out: dict[str, Landmark] = {}
    for key, spec in _read_toml(path).items():
        try:
            segment, position = spec["segment"], tuple(float(v) for v in spec["position"])
            sided, description = bool(spec.get("sided", False)), str(spec.get("description", ""))
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
            out[prefix + key] = Landmark(prefix + key, seg, (x, mirror * y, z), description)
    return out


def list_protocols() -> list[str]:
    """Names of the protocols shipped in :func:`protocols_dir` (files with a [markers] table)."""
    names = []
    for path in sorted(protocols_dir().glob("*.toml")):
        if "markers" in _read_toml(os.fspath(path)):
            names.append(path.stem)
    return names


def load_protocol(name_or_path: str | os.PathLike) -> Protocol:
    """Load a protocol by shipped name (``plugin_gait``) or by path to a TOML file."""
    path = Path(name_or_path)
    if path.suffix != ".toml":
        path = protocols_dir() / f"{name_or_path}.toml"
        if not path.is_file():
            raise ProtocolError(f"unknown protocol {os.fspath(name_or_path)!r}",
                                hint=f"shipped protocols: {', '.join(list_protocols())}")
    data = _read_toml(os.fspath(path))
    landmarks = load_landmarks()
    table = data.get("markers")
    if not isinstance(table, dict) or not table:
        raise ProtocolError("no [markers] table", path=path,
                            hint="map each label to a landmark: LASI = { landmark = \"L_ASIS\" }")
    markers = []
    for label, spec in table.items():
        spec = {"landmark": spec} if isinstance(spec, str) else spec
        name = spec.get("landmark") if isinstance(spec, dict) else None
        if name not in landmarks:
            raise ProtocolError(f"marker {label!r}: unknown landmark {name!r}", path=path,
                                hint="landmarks are listed in protocols/landmarks.toml")
        markers.append(ProtocolMarker(label, landmarks[name], bool(spec.get("required", False)),
                                      tuple(str(a) for a in spec.get("aliases", ()))))
    keys = [k for m in markers for k in m.keys]
    clashes = sorted({k for k in keys if keys.count(k) > 1})
    if clashes:
        raise ProtocolError(f"labels or aliases used twice: {', '.join(clashes)}", path=path)
    return Protocol(str(data.get("name", path.stem)), str(data.get("description", "")),
                    tuple(markers), os.fspath(path))


@dataclass(frozen=True)
class ProtocolMatch:
    """How a trial's markers map onto a protocol.

    ``indices[j]`` is the trial marker index of protocol marker ``j`` or -1 when absent.
    """

    protocol: Protocol
    indices: tuple[int, ...]
    missing: tuple[str, ...]
    missing_required: tuple[str, ...]

    @property
    def found(self) -> int:
        return sum(i >= 0 for i in self.indices)

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


def match_protocol(trial: Trial, protocol: Protocol) -> ProtocolMatch:
    """Map ``protocol``'s markers to ``trial``'s by normalised label (first occurrence wins)."""
    first: dict[str, int] = {}
    for i, name in enumerate(trial.names):
        first.setdefault(name, i)
    indices = []
    for m in protocol.markers:
        hit = next((first[k] for k in m.keys if k in first), -1)
        indices.append(hit)
    missing = tuple(m.label for m, i in zip(protocol.markers, indices) if i < 0)
    missing_required = tuple(m.label for m, i in zip(protocol.markers, indices)
                             if i < 0 and m.required)
    return ProtocolMatch(protocol, tuple(indices), missing, missing_required)
