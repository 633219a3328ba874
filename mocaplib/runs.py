"""Runs of valid samples along time (numpy only: the Trial container and the filters both use
it)."""

from __future__ import annotations

import numpy as np


def valid_runs(valid: np.ndarray) -> np.ndarray:
    """(start, stop) pairs (R, 2) of the runs of True in ``valid`` (F,) bool, stop exclusive."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(valid, int), [0]])))
    return edges.reshape(-1, 2)
