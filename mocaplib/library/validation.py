"""Validation of library files (``mocaplib validate``, :func:`validate_library`): the numbers,
the shipped JSON Schema, the content checksum, and the rules the schema cannot state
(``docs/library-format.md``, *Validation*). :func:`reading_problems` is the part
:func:`mocaplib.library.format.load_library` applies: what would make a file's numbers
unusable.
"""

from __future__ import annotations

import functools
import math
import os
import re
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..errors import LibraryError
from ..gait.poulaine import Poulaine
from ..gait.qc import qc_failures
from ..io.fastjson import all_finite, collection_paused
from ..io.jsonvalues import OutOfRange, float_or_nan, is_finite_number
from .controlspace_rules import control_space_problems
from .controlspace_rules import control_space_warning  # noqa: F401 (imported from here)
from .document import CHECKSUM_KEY, content_sha256, read_document, schema
from .entry import DRIFT_DISPLACEMENT, DRIFT_VELOCITIES, drift_displacements

#: Largest |velocity| (m/s, rad/s) and |Fourier coefficient| (rad, or m for pelvis_t*) an entry
#: may have: far beyond any human locomotion, so only corrupt files are refused (and the control
#: space's geometry never overflows).
PLAUSIBLE_SPEED, PLAUSIBLE_COEFFICIENT = 100.0, 1000.0
#: Range (m) of a segment length, and largest |coordinate| (m) of a joint shift, in a library's
#: skeleton: the shortest segment (shoulder_drop) of a 0.8 m subject is 26 mm, the longest
#: (hip_height) of a 2.3 m one 1.2 m; a skeleton beyond them is no person's (a unit slip, a
#: corrupt file).
PLAUSIBLE_SEGMENT_M, PLAUSIBLE_SHIFT_M = (0.001, 2.0), 0.5
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


@dataclass(frozen=True)
class Problem:
    """One reason a library is invalid: ``where`` (a JSON path such as ``entries[3].T``) and why."""

    where: str
    message: str

    def __str__(self) -> str:
        return f"{self.where}: {self.message}"


def _matrix(rows) -> np.ndarray:
    """Rows of JSON numbers (the schema checked their types) as a float array, null as NaN:
    numpy converts a whole list at once."""
    return np.array(rows, dtype=np.float64)


#: Parameters of each pattern type (``entries[i].pattern.parameters``).
PATTERN_PARAMETERS = {"line": ("direction", "length", "point"),
                      "arc": ("centre", "length", "radius", "turn"),
                      "point": ("length", "point")}
#: How far (rad) an angle DOF's mean ``a[d][0]`` may lie outside its ``dof_ranges``: rounding
#: only. The fitted angles stay within the ranges, so does their mean: the closest measured is
#: 0.88 deg inside (17 real files), so a mean outside is a unit slip (degrees stored as rad).
RANGE_TOLERANCE = 1e-6


def validate_library(library, *, finite: bool = False) -> list[Problem]:
    """Schema and semantic problems of a library (path, JSON dict or
    :class:`~mocaplib.library.format.Library`).

    Checks, after the numbers (no NaN or Infinity: JSON has none) and the schema: DOF names
    unique, units/ranges one per DOF, ranges lo <= hi; every entry's coefficients of shape
    (D, N+1) with N the header's, finite, ``b[:, 0] = 0``, zero beyond the entry's ``n``, each
    angle DOF's mean ``a[d][0]`` within its range; ``T > 0`` and ``end_s - start_s = T``
    (1 ms); velocities finite; ids unique and ``cycle_index`` the id's ``_c<k>``; the pattern's
    parameters those of its type; the root drift's displacement the one its velocities give
    over T, its turn rate of the entry's ω̂'s sign; a poulaine's phases in order, speed
    profiles rising and parameters those of its characteristic points; the chosen entries'
    control space triangulated, and its stored tetrahedra its own (none stored when the points
    are degenerate, :func:`mocaplib.library.triangulation.degeneracy`: such a library is valid
    without a control space, :func:`control_space_warning`); every QC metric within
    ``qc_thresholds`` or listed in the entry's ``qc_waived`` with a reason.

    Parameters
    ----------
    library : str, os.PathLike, dict or Library
        A library file, its parsed JSON document, or a loaded :class:`Library`.
    finite : bool
        The document's numbers are known finite (as
        :func:`~mocaplib.library.document.read_document` says of a file it read): NaN and
        infinities are not looked for. A file given by its path is read so.

    Returns
    -------
    list of Problem
        Every problem found, each with the JSON path it is at; empty for a valid library.

    Notes
    -----
    Python's cyclic garbage collector is paused while it runs: the checks make no reference
    cycles, and each collection would visit every value of the document (0.15 to 0.3 s on a
    5,000-entry library).
    """
    with collection_paused():
        return _validation_problems(library, finite)


