"""The report viewer's picked blends: their feet planted on locks its JavaScript finds
(templates/motion.js ``findLocks``), by the rule planting finds stances by, measured in Python
on the poses node computes (tests/viewer_poses.py)."""

from __future__ import annotations

import shutil
from functools import lru_cache

import numpy as np
import pytest

from mocaplib.gait.fourier import RootDrift, synthesize
from mocaplib.library.foot_targets import BLEND_S, flattest, foot_axes, mask_runs
from mocaplib.library.legs import LEG_DOFS, LegChains
from mocaplib.library.planting import STANCE_RATE, stance_frames
from mocaplib.skeleton import ROOT_Z

pytestmark = [pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed"),
              pytest.mark.usefixtures("sample_dir")]

SLIDE, PENETRATION, HOVER = 0.002, 0.0005, 0.003
#: Every how many tetrahedra of the gait cells a blend is picked at the centroid of.
EVERY = 2


@lru_cache(maxsize=1)
def picked():
    """The samples' library and the viewer's blends at the centroids of every
    :data:`EVERY`-th tetrahedron of its gait cells (those a cell holds)."""
    from test_planting import sample_library
    from viewer_poses import cell_centroids, viewer_blends

    library = sample_library()[0]
    return library, [b for b in viewer_blends(library, cell_centroids(library, EVERY))
                     if b is not None]


def python_locks(skeleton, blend) -> np.ndarray:
    """The locks (L, 6) of a blend as planting's Python finds its stances: the motion sampled
    at :data:`STANCE_RATE` (a whole number of samples a cycle) from a cycle before to one after,
    each stance within ``BLEND_S`` of the cycle locked at its flattest sample."""
    count = int(np.ceil(blend["T"] * STANCE_RATE))
    rate = count / blend["T"]
    k = np.arange(-count, 2 * count)
    world = RootDrift(0.0, 0.0, 0.0, *blend["drift"]).restore(
        synthesize(blend["a"], blend["b"], blend["T"], (k % count) / rate), k / rate)
    points, orientation, _ = LegChains(skeleton, world).frames(world[:, LEG_DOFS],
                                                               world[:, ROOT_Z])
    _, heading = foot_axes(orientation)
    locks = []
    stance = stance_frames(skeleton, world, rate)
    for side in (0, 1):
        for first, last in mask_runs(stance[:, side]):
            t0, t1 = (first - count) / rate, (last - 1 - count) / rate
            if t1 >= -BLEND_S and t0 <= blend["T"] + BLEND_S:
                flat = first + flattest(points[first:last, side, 1:, 2])
                locks.append([side, t0, t1, *points[flat, side, 1, :2], heading[flat, side]])
    return np.array(locks, dtype=float).reshape(-1, 6)


def test_a_picked_blends_locks_are_its_stances_as_planting_finds_them():
    library, blends = picked()
    assert len(blends) >= 90
    for blend in blends:
        ours = python_locks(library.skeleton, blend)
        theirs = blend["locks"]
        assert len(theirs) >= 2 and theirs.shape == ours.shape, (theirs, ours)
        np.testing.assert_allclose(theirs[:, :5], ours[:, :5], atol=1e-9)
        np.testing.assert_allclose(np.angle(np.exp(1j * (theirs[:, 5] - ours[:, 5]))), 0.0,
                                   atol=1e-9)


def test_a_picked_blends_feet_meet_the_targets():
    # measured on the samples' 98 blends: slide 1.86 mm, nothing below the floor, hover 1.40 mm
    # (posed from their series alone, without locks: slide 39.5 mm, 36.8 mm below the floor)
    _, blends = picked()
    slide, below, hover = (max(getattr(b["contact"], name) for b in blends)
                           for name in ("slide_m", "penetration_m", "hover_m"))
    assert slide <= SLIDE and below <= PENETRATION and hover <= HOVER, (slide, below, hover)
    assert min(b["contact"].stances for b in blends) >= 2
    # the locks are what holds them: without, the same poses slide and sink
    assert max(b["alone"].slide_m for b in blends) > 10 * SLIDE


def test_a_picked_blend_of_real_walks_meets_the_targets():
    # the real walks of several subjects and labs, drawn on the library's body: measured at
    # every tetrahedron's centroid (21 blends), slide 1.42 mm, nothing below the floor, hover
    # 2.16 mm (without locks: slide 37.8 mm, 18.7 mm below the floor)
    from viewer_poses import cell_centroids, viewer_blends
    from walking_library import real_walks

    library = real_walks()[0]
    blends = [b for b in viewer_blends(library, cell_centroids(library, 1)) if b is not None]
    assert len(blends) >= 10
    slide, below, hover = (max(getattr(b["contact"], name) for b in blends)
                           for name in ("slide_m", "penetration_m", "hover_m"))
    assert slide <= SLIDE and below <= PENETRATION and hover <= HOVER, (slide, below, hover)
    assert min(b["contact"].stances for b in blends) >= 2
