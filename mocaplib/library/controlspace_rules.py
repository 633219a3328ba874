"""The rules of a library's control space (:mod:`mocaplib.library.validation`): the chosen
entries triangulated as :class:`mocaplib.library.controlspace.ControlSpace` does for queries,
the tetrahedra, gaits and hull a file stores compared with theirs, and why a valid library has
no control space (``docs/library-format.md``, *Validation*).
"""

from __future__ import annotations

import numpy as np

from ..errors import LibraryError
from ..io.jsonvalues import float_or_nan, is_finite_number
from .cells import build_cells, cell_tetrahedra, frontal_tetrahedra
from .document import CONTROL_AXES, FRONTAL_WEIGHTS_VERSION, GAIT_CELLS_VERSION, library_document
from .triangulation import DEGENERACY_HINT, degeneracy, delaunay_tetrahedra


def control_space_problems(doc: dict) -> list[tuple[str, str]]:
    """The chosen entries' control space, as :class:`mocaplib.library.controlspace.ControlSpace`
    builds it for queries: failing to triangulate, or tetrahedra stored that are not its own.
    A degenerate one (:func:`~mocaplib.library.triangulation.degeneracy`) is no problem: the
    library has no control space (:func:`control_space_warning`), and must store none. Each
    problem is (its JSON path, the message)."""

    x = _normalised_points(doc)
    if degeneracy(x):
        if "tetrahedra" in doc["control_space"]:
            return [("control_space.tetrahedra", "tetrahedra are stored but the chosen entries "
                                                 "span no 3-D control space; write the "
                                                 "library again")]
        return []
    try:
        every = delaunay_tetrahedra(x)
    except LibraryError as exc:
        return [("control_space", f"the control space of the {len(x)} chosen entries with "
                                  f"finite velocities: {exc.message}")]
    stored = doc["control_space"].get("tetrahedra")
    return [] if stored is None else _tetrahedra_problems(doc, stored, every)


def control_space_warning(library) -> str | None:
    """Why a valid library (path, JSON dict or :class:`~mocaplib.library.format.Library`) has
    no control space, with what to do; None when it has one. A library of fewer than 4
    entries with distinct velocities, or whose entries lie on a plane or a line, is valid:
    its entries can be read, animated and retargeted, but no command can be blended."""
    document = library_document(library)
    x = _normalised_points(document)
    reason = degeneracy(x)
    if reason is None:
        return None
    return (f"no control space: the control space of the {len(x)} chosen entries with finite "
            f"velocities is degenerate: it {reason}; `mocaplib query` cannot blend commands "
            f"and the report has no control-space figures; {DEGENERACY_HINT}")


def _normalised_points(doc: dict) -> np.ndarray:
    """The chosen entries' normalised (v, omega, v_l) (E, 3), those with finite velocities."""
    points = control_points([e for e in doc["entries"] if e.get("chosen", True)])
    points = points[np.isfinite(points).all(axis=1)]
    return points / np.asarray(doc["control_space"]["scale"], dtype=np.float64)


def _tetrahedra_problems(doc: dict, stored: dict, every) -> list[tuple[str, str]]:
    """The stored ``control_space.tetrahedra`` against the chosen entries' own: the same entries
    in the file's order (with finite velocities and period); from
    :data:`~mocaplib.library.document.GAIT_CELLS_VERSION` the tetrahedra of their gait cells
    with each one's gait and the hull of all of them (from
    :data:`~mocaplib.library.document.FRONTAL_WEIGHTS_VERSION` with the cells' frontal
    tetrahedra and their gaits), before it the tetrahedra of all of them.
    ``every``: the Delaunay tetrahedra of the chosen entries with finite velocities (those
    with a finite period too, when they are all)."""

    where = "control_space.tetrahedra"
    hint = "write the library again (mocaplib build, or mocaplib mirror)"
    entries = [e for e in doc["entries"] if e.get("chosen", True)
               and all(is_finite_number(e.get(k)) for k in ("v", "omega", "v_l", "T"))]
    if stored["ids"] != [e["id"] for e in entries]:
        return [(where, f"ids are not the control space's entries (chosen, with finite "
                               f"velocities and period, in the file's order); {hint}")]
    points, scale = control_points(entries), doc["control_space"]["scale"]
    if len(points) != len(every.points):            # an entry without a finite period
        every = delaunay_tetrahedra(points / np.asarray(scale, dtype=np.float64))
    if doc["format_version"] < GAIT_CELLS_VERSION:
        if not _same_rows(stored["simplices"], every.simplices):
            return [(where, f"simplices are not the tetrahedra of these entries "
                                   f"(format_version {doc['format_version']}: of all of "
                                   f"them); {hint}")]
        return []
    cells, _ = build_cells(points, scale, classes=[e.get("locomotion_class") for e in entries],
                           v_f=[float_or_nan(e.get("v_f")) for e in entries])
    simplices, gaits = cell_tetrahedra(cells)
    if len(stored["gaits"]) != len(stored["simplices"]) or not _same_rows(
            stored["simplices"], simplices, stored["gaits"], gaits):
        return [(where, f"simplices and gaits are not the tetrahedra of these entries' "
                               f"gait cells; {hint}")]
    if not _same_rows(stored["hull"], every.convex_hull):
        return [(where, f"hull is not the boundary of these entries' points; {hint}")]
    if doc["format_version"] >= FRONTAL_WEIGHTS_VERSION:
        frontal, frontal_gaits = frontal_tetrahedra(cells)
        if len(stored["frontal_gaits"]) != len(stored["frontal_simplices"]) or not _same_rows(
                stored["frontal_simplices"], frontal, stored["frontal_gaits"], frontal_gaits):
            return [(where, f"frontal_simplices and frontal_gaits are not the frontal "
                            f"tetrahedra of these entries' gait cells; {hint}")]
    return []


def _same_rows(stored: list, expected: np.ndarray, stored_gaits: list | None = None,
               expected_gaits: list | None = None) -> bool:
    """Whether the rows of vertex numbers ``stored`` (R, K) (JSON lists) and ``expected``
    (R', K), each with its gait (``stored_gaits`` (R,), ``expected_gaits`` (R',)) when
    given, are the same simplices or triangles whatever the order of the rows and of the
    vertices in each row."""
    expected = np.asarray(expected, dtype=np.int64)
    try:
        rows = np.asarray(stored, dtype=np.int64)
    except (ValueError, OverflowError, TypeError):      # rows of several lengths
        return False
    if rows.size == 0 or expected.size == 0:
        return rows.size == expected.size
    if rows.shape != expected.shape:
        return False
    tables = [np.sort(rows, axis=1), np.sort(expected, axis=1)]
    if stored_gaits is not None:
        _, codes = np.unique(np.asarray([*stored_gaits, *expected_gaits], dtype=str),
                             return_inverse=True)
        tables = [np.column_stack([tables[0], codes[:len(rows)]]),
                  np.column_stack([tables[1], codes[len(rows):]])]
    first, second = (t[np.lexsort(t.T[::-1])] for t in tables)
    return np.array_equal(first, second)


def control_points(entries: list[dict]) -> np.ndarray:
    """The entries' (v, omega, v_l) (E, 3), null as NaN."""
    return np.array([[float_or_nan(e[axis]) for axis in CONTROL_AXES] for e in entries],
                    dtype=np.float64).reshape(-1, 3)
