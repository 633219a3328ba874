"""Small synthetic trials for protocol and inspect tests: a protocol's markers at their nominal
landmark positions on the nominal 1.75 m skeleton, standing upright and gliding along a heading."""

from __future__ import annotations

import numpy as np

from fk_data import neutral_q
from mocaplib.markersets.protocols import Protocol
from mocaplib.skeleton import DOF_NAMES, Skeleton
from mocaplib.trial import Trial


def select(trial: Trial, indices) -> Trial:
    """A copy of ``trial`` holding only the markers at ``indices`` (same frames)."""
    indices = list(indices)
    return Trial(trial.markers[:, indices, :], [trial.labels[i] for i in indices], trial.rate,
                 first_frame=trial.first_frame, units=trial.units,
                 vertical_axis=trial.vertical_axis, events=list(trial.events),
                 source=trial.source, warnings=list(trial.warnings))


def walker_trial(protocol: Protocol, *, heading: float = 0.0, speed: float = 1.2,
                 n_frames: int = 40, rate: float = 100.0, labels=None) -> Trial:
    """Markers (F, M, 3) m of ``protocol`` in the neutral pose, facing and moving along
    ``heading`` (rad, CCW from +X) at ``speed`` m/s; ``labels`` renames the markers."""
    skeleton = Skeleton.from_height(1.75)
    segments, offsets = protocol.nominal_offsets()
    q = neutral_q(skeleton, n_frames)
    travel = speed * np.arange(n_frames) / rate
    q[:, DOF_NAMES.index("pelvis_tx")] = travel * np.cos(heading)
    q[:, DOF_NAMES.index("pelvis_ty")] = travel * np.sin(heading)
    q[:, DOF_NAMES.index("pelvis_rotation")] = heading
    markers = skeleton.points(q, segments, offsets)
    return Trial(markers, list(labels or protocol.labels), rate)
