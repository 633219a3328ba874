"""Segments from the motion (mocaplib.markersets.draft_motion): rigid clusters of a synthetic
walk, whose markers ride on known segments, and the head found by the chain."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.io.c3d import read_c3d
from mocaplib.library.command import Command
from mocaplib.markersets.draft import _motion_markers, marker_labels
from mocaplib.markersets.draft_motion import (MOTION_PENALTY, head_cluster, motion_cost,
                                              rigid_clusters)
from mocaplib.markersets.matching import match_protocol
from mocaplib.markersets.protocols import load_protocol
from mocaplib.synth.capture import synthesize_capture


def _walk(protocol):
    """A synthetic straight walk with ``protocol``'s markers: the trajectories (F, M, 3) and
    each marker's segment (M,)."""
    trial = synthesize_capture(Command.from_kind("straight", speed=1.2), duration=2.7, seed=1,
                               protocol=protocol, session_seed=4).trial
    match = match_protocol(trial, load_protocol(protocol))
    segment = {i: m.landmark.segment for m, i in zip(match.protocol.markers, match.indices)}
    return trial.markers, [segment.get(i) for i in range(len(trial.labels))]


def test_rigid_clusters_hold_markers_of_one_segment():
    X, segments = _walk("cluster_fullbody")
    clusters, weights = rigid_clusters(X)
    assert len(clusters) >= 10, clusters          # pelvis, trunk, head, two of each limb bone
    for members in clusters:
        # the synthetic markers have 1 mm noise and no skin motion: a cluster is one bone,
        # or a bone and a landmark on its joint's axis (rigid with both bones)
        assert len({segments[k] for k in members}) <= 2, [segments[k] for k in members]
    assert weights.shape == (X.shape[1],) and ((weights >= 0) & (weights <= 1)).all()
    assert np.count_nonzero(weights) >= X.shape[1] // 2      # most markers carry evidence


@pytest.mark.parametrize("name, has_head", [("cmu/07_01.c3d", True),
                                             ("c3dviewer_examples/running.c3d", True),
                                             ("btkdata/Gait.c3d", False)])
def test_the_head_is_the_compact_cluster_above_the_others(real_c3d, name, has_head):
    # real captures: the synthetic walker's head does not move on its trunk
    trial = read_c3d(real_c3d(name))
    labels = marker_labels(trial)
    X = _motion_markers(trial, labels)
    clusters, _ = rigid_clusters(X)
    head = head_cluster(X, clusters)
    if has_head:          # the four Plug-in Gait head markers, and only they
        assert head is not None
        assert sorted(labels[k] for k in clusters[head]) == ["LBHD", "LFHD", "RBHD", "RFHD"]
    else:                 # Helen Hayes has no head marker: its top cluster is the trunk's
        assert head is None


def test_motion_cost_penalises_landmarks_off_the_clusters_segment():
    weights = np.array([1.0, 0.5, 0.0])
    extra = motion_cost(weights, [[0, 1], [2]], ["head", None], ["head", "torso", "head"])
    np.testing.assert_allclose(extra, [[0, MOTION_PENALTY, 0], [0, MOTION_PENALTY / 2, 0],
                                       [0, 0, 0]])


def test_a_single_marker_has_no_cluster():
    clusters, weights = rigid_clusters(np.zeros((20, 1, 3)))
    assert clusters == [] and weights.tolist() == [0.0]
