"""Skin markers on the synthetic body, with the artefacts of a real capture.

Each protocol marker sits where the generator's body (:mod:`.bones`, ``synthetic_body.toml``)
puts its landmark's marker, on its own bone (the fit's landmark catalogue is not read), then,
each switchable through :class:`MarkerSettings`:

placement
    An offset from there, normal with ``placement_sd`` (default 3 mm) per axis, clipped at
    2.5 sd, in the bone's frame: technicians never put markers exactly on the landmark. In a
    real session the markers stay on the subject between captures, so the offset belongs to
    the session: it is drawn from the session's own random stream (``placement_rng``, seeded
    by a plan's ``session_seed``) and is the same in every capture of that session. Without a
    session stream it is drawn from the capture's (a new placement per capture).
soft tissue
    A displacement in the bone's frame that follows the nearby joints (a thigh marker moves
    with hip and knee flexion...): ``gain x sum_j c_j (q_j - mean q_j)`` with random unit-scale
    vectors ``c_j`` fixed per capture and gains of 1-12 mm/rad by bone (thigh largest, head
    least), i.e. several millimetres, as measured by bone-pin studies (Leardini et al. 2005).
    ``soft_tissue`` scales the gains (default 1; 0 turns it off); they also scale with the
    subject's body-mass index relative to 22.9 kg/m² (more soft tissue, more artefact).
the body's own joints
    Markers ride on the bones that carry them, so they feel every joint of the body, those the
    fitting skeleton lacks too: a flexible spine (T10 and L5 apart from C7), the shoulder
    girdle (acromion, scapula), the toes (hallux, 2nd toe), the hands (finger markers), the
    knee's rollback and screw-home rotation, the subtalar joint.
noise
    White measurement noise, ``noise_sd`` (default 0.7 mm) per coordinate.
gaps
    ``gaps`` occlusions (default 0): random markers missing (NaN) for random stretches of up to
    ``max_gap_s`` seconds.
swap
    ``swap`` (default off): one left/right pair exchanges its labels for the whole capture.

Clusters
    A protocol's tracking markers (on a segment, no landmark) are strapped on rigid plates, one
    per segment's bone, where :data:`CLUSTER_PLATES` says: the k-th tracking marker of a
    segment is the plate's k-th corner. A plate is placed with its own error
    (:data:`PLATE_PLACEMENT`: 15 mm and 10° sd, the session's), and its soft-tissue artefact is
    mostly rigid, as bone-pin studies find for thigh and shank clusters (Cappozzo et al. 1996;
    Leardini et al. 2005; Barré et al. 2013: the rigid part is the larger): the plate moves and
    turns as one (:data:`PLATE_TURN` radians of turn per radian of the driving joints, with the
    bone's gain of :data:`SOFT_TISSUE` for its move) and each marker adds a fifth of a skin
    marker's own artefact (the plate's deformation, the skin under each base).
    Markers a protocol flags ``static_only`` are written only on standing captures.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..errors import SynthError
from ..markersets.protocols import Protocol
from .body import BodyMotion
from .bones import Body, vector_turn

REFERENCE_BMI = 70.0 / 1.75 ** 2
#: Soft-tissue gain (m/rad) and the joint angles that drive it, by the kind of bone a marker
#: rides on: (bone, angle index), "{s}" the marker's side (both for a central marker).
SOFT_TISSUE = {
    "pelvis": (0.006, (("femur_{s}", 0),)),
    "lumbar": (0.006, (("femur_{s}", 0),)),
    "thorax": (0.004, (("humerus_{s}", 0), ("thorax", 2))),
    "girdle": (0.004, (("humerus_{s}", 0), ("thorax", 2))),
    "head": (0.001, (("head", 2),)),
    "humerus": (0.010, (("humerus_{s}", 0), ("forearm_{s}", 0))),
    "forearm": (0.005, (("forearm_{s}", 0),)),
    "hand": (0.003, (("hand_{s}", 0),)),
    "femur": (0.012, (("femur_{s}", 0), ("tibia_{s}", 0))),
    "tibia": (0.006, (("tibia_{s}", 0), ("talus_{s}", 0))),
    "foot": (0.003, (("talus_{s}", 0),)),
    "toes": (0.003, (("toes_{s}", 0),)),
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


def _bone_of(segment: str) -> str:
    """The body's bone a fitting segment's tracking markers ride on (``torso`` -> ``thorax``)."""
    bare, _, side = segment.partition("_")
    return {"torso": "thorax"}.get(bare, bare) + (f"_{side}" if side else "")


def cluster_plates(protocol: Protocol, body: Body, draw: np.random.Generator
                   ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each plate the protocol's tracking markers need: segment name -> (centre (3,) and
    corners (K, 3), placed with :data:`PLATE_PLACEMENT` drawn from ``draw``), in the frame of
    the body's bone of that name, metres. Raises :class:`SynthError` for a segment the
    generator has no plate for, or more markers than the plate has corners."""
    scale = body.height / 1.75
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
        turned = vector_turn(draw.normal(0.0, turn, 3))
        plates[segment] = (centre + draw.normal(0.0, shift, 3), corners[:count] @ turned.T)
    return plates


