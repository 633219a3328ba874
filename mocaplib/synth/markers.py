"""Skin markers on the synthetic body, with the artefacts of a real capture.

Each protocol marker sits at its landmark's nominal offset (``Protocol.nominal_offsets``,
scaled by height) on its segment, then, each switchable through :class:`MarkerSettings`:

placement
    An offset from nominal, normal with ``placement_sd`` (default 3 mm) per axis, clipped at
    2.5 sd, in the segment frame: technicians never put markers exactly on the atlas. In a real
    session the markers stay on the subject between captures, so the offset belongs to the
    session: it is drawn from the session's own random stream (``placement_rng``, seeded by a
    plan's ``session_seed``) and is the same in every capture of that session. Without a
    session stream it is drawn from the capture's (a new placement per capture).
soft tissue
    A displacement in the segment frame that follows the nearby joints (a thigh marker moves
    with hip and knee flexion...): ``gain x sum_j c_j (q_j - mean q_j)`` with random unit-scale
    vectors ``c_j`` fixed per capture and gains of 1-12 mm/rad by segment (thigh largest, head
    least), i.e. several millimetres, as measured by bone-pin studies (Leardini et al. 2005).
    ``soft_tissue`` scales the gains (default 1; 0 turns it off); they also scale with the
    subject's body-mass index relative to 22.9 kg/m² (more soft tissue, more artefact).
richer body
    Markers feel the joints the fitting skeleton lacks: markers on the toes (past the
    metatarsal heads: hallux, 2nd toe) the toe joint, the finger marker the wrist, arm and
    acromion markers the shoulder girdle.
noise
    White measurement noise, ``noise_sd`` (default 0.7 mm) per coordinate.
gaps
    ``gaps`` occlusions (default 0): random markers missing (NaN) for random stretches of up to
    ``max_gap_s`` seconds.
swap
    ``swap`` (default off): one left/right pair exchanges its labels for the whole capture.

Clusters
    A protocol's tracking markers (on a segment, no landmark) are strapped on rigid plates, one
    per segment, where :data:`CLUSTER_PLATES` says: the k-th tracking marker of a segment is
    the plate's k-th corner. A plate is placed with its own error (:data:`PLATE_PLACEMENT`: 15
    mm and 10° sd, the session's), and its soft-tissue artefact is mostly rigid, as bone-pin
    studies find for thigh and shank clusters (Cappozzo et al. 1996; Leardini et al. 2005;
    Barré et al. 2013: the rigid part is the larger): the plate moves and turns as one
    (:data:`PLATE_TURN` radians of turn per radian of the driving joints, with the segment's
    gain of :data:`SOFT_TISSUE` for its move) and each marker adds a fifth of a skin marker's
    own artefact (the plate's deformation, the skin under each base).
    Markers a protocol flags ``static_only`` are written only on standing captures.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..errors import SynthError
from ..protocols import Protocol
from ..skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton
from .body import BodyMotion
from .gait import FootGeometry

_Q = {name: j for j, name in enumerate(DOF_NAMES)}
REFERENCE_BMI = 70.0 / 1.75 ** 2
#: Soft-tissue gain (m/rad) and the joints that drive it, by segment ("{s}": the marker's side).
SOFT_TISSUE = {
    "pelvis": (0.006, ("hip_flexion_{s}",)),
    "torso": (0.004, ("shoulder_flexion_{s}", "trunk_rotation")),
    "head": (0.001, ("neck_rotation",)),
    "humerus": (0.010, ("shoulder_flexion_{s}", "elbow_flexion_{s}")),
    "forearm": (0.005, ("elbow_flexion_{s}",)),
    "femur": (0.012, ("hip_flexion_{s}", "knee_flexion_{s}")),
    "tibia": (0.006, ("knee_flexion_{s}", "ankle_dorsiflexion_{s}")),
    "foot": (0.003, ("ankle_dorsiflexion_{s}",)),
}


#: Plate of a cluster on each segment (left side, 1.75 m subject, scaled by height; the right
#: mirrors y): its centre in the segment frame and its corners about the centre (m), an
#: irregular triangle facing outwards 15 mm off the skin, on the lateral thigh and shank and
#: the lateral upper arm and forearm, in their middle third.
CLUSTER_PLATES = {
    "femur": ((0.025, 0.090, -0.230), ((0.045, 0.0, 0.035), (-0.040, 0.005, 0.040),
                                        (0.005, 0.012, -0.055))),
    "tibia": ((0.020, 0.065, -0.190), ((0.040, 0.0, 0.035), (-0.035, 0.005, 0.040),
                                        (0.000, 0.010, -0.050))),
    "humerus": ((0.005, 0.060, -0.170), ((0.035, 0.0, 0.030), (-0.030, 0.005, 0.035),
                                          (0.000, 0.010, -0.045))),
    "forearm": ((0.010, 0.050, -0.120), ((0.030, 0.0, 0.030), (-0.030, 0.005, 0.030),
                                          (0.000, 0.010, -0.040))),
}
#: Placement error of a plate: sd of its centre per axis (m) and of its turn (rad).
PLATE_PLACEMENT = (0.015, np.deg2rad(10.0))
#: Soft-tissue turn of a plate, rad per rad of each driving joint's excursion (4°/rad).
PLATE_TURN = np.deg2rad(4.0)
#: Share of a skin marker's own soft-tissue artefact each plate marker keeps.
PLATE_DEFORMATION = 0.2


@dataclass(frozen=True)
class MarkerSettings:
    """Which artefacts to add, and how much (metres, seconds). Defaults are documented above."""

    placement_sd: float = 0.003
    soft_tissue: float = 1.0
    noise_sd: float = 0.0007
    gaps: int = 0
    max_gap_s: float = 0.3
    swap: bool = False

    def __post_init__(self):
        values = asdict(self)
        bad = {k: v for k, v in values.items() if k != "swap" and not (v >= 0)}
        if bad or not isinstance(self.gaps, int):
            raise SynthError(f"marker settings must be >= 0 (gaps a whole number), got {bad}")

    def as_dict(self) -> dict:
        return asdict(self)


def _side(landmark: str, segment: str) -> tuple[str, ...]:
    """The sides (``"l"``, ``"r"``) a marker on ``landmark`` and ``segment`` belongs to."""
    if landmark.startswith("L_") or segment.endswith("_l"):
        return ("l",)
    if landmark.startswith("R_") or segment.endswith("_r"):
        return ("r",)
    return ("l", "r")


def _small_turns(vectors: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors (..., 3) (Rodrigues)."""
    angle = np.linalg.norm(vectors, axis=-1)[..., None, None]
    k = np.zeros(vectors.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -vectors[..., 2], vectors[..., 1], -vectors[..., 0]
    k = k - np.swapaxes(k, -1, -2)
    with np.errstate(invalid="ignore", divide="ignore"):
        sin = np.where(angle > 0, np.sin(angle) / angle, 1.0)
        cos = np.where(angle > 0, (1 - np.cos(angle)) / angle ** 2, 0.5)
    return np.eye(3) + sin * k + cos * (k @ k)


def cluster_plates(protocol: Protocol, height: float, draw: np.random.Generator
                   ) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Each plate the protocol's tracking markers need: segment index -> (centre (3,) and
    corners (K, 3), placed with :data:`PLATE_PLACEMENT` drawn from ``draw``), in the segment
    frame, metres, for a subject ``height`` m tall. Raises :class:`SynthError` for a segment
    the generator has no plate for, or more markers than the plate has corners."""
    scale = height / 1.75
    plates = {}
    for segment in dict.fromkeys(m.landmark.segment for m in protocol.markers if m.tracking):
        bare, mirror = segment.rsplit("_", 1)[0], (-1.0 if segment.endswith("_r") else 1.0)
        count = sum(m.tracking and m.landmark.segment == segment for m in protocol.markers)
        if bare not in CLUSTER_PLATES or count > len(CLUSTER_PLATES[bare][1]):
            raise SynthError(
                f"protocol {protocol.name!r}: no synthetic cluster for {count} tracking "
                f"markers on {segment}", path=protocol.path,
                hint=f"the generator straps plates of up to 3 markers on "
                     f"{', '.join(CLUSTER_PLATES)}")
        centre, corners = (np.array(x, dtype=float) * scale for x in CLUSTER_PLATES[bare])
        centre[1] *= mirror
        corners[:, 1] *= mirror
        shift, turn = PLATE_PLACEMENT
        turned = _small_turns(draw.normal(0.0, turn, 3))
        plates[SEGMENT_NAMES.index(segment)] = (centre + draw.normal(0.0, shift, 3),
                                                corners[:count] @ turned.T)
    return plates


def _rotate_about_y(points: np.ndarray, centre: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Points (F, 3) rotated by ``angle`` (F,) about the -Y axis through ``centre`` (3,)."""
    d = points - centre
    c, s = np.cos(angle), np.sin(angle)
    return centre + np.stack([c * d[:, 0] - s * d[:, 2], d[:, 1], s * d[:, 0] + c * d[:, 2]], 1)


