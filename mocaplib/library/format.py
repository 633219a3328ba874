"""The motion library file: one locomotion cycle per entry, written as deterministic JSON.

A library holds, for every entry, the cycle's average velocities (v̂, ω̂, v̂_l, v̂_f) and the
Fourier coefficients of every degree of freedom of the fixed skeleton
(:data:`mocaplib.skeleton.DOF_NAMES`), with the quality metrics that justify keeping it.
The format is specified in ``docs/library-format.md`` and by the JSON Schema shipped as
``mocaplib/schema/library.schema.json``.

An entry's coordinates (:meth:`Library.angles`), ``t`` in seconds from the cycle start, period
``T`` s, ``tau = t mod T`` in [0, T)::

    q_d(t) = a[d, 0] + sum_{k=1..N} ( a[d, k] cos(2 pi k tau / T) + b[d, k] sin(2 pi k tau / T) )
             + ramp[d] tau / T

``a`` and ``b`` have shape ``(D, N + 1)``, ``b[:, 0] = 0``; ``ramp`` (D,) is 0 when the entry
stores none. Units are those of the DOF: radians, metres for ``pelvis_t*``. Root channels are
stored in the frame moving along the cycle's path; the per-cycle displacement of that frame is
stored apart (``root_drift``).

Files are deterministic: keys sorted, floats written with 10 significant digits, no time stamps,
so the same inputs and settings give byte-identical files. Files are written atomically and
carry ``content_sha256``, a checksum of their content (:func:`content_sha256`) that
:func:`validate_library` verifies.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .. import __version__
from ..errors import LibraryError
from ..gait.qc import DEFAULT_QC_THRESHOLDS, QC_NAMES, qc_failures
from ..io import read_regular
from ..io.atomic import atomic_write_text
from ..io.jsonvalues import (OutOfRange, canonical_sha256, float_or_nan, jcs_sha256, json_values,
                             parse_json)
from ..skeleton import DOFS
from .entry import DRIFT_DISPLACEMENT, DRIFT_VELOCITIES, LibraryEntry, drift_displacement

if TYPE_CHECKING:
    import pandas as pd

FORMAT = "mocaplib-library"
#: The version this mocaplib writes; it reads :data:`READ_VERSIONS` (docs/library-format.md,
#: *Versions*).
FORMAT_VERSION = 3
READ_VERSIONS = (1, 2, 3)
#: Versions whose ``content_sha256`` is :func:`mocaplib.io.jsonvalues.canonical_sha256` (numbers
#: as Python prints them); later versions carry :func:`mocaplib.io.jsonvalues.jcs_sha256`.
PYTHON_CHECKSUM_VERSIONS = (1, 2)
#: The ``format`` of a build's diagnostics sidecar (``<stem>.diagnostics.json``), not a library.
DIAGNOSTICS_FORMAT = "mocaplib-diagnostics"
CONTROL_AXES = ("v", "omega", "v_l")
CONTROL_UNITS = ("m/s", "rad/s", "m/s")
#: Largest |velocity| (m/s, rad/s) and |Fourier coefficient| (rad, or m for pelvis_t*) an entry
#: may have: far beyond any human locomotion, so only corrupt files are refused (and the control
#: space's geometry never overflows).
PLAUSIBLE_SPEED, PLAUSIBLE_COEFFICIENT = 100.0, 1000.0
FOURIER_FORMULA = ("q_d(t) = a[d][0] + sum_{k=1..N} (a[d][k] cos(2 pi k t / T) "
                   "+ b[d][k] sin(2 pi k t / T)), t in s from the cycle start")
ROOT_DRIFT_TEXT = ("displacement of the path frame over one cycle, expressed in the frame at the "
                   "cycle start: dx_m forward, dy_m left, dheading_rad counter-clockwise")
#: Largest difference between a stored root-drift displacement and the one its velocities and T
#: give (m, rad). Files store 10 significant digits: on the 68 samples and the 17 real files
#: (with and without --all-cycles) the two agree to 1.1e-9, so 1e-6 flags only edits.
DRIFT_TOLERANCE = 1e-6
#: An entry poulaine's parameters (m), read on its characteristic points; stored values must
#: agree with the points to this (m): stored with 10 significant digits they agree to 1e-10.
POULAINE_PARAMETERS = ("step_length_m", "foot_spacing_m", "stance_m")
POULAINE_TOLERANCE = 1e-6
#: Turn rates (rad/s) above which an entry's ω̂ and its root drift's ω must share a sign. ω̂
#: follows the shoulder line, the drift the pelvis: on those files they differ by up to 0.11
#: rad/s (running.c3d), and opposite signs occur only where the smaller is at most 0.039 rad/s
#: (BTS.c3d with --all-cycles), 5 times below this.
TURN_SIGN_RATE = 0.2

_SIGNIFICANT = 10
#: The top-level key of the content checksum (:func:`content_sha256`).
CHECKSUM_KEY = "content_sha256"
#: Largest library file read (bytes): 68 entries take 1.3 MB, so this is room for about
#: 100,000 entries, and a link to an endless file cannot exhaust the memory.
MAX_LIBRARY_BYTES = 2 << 30


@dataclass(frozen=True)
class Problem:
    """One reason a library is invalid: ``where`` (a JSON path such as ``entries[3].T``) and why."""

    where: str
    message: str

    def __str__(self) -> str:
        return f"{self.where}: {self.message}"


def assemble_library(entries: list[LibraryEntry], *, settings: dict,
                     qc_thresholds: dict | None = None) -> "Library":
    """A library of ``entries``, sorted by id, their numbers as the file stores them (10
    significant digits).

    The header's segment lengths are the per-length median over entries (or the nominal
    1.75 m skeleton's when no entry carries lengths), its joint shifts the per-segment median
    over the entries that carry them; the Fourier order N is the largest
    entry order and smaller orders are zero-padded (exact); control-space scales are
    :func:`control_scale`.
    """
    from ..skeleton import Skeleton

    entries = sorted((LibraryEntry.from_json(to_json_data(e.to_json())) for e in entries),
                     key=lambda e: e.id)
    n_max = max((e.fourier.n for e in entries), default=0)
    entries = [replace(e, fourier=e.fourier.padded(n_max)) for e in entries]
    lengths = [e.segment_lengths_m for e in entries if e.segment_lengths_m]
    if lengths:
        segment_lengths = {k: float(np.median([lens[k] for lens in lengths])) for k in lengths[0]}
    else:
        segment_lengths = Skeleton.from_height(1.75).lengths
    shifts = [e.joint_shifts_m for e in entries if e.joint_shifts_m]
    joint_shifts = {name: np.median([s[name] for s in shifts if name in s], axis=0).tolist()
                    for name in sorted({name for s in shifts for name in s})}
    doc = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "tool_version": __version__,
        "settings": settings,
        "skeleton": {
            "dof_names": [d.name for d in DOFS],
            "dof_units": ["m" if d.translation else "rad" for d in DOFS],
            # null = unbounded: the root's rotation, and its position (the solver's ±1000 m
            # guard is no joint limit)
            "dof_ranges": [[None, None] if d.translation else [d.lower, d.upper] for d in DOFS],
            "segment_lengths_m": segment_lengths,
            **({"joint_shifts_m": joint_shifts} if joint_shifts else {}),
        },
        "fourier": {"formula": FOURIER_FORMULA, "time_origin": "cycle_start",
                    "n_harmonics": n_max, "coefficient_shape": "D x (N+1)",
                    "root_drift": ROOT_DRIFT_TEXT},
        "control_space": {"axes": list(CONTROL_AXES), "units": list(CONTROL_UNITS),
                          "scale": control_scale(), "normalised": "x / scale",
                          "alternative_axes": ["v_f", "omega", "v_l"]},
        "qc_thresholds": dict(DEFAULT_QC_THRESHOLDS if qc_thresholds is None else qc_thresholds),
        "entries": [e.to_json() for e in entries],
    }
    doc = to_json_data(doc)
    doc[CHECKSUM_KEY] = content_sha256(doc)
    return Library(doc)


def control_scale() -> list[float]:
    """Normalisation scales of (v, omega, v_l): :data:`mocaplib.library.controlspace.DEFAULT_SCALE`.

    Fixed, not derived from the entries, so adding a capture does not re-shape the
    triangulation of the others.
    """
    from .controlspace import DEFAULT_SCALE

    return [float(DEFAULT_SCALE[axis]) for axis in CONTROL_AXES]


def _control_points(entries: list[dict]) -> np.ndarray:
    return np.array([[float_or_nan(e[axis]) for axis in CONTROL_AXES] for e in entries],
                    dtype=np.float64).reshape(-1, 3)


# --------------------------------------------------------------------------- the Library
class Library:
    """A motion library in memory: the JSON document, its entries and array and table views.

    Attributes
    ----------
    document : dict
        The file's content as JSON data (see ``docs/library-format.md``).
    entries : list[LibraryEntry]
        The entries (:class:`mocaplib.library.entry.LibraryEntry`), in the file's order (by id).
    table : DataFrame
        One row per entry, index ``id``; columns ``locomotion_class, source_file,
        source_sha256, cycle_index, chosen, mirrored, mirror_of, start_s, end_s, T,
        pattern_type, pattern_residual_m, arc_angle_rad, v, omega, v_l, v_f, fourier_n`` and
        one ``qc_<metric>`` column per QC metric, the poulaine's ``step_length_m,
        foot_spacing_m, stance_m`` and ``poulaine_fit_rms_m`` (the larger of the two ankles' fit
        errors; all NaN for an entry without a poulaine), and ``qc_waived`` (comma-separated
        metric names).
    """

    def __init__(self, document: dict, *, file_sha256: str | None = None):
        self.document = document
        #: SHA-256 of the file's bytes when read by :func:`load_library` (None: built in
        #: memory); a build's diagnostics sidecar names the library it belongs to by it.
        self.file_sha256 = file_sha256

    # ------------------------------------------------------------------ views
    @property
    def skeleton(self):
        """The header's :class:`~mocaplib.skeleton.Skeleton`: the entries' median lengths and
        joint shifts."""
        from ..skeleton import Skeleton

        header = self.document["skeleton"]
        return Skeleton(header["segment_lengths_m"], header.get("joint_shifts_m", {}))

    def entry_skeleton(self, entry_id: str):
        """The :class:`~mocaplib.skeleton.Skeleton` of the subject of entry ``entry_id``: its
        own segment lengths and joint shifts when it records them, the header's otherwise."""
        from ..skeleton import Skeleton

        entry, header = self.entry(entry_id), self.document["skeleton"]
        return Skeleton(entry.segment_lengths_m or header["segment_lengths_m"],
                        entry.joint_shifts_m or header.get("joint_shifts_m", {}))

    @property
    def dof_names(self) -> list[str]:
        return list(self.document["skeleton"]["dof_names"])

    @property
    def n_harmonics(self) -> int:
        return int(self.document["fourier"]["n_harmonics"])

    @property
    def settings(self) -> dict:
        return self.document["settings"]

    @property
    def control_scale(self) -> np.ndarray:
        """Normalisation scales of (v, omega, v_l), shape (3,): normalised = value / scale."""
        return np.asarray(self.document["control_space"]["scale"], dtype=np.float64)

    @cached_property
    def entries(self) -> list[LibraryEntry]:
        return [LibraryEntry.from_json(e) for e in self.document["entries"]]

    @cached_property
    def _by_id(self) -> dict[str, LibraryEntry]:
        return {e.id: e for e in self.entries}

    @cached_property
    def table(self) -> pd.DataFrame:
        import pandas as pd  # here: reading and writing a library need no pandas

        rows = []
        for e in self.entries:
            row = {"id": e.id, "locomotion_class": e.locomotion_class,
                   "source_file": e.source_file, "source_sha256": e.source_sha256,
                   "cycle_index": e.cycle_index, "chosen": bool(e.chosen),
                   "mirrored": e.mirrored, "mirror_of": e.mirror_of,
                   "start_s": float_or_nan(e.start_s), "end_s": float_or_nan(e.end_s),
                   "T": float_or_nan(e.T),
                   "pattern_type": e.pattern.type,
                   "pattern_residual_m": float_or_nan(e.pattern.residual_m),
                   "arc_angle_rad": float_or_nan(e.pattern.arc_angle_rad),
                   **{key: float_or_nan(getattr(e, key)) for key in ("v", "omega", "v_l", "v_f")},
                   "fourier_n": int(e.fourier.n),
                   **{f"qc_{name}": float_or_nan(e.qc.get(name)) for name in QC_NAMES},
                   **{key: float_or_nan(getattr(e.poulaine, key, None))
                      for key in POULAINE_PARAMETERS},
                   "poulaine_fit_rms_m": math.nan if e.poulaine is None else max(
                       float_or_nan(e.poulaine.left.fit_rms_m), float_or_nan(e.poulaine.right.fit_rms_m)),
                   "qc_waived": ",".join(sorted(e.qc_waived))}
            rows.append(row)
        columns = ["id", "locomotion_class", "source_file", "source_sha256", "cycle_index",
                   "chosen", "mirrored", "mirror_of", "start_s", "end_s", "T", "pattern_type",
                   "pattern_residual_m", "arc_angle_rad", "v", "omega", "v_l", "v_f", "fourier_n",
                   *(f"qc_{name}" for name in QC_NAMES), *POULAINE_PARAMETERS,
                   "poulaine_fit_rms_m", "qc_waived"]
        return pd.DataFrame(rows, columns=columns).set_index("id")

    def __len__(self) -> int:
        return len(self.document["entries"])

    def __repr__(self) -> str:
        return (f"<Library {len(self)} entries, {len(self.dof_names)} DOFs, "
                f"N={self.n_harmonics}, mocaplib {self.document['tool_version']}>")

    def entry(self, entry_id: str) -> LibraryEntry:
        """The entry ``entry_id``; LibraryError naming the ids when there is none."""
        try:
            return self._by_id[entry_id]
        except KeyError:
            raise LibraryError(f"no entry {entry_id!r} in the library",
                               hint=f"ids are: {', '.join(list(self._by_id)[:20])}") from None

    def coefficients(self, entry_id: str) -> tuple[np.ndarray, np.ndarray]:
        """Fourier ``a`` and ``b`` of one entry, each shape (D, N+1), DOF units (copies)."""
        fourier = self.entry(entry_id).fourier
        return fourier.a.copy(), fourier.b.copy()

    def coefficient_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Stacked ``a`` and ``b`` of every entry in ``entries`` order, each (E, D, N+1)."""
        shape = (len(self), len(self.dof_names), self.n_harmonics + 1)
        if not len(self):
            return np.zeros(shape), np.zeros(shape)
        return (np.stack([e.fourier.a for e in self.entries]),
                np.stack([e.fourier.b for e in self.entries]))

    def poulaine(self, entry_id: str):
        """The entry's :class:`mocaplib.gait.poulaine.Poulaine`, or None when it has none (a rest
        entry, or a library written before poulaines were stored)."""
        data = self.entry(entry_id).poulaine
        return None if data is None else data.model()

    def root_drift(self, entry_id: str):
        """The entry's path frame as a :class:`mocaplib.gait.fourier.RootDrift` starting at the
        origin facing +X: ``root_drift(e).restore(angles(e, t), t)`` puts the cycle in that
        world frame."""
        from ..gait.fourier import RootDrift

        drift = self.entry(entry_id).root_drift
        return RootDrift(0.0, 0.0, 0.0, *(float_or_nan(getattr(drift, key))
                                          for key in DRIFT_VELOCITIES))

    def angles(self, entry_id: str, t: np.ndarray) -> np.ndarray:
        """The entry's coordinates at times ``t``: the captured cycle
        (:class:`mocaplib.gait.fourier.CycleEncoding`), periodic with period T.

        With ``tau = t mod T`` in [0, T) (``t`` outside [0, T) repeats the cycle)::

            q_d(t) = a[d, 0] + sum_{k=1..N} (a[d, k] cos(2 pi k tau / T)
                                             + b[d, k] sin(2 pi k tau / T)) + ramp[d] tau / T

        ``ramp`` (``fourier.ramp``, the DOF's change from the cycle's start to its end) is 0
        when not stored. Over several cycles the ramp restarts with each: the value steps by
        ``-ramp[d]`` at every t = kT (just before T it is ``q_d(0) + ramp[d]``, at T
        ``q_d(0)``). The series alone (ramp left out) is the closed cycle blending uses; the
        captured trend over K cycles (a stair's rise) adds ``k·ramp[d]`` in cycle k.

        Parameters
        ----------
        entry_id : str
            The entry's id.
        t : ndarray, any shape
            Seconds from the cycle's start.

        Returns
        -------
        ndarray, shape (*t.shape, D)
            Joint coordinates in :attr:`dof_names` order: radians, the root's translations in
            metres, the root in the cycle's path frame (see :meth:`root_drift`).

        Raises
        ------
        LibraryError
            No entry ``entry_id``.
        """
        from ..gait.fourier import synthesize

        entry = self.entry(entry_id)
        fourier, period = entry.fourier, float_or_nan(entry.T)
        tau = np.mod(np.asarray(t, dtype=float), period)
        tau = np.where(tau < period, tau, 0.0)  # mod rounds a tiny negative t up to T
        return synthesize(fourier.a, fourier.b, period, tau) + (
            0.0 if fourier.ramp is None else np.multiply.outer(tau / period, fourier.ramp))

    # ------------------------------------------------------------------ output
    def to_json(self) -> str:
        """The file's text: deterministic (sorted keys, 10 significant digits), with its
        :func:`content_sha256` (recomputed), ends with a newline."""
        data = to_json_data({k: v for k, v in self.document.items() if k != CHECKSUM_KEY})
        data[CHECKSUM_KEY] = content_sha256(data)
        return _dump(data) + "\n"

    def write(self, path: str | os.PathLike) -> Path:
        """Write the library atomically (:meth:`to_json`).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write; a file already there is replaced only once the new one is
            complete.

        Returns
        -------
        Path
            The path written.
        """
        return atomic_write_text(path, self.to_json())


def _matrix(rows) -> np.ndarray:
    return np.array([[float_or_nan(x) for x in row] for row in rows], dtype=np.float64)


def diagnostics_path(library_path: str | os.PathLike) -> Path:
    """Where the diagnostics sidecar of a library file goes: ``<stem>.diagnostics.json``."""
    path = Path(library_path)
    return path.with_name(f"{path.stem}.diagnostics.json")


# --------------------------------------------------------------------------- reading
def load_library(path: str | os.PathLike) -> Library:
    """Read a library file.

    The file is checked for numbers JSON cannot hold (NaN, Infinity), against the schema and
    for what would make its numbers unusable (coefficient shapes, non-finite or implausible
    values, periods), so a table built from it can be trusted. A QC metric over its threshold,
    fields that disagree with each other or a degenerate control space do not prevent loading:
    run :func:`validate_library` for those.

    Parameters
    ----------
    path : str or os.PathLike
        The library JSON file.

    Returns
    -------
    Library
        The entries, skeleton, settings and control-space scale of the file.

    Raises
    ------
    LibraryError
        The file is not a valid library; the message names the file and each problem.
    """
    document, sha256 = _read_document(path)
    problems = _structure_problems(document) or _named(document, _skeleton_problems(document)
                                                       + _entry_problems(document, qc=False))
    if problems:
        raise LibraryError(f"not a valid mocaplib library: {problems[0]}"
                           + (f" (and {len(problems) - 1} more problems)" if len(problems) > 1
                              else ""), path=path, hint="run `mocaplib validate` on it")
    return Library(document, file_sha256=sha256)


def _read_document(path: str | os.PathLike) -> tuple[object, str]:
    """The file's JSON data (:func:`mocaplib.io.jsonvalues.parse_json`: NaN, ±Infinity and
    numbers beyond a double are read as floats, for :func:`_non_finite_problems` to name where
    they are) and the SHA-256 of its bytes."""
    hint = "a library is a JSON file written by `mocaplib build`"
    try:
        data = read_regular(path, limit=MAX_LIBRARY_BYTES)
    except OSError as exc:
        raise LibraryError(f"cannot read library: {exc.strerror}", path=path,
                           hint="check the path") from exc
    try:
        document = parse_json(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise LibraryError("library is not UTF-8 text", path=path, hint=hint) from exc
    except json.JSONDecodeError as exc:
        raise LibraryError(f"library is not valid JSON: {exc.msg} at line {exc.lineno}",
                           path=path, hint=hint) from exc
    except ValueError as exc:
        raise LibraryError(f"library is not a mocaplib library: {exc}", path=path,
                           hint=hint) from None
    if isinstance(document, dict) and document.get("format") == DIAGNOSTICS_FORMAT:
        library = document.get("library")
        raise LibraryError("this is a build's diagnostics sidecar, not a library", path=path,
                           hint=f"give the library beside it"
                                f"{f', {library}' if isinstance(library, str) else ''}")
    return document, hashlib.sha256(data).hexdigest()


def schema() -> dict:
    """The JSON Schema (draft 2020-12) of library files, as shipped in the package."""
    from importlib import resources  # here: only validation reads the schema

    text = resources.files("mocaplib").joinpath("schema/library.schema.json").read_text("utf-8")
    return json.loads(text)


# --------------------------------------------------------------------------- validation
#: Parameters of each pattern type (``entries[i].pattern.parameters``).
PATTERN_PARAMETERS = {"line": ("direction", "length", "point"),
                      "arc": ("centre", "length", "radius", "turn"),
                      "point": ("length", "point")}
#: How far (rad) an angle DOF's mean ``a[d][0]`` may lie outside its ``dof_ranges``: rounding
#: only. The fitted angles stay within the ranges, so does their mean: the closest measured is
#: 0.88 deg inside (17 real files), so a mean outside is a unit slip (degrees stored as rad).
RANGE_TOLERANCE = 1e-6


def validate_library(library) -> list[Problem]:
    """Schema and semantic problems of a library (path, JSON dict or :class:`Library`).

    Checks, after the numbers (no NaN or Infinity: JSON has none) and the schema: DOF names
    unique, units/ranges one per DOF, ranges lo <= hi; every entry's coefficients of shape
    (D, N+1) with N the header's, finite, ``b[:, 0] = 0``, zero beyond the entry's ``n``, each
    angle DOF's mean ``a[d][0]`` within its range; ``T > 0`` and ``end_s - start_s = T``
    (1 ms); velocities finite; ids unique and ``cycle_index`` the id's ``_c<k>``; the pattern's
    parameters those of its type; the root drift's displacement the one its velocities give
    over T, its turn rate of the entry's ω̂'s sign; a poulaine's phases in order, speed
    profiles rising and parameters those of its characteristic points; the chosen entries' normalised
    (v, omega, v_l) points not degenerate (:func:`mocaplib.library.triangulation.degeneracy`: the rule
    the control space uses); every QC metric within ``qc_thresholds`` or listed in the
    entry's ``qc_waived`` with a reason.

    Parameters
    ----------
    library : str, os.PathLike, dict or Library
        A library file, its parsed JSON document, or a loaded :class:`Library`.

    Returns
    -------
    list of Problem
        Every problem found, each with the JSON path it is at; empty for a valid library.
    """
    if isinstance(library, Library):
        document = library.document
    elif isinstance(library, dict):
        document = library
    else:
        try:
            document, _ = _read_document(library)
        except LibraryError as exc:
            return [Problem("file", exc.message if not exc.hint else
                            f"{exc.message} ({exc.hint})")]
    problems = _structure_problems(document)
    if problems:
        return problems
    return _named(document, _checksum_problems(document) + _skeleton_problems(document)
                  + _entry_problems(document) + _consistency_problems(document)
                  + _control_space_problems(document))


def content_sha256(document: dict) -> str:
    """The library's content checksum, the one its ``format_version`` carries: SHA-256 of the
    RFC 8785 (JCS) form of the document without ``content_sha256``
    (:func:`mocaplib.io.jsonvalues.jcs_sha256`), or for versions
    :data:`PYTHON_CHECKSUM_VERSIONS` of its Python-printed canonical JSON
    (:func:`mocaplib.io.jsonvalues.canonical_sha256`). Reformatting a file keeps it; changing
    a value, a key or an entry changes it. Raises ValueError for content JCS cannot hold
    (NaN, ±inf)."""
    content = {k: v for k, v in document.items() if k != CHECKSUM_KEY}
    if document.get("format_version") in PYTHON_CHECKSUM_VERSIONS:
        return canonical_sha256(content)
    return jcs_sha256(content)


def checksum_status(library) -> str | None:
    """Whether a library (path, JSON dict or :class:`Library`) is the content it was written
    with: ``"verified"`` (its stored :func:`content_sha256` matches), ``"mismatch"`` (it was
    changed after it was written), ``"absent"`` (no checksum: written by a mocaplib that did
    not store one, or built in memory by another tool); None when it is no library document
    (not an object of format ``mocaplib-library``). Raises :class:`LibraryError` for a file
    that cannot be read as JSON."""
    document = library.document if isinstance(library, Library) else (
        library if isinstance(library, dict) else _read_document(library)[0])
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        return None
    stored = document.get(CHECKSUM_KEY)
    if stored is None:
        return "absent"
    try:
        computed = content_sha256(document)
    except ValueError:              # NaN or infinity: never in a file mocaplib wrote
        return "mismatch"
    return "verified" if stored == computed else "mismatch"


#: What a library without a checksum is told (``mocaplib validate``, the report).
NO_CHECKSUM_NOTE = ("no content checksum (written by a mocaplib that did not store one): its "
                    "integrity cannot be checked; build it again to add one")


def _checksum_problems(document: dict) -> list[Problem]:
    if checksum_status(document) != "mismatch":
        return []
    return [Problem(CHECKSUM_KEY, "the content does not match the checksum the file was "
                                  "written with: it was changed after `mocaplib build` wrote "
                                  "it (by hand or by another tool), so its values cannot be "
                                  "trusted; build it again")]


def _structure_problems(document) -> list[Problem]:
    """Numbers JSON cannot hold, then the schema's problems."""
    return _named(document, _non_finite_problems(document) + _schema_problems(document))