def _drivers(body: Body, motion: BodyMotion, bone: str, side: str) -> np.ndarray:
    """The joint angles (F, J) that drive the soft tissue of a marker on ``bone`` (a body bone
    name) of ``side`` ("l", "r", or "" for a central marker: both sides' drive it), each
    centred on its mean over the capture."""
    kind = bone.rsplit("_", 1)[0] if bone.endswith(("_l", "_r")) else bone
    columns = []
    for name, k in SOFT_TISSUE[kind][1]:
        for s in ((side,) if side else ("l", "r")) if "{s}" in name else ("",):
            columns.append(motion.pose.angles[name.format(s=s)][:, k])
    drive = np.stack(columns, axis=1)
    return drive - drive.mean(axis=0)


def _side_of(label_landmark: str, bone: str) -> str:
    """The side ("l", "r") of a marker on ``label_landmark`` and ``bone``, "" when central."""
    if label_landmark.startswith(("L_", "R_")):
        return label_landmark[0].lower()
    return bone[-1] if bone.endswith(("_l", "_r")) else ""


def _gain(bone: str) -> float:
    kind = bone.rsplit("_", 1)[0] if bone.endswith(("_l", "_r")) else bone
    return SOFT_TISSUE[kind][0]


def skin_markers(motion: BodyMotion, body: Body, protocol: Protocol,
                 settings: MarkerSettings, rng: np.random.Generator, *, rate: float,
                 mass: float = 70.0, placement_rng: np.random.Generator | None = None
                 ) -> tuple[np.ndarray, list[str], dict]:
    """Marker positions (F, M, 3) m (NaN in gaps), labels (M,) and a record of what was done
    (``{"gaps": [...], "swap": [a, b] or None}``). Soft-tissue gains grow with the body-mass
    index (``mass`` kg / height² relative to 22.9 kg/m², that of 70 kg at 1.75 m).
    ``placement_rng`` (the session's stream) draws the placement offsets, else ``rng``.
    Raises :class:`SynthError` for a protocol landmark the body has no place for."""
    n = len(motion.time)
    labels = list(protocol.labels)
    bones, nominal = [], []
    for marker in protocol.markers:
        if marker.tracking:
            bones.append(body.index(_bone_of(marker.landmark.segment)))
            nominal.append(np.zeros(3))
            continue
        place = body.landmarks.get(marker.landmark.name)
        if place is None:
            raise SynthError(f"protocol {protocol.name!r}: the synthetic body has no landmark "
                             f"{marker.landmark.name} (marker {marker.label})",
                             path=protocol.path, hint="add it to protocols/synthetic_body.toml")
        bones.append(place[0])
        nominal.append(place[1])
    bones, nominal = np.array(bones, dtype=int), np.array(nominal)
    sd = settings.placement_sd
    draw = rng if placement_rng is None else placement_rng
    placed = nominal + np.clip(draw.normal(0.0, sd, nominal.shape), -2.5 * sd, 2.5 * sd)
    plates = cluster_plates(protocol, body, draw)
    corner = {}
    for m, marker in enumerate(protocol.markers):
        if marker.tracking:
            segment = marker.landmark.segment
            corner[m] = k = sum(protocol.markers[i].landmark.segment == segment for i in corner)
            placed[m] = plates[segment][0] + plates[segment][1][k]
    local = np.broadcast_to(placed, (n,) + placed.shape).copy()
    tissue = settings.soft_tissue * mass / body.height ** 2 / REFERENCE_BMI
    for segment, (centre, _) in plates.items():
        bone = _bone_of(segment)
        drive = _drivers(body, motion, bone, bone[-1])                       # (F, J)
        move = drive @ rng.normal(0.0, 1.0 / np.sqrt(3.0), (drive.shape[1], 3))
        turn = vector_turn(tissue * PLATE_TURN * (drive @ rng.normal(
            0.0, 1.0 / np.sqrt(3.0), (drive.shape[1], 3))))                  # (F, 3, 3)
        on = [m for m in corner if protocol.markers[m].landmark.segment == segment]
        local[:, on] = (centre + np.einsum("fij,mj->fmi", turn, placed[on] - centre)
                        + tissue * _gain(bone) * move[:, None])
    for m, marker in enumerate(protocol.markers):
        bone = body.bones[bones[m]].name
        drive = _drivers(body, motion, bone, _side_of(marker.landmark.name, bone))
        share = PLATE_DEFORMATION if m in corner else 1.0
        directions = rng.normal(0.0, 1.0 / np.sqrt(3.0), (drive.shape[1], 3))
        local[:, m] += share * tissue * _gain(bone) * (drive @ directions)
    R, t = body.forward(motion.pose)
    world = np.einsum("fmij,fmj->fmi", R[:, bones], local) + t[:, bones]
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
