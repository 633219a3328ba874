"""The sample data the figures draw, computed once per docs build with mocaplib's own functions
from the shipped captures (``sample_c3d/``)."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

SAMPLES = Path(__file__).resolve().parents[2] / "sample_c3d"
#: The captures of the small library the control-space figures show: each velocity class of
#: the samples at its normal speed, and the spot turns and runs.
LIBRARY_CAPTURES = (
    "walk_straight_slow", "walk_straight_normal", "walk_straight_fast",
    "walk_curve_r1_left_normal", "walk_curve_r1_right_normal", "walk_curve_r2_left_normal",
    "walk_curve_r2_right_normal", "side_left_normal", "side_right_normal",
    "diag_left_60_normal", "diag_right_60_normal", "diag_left_120_normal",
    "diag_right_120_normal", "turn_spot_left_normal", "turn_spot_right_normal",
    "side_left_curve_left_r2", "side_right_curve_right_r2", "run_2p5")


@lru_cache(maxsize=None)
def static():
    """The session's static trial (neutral pose)."""
    from mocaplib import read_c3d

    return read_c3d(SAMPLES / "rest.c3d")


@lru_cache(maxsize=None)
def capture(name: str):
    """One sample capture read, fitted, its events and cycles: ``(trial, fitted, events,
    cycles)`` as ``mocaplib cycles`` computes them (:func:`mocaplib.process`)."""
    from mocaplib import process

    done = process(SAMPLES / f"{name}.c3d", static=static(), static_pose="neutral")
    return done.trial, done.fitted, done.events, done.cycles


@lru_cache(maxsize=None)
def library():
    """The :class:`~mocaplib.library.format.Library` of :data:`LIBRARY_CAPTURES`, built in
    this process as ``mocaplib build`` builds it."""
    from mocaplib.build.pipeline import build_library
    from mocaplib.build.settings import BuildSettings

    settings = BuildSettings(static=str(SAMPLES / "rest.c3d"), static_pose="neutral")
    return build_library([SAMPLES / f"{name}.c3d" for name in LIBRARY_CAPTURES], settings,
                         progress=False).library


@lru_cache(maxsize=None)
def capture_static():
    """The static trial fitted on itself (neutral pose), as ``mocaplib fit`` fits it."""
    from mocaplib.model.fitting import fit_capture

    return fit_capture(static(), static=static(), static_pose="neutral")