def _non_finite_problems(document) -> list[Problem]:
    """Every NaN or ±Infinity (read from the non-standard JSON tokens), in document order."""
    problems, stack = [], [((), document)]
    while stack:
        parts, value = stack.pop()
        if isinstance(value, dict):
            stack += [((*parts, key), item) for key, item in reversed(value.items())]
        elif isinstance(value, list):
            stack += [((*parts, i), item) for i, item in reversed(list(enumerate(value)))]
        elif isinstance(value, OutOfRange):
            problems.append(Problem(_json_path(parts), "a number beyond the range of a double "
                                    "(±1.8e308): no reader can hold it"))
        elif isinstance(value, float) and not math.isfinite(value):
            token = "NaN" if value != value else "Infinity" if value > 0 else "-Infinity"
            problems.append(Problem(_json_path(parts), f"{token} is not a JSON number (JSON "
                                    "readers such as nlohmann::json and System.Text.Json "
                                    "refuse the file): write null for a number that could "
                                    "not be computed"))
    return problems


def _schema_problems(document) -> list[Problem]:
    from jsonschema import Draft202012Validator

    validator = Draft202012Validator(schema())
    errors = sorted((_specific(error) for error in validator.iter_errors(document)),
                    key=lambda e: list(map(str, e.absolute_path)))
    return [Problem(_json_path(error.absolute_path), f"schema: {error.message[:300]}")
            for error in errors]


