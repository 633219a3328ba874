"""Front and back, left and right: the subject's forward direction from the marker set's
front/back cues (:func:`forward_cues`, :func:`forward_direction`), which tell left/right
markers whose labels are exchanged (:func:`mocaplib.markersets.matching.find_side_swaps`).

Markers are ``(F, M, 3)`` arrays in metres, Z up.
"""

from __future__ import annotations

import numpy as np

from .protocols import role_landmarks

#: The catalogue's roles (:func:`mocaplib.markersets.protocols.role_landmarks`) of the front
#: and back landmarks giving the subject's forward direction, in order of trust. A side is
#: usable in a frame when its central landmark or both sided ones are present.
FORWARD_CUE_ROLES = (("pelvis_front", "pelvis_back"), ("chest_front", "spine"),
                     ("head_front", "head_back"))


def forward_direction(by_landmark: dict[str, np.ndarray], n_frames: int) -> np.ndarray:
    """Unit horizontal forward direction per frame, shape (F, 2), NaN where unknown: the
    first of :func:`forward_cues` known in each frame."""
    forward = np.full((n_frames, 2), np.nan)
    for cue in forward_cues(by_landmark, n_frames):
        todo = np.isnan(forward[:, 0])
        forward[todo] = cue[todo]
    return forward


def forward_cues(by_landmark: dict[str, np.ndarray], n_frames: int) -> list[np.ndarray]:
    """The unit horizontal forward direction per frame (F, 2), NaN where unknown, from each
    front/back cue the landmarks (``by_landmark``: name -> (F, 3)) give, in this order: ASIS
    against PSIS or sacrum, sternum against spine, front against back of the head (each the
    mean of a pair, so an exchange of left and right leaves it)."""
    out = []
    for anterior, posterior in FORWARD_CUE_ROLES:
        front = _side_mean(by_landmark, role_landmarks(anterior))
        back = _side_mean(by_landmark, role_landmarks(posterior))
        if front is None or back is None:
            continue
        cue = (front - back)[:, :2]
        norm = np.linalg.norm(cue, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            out.append(np.where(norm > 1e-3, cue / norm, np.nan))
    return out


def _side_mean(by_landmark: dict[str, np.ndarray], names: tuple[str, ...]) -> np.ndarray | None:
    """Per-frame mean of balanced landmarks (each central one, or both of a sided pair)."""
    parts = []
    for name in names:
        if name.startswith("L_"):
            pair = [by_landmark.get(name), by_landmark.get("R_" + name[2:])]
            if all(p is not None for p in pair):
                parts.append((pair[0] + pair[1]) / 2)
        elif not name.startswith("R_") and name in by_landmark:
            parts.append(by_landmark[name])
    if not parts:
        return None
    stack = np.stack(parts)
    count = np.isfinite(stack[..., 0]).sum(axis=0)
    mean = np.nansum(stack, axis=0) / np.maximum(count, 1)[:, None]
    mean[count == 0] = np.nan
    return mean
