"""Runs of frames along time (numpy only: the Trial container, the filters and the cycles all
use it): the runs of valid samples, and the run of frames between two times, found in O(1)
rather than by a mask over the whole capture."""

from __future__ import annotations

import math

import numpy as np


def valid_runs(valid: np.ndarray) -> np.ndarray:
    """(start, stop) pairs (R, 2) of the runs of True in ``valid`` (F,) bool, stop exclusive."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(valid, int), [0]])))
    return edges.reshape(-1, 2)


def frames_within(start_s: float, end_s: float, rate: float, n_frames: int) -> slice:
    """The frames k of a capture of ``n_frames`` at ``rate`` Hz whose time ``k / rate`` lies
    in [``start_s``, ``end_s``] (s), as a slice: the same frames as the mask
    ``(np.arange(n_frames) / rate >= start_s) & (np.arange(n_frames) / rate <= end_s)``,
    in O(1) whatever the capture's length (an empty slice when there is none)."""
    rate = float(rate)
    return slice(_first_at_or_after(start_s, rate, n_frames),
                 _first_at_or_after(end_s, rate, n_frames, strictly=True))


def _first_at_or_after(time_s: float, rate: float, n_frames: int, *,
                       strictly: bool = False) -> int:
    """The first frame k in [0, n_frames] with ``k / rate >= time_s`` (``> time_s`` when
    ``strictly``): a guess from ``time_s * rate``, moved until the division, rounded as numpy
    rounds it, agrees."""
    if math.isnan(time_s):
        return n_frames
    def after(k: int) -> bool:
        return k / rate > time_s if strictly else k / rate >= time_s
    guess = math.ceil(time_s * rate) if math.isfinite(time_s) else (0 if time_s < 0 else n_frames)
    k = min(max(guess, 0), n_frames)
    while k > 0 and after(k - 1):
        k -= 1
    while k < n_frames and not after(k):
        k += 1
    return k