def _specific(error):
    """The error of an ``anyOf`` branch the value's type matches ("2.0 is greater than the
    maximum of 1" rather than "2.0 is not valid under any of the given schemas"): the schema
    writes a nullable number as anyOf number or null; ``error`` itself when there is none."""
    from jsonschema.exceptions import best_match

    specific = [e for e in error.context or () if e.relative_path or e.validator != "type"]
    return _specific(best_match(specific)) if specific else error


def _json_path(parts) -> str:
    text = ""
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text or "(document)"


def _named(document, problems: list[Problem]) -> list[Problem]:
    """``problems`` with the entry's id before the message of those about an entry."""
    entries = document.get("entries") if isinstance(document, dict) else None
    named = []
    for problem in problems:
        found = re.match(r"entries\[(\d+)\]", problem.where)
        i = int(found.group(1)) if found else -1
        if (isinstance(entries, list) and 0 <= i < len(entries)
                and isinstance(entries[i], dict) and isinstance(entries[i].get("id"), str)):
            problem = Problem(problem.where, f"entry {entries[i]['id']!r}: {problem.message}")
        named.append(problem)
    return named


def _skeleton_problems(doc: dict) -> list[Problem]:
    skel = doc["skeleton"]
    names = skel["dof_names"]
    problems = []
    if len(set(names)) != len(names):
        dupes = sorted({n for n in names if names.count(n) > 1})
        problems.append(Problem("skeleton.dof_names", f"duplicate DOF names: {dupes}"))
    for key in ("dof_units", "dof_ranges"):
        if len(skel[key]) != len(names):
            problems.append(Problem(f"skeleton.{key}",
                                    f"{len(skel[key])} items for {len(names)} DOFs"))
    return problems