def _validation_problems(library, finite: bool) -> list[Problem]:
    """:func:`validate_library`'s problems."""
    if isinstance(library, dict):
        document = library
    elif not isinstance(library, (str, os.PathLike)):
        document = library.document
    else:
        try:
            document, _, finite = read_document(library, file_sha256=False)
        except LibraryError as exc:
            return [Problem("file", exc.message if not exc.hint else
                            f"{exc.message} ({exc.hint})")]
    problems = _structure_problems(document, finite)
    if problems:
        return problems
    # the checksum (RFC 8785 bytes, SHA-256) is taken in a second thread while the rules run:
    # its numpy passes and hashing release the GIL (0.3 s less on a 5,000-entry library)
    with ThreadPoolExecutor(max_workers=1) as pool:
        checksum = pool.submit(_checksum_problems, document)
        rules = (_skeleton_problems(document) + _entry_problems(document)
                 + _consistency_problems(document)
                 + [Problem(where, message)
                    for where, message in control_space_problems(document)])
        return _named(document, checksum.result() + rules)


def _checksum_problems(document: dict) -> list[Problem]:
    """The stored checksum against the content's (whose numbers are finite: checked first)."""
    stored = document.get(CHECKSUM_KEY)
    try:
        if stored is None or stored == content_sha256(document, finite=True):
            return []
    except ValueError:                  # no RFC 8785 form (an integer beyond 2**53)
        pass
    return [Problem(CHECKSUM_KEY, "the content does not match the checksum the file was "
                                  "written with: it was changed after `mocaplib build` wrote "
                                  "it (by hand or by another tool), so its values cannot be "
                                  "trusted; build it again")]


def reading_problems(document, *, finite: bool = False) -> list[Problem]:
    """What makes a library document unusable (:func:`mocaplib.library.format.load_library`
    refuses it): numbers JSON cannot hold (not looked for when ``finite``: known finite), the
    schema, the skeleton's lists, and each entry's coefficient shapes, finite values, period
    and velocities (QC thresholds not applied)."""
    return _structure_problems(document, finite) or _named(
        document, _skeleton_problems(document) + _entry_problems(document, qc=False))


def _structure_problems(document, finite: bool = False) -> list[Problem]:
    """Numbers JSON cannot hold (none when ``finite``), then the schema's problems."""
    return _named(document, ([] if finite else _non_finite_problems(document))
                  + _schema_problems(document))


def _non_finite_problems(document) -> list[Problem]:
    """Every NaN or ±Infinity (read from the non-standard JSON tokens), in document order."""
    if all_finite(document):
        return []
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
    """The schema's problems: none when the compiled validator (jsonschema-rs, the same
    schema) passes the document, else each as jsonschema words it (imported then: 0.07 s)."""
    try:
        if _compiled_schema().is_valid(document):
            return []
    except ValueError:      # values it cannot take (OutOfRange): jsonschema says what they are
        pass
    from jsonschema import Draft202012Validator

    validator = Draft202012Validator(schema())
    errors = sorted((_specific(error) for error in validator.iter_errors(document)),
                    key=lambda e: list(map(str, e.absolute_path)))
    return [Problem(_json_path(error.absolute_path), f"schema: {error.message[:300]}")
            for error in errors]


