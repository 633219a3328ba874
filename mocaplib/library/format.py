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
carry ``content_sha256``, a checksum of their content
(:func:`mocaplib.library.document.content_sha256`) that
:func:`mocaplib.library.validation.validate_library` verifies.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .. import __version__
from ..errors import LibraryError
from ..gait.fourier import RootDrift, synthesize
from ..gait.qc import DEFAULT_QC_THRESHOLDS, QC_NAMES
from ..io.atomic import atomic_write_text
from ..io.jsonvalues import float_or_nan, json_values
from ..skeleton import DOFS, ROOT_Z, Skeleton
from .controlspace import DEFAULT_SCALE, stored_tetrahedra
from .document import (CHECKSUM_KEY, CONTROL_AXES, CONTROL_UNITS, FORMAT, FORMAT_VERSION,
                       content_sha256, read_document)
from .entry import DRIFT_VELOCITIES, LibraryEntry
from .validation import POULAINE_PARAMETERS, reading_problems

if TYPE_CHECKING:
    import pandas as pd

FOURIER_FORMULA = ("q_d(t) = a[d][0] + sum_{k=1..N} (a[d][k] cos(2 pi k t / T) "
                   "+ b[d][k] sin(2 pi k t / T)), t in s from the cycle start")
ROOT_DRIFT_TEXT = ("displacement of the path frame over one cycle, expressed in the frame at the "
                   "cycle start: dx_m forward, dy_m left, dheading_rad counter-clockwise")

_SIGNIFICANT = 10


def assemble_library(entries: list[LibraryEntry], *, settings: dict,
                     qc_thresholds: dict | None = None) -> "Library":
    """A library of ``entries``, sorted by id, their numbers as the file stores them (10
    significant digits).

    The header's segment lengths are the per-length median over entries (or the nominal
    1.75 m skeleton's when no entry carries lengths), its joint shifts the per-segment median
    over the entries that carry them; the Fourier order N is the largest
    entry order and smaller orders are zero-padded (exact); control-space scales are
    :func:`control_scale`; the control space's tetrahedra are stored with them
    (:func:`mocaplib.library.controlspace.stored_tetrahedra`) unless the entries span no
    3-D control space.
    """

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
    doc = with_tetrahedra(to_json_data(doc))
    doc[CHECKSUM_KEY] = content_sha256(doc)
    return Library(doc)


def with_tetrahedra(document: dict) -> dict:
    """``document`` (a library's JSON data, without its checksum) with the tetrahedra of its
    entries' control space stored in ``control_space`` as :func:`stored_tetrahedra` gives them
    (none when the entries span no 3-D control space); a file of an earlier version is left as
    it was written."""
    if document.get("format_version") != FORMAT_VERSION:
        return document
    control_space = {k: v for k, v in document["control_space"].items() if k != "tetrahedra"}
    tetrahedra = stored_tetrahedra(Library({**document, "control_space": control_space}))
    if tetrahedra is not None:
        control_space["tetrahedra"] = tetrahedra
    return {**document, "control_space": control_space}