def _entry_problems(doc: dict, *, qc: bool = True) -> list[Problem]:
    """Problems of the entries: ids, coefficients, periods, velocities and (``qc``) QC."""
    n_dof = len(doc["skeleton"]["dof_names"])
    n_harm = doc["fourier"]["n_harmonics"]
    thresholds = doc["qc_thresholds"]
    problems = []
    seen: set[str] = set()
    for i, e in enumerate(doc["entries"]):
        where = f"entries[{i}]"
        if e["id"] in seen:
            problems.append(Problem(f"{where}.id", f"duplicate id {e['id']!r}"))
        seen.add(e["id"])
        problems += _fourier_problems(e["fourier"], f"{where}.fourier", n_dof, n_harm)
        period = float_or_nan(e["T"])
        if not (math.isfinite(period) and period > 0):
            problems.append(Problem(f"{where}.T", f"period must be finite and > 0, got {period}"))
        elif abs((e["end_s"] - e["start_s"]) - period) > 1e-3:
            problems.append(Problem(f"{where}.T", f"T = {period} s but end_s - start_s = "
                                                  f"{e['end_s'] - e['start_s']} s"))
        for key in ("v", "omega", "v_l", "v_f"):
            if not math.isfinite(float_or_nan(e[key])):
                problems.append(Problem(f"{where}.{key}", "velocity is missing or not finite"))
            elif abs(float_or_nan(e[key])) > PLAUSIBLE_SPEED:
                problems.append(Problem(f"{where}.{key}", f"velocity {e[key]} is not a "
                                                          f"locomotion's (|value| > "
                                                          f"{PLAUSIBLE_SPEED:g})"))
        for failure in qc_failures(e["qc"], thresholds, e["qc_waived"]) if qc else ():
            problems.append(Problem(f"{where}.qc", f"{failure} (fix the capture, or waive it "
                                                   f"with a reason in qc_waived)"))
    return problems