@functools.cache
def _compiled_schema():
    """The shipped schema compiled by jsonschema-rs (draft 2020-12, formats not asserted, as
    jsonschema's default)."""
    import jsonschema_rs

    return jsonschema_rs.Draft202012Validator(schema(), validate_formats=False)


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
    problems += _body_problems(skel, "skeleton")
    for i, entry in enumerate(doc["entries"]):
        problems += _body_problems(entry, f"entries[{i}]")
    return problems


def _body_problems(holder: dict, where: str) -> list[Problem]:
    """Segment lengths outside :data:`PLAUSIBLE_SEGMENT_M` and joint shifts beyond
    :data:`PLAUSIBLE_SHIFT_M` in ``holder``'s ``segment_lengths_m`` and ``joint_shifts_m``."""
    lo, hi = PLAUSIBLE_SEGMENT_M
    problems = [Problem(f"{where}.segment_lengths_m.{name}",
                        f"segment length {value} m is no person's (a segment is {lo * 1000:g} "
                        f"mm to {hi:g} m long)")
                for name, value in (holder.get("segment_lengths_m") or {}).items()
                if not lo <= float_or_nan(value) <= hi]
    problems += [Problem(f"{where}.joint_shifts_m.{name}",
                         f"joint shift {value} m is no person's (each coordinate within "
                         f"±{PLAUSIBLE_SHIFT_M:g} m)")
                 for name, value in (holder.get("joint_shifts_m") or {}).items()
                 if not all(abs(float_or_nan(x)) <= PLAUSIBLE_SHIFT_M for x in value)]
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
    drift_problems = _drift_problems(doc["entries"])
    range_problems = (_range_problems(doc["entries"], angles, len(skel["dof_names"]))
                      if angles else {})
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
        problems += drift_problems.get(i, [])
        if e.get("poulaine") is not None:
            problems += _poulaine_problems(e["poulaine"], f"{where}.poulaine")
        problems += range_problems.get(i, [])
    return problems


def _range_problems(entries: list[dict], angles: list[tuple], n_dof: int
                    ) -> dict[int, list[Problem]]:
    """By entry index, each angle DOF's mean ``a[d][0]`` outside its range (``angles``: rows
    (d, name, lo, hi) in rad) beyond :data:`RANGE_TOLERANCE`, of the entries with ``n_dof``
    coefficient rows: compared for all the entries at once."""
    dofs = [d for d, *_ in angles]
    rows = [i for i, e in enumerate(entries) if len(e["fourier"]["a"]) == n_dof]
    means = _matrix([[a[d][0] if a[d] else None for d in dofs]
                     for a in (entries[i]["fourier"]["a"] for i in rows)]).reshape(-1, len(dofs))
    lo, hi = (np.array([angle[k] for angle in angles], dtype=np.float64) for k in (2, 3))
    outside = ~((lo - RANGE_TOLERANCE <= means) & (means <= hi + RANGE_TOLERANCE))
    problems: dict[int, list[Problem]] = {}
    for r, k in zip(*np.nonzero(outside & np.isfinite(means))):
        d, name, lo_d, hi_d = angles[k]
        problems.setdefault(rows[r], []).append(Problem(
            f"entries[{rows[r]}].fourier.a[{d}][0]",
            _range_message(name, float(means[r, k]), lo_d, hi_d)))
    return problems


def _range_message(name: str, mean: float, lo: float, hi: float) -> str:
    """Why an angle DOF's mean over a cycle (rad, after the root drift is taken out) outside
    its range [lo, hi] rad is refused, and its likely cause: degrees stored as radians when
    the number read in degrees lies in the range and in radians beyond a turn; otherwise a
    cycle that is not periodic (its start and end poses differ: the drift taken out moves
    the mean)."""
    said = (f"mean {name} {mean:.6g} rad ({math.degrees(mean):.1f}°, over the cycle after its "
            f"start-to-end drift is taken out) lies outside its range [{lo:.4g}, {hi:.4g}] rad "
            f"([{math.degrees(lo):.1f}°, {math.degrees(hi):.1f}°])")
    if abs(mean) > 2 * math.pi and lo <= math.radians(mean) <= hi:
        return said + ": degrees stored as radians?"
    return said + (": the cycle is not periodic (its start and end poses differ, and the drift "
                   "taken out moves its mean): leave it out, or choose a steadier cycle")


