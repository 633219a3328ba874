"""Data of the report's figure viewer: the skeleton, every entry's series, the tetrahedra.

The viewer (``templates/figure.js`` on ``templates/motion.js``) animates an entry's cycle as a
stick figure, posed by forward kinematics in JavaScript from :func:`skeleton_data` (the
description of docs/library-format.md, "Posing the skeleton") and from the entry's series with
its feet planted as ``mocaplib query`` writes them
(:func:`mocaplib.library.planting.planted_series`), each leg then moved in JavaScript to its
foot's lock (``plantedPose``: on the samples nothing slides more than 1.8 mm or goes below the
floor, tests/test_planting.py), and plays the blend of a control-space point picked with the
mouse, located in the tetrahedra of the control space's gait cells with side-steps put on the
cone, as ``mocaplib query`` locates a command (:func:`viewer_data`'s ``space``): nothing is
triangulated in the browser. A blend's feet are planted the same way on locks found in
JavaScript (``findLocks``: its stances by planting's rule, tests/test_viewer_blends.py).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

from ..build.workers import run_tasks
from ..export.bvh import end_sites
from ..gait.fourier import RootDrift
from ..library.cells import cell_tetrahedra, frontal_tetrahedra
from ..library.foot_targets import APPROACH_SPEED, BLEND_S, STANCE_KNEE
from ..library.legs import KNEE_START, KNEES, LEG_DOFS, LEG_SEGMENTS
from ..library.planting import (CONTACT_RISE, CONTACT_SPEED, MAX_LEVEL, MIN_STANCE_S,
                                 ROLL_RISE, ROLL_SHIFT, STANCE_GAP_S, STANCE_RATE, STILL_SPEED,
                                 planted_series)
from ..skeleton import DOF_NAMES, DOFS, SEGMENT_NAMES, SEGMENTS, Skeleton

#: Decimals of the Fourier coefficients in the page: 1e-6 rad (and m), far below a pixel.
COEFFICIENT_DECIMALS = 6
#: Decimals of the feet's locks in the page: 0.1 mm, 0.1 ms, 1e-4 rad.
LOCK_DECIMALS = 4
#: The entry shown first: the one nearest this (v̂, ω̂, v̂_l) (m/s, rad/s, m/s), normal walking.
FIRST_SHOWN = (1.2, 0.0, 0.0)
#: Entries one worker task plants when the viewer's cycles are planted by several jobs.
PLANTED_PER_TASK = 25
#: Segment origins joined by a line besides each segment's bone to its parent.
EXTRA_LINES = (("femur_l", "femur_r"), ("humerus_l", "humerus_r"))


def skeleton_data(skeleton: Skeleton) -> dict:
    """The skeleton for the page's forward kinematics: ``segments`` (name, parent index or -1,
    joint centre ``offset`` in the parent's frame (m), ``dofs`` as [DOF index, axis, is a
    translation], parents before children), ``ends`` (segment index -> points drawn in its
    frame, m: head top, finger tip, heel and toe), ``lines`` (pairs of segment indices),
    ``feet`` (left, right: the foot's segment index, its thigh's, its leg's DOF indices hip to
    ankle and the knee's), ``fade_s``, the time over which a lock's correction fades in and
    out (s), ``approach_speed`` (m/s, :data:`~mocaplib.library.foot_targets.APPROACH_SPEED`),
    ``knee_start`` (rad, :data:`~mocaplib.library.legs.KNEE_START`), ``stance_knee`` (rad,
    :data:`~mocaplib.library.foot_targets.STANCE_KNEE`) and ``stance``, the constants by which
    a blend's stances are found (:mod:`mocaplib.library.planting`: ``rate`` its
    ``STANCE_RATE``, the others its constants of the same names in lower case)."""
    offsets = skeleton.joint_offsets()
    segments = [{"name": seg.name,
                 "parent": -1 if seg.parent is None else SEGMENT_NAMES.index(seg.parent),
                 "offset": offsets[s].tolist(),
                 "dofs": [[DOF_NAMES.index(name), list(DOFS[DOF_NAMES.index(name)].axis),
                           DOFS[DOF_NAMES.index(name)].translation] for name in seg.dofs]}
                for s, seg in enumerate(SEGMENTS)]
    ends = {}
    for name, tip in end_sites(skeleton).items():
        points = skeleton.sole().tolist() if name.startswith("foot") else [list(map(float, tip))]
        ends[SEGMENT_NAMES.index(name)] = points
    return {"segments": segments, "ends": ends,
            "lines": [[SEGMENT_NAMES.index(a), SEGMENT_NAMES.index(b)] for a, b in EXTRA_LINES],
            "feet": [{"segment": int(foot), "hip": int(thigh), "dofs": dofs.tolist(),
                      "knee": int(knee)}
                     for thigh, foot, dofs, knee in zip(LEG_SEGMENTS[:, 0], LEG_SEGMENTS[:, 2],
                                                        LEG_DOFS, KNEES)],
            "fade_s": BLEND_S, "approach_speed": APPROACH_SPEED, "knee_start": KNEE_START,
            "stance_knee": STANCE_KNEE,
            "stance": {"rate": STANCE_RATE, "contact_speed": CONTACT_SPEED,
                       "contact_rise": CONTACT_RISE, "min_stance_s": MIN_STANCE_S,
                       "still_speed": STILL_SPEED, "stance_gap_s": STANCE_GAP_S,
                       "roll_rise": ROLL_RISE, "roll_shift": ROLL_SHIFT, "max_level": MAX_LEVEL}}


def viewer_data(library, cs, classes: list[str], colours: dict, *, jobs: int = 1,
                planted: Callable[[], list[tuple]] | None = None) -> dict:
    """Everything the figure viewer needs, as JSON data.

    ``entries``: per library entry (``library.entries`` order) its id, class, colour,
    ``mirror_of`` (null unless a mirror image), period ``T`` (s), Fourier ``a``/``b`` of its
    cycle with the feet planted on the library's skeleton (an entry without a finite drift:
    its own, up to its order), the ``locks`` of its feet
    (:class:`~mocaplib.library.planting.PlantedSeries`, the foot an integer; none without a
    finite drift), and root ``drift`` (u_f, u_l, omega); ``space`` (null without a
    gait cell):
    the chosen entries (``entries``: indices into the list above) at their normalised
    ``points`` in the cells (side-steps on the cone), the ``simplices`` of the gait cells
    (rows of 4 indices into them, :func:`~mocaplib.library.cells.cell_tetrahedra`) with
    their ``gaits``, the ``axes`` and ``scale``, and ``frontal``: the cells' frontal
    tetrahedra where a picked point's weights are computed (``points`` on the frontal axes,
    normalised, ``simplices`` and ``gaits``, :func:`~mocaplib.library.cells.frontal_tetrahedra`);
    ``skeleton``: :func:`skeleton_data` of the library's segment lengths; ``first``: the entry
    shown first (:data:`FIRST_SHOWN`). ``classes``: each entry's class label; ``colours``:
    class -> CSS colour. ``jobs``: worker processes planting
    the cycles (:func:`planted_cycles`); ``planted``: what :func:`start_planting` returned for
    the library, if it was called (the cycles are planted here otherwise).
    """
    entries = []
    planted = start_planting(library, jobs=jobs) if planted is None else planted
    for e, cls, fields in zip(library.entries, classes, planted()):
        entries.append({
            "id": e.id, "class": cls, "colour": colours.get(cls, "#808080"),
            "mirror_of": e.mirror_of, "T": float(e.T), **fields,
            "drift": [float(x) for x in e.root_drift.velocities],
            "velocity": [float(x) for x in e.velocity]})
    space = None
    if cs is not None and cs.cells:
        row = {e.id: i for i, e in enumerate(library.entries)}
        simplices, gaits = cell_tetrahedra(cs.cells)
        frontal, frontal_gaits = frontal_tetrahedra(cs.cells)
        with_frontal = [c for c in cs.cells.values() if c.frontal is not None]
        space = {"entries": [row[i] for i in cs.ids],
                 "points": next(iter(cs.cells.values())).tri.points.tolist(),
                 "simplices": simplices.tolist(), "gaits": gaits, "axes": list(cs.axes),
                 "scale": [float(s) for s in cs.scale],
                 "frontal": {"points": with_frontal[0].frontal.points.tolist() if with_frontal
                             else [], "simplices": frontal.tolist(), "gaits": frontal_gaits}}
    walk = np.array([e["velocity"] for e in entries]) - FIRST_SHOWN
    first = int(np.argmin(np.linalg.norm(walk / library.control_scale, axis=1)))
    return {"entries": entries, "space": space, "first": first,
            "skeleton": skeleton_data(library.skeleton)}


def viewer_cycles(library) -> list[tuple]:
    """Each entry's cycle as the viewer plants it, ``(a, b, T, drift)``: its coefficients (D,
    N+1) on the header's body (its pelvis height scaled:
    :meth:`~mocaplib.library.format.Library.on_header_body`), period (s) and drift velocities
    (3,)."""
    a, b = library.on_header_body(*library.coefficient_arrays())
    return [(a[i, :, :e.fourier.n + 1], b[i, :, :e.fourier.n + 1], float(e.T),
             np.array(e.root_drift.velocities, dtype=np.float64))
            for i, e in enumerate(library.entries)]


def start_planting(library, *, jobs: int = 1) -> Callable[[], list[dict]]:
    """Start planting the viewer's cycle of every entry of ``library`` (:func:`viewer_cycles`,
    :func:`planted_cycles`,
    ``jobs`` worker processes) and return the function that waits for them and returns them
    (or raises what planting raised). With ``jobs`` > 1 a thread of this process drives the
    workers meanwhile, so that the report's other sections are made while they plant; with one
    job the cycles are planted when the function is called."""
    cycles = viewer_cycles(library)
    skeleton = library.skeleton
    if jobs <= 1:
        return lambda: planted_cycles(skeleton, cycles)
    outcome: dict = {}

    def plant() -> None:
        try:
            outcome["value"] = planted_cycles(skeleton, cycles, jobs=jobs)
        except BaseException as exc:          # re-raised in the caller's thread
            outcome["error"] = exc

    thread = threading.Thread(target=plant, name="mocaplib-planting", daemon=True)
    thread.start()

    def result() -> list[dict]:
        thread.join()
        if "error" in outcome:
            raise outcome["error"]
        return outcome["value"]
    return result


def planted_cycles(skeleton: Skeleton, cycles: list[tuple], *, jobs: int = 1) -> list[dict]:
    """Each cycle ``(a, b, T, drift)`` (coefficients (D, N+1), period s, drift velocities (3,))
    as :func:`~mocaplib.library.planting.planted_series` plants it on ``skeleton``, as the
    page holds it: ``a``, ``b`` (:func:`_rounded`) and ``locks`` (rows of the foot, an integer,
    and the lock's numbers to :data:`LOCK_DECIMALS` decimals), or the cycle's own (no locks)
    where its coefficients or drift are not finite. ``jobs`` > 1: :data:`PLANTED_PER_TASK`
    cycles a task in worker processes
    (:func:`mocaplib.build.workers.run_tasks`); a task whose worker failed is planted here
    again, so that a real error shows as itself."""
    chunks = [cycles[k:k + PLANTED_PER_TASK] for k in range(0, len(cycles), PLANTED_PER_TASK)]
    planted: list = [None] * len(chunks)
    for index, value, error in run_tasks(_planted_chunk, [(skeleton, c) for c in chunks],
                                         jobs=jobs):
        planted[index] = _planted_chunk(skeleton, chunks[index]) if error else value
    return [pair for chunk in planted for pair in chunk]


def _planted_chunk(skeleton: Skeleton, cycles: list[tuple]) -> list[dict]:
    """:func:`planted_cycles` of one task."""
    out = []
    for a, b, period, drift in cycles:
        locks = np.zeros((0, 6))
        if np.isfinite(drift).all() and np.isfinite([a, b]).all():
            planted = planted_series(skeleton, a, b, period, RootDrift(0.0, 0.0, 0.0, *drift))
            a, b, locks = planted.a, planted.b, planted.locks
        out.append({**_rounded(a, b), "locks": [[int(row[0]), *row[1:]] for row in
                                                np.round(locks, LOCK_DECIMALS).tolist()]})
    return out


def _rounded(a: np.ndarray, b: np.ndarray) -> dict:
    """Fourier coefficients ``a``, ``b`` (D, N+1) for the page: ``{"a": rows, "b": rows}``, to
    :data:`COEFFICIENT_DECIMALS` decimals, each DOF's row without its trailing zero harmonics
    (rows of different lengths: the viewer sums what each row holds)."""
    rows_a = np.round(a, COEFFICIENT_DECIMALS) + 0.0          # + 0.0: no negative zeros
    rows_b = np.round(b, COEFFICIENT_DECIMALS) + 0.0
    nonzero = (rows_a != 0) | (rows_b != 0)                                  # (D, N+1)
    lengths = np.where(nonzero.any(axis=1),
                       nonzero.shape[1] - np.argmax(nonzero[:, ::-1], axis=1), 1)
    return {"a": [ra[:n] for ra, n in zip(rows_a.tolist(), lengths)],
            "b": [rb[:n] for rb, n in zip(rows_b.tolist(), lengths)]}