def _fourier_problems(fourier: dict, where: str, n_dof: int, n_harm: int) -> list[Problem]:
    problems = []
    a, b = fourier["a"], fourier["b"]
    for key, rows in (("a", a), ("b", b)):
        if len(rows) != n_dof or any(len(row) != n_harm + 1 for row in rows):
            shape = (len(rows), sorted({len(row) for row in rows}))
            problems.append(Problem(f"{where}.{key}", f"coefficients must be {n_dof} rows of "
                                                      f"{n_harm + 1}, got {shape}"))
            return problems
        values = _matrix(rows)
        if not np.isfinite(values).all():
            problems.append(Problem(f"{where}.{key}", "coefficients contain null or non-finite "
                                                      "values"))
        elif np.abs(values).max(initial=0.0) > PLAUSIBLE_COEFFICIENT:
            problems.append(Problem(f"{where}.{key}", f"coefficients beyond "
                                                      f"±{PLAUSIBLE_COEFFICIENT:g} (rad or m) "
                                                      "are not a joint's"))
        elif np.any(values[:, int(fourier["n"]) + 1:]):
            problems.append(Problem(f"{where}.{key}", f"harmonics beyond the fitted order n = "
                                                      f"{fourier['n']} must be 0 (padding)"))
    ramp = fourier.get("ramp")
    if ramp is not None and (len(ramp) != n_dof or not np.isfinite(_matrix([ramp])).all()):
        problems.append(Problem(f"{where}.ramp", f"must be {n_dof} finite numbers (one per "
                                                 f"DOF), got {len(ramp)}"))
    if any(row[0] not in (0, 0.0) for row in b):
        problems.append(Problem(f"{where}.b", "b[:, 0] must be 0 (there is no sin(0) term)"))
    if fourier["n"] > n_harm:
        problems.append(Problem(f"{where}.n", f"fitted order {fourier['n']} exceeds the "
                                              f"library's n_harmonics {n_harm}"))
    return problems


