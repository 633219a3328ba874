"""Segments from the motion itself, for :func:`mocaplib.markersets.draft.draft_protocol`.

Rigid clusters
    Markers on one bone keep their distances over the capture. The spread of each pair's
    distance (:func:`distance_spread`: the interquartile range over the frames both are seen,
    as a standard deviation, so that gaps and a few swapped frames do not count) is clustered
    hierarchically (complete linkage): every pair of a cluster spreads less than
    :func:`rigid_threshold`, a few times the capture's noise (the spread of each marker's most
    rigid pair), between :data:`RIGID_MIN` and :data:`RIGID_MAX`. On the shared files pairs of
    one segment spread 1.3-3.1 mm (median), pairs of two segments 2.8 mm and more (5th
    percentile): a marker near a joint's axis can be rigid with both bones, and the cluster
    whose spread is smaller takes it.
The head
    Two rigid clusters are two bones. The head's markers move together and apart from the
    trunk's: the highest cluster (:func:`head_cluster`) is the head when it is compact (no
    wider than :data:`HEAD_WIDTH`) and wholly above every other cluster, as a head sits above
    C7 and the acromions. The drafter then takes the highest marker for the head's (which sets
    the subject's height) and :func:`motion_cost` adds :data:`MOTION_PENALTY`, weighted by each
    member's confidence (how far inside the threshold its cluster's spreads stay), to every
    landmark off the head: a head whose places alone sit nearer the trunk's landmarks (a
    runner's forward lean) is kept on the head.
"""

from __future__ import annotations

import warnings

import numpy as np

#: Frames a pair must be seen together in for its distance's spread to count.
MIN_FRAMES = 10
#: At most this many frames are read for the spreads (evenly spaced): enough for the
#: quartiles, and the (F, M, M) distances stay small on long captures.
MAX_FRAMES = 400
#: Bounds (m) of the rigidity threshold: a few times the capture's noise, never under 3 mm
#: (the real files' pairs of one segment spread 1.3-3.1 mm, median) nor over 6 mm (pairs of two
#: segments spread 2.8-7 mm and more, 5th percentile).
RIGID_MIN = 0.003
RIGID_MAX = 0.006
#: The threshold is this many times the capture's noise (the median of each marker's
#: smallest spread, m) when that falls between the bounds.
NOISE_FACTOR = 3.0
#: The head's cluster holds at least this many markers, no farther apart than this (m): head
#: markers lie within 0.2 m of each other, the acromions 0.3 m and more apart.
HEAD_MARKERS = 3
HEAD_WIDTH = 0.25
#: Cost (m) added to a landmark off the segment of the marker's cluster, at full confidence.
MOTION_PENALTY = 0.15


def distance_spread(X: np.ndarray) -> np.ndarray:
    """Spread (M, M) m of each pair's distance over the frames of X (F, M, 3) m: the
    interquartile range / 1.349 (a standard deviation for normal noise); inf for a pair seen
    together in fewer than :data:`MIN_FRAMES` frames and on the diagonal."""
    step = max(1, len(X) // MAX_FRAMES)
    X = X[::step]
    d = np.linalg.norm(X[:, :, None] - X[:, None], axis=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        low, high = np.nanpercentile(d, [25, 75], axis=0)
    spread = (high - low) / 1.349
    spread[(np.isfinite(d).sum(axis=0) < MIN_FRAMES) | ~np.isfinite(spread)] = np.inf
    np.fill_diagonal(spread, np.inf)
    return spread


def rigid_threshold(spread: np.ndarray) -> float:
    """The capture's rigidity threshold (m) from the spreads (M, M): :data:`NOISE_FACTOR`
    times the median of each marker's smallest spread, within [:data:`RIGID_MIN`,
    :data:`RIGID_MAX`]."""
    smallest = spread.min(axis=1)
    smallest = smallest[np.isfinite(smallest)]
    noise = float(np.median(smallest)) if len(smallest) else 0.0
    return float(np.clip(NOISE_FACTOR * noise, RIGID_MIN, RIGID_MAX))


def rigid_clusters(X: np.ndarray) -> tuple[list[list[int]], np.ndarray]:
    """Rigid clusters of the markers X (F, M, 3) m, as the module describes: the clusters of
    two markers or more (indices into M, most members first) and each marker's weight (M,)
    0-1 as evidence of its cluster's segment: 1 minus the median spread of its cluster's pairs
    over the threshold; 0 for a marker in no cluster, or rigid also with a marker outside its
    cluster (near a joint's axis, on either bone)."""
    from scipy.cluster.hierarchy import fcluster, linkage  # heavy: loaded when a draft runs
    from scipy.spatial.distance import squareform

    spread = distance_spread(X)
    weights = np.zeros(len(spread))
    if len(spread) < 2:
        return [], weights
    threshold = rigid_threshold(spread)
    finite = np.where(np.isfinite(spread), spread, 1.0)        # 1 m: never rigid
    np.fill_diagonal(finite, 0.0)
    labels = fcluster(linkage(squareform(finite, checks=False), method="complete"),
                      t=threshold, criterion="distance")
    clusters = sorted(([int(k) for k in np.flatnonzero(labels == c)] for c in set(labels)),
                      key=len, reverse=True)
    clusters = [c for c in clusters if len(c) > 1]
    for members in clusters:
        inside = spread[np.ix_(members, members)][~np.eye(len(members), dtype=bool)]
        outside = np.delete(spread[members], members, axis=1)
        own = np.nanmedian(np.where(np.eye(len(members), dtype=bool), np.nan,
                                    spread[np.ix_(members, members)]), axis=1)
        shared = outside.min(axis=1, initial=np.inf) < own     # as rigid with another body
        weights[members] = np.where(shared, 0.0,
                                    np.clip(1.0 - np.median(inside) / threshold, 0.0, 1.0))
    return clusters, weights


def head_cluster(X: np.ndarray, clusters: list[list[int]]) -> int | None:
    """The index of the cluster that is the head, or None: the cluster of
    :data:`HEAD_MARKERS` markers or more, no wider than :data:`HEAD_WIDTH`, whose every member
    sits above every marker of the other clusters (median heights over X (F, M, 3) m, Z up).
    The trunk's top cluster (acromions, C7) is wider; a marker set without head markers has no
    such cluster."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        heights = np.nanmedian(X[..., 2], axis=0)
        centre = np.nanmedian(X, axis=0)
    if not clusters:
        return None
    lowest = [min(heights[c]) for c in clusters]          # each cluster's lowest member (m)
    top = int(np.nanargmax(lowest))
    members = clusters[top]
    others = [k for i, c in enumerate(clusters) if i != top for k in c]
    width = np.linalg.norm(centre[members][:, None] - centre[members][None], axis=2).max()
    if len(members) >= HEAD_MARKERS and width <= HEAD_WIDTH and others \
            and lowest[top] > np.nanmax(heights[others]):
        return top
    return None


def motion_cost(weights: np.ndarray, clusters: list[list[int]], segments: list[str | None],
                lm_segments: list[str]) -> np.ndarray:
    """Extra cost (M, L) m: :data:`MOTION_PENALTY` times each marker's weight (M,) from
    :func:`rigid_clusters` on every landmark off the segment its cluster rides on
    (``segments``, per cluster)."""
    extra = np.zeros((len(weights), len(lm_segments)))
    for members, segment in zip(clusters, segments):
        if segment is not None:
            off = np.array([s != segment for s in lm_segments])
            extra[members] = MOTION_PENALTY * weights[members, None] * off[None]
    return extra