def control_scale() -> list[float]:
    """Normalisation scales of (v, omega, v_l): :data:`mocaplib.library.controlspace.DEFAULT_SCALE`.

    Fixed, not derived from the entries, so adding a capture does not re-shape the
    triangulation of the others.
    """
    return [float(DEFAULT_SCALE[axis]) for axis in CONTROL_AXES]

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
        header = self.document["skeleton"]
        return Skeleton(header["segment_lengths_m"], header.get("joint_shifts_m", {}))

    def entry_skeleton(self, entry_id: str):
        """The skeleton of the subject of one entry.

        Parameters
        ----------
        entry_id : str
            An entry's id.

        Returns
        -------
        Skeleton
            Its own segment lengths and joint shifts when it records them, the header's
            otherwise.
        """
        entry, header = self.entry(entry_id), self.document["skeleton"]
        return Skeleton(entry.segment_lengths_m or header["segment_lengths_m"],
                        entry.joint_shifts_m or header.get("joint_shifts_m", {}))

    def body_scales(self) -> np.ndarray:
        """Per entry (E,), in :attr:`entries` order, the factor that puts its pelvis height on
        the header's body (:attr:`skeleton`): the header's leg (thigh, shank and ankle height:
        the hip's height over the floor, the leg straight) over the entry's own (1 where it
        records no lengths). An entry of another subject posed on that body, alone or blended,
        stands on its feet so (on the shared lab walks' library a subject with legs 92 mm
        longer than the header's floated 64-102 mm above the floor, never planted)."""
        def leg(lengths: dict) -> float:
            return lengths["thigh"] + lengths["shank"] + lengths["ankle_height"]

        header = leg(self.document["skeleton"]["segment_lengths_m"])
        return np.array([header / leg(e.segment_lengths_m) if e.segment_lengths_m else 1.0
                         for e in self.entries])

    def on_header_body(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every entry's Fourier coefficients ``a``, ``b`` (E, D, N+1), in :attr:`entries`
        order, with its pelvis height (``pelvis_tz``) scaled by :meth:`body_scales` (new
        arrays)."""
        scale = np.ones(a.shape[:2])
        scale[:, ROOT_Z] = self.body_scales()
        return a * scale[..., None], b * scale[..., None]

    @property
    def dof_names(self) -> list[str]:
        """The D coordinate names, in the order of every (…, D) array of the library."""
        return list(self.document["skeleton"]["dof_names"])

    @property
    def n_harmonics(self) -> int:
        """N, the highest harmonic of every entry's series (coefficients (D, N+1))."""
        return int(self.document["fourier"]["n_harmonics"])

    @property
    def settings(self) -> dict:
        """The build's settings, as recorded in the file."""
        return self.document["settings"]

    @property
    def control_scale(self) -> np.ndarray:
        """Normalisation scales of (v, omega, v_l), shape (3,): normalised = value / scale."""
        return np.asarray(self.document["control_space"]["scale"], dtype=np.float64)

    @cached_property
    def entries(self) -> list[LibraryEntry]:
        """The entries, in the file's order (sorted by id)."""
        return [LibraryEntry.from_json(e) for e in self.document["entries"]]

    @cached_property
    def _by_id(self) -> dict[str, LibraryEntry]:
        return {e.id: e for e in self.entries}

    @cached_property
    def table(self) -> pd.DataFrame:
        """One row per entry, index ``id``: its class, source, cycle, period, pattern,
        velocities (SI), Fourier order, QC metrics (``qc_<name>``) and poulaine parameters."""
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
        """One entry by its id.

        Parameters
        ----------
        entry_id : str
            The entry's id.

        Returns
        -------
        LibraryEntry

        Raises
        ------
        LibraryError
            Naming the library's ids when there is no such entry.
        """
        try:
            return self._by_id[entry_id]
        except KeyError:
            raise LibraryError(f"no entry {entry_id!r} in the library",
                               hint=f"ids are: {', '.join(list(self._by_id)[:20])}") from None

    def coefficients(self, entry_id: str) -> tuple[np.ndarray, np.ndarray]:
        """One entry's Fourier coefficients.

        Parameters
        ----------
        entry_id : str
            The entry's id.

        Returns
        -------
        a, b : ndarray, each (D, N+1)
            Copies, in each DOF's unit (rad, or m for the root's translations).
        """
        fourier = self.entry(entry_id).fourier
        return fourier.a.copy(), fourier.b.copy()

    def coefficient_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Every entry's Fourier coefficients.

        Returns
        -------
        a, b : ndarray, each (E, D, N+1)
            In :attr:`entries` order, zero-padded to :attr:`n_harmonics`.
        """
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
    run :func:`mocaplib.library.validation.validate_library` for those.

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
    document, sha256, finite = read_document(path)
    problems = reading_problems(document, finite=finite)
    if problems:
        raise LibraryError(f"not a valid mocaplib library: {problems[0]}"
                           + (f" (and {len(problems) - 1} more problems)" if len(problems) > 1
                              else ""), path=path, hint="run `mocaplib validate` on it")
    return Library(document, file_sha256=sha256)


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