def _consistency_problems(doc: dict) -> list[Problem]:
    """Fields that must agree with each other or lie in their documented ranges: what a hand
    edit or a unit slip breaks while the schema still holds."""
    skel = doc["skeleton"]
    ranges = [[-math.inf if lo is None else lo, math.inf if hi is None else hi]
              for lo, hi in skel["dof_ranges"]]
    problems = [Problem(f"skeleton.dof_ranges[{d}]", f"{name}: lower limit {lo} > upper {hi}")
                for d, (name, (lo, hi)) in enumerate(zip(skel["dof_names"], ranges)) if lo > hi]
    angles = [(d, name, lo, hi) for d, (name, unit, (lo, hi))
              in enumerate(zip(skel["dof_names"], skel["dof_units"], ranges)) if unit == "rad"]
    ids = [e["id"] for e in doc["entries"]]
    if ids != sorted(ids):
        first = next(i for i in range(1, len(ids)) if ids[i] < ids[i - 1])
        problems.append(Problem(f"entries[{first}].id", f"entries must be sorted by id: "
                                                        f"{ids[first]!r} follows "
                                                        f"{ids[first - 1]!r}"))
    for i, e in enumerate(doc["entries"]):
        where = f"entries[{i}]"
        found = re.search(r"_c(\d+)(@[0-9a-f]+)?$", e["id"])
        if found and int(found.group(1)) != e["cycle_index"]:
            problems.append(Problem(f"{where}.cycle_index", f"{e['cycle_index']}, but the id "
                                                            f"names cycle {found.group(1)}"))
        if re.search(r"[/\\]", e["source_file"]):
            problems.append(Problem(f"{where}.source_file", "must be a file name, without "
                                                            "its folder"))
        if e.get("mirror_of") == e["id"]:
            problems.append(Problem(f"{where}.mirror_of", "an entry cannot be its own mirror "
                                                          "image"))
        for key in ("right_toe_off_s", "left_toe_off_s"):
            toe_off = e.get(key)
            if toe_off is not None and math.isfinite(float_or_nan(e["T"])) \
                    and not toe_off < e["T"]:
                problems.append(Problem(f"{where}.{key}", f"{toe_off} s is not inside the "
                                                          f"cycle of T = {e['T']} s"))
        problems += _pattern_problems(e["pattern"], f"{where}.pattern")
        problems += _drift_problems(e, f"{where}.root_drift")
        if e.get("poulaine") is not None:
            problems += _poulaine_problems(e["poulaine"], f"{where}.poulaine")
        rows = e["fourier"]["a"]
        for d, name, lo, hi in angles if len(rows) == len(skel["dof_names"]) else ():
            mean = float_or_nan(rows[d][0]) if rows[d] else math.nan
            if not lo - RANGE_TOLERANCE <= mean <= hi + RANGE_TOLERANCE and math.isfinite(mean):
                problems.append(Problem(f"{where}.fourier.a[{d}][0]", f"mean {name} {mean:.6g} "
                                        f"rad lies outside its range [{lo:.4g}, {hi:.4g}] rad "
                                        "(degrees stored as radians?)"))
    return problems