def skin_markers(body: BodyMotion, skeleton: Skeleton, protocol: Protocol, height: float,
                 settings: MarkerSettings, rng: np.random.Generator, *, rate: float,
                 mass: float = 70.0, placement_rng: np.random.Generator | None = None
                 ) -> tuple[np.ndarray, list[str], dict]:
    """Marker positions (F, M, 3) m (NaN in gaps), labels (M,) and a record of what was done
    (``{"gaps": [...], "swap": [a, b] or None}``). Soft-tissue gains grow with the body-mass
    index (``mass`` kg / ``height``² relative to 22.9 kg/m², that of 70 kg at 1.75 m).
    ``placement_rng`` (the session's stream) draws the placement offsets, else ``rng``."""
    q = body.q
    n = len(q)
    segments, nominal = protocol.nominal_offsets(height)
    names = [m.landmark.name for m in protocol.markers]
    labels = list(protocol.labels)
    sd = settings.placement_sd
    draw = rng if placement_rng is None else placement_rng
    placed = nominal + np.clip(draw.normal(0.0, sd, nominal.shape), -2.5 * sd, 2.5 * sd)
    plates = cluster_plates(protocol, height, draw)
    corner = {}
    for m, marker in enumerate(protocol.markers):
        if marker.tracking:
            corner[m] = k = sum(corner.get(i) is not None and segments[i] == segments[m]
                                for i in corner)
            placed[m] = plates[segments[m]][0] + plates[segments[m]][1][k]
    local = np.broadcast_to(placed, (n,) + placed.shape).copy()
    geom = FootGeometry.from_skeleton(skeleton)
    forearm = skeleton.lengths["forearm"]
    centred = q - q.mean(axis=0)
    tissue = settings.soft_tissue * mass / height ** 2 / REFERENCE_BMI
    for s, (centre, _) in plates.items():
        gain, dofs = SOFT_TISSUE[SEGMENT_NAMES[s].rsplit("_", 1)[0]]
        side = SEGMENT_NAMES[s][-1]
        drive = centred[:, [_Q[dof.format(s=side)] for dof in dofs]]            # (F, J)
        move = drive @ rng.normal(0.0, 1.0 / np.sqrt(3.0), (len(dofs), 3))
        turn = _small_turns(tissue * PLATE_TURN * (drive @ rng.normal(
            0.0, 1.0 / np.sqrt(3.0), (len(dofs), 3))))                          # (F, 3, 3)
        on = [m for m in corner if segments[m] == s]
        local[:, on] = (centre + np.einsum("fij,mj->fmi", turn, placed[on] - centre)
                        + tissue * gain * move[:, None])
    for m, (name, seg) in enumerate(zip(names, segments)):
        seg_name = SEGMENT_NAMES[seg]
        sides = _side(name, seg_name)
        col = 0 if sides == ("l",) else 1
        if name.endswith("_FINGER"):
            local[:, m] = _rotate_about_y(local[:, m], np.array([0, 0, -forearm]),
                                          body.wrist[:, col])
        elif seg_name.startswith("foot") and nominal[m, 0] > geom.mtp + 0.01:   # on the toes
            local[:, m] = _rotate_about_y(local[:, m], np.array([geom.mtp, 0, -geom.ankle_height]),
                                          body.toe[:, col])
        gain, dofs = SOFT_TISSUE[seg_name.rsplit("_", 1)[0]]
        for dof in dofs:
            for side in (sides if "{s}" in dof else ("",)):
                j = _Q[dof.format(s=side)]
                direction = rng.normal(0.0, 1.0 / np.sqrt(3.0), 3)
                share = PLATE_DEFORMATION if m in corner else 1.0
                local[:, m] += share * tissue * gain * centred[:, j, None] * direction
    transforms = skeleton.forward(q)
    T = transforms[:, segments]
    world = np.einsum("fmij,fmj->fmi", T[..., :3, :3], local) + T[..., :3, 3]
    torso = transforms[:, SEGMENT_NAMES.index("torso"), :3, :3]
    for m, (name, seg) in enumerate(zip(names, segments)):
        seg_name = SEGMENT_NAMES[seg]
        if seg_name.startswith(("humerus", "forearm")) or name.endswith("_ACROMION"):
            col = 0 if _side(name, seg_name) == ("l",) else 1
            world[:, m] += np.einsum("fij,fj->fi", torso, body.girdle[:, col])
    world += rng.normal(0.0, settings.noise_sd, world.shape)

    record: dict = {"gaps": [], "swap": None}
    for _ in range(settings.gaps):
        m = int(rng.integers(len(labels)))
        length = int(rng.integers(2, max(3, int(settings.max_gap_s * rate) + 1)))
        start = int(rng.integers(0, max(1, n - length)))
        world[start:start + length, m] = np.nan
        record["gaps"].append({"label": labels[m], "start_frame": start + 1,
                               "end_frame": min(start + length, n)})
    if settings.swap:
        pairs = [(a, labels.index("R" + a[1:])) for a in labels
                 if a.startswith("L") and "R" + a[1:] in labels]
        if pairs:
            left, right = pairs[int(rng.integers(len(pairs)))]
            i = labels.index(left)
            labels[i], labels[right] = labels[right], labels[i]
            record["swap"] = [left, labels[i]]
    return world, labels, record
