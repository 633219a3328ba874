"""An entry's cycle seen from a later instant (mocaplib.library.phase): the same motion, and a cycle that
starts at a right toe-off read from its left toe-off by the control space and the mirror."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mocaplib.gait.fourier import RootDrift, synthesize
from mocaplib.skeleton import ROOT_X, ROOT_Y
from mocaplib.library.phase import from_left_toe_off, start_later
from mocaplib.skeleton import DOF_NAMES, ROOT_HEADING

from test_controlspace import hand_library
from test_mirror import _entry

ROOT = [ROOT_X, ROOT_Y, ROOT_HEADING]


def _world(entry, t):
    q = synthesize(entry.fourier.a, entry.fourier.b, entry.T, t)
    return RootDrift(0, 0, 0, *entry.root_drift.velocities).restore(q, t)


def _right_toe_off_start(entry):
    """``entry`` (starting at a left toe-off) cut from its right toe-off instead, flagged as a
    build flags a fallback cycle."""
    tau = entry.right_toe_off_s
    return start_later(entry, tau, cycle_start="right_toe_off",
                       left_toe_off_s=float(entry.T) - tau)


def test_a_later_start_is_the_same_motion_from_there():
    entry = _entry(seed=5)
    later = _right_toe_off_start(entry)
    assert later.cycle_start == "right_toe_off" and later.right_toe_off_s == 0.0
    np.testing.assert_allclose(later.start_s, entry.start_s + entry.right_toe_off_s)
    t = np.linspace(0.0, 2.5, 60)
    source = _world(entry, t + entry.right_toe_off_s)
    seen = _world(later, t)
    # joints equal to round-off; the root a constant rigid motion of the floor away
    np.testing.assert_allclose(np.delete(seen, ROOT, axis=1), np.delete(source, ROOT, axis=1),
                               atol=1e-12)
    turn = seen[:, ROOT_HEADING] - source[:, ROOT_HEADING]
    c, s = np.cos(turn), np.sin(turn)
    moved = np.column_stack([seen[:, ROOT_X] - (c * source[:, ROOT_X] - s * source[:, ROOT_Y]),
                             seen[:, ROOT_Y] - (s * source[:, ROOT_X] + c * source[:, ROOT_Y])])
    assert np.ptp(turn) < 1e-12 and np.ptp(moved, axis=0).max() < 1e-12


def test_from_left_toe_off_gives_the_cycle_from_its_left_toe_off_back():
    entry = _entry()
    back = from_left_toe_off(_right_toe_off_start(entry))
    assert back.cycle_start is None and back.left_toe_off_s is None
    np.testing.assert_allclose(back.start_s, entry.start_s + entry.T)   # one period on
    np.testing.assert_allclose(back.right_toe_off_s, entry.right_toe_off_s, atol=1e-12)
    # series and drift of the same cycle: equal to round-off (1e-12 rad or m)
    np.testing.assert_allclose(back.fourier.a, entry.fourier.a, atol=1e-12)
    np.testing.assert_allclose(back.fourier.b, entry.fourier.b, atol=1e-12)
    np.testing.assert_allclose(back.root_drift.velocities, entry.root_drift.velocities,
                               atol=1e-12)
    assert from_left_toe_off(entry) is entry


def test_an_entry_needs_both_cycle_start_and_its_left_toe_off():
    from mocaplib.errors import LibraryError

    with pytest.raises(LibraryError, match="needs both cycle_start .* and left_toe_off_s"):
        replace(_entry(), cycle_start="right_toe_off")
    with pytest.raises(LibraryError, match="needs both cycle_start"):
        replace(_entry(), cycle_start="left_toe_off", left_toe_off_s=0.3)


def test_the_mirror_of_a_fallback_entry_is_that_of_its_cycle_from_left_toe_off():
    from mocaplib.library.mirror import mirror_entry

    entry = _entry()
    image = mirror_entry(_right_toe_off_start(entry))
    expected = mirror_entry(entry)
    assert image.cycle_start is None
    np.testing.assert_allclose(image.fourier.a, expected.fourier.a, atol=1e-12)
    np.testing.assert_allclose(image.fourier.b, expected.fourier.b, atol=1e-12)
    np.testing.assert_allclose(image.start_s, expected.start_s + entry.T)


def test_the_control_space_blends_a_fallback_entry_from_its_left_toe_off():
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.format import assemble_library

    rng = np.random.default_rng(2)
    n = len(DOF_NAMES)
    a, b = rng.normal(0, 0.1, (2, 5, n, 3))
    b[..., 0] = 0.0
    points = [(0.5, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 0.5, 0.0), (1.0, 0.0, 0.3),
              (1.5, 0.2, 0.1)]
    library = hand_library(points, a=a, b=b)
    plain = library.entries[4]
    flagged = start_later(replace(plain, right_toe_off_s=0.4), 0.4,
                          cycle_start="right_toe_off", left_toe_off_s=0.6)
    assert not np.allclose(flagged.fourier.a, plain.fourier.a)
    mixed = assemble_library([*library.entries[:4], flagged], settings={})
    cs = ControlSpace.from_library(mixed)
    row = cs.ids.index(flagged.id)
    np.testing.assert_allclose(cs.a[row], plain.fourier.a, atol=1e-12)
    np.testing.assert_allclose(cs.b[row], plain.fourier.b, atol=1e-12)