def _pattern_problems(pattern: dict, where: str) -> list[Problem]:
    """The parameters of the pattern's type (:data:`PATTERN_PARAMETERS`) and their values."""
    kind, params = pattern["type"], pattern["parameters"]
    if sorted(params) != list(PATTERN_PARAMETERS[kind]):
        return [Problem(f"{where}.parameters", f"the parameters of {kind} patterns are "
                                               f"{', '.join(PATTERN_PARAMETERS[kind])}; got "
                                               f"{', '.join(sorted(params)) or 'none'}")]
    problems = []
    for key in sorted(set(params) & {"centre", "direction", "point"}):
        xy = params[key]
        if not (isinstance(xy, list) and len(xy) == 2 and all(map(_is_number, xy))):
            problems.append(Problem(f"{where}.parameters.{key}", f"must be [x, y], got {xy!r}"))
        elif key == "direction" and abs(math.hypot(*xy) - 1.0) > 1e-6:
            # stored to 10 digits, the unit vectors of the files at hand are within 7e-11 of 1
            problems.append(Problem(f"{where}.parameters.direction", f"must be a unit vector, "
                                                                     f"its length is "
                                                                     f"{math.hypot(*xy):.6g}"))
    if not (_is_number(params["length"]) and params["length"] >= 0):
        problems.append(Problem(f"{where}.parameters.length", f"must be a number of metres "
                                                              f">= 0, got {params['length']!r}"))
    if "radius" in params and not (_is_number(params["radius"]) and params["radius"] > 0):
        problems.append(Problem(f"{where}.parameters.radius", f"must be a number of metres "
                                                              f"> 0, got {params['radius']!r}"))
    if kind == "arc" and not (_is_number(params["turn"]) and params["turn"] in (1, -1)):
        problems.append(Problem(f"{where}.parameters.turn", f"must be 1 (counter-clockwise) "
                                                            f"or -1, got {params['turn']!r}"))
    return problems