def entry_problems(library) -> dict[str, list[Problem]]:
    """The problems of :func:`validate_library` that are an entry's own, by entry id: those
    at ``entries[i]`` (its numbers, fields, QC) — what leaving the entry out removes."""
    document = library if isinstance(library, dict) else library.document
    by_id: dict[str, list[Problem]] = {}
    for problem in validate_library(document):
        found = re.match(r"entries\[(\d+)\]", problem.where)
        if found and int(found.group(1)) < len(document["entries"]):
            by_id.setdefault(document["entries"][int(found.group(1))]["id"], []).append(problem)
    return by_id


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
        if not (isinstance(xy, list) and len(xy) == 2 and all(map(is_finite_number, xy))):
            problems.append(Problem(f"{where}.parameters.{key}", f"must be [x, y], got {xy!r}"))
        elif key == "direction" and abs(math.hypot(*xy) - 1.0) > 1e-6:
            # stored to 10 digits, the unit vectors of the files at hand are within 7e-11 of 1
            problems.append(Problem(f"{where}.parameters.direction", f"must be a unit vector, "
                                                                     f"its length is "
                                                                     f"{math.hypot(*xy):.6g}"))
    if not (is_finite_number(params["length"]) and params["length"] >= 0):
        problems.append(Problem(f"{where}.parameters.length", f"must be a number of metres "
                                                              f">= 0, got {params['length']!r}"))
    if "radius" in params and not (is_finite_number(params["radius"]) and params["radius"] > 0):
        problems.append(Problem(f"{where}.parameters.radius", f"must be a number of metres "
                                                              f"> 0, got {params['radius']!r}"))
    if kind == "arc" and not (is_finite_number(params["turn"]) and params["turn"] in (1, -1)):
        problems.append(Problem(f"{where}.parameters.turn", f"must be 1 (counter-clockwise) "
                                                            f"or -1, got {params['turn']!r}"))
    return problems


def _drift_problems(entries: list[dict]) -> dict[int, list[Problem]]:
    """By entry index, the root drift's displacement against its velocities over T, and its
    turn's sign: computed for all the entries at once."""
    drifts = [e["root_drift"] for e in entries]
    velocities = _matrix([[d[k] for k in DRIFT_VELOCITIES] for d in drifts]).reshape(-1, 3)
    stored = _matrix([[d[k] for k in DRIFT_DISPLACEMENT] for d in drifts]).reshape(-1, 3)
    period = _matrix([e["T"] for e in entries])
    omega = _matrix([e["omega"] for e in entries])
    expected = drift_displacements(velocities, period)
    wrong = ~(np.abs(stored - expected) <= DRIFT_TOLERANCE * np.fmax(1.0, np.abs(expected)))
    wrong &= np.isfinite(period)[:, None]
    turn = velocities[:, DRIFT_VELOCITIES.index("omega_rad_s")]
    flipped = (np.fmin(np.abs(omega), np.abs(turn)) > TURN_SIGN_RATE) & (omega * turn < 0)
    problems: dict[int, list[Problem]] = {}
    for i in np.flatnonzero(wrong.any(axis=1) | flipped).tolist():
        drift, where, found = drifts[i], f"entries[{i}].root_drift", []
        if wrong[i].any():
            found.append(Problem(where, "the displacement does not follow from u_f_m_s, "
                                        f"u_l_m_s, omega_rad_s over T = {float(period[i])} s: "
                                 + ", ".join(f"{k} {drift[k]:.6g}, expected "
                                             f"{float(expected[i, j]):.6g}"
                                             for j, k in enumerate(DRIFT_DISPLACEMENT)
                                             if wrong[i, j])))
        if flipped[i]:
            found.append(Problem(f"{where}.omega_rad_s",
                                 f"{drift['omega_rad_s']:.4g} rad/s turns the other way from "
                                 f"the entry's omega {float(omega[i]):.4g} rad/s (a sign "
                                 "flipped?)"))
        problems[i] = found
    return problems


def _poulaine_problems(poulaine: dict, where: str) -> list[Problem]:
    """Phases in order, speed profiles rising, rows of one length, and the stored parameters
    those of the characteristic points."""

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