def _drift_problems(e: dict, where: str) -> list[Problem]:
    """The root drift's displacement against its velocities over T, and its turn's sign."""
    drift, period = e["root_drift"], float_or_nan(e["T"])
    problems = []
    if math.isfinite(period):
        expected = drift_displacement(drift, period)
        wrong = [key for key in DRIFT_DISPLACEMENT if not abs(drift[key] - expected[key])
                 <= DRIFT_TOLERANCE * max(1.0, abs(expected[key]))]
        if wrong:
            problems.append(Problem(where, "the displacement does not follow from u_f_m_s, "
                                           f"u_l_m_s, omega_rad_s over T = {period} s: " +
                                           ", ".join(f"{k} {drift[k]:.6g}, expected "
                                                     f"{expected[k]:.6g}" for k in wrong)))
    omega, turn = float_or_nan(e["omega"]), drift["omega_rad_s"]
    if min(abs(omega), abs(turn)) > TURN_SIGN_RATE and omega * turn < 0:
        problems.append(Problem(f"{where}.omega_rad_s", f"{turn:.4g} rad/s turns the other way "
                                                        f"from the entry's omega {omega:.4g} "
                                                        "rad/s (a sign flipped?)"))
    return problems


def _poulaine_problems(poulaine: dict, where: str) -> list[Problem]:
    """Phases in order, speed profiles rising, rows of one length, and the stored parameters
    those of the characteristic points."""
    from ..gait.poulaine import Poulaine

    problems = []
    for side in ("left", "right"):
        path = poulaine[side]
        if any(b < a for a, b in zip(path["phases"], path["phases"][1:])):
            problems.append(Problem(f"{where}.{side}.phases", "must increase: the points are "
                                                              "stored in the order they occur"))
        if len({len(row) for row in path["timing"]}) > 1 or any(
                b < a for row in path["timing"] for a, b in zip(row, row[1:])):
            problems.append(Problem(f"{where}.{side}.timing", "every segment's speed profile "
                                                              "must rise from 0 to 1, with as "
                                                              "many knots as the others'"))
    if problems:
        return problems
    computed = dict(zip(POULAINE_PARAMETERS, Poulaine.from_dict(poulaine).parameters))
    wrong = [key for key in POULAINE_PARAMETERS
             if not abs(poulaine[key] - computed[key]) <= POULAINE_TOLERANCE]
    if wrong:
        problems.append(Problem(where, "parameters that are not those of its characteristic "
                                       "points: " + ", ".join(f"{k} {poulaine[k]:.6g}, the "
                                                              f"points give {computed[k]:.6g}"
                                                              for k in wrong)))
    return problems


def _is_number(value) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _control_space_problems(doc: dict) -> list[Problem]:
    """The chosen entries' control space, as :class:`mocaplib.library.controlspace.ControlSpace`
    builds it for queries: degenerate (:func:`~mocaplib.library.triangulation.degeneracy`), or failing
    to triangulate."""
    from .triangulation import DEGENERACY_HINT, degeneracy, delaunay_tetrahedra

    points = _control_points([e for e in doc["entries"] if e.get("chosen", True)])
    points = points[np.isfinite(points).all(axis=1)]
    x = points / np.asarray(doc["control_space"]["scale"], dtype=np.float64)
    what = f"the control space of the {len(x)} chosen entries with finite velocities"
    reason = degeneracy(x)
    if reason:
        return [Problem("control_space", f"{what} is degenerate: it {reason}; "
                                         f"{DEGENERACY_HINT}")]
    try:
        delaunay_tetrahedra(x)
    except LibraryError as exc:
        return [Problem("control_space", f"{what}: {exc.message}")]
    return []


# --------------------------------------------------------------------------- JSON text
def to_json_data(obj, digits: int = _SIGNIFICANT):
    """``obj`` as plain JSON values (:func:`mocaplib.io.jsonvalues.json_values`) with floats
    rounded to ``digits`` significant digits (10 by default); LibraryError for a value JSON
    cannot hold.
    """
    try:
        return json_values(obj, significant=digits)
    except TypeError as exc:
        raise LibraryError(f"cannot store in a library file: {exc}") from None


def json_text(obj) -> str:
    """Deterministic JSON text of ``obj`` (see :func:`to_json_data`), ending with a newline."""
    return _dump(to_json_data(obj)) + "\n"


def _dump(obj, level: int = 0) -> str:
    """JSON text with sorted keys; lists of scalars on one line, everything else indented."""
    pad, inner = "  " * level, "  " * (level + 1)
    if isinstance(obj, dict):
        if not obj:
            return "{}"
        items = [f"{inner}{json.dumps(k, ensure_ascii=False)}: {_dump(obj[k], level + 1)}"
                 for k in sorted(obj)]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(obj, list):
        if all(not isinstance(v, (dict, list)) for v in obj):
            return "[" + ", ".join(_dump(v) for v in obj) + "]"
        return "[\n" + ",\n".join(inner + _dump(v, level + 1) for v in obj) + "\n" + pad + "]"
    if isinstance(obj, float):
        return repr(obj)
    return json.dumps(obj, ensure_ascii=False)
