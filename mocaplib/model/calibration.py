"""Subject calibration: one subject's fixed skeleton and marker offsets from a trial.

Steps (all in metres, world Z up):

0. **Same subject** (only with a static trial, :func:`check_same_subject`). A static calibrates
   the motion only if it shows the same person with the same markers on: the distance between
   two markers on one segment is then the same in both trials, up to soft tissue and noise.
   The median over all such pairs of |d_motion − d_static| (each distance the median over its
   trial's frames) above :data:`SAME_SUBJECT_LIMIT` (5 mm) is a :class:`CalibrationError`
   (the figures behind the limit: docs/guide/fitting.md, Calibration). The same markers taken
   off and put back pass: it is the same person (the ``free`` static pose then absorbs the new
   placement). The same difference picks, among several statics (one per subject or session),
   the one that shows a capture's subject (:func:`choose_static`).

1. **Markers, swaps and locks.** The protocol's markers seen in at least 10 % of the trial's frames
   are used. A joint whose segment and descendants carry too few markers to be seen (none; or one
   for a 3-DOF joint) has its DOFs *locked* (held at 0 by the fit); a segment with no marker
   below it is also listed as *left out*. Fewer than 3 pelvis markers is an error. Two markers
   whose labels are exchanged, in all or part of the frames (each marker far from its model
   position, near the other's after the nominal fit of step 2; :func:`mocaplib.model.ik.find_repairs`)
   are exchanged back, and listed in ``swapped``; the motion's frames of step 5 are checked the
   same way against the static's model. Tracking markers (no landmark) are left out of the
   nominal fits: their offsets are measured in step 4 (4' with a neutral static), in the
   segment frames the landmarks build.
2. **Height and nominal model.** Height is estimated from distances between markers on the
   same segment against the landmark catalogue's nominal ones (``protocols/landmarks.toml``),
   unless given; the nominal skeleton (:meth:`Skeleton.from_height`) and nominal offsets are
   fitted to up to ``n_frames`` calibration frames.
3. **Anatomical joint centres.** Hip: Harrington et al. (2007, J Biomech 40:595) regression
   from pelvis width PW (ASIS–ASIS) and depth PD (mid-ASIS to mid-PSIS, or sacrum), in the
   ASIS pelvis frame: x = −0.24 PD − 9.9 mm, y = ±(0.33 PW + 7.3 mm), z = −0.30 PW − 10.9 mm.
   Knee, ankle, elbow without landmarks in the trial (a cluster set calibrated from its
   motion): the functional centre of the two segments' markers
   (:func:`mocaplib.model.anatomy.functional_centre`). Knee, ankle, elbow: the midpoint of lateral
   and medial landmarks when both exist, otherwise
   the lateral landmark moved by its documented offset from the joint in the catalogue (knee
   50 mm, ankle 35 mm, elbow 35 mm medial for a 1.75 m subject, scaled by height), turned by
   the nominal fit's segment orientation; the elbow's chord, without an upper-arm marker, lies
   in Plug-in Gait's plane: the shoulder centre, the lateral elbow marker and a point along
   the normal of the arm's plane (shoulder centre, elbow marker, mid-wrist), so the centre
   lies on that normal. Shoulder: the acromion lowered by the
   subject's measured shoulder offset plus the marker radius along Plug-in Gait's thorax axis
   (:func:`shoulder_drops`, :func:`thorax_axis`), else moved by the catalogue offset (20 mm
   medial, 33.5 mm down, 10 mm forward, scaled). Wrist: mid radial/ulnar styloids.
   Segment lengths are the median distances between those centres.
4. **Registration.** Poses are fitted to the markers plus the joint centres (as stiff virtual
   markers); each marker's offset is re-registered as the least-squares (mean) position in its
   segment's frame over those poses, and each segment's offsets are turned (Kabsch, about
   their centroid) onto the catalogue layout, which makes the segment frames anatomical: zero
   angles put the markers in the catalogue's layout, as the DOF sign table describes. The
   pelvis, legs and arms then get their anatomical frames from the joint centres
   (:func:`mocaplib.model.anatomy.segment_frames`; the arms' from the shoulders where the torso's
   layout puts them, or, with a measured shoulder offset, from the acromion lowered by it,
   :func:`shoulder_shifts`): their markers' offsets are measured in them and each joint
   centre below the hips and shoulders becomes a joint shift.
4b. **Functional knee axes** (:func:`functional_knee_turns`). The knee hinge's axis from
   the landmarks, turned about the thigh from the knee's own, takes the shank out of its plane
   as the knee flexes and the fit turns the hip to follow: hip rotation coupled to knee
   flexion. Each knee's axis is turned about the femur's long axis by the angle whose poses
   best fit the thigh and shank markers of step 5's frames (the motion's), the leg frames of
   step 4 built again on it (:func:`mocaplib.model.anatomy.leg_frames`, ``knee_turn``); a knee
   that flexes less than :data:`KNEE_AXIS_MIN_FLEXION` there keeps the anatomical axis.
4'. **Neutral static** (``static_pose="neutral"``, as OpenSim's MarkerPlacer does with the
   model's default pose): the subject is taken to stand in the anatomical neutral pose, every
   joint angle 0 (:func:`neutral_offsets`). Only
   the root pose is fitted to the static frames; the shoulders and elbows are moved onto
   their anatomical centres of step 3 (:func:`neutral_shifts`; the elbow's from its lateral
   landmark, :data:`NEUTRAL_CHORD_JOINTS`); and each marker's offset is then measured
   directly in its segment frame (the mean of ``R_s^T (x − t_s)``, no turning onto the
   catalogue), so a marker placed off its landmark keeps its true offset and the placement
   error does not become a joint-angle offset. Step 5 is then skipped: the model is the
   static's. Only for statics recorded in that pose: real lab statics often are not (arms
   abducted, feet turned out; docs/results/fit_accuracy.md, Real files), so the default,
   ``static_pose="free"``, runs step 4 on the static and step 5 on the motion.
5. **Refinement** (on the motion trial, also when a static trial gave steps 1-4). With a
   static, the arms' anatomical frames of step 4 are first built over the static's frames and
   the motion's together (:data:`PLACED_ON_STATIC_AND_MOTION`): the elbow centres become the
   forearms' joint shifts and the upper arms' markers are measured in them. Alternate: fit
   poses to the markers alone; re-register offsets (torso, head and feet turned back onto
   the catalogue layout; the markers on an anatomical frame of step 4 kept, but the
   forearms', :data:`FOLLOWING_IN_REFINEMENT`, re-registered); solve the segment
   lengths by linear least squares (marker positions are affine in the lengths for fixed
   poses and offsets) with a 15 mm Gaussian prior towards the anatomical lengths; shoulders
   placed by a measured offset follow the acromion marker's new offset. Stop when the marker
   RMS falls by less than 1 %; the best model is kept.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import UNITS_HINT, CalibrationError
from ..markersets import protocols as _protocols
from ..markersets.protocols import Protocol, label_match, match_trial
from ..numeric import distinct, median, nanmedian
from ..skeleton import (
    DOF_NAMES,
    DOFS,
    HEIGHT_PROPORTIONS,
    ROOT_HEADING,
    SEGMENT_NAMES,
    SEGMENTS,
    SHIFTS,
    Skeleton,
    partner_name,
)
from ..statics import STATIC_POSES, standing_part, static_names
from ..trial import Trial
from .anatomy import (
    WANDS,
    chord_centre,
    davis_hip,
    functional_centre,
    harrington_hips,
    leg_frames,
    marker_frames,
    offsets_in_frames,
    segment_frames,
)
from .ik import MIN_PELVIS_MARKERS, find_repairs, initial_pose, solve_poses
from .motion import apply_repairs

#: Markers seen in fewer than this fraction of frames are not used.
MIN_PRESENCE = 0.10
#: Prior standard deviation of segment lengths around the anatomical estimate, metres.
LENGTH_PRIOR = 0.015
#: Typical marker residual (soft tissue + noise), metres: scales the length prior.
MARKER_SIGMA = 0.005
#: A DOF that one frame's markers determine with a standard deviation above this (radians;
#: :func:`unobservable_dofs`, markers off by MARKER_SIGMA) is held at 0: the largest amplitude
#: of ankle inversion in walking, which it would drown.
UNOBSERVABLE_SD = np.deg2rad(8.0)
#: An end segment's markers lie on one line when all are within this distance (m) of it...
LINE_TOLERANCE = 0.01
#: ...and a DOF turns the segment about that line when its axis is within this angle (rad).
LINE_ANGLE = np.deg2rad(30.0)
#: Weight of anatomical joint centres (virtual markers) against real markers in step 4.
CENTRE_WEIGHT = 10.0

#: Largest median difference (m) of within-segment marker distances between a static trial and
#: the motion it calibrates (step 0): 2.5x the largest measured within one real session
#: (2.0 mm), under a third of the smallest measured between two people (17 mm).
SAME_SUBJECT_LIMIT = 0.005
#: Marker pairs closer than this (m) are not compared in step 0 (their ratio is noisy).
MIN_PAIR_DISTANCE = 0.05
#: Step 0 needs at least this many marker pairs seen in both trials; with fewer it is skipped.
MIN_PAIRS = 3

#: Heights (m) the markers may suggest before the capture is refused as having wrong units:
#: a factor of 10 (cm read as mm or mm as cm) or more off any walking person's 0.8-2.3 m.
PLAUSIBLE_HEIGHT = (0.4, 5.0)


#: Joints a static in the neutral pose moves to their anatomical centres (:func:`neutral_shifts`):
#: the shoulders (from the acromion) and the elbows. The hips, knees and ankles keep the
#: nominal layout. Moved to Harrington's centres, the hips lower the knee's flexion error
#: (exact markers of ``run_3p0``: 3.6° to 2.4° RMS) but take the leg down with them, the ankle
#: from 18 mm above its true centre to 7 mm below, and ankle inversion's error grows as that
#: pivot nears the foot markers (2.5° to 6.9°): the fit's ankle has no DOF for the foot's turn
#: about the shank that an oblique subtalar axis gives, and reads it as a roll about the pivot,
#: less the higher the pivot. A modelling difference, not an inconsistent calibration
#: (``python benchmarks/fit_accuracy.py --only ankle``; docs/results/fit_accuracy.md).
NEUTRAL_CENTRES = ("humerus_r", "humerus_l", "forearm_r", "forearm_l")
#: The chord joints of a static in the neutral pose: not the elbow, whose centre is then its
#: lateral landmark moved by the catalogue offset turned by the pelvis's orientation (every
#: segment's in that pose), i.e. along the mediolateral axis, a hanging arm's flexion axis.
#: The chord's plane (shoulder centre, upper-arm marker, lateral epicondyle) is nearly
#: edge-on to that axis and leans with millimetres of the markers' fore-aft placement: 11 mm
#: forward on the samples' exact markers.
NEUTRAL_CHORD_JOINTS = ("tibia", "foot")
#: Segments whose frames stay aligned with the catalogue layout during refinement (step 5).
#: The others follow their markers, unless an anatomical frame of step 4 holds them.
ALIGNED_IN_REFINEMENT = ("pelvis", "torso", "head", "foot_r", "foot_l")

#: Turns of each knee's flexion axis about the femur's long axis (radians) that step 4b tries
#: (:func:`functional_knee_turns`); the chosen one is the vertex of the parabola through the
#: best of them and its neighbours, so within this span.
KNEE_AXIS_TURNS = np.radians(np.arange(-30.0, 31.0, 15.0))
#: Every how many of step 5's frames step 4b fits. On the 8 shared real captures with a
#: moving knee, every second frame and turns 15° apart, started from the anatomical axes'
#: poses, choose turns within 0.9° of every frame's with turns 10° apart started cold (1.8°
#: on PiG_Motion-FlatFoot-Full's right knee, turned −3.2° against −1.4°), at 40 % of the cost.
KNEE_AXIS_FRAME_STEP = 2
#: Knee flexion range (radians) the calibration frames must show for a functional knee axis;
#: a knee that flexes less (a static, standing) keeps its anatomical axis.
KNEE_AXIS_MIN_FLEXION = np.radians(20.0)

#: Joint centres from landmarks: child segment (its origin is the joint) and its landmarks
#: (lateral, medial); the lateral one alone is used with its catalogue offset.
_LANDMARK_JOINTS = {
    "tibia": ("KNEE_LAT", "KNEE_MED"),
    "foot": ("ANKLE_LAT", "ANKLE_MED"),
    "humerus": ("ACROMION", None),
    "forearm": ("ELBOW_LAT", "ELBOW_MED"),
}
#: The joint at each child segment's origin, as named in joint widths and reports.
_JOINT_NAMES = {"tibia": "knee", "foot": "ankle", "humerus": "shoulder", "forearm": "elbow"}
#: Marker diameter (m) assumed when a file gives joint widths but no diameter: Plug-in Gait's.
DEFAULT_MARKER_DIAMETER = 0.014
#: Lengths the joint centres of the pelvis, legs and arms set, which refinement keeps when both
#: centres (the origins of the two segments named) are known on both sides.
_ANATOMICAL_LENGTHS = {"hip_width": ("femur", "femur"), "thigh": ("femur", "tibia"),
                       "shank": ("tibia", "foot"), "upper_arm": ("humerus", "forearm")}
#: Segments whose markers refinement (step 5) re-registers on the motion although their
#: anatomical frames are known: the forearms. Held at a static's offsets, the elbows of
#: HC030A05 and HC030A22 (static HC030A01) read 10-32° less flexion than Plug-in Gait (r down
#: to -0.47); re-registered, within 3.9°. Likely cause, not traced further: the wrist and hand
#: markers turn about the forearm's long axis with pronation, which the fit's forearm lacks,
#: by another amount standing than walking.
FOLLOWING_IN_REFINEMENT = ("forearm_l", "forearm_r")
#: Segments whose anatomical frames, with a static, are built over the static's calibration
#: frames and the motion's together before refinement (step 5), the elbow centre (the
#: forearm's origin) and the upper arm's markers measured in them: the chord places the
#: elbow centre on the normal of the arm's plane, which the static shows at one flexion
#: (HC030A01's left elbow 22°, its walks about 33°); Plug-in Gait places it again on every
#: frame, sliding 10-14 mm fore-aft in the upper arm with flexion. From the static alone the
#: elbows of HC030A05 and HC030A22 read 4.4-8.0° more flexion than Plug-in Gait's; from the
#: motion alone within 1.1°, but the right shoulders 5.2-6.3° more; from both, elbows 1.6-4.3°
#: and shoulders within 4.3° (docs/guide/fitting.md, The arms).
PLACED_ON_STATIC_AND_MOTION = ("humerus_l", "humerus_r", "forearm_l", "forearm_r")
#: Joints whose centre a lateral marker and a segment wand give by the chord.
_CHORD_JOINTS = ("tibia", "foot", "forearm")


@dataclass
class SubjectModel:
    """One subject's calibrated model, what :func:`mocaplib.model.ik.fit` needs.

    Attributes
    ----------
    skeleton : Skeleton with this subject's segment lengths (metres).
    protocol : Protocol the labels come from.
    labels : list[str], length M. Protocol labels of the markers used, in model order.
    marker_segments : int ndarray, shape (M,). Segment index of each marker.
    marker_offsets : ndarray, shape (M, 3). Each marker in its segment's frame, metres.
    locked_dofs : list[str]. DOFs held at 0 because too few markers see them.
    left_out : list[str]. Segments with no marker on them or below them.
    rms : float. Marker RMS of the calibration fit, metres.
    history : list[float]. Marker RMS after each refinement round, metres.
    source : str or None. The calibration trial's file (the static one when given).
    swapped : list of (label, label). Pairs whose labels the calibration trial exchanges (in
        all or part of its frames, :func:`mocaplib.model.ik.find_repairs`); calibration read them
        exchanged back. A fit finds the motion's own (``Motion.repairs``).
    centre_methods : dict[str, str]. How each joint centre was found (``"knee_l"``: ``"chord,
        knee width from the measurements"``...), see :func:`joint_centres`.
    unobservable : dict[str, float]. DOFs the markers cannot see well enough, held at 0 (also
        in ``locked_dofs``), with the standard deviation (radians) one frame's markers would
        leave them at (:func:`unobservable_dofs`).
    static_window_s : (start, end) or None. Seconds from the static's first frame of the
        stretch of it used (:func:`standing_part`); None without a static.
    knee_axis_turns : dict[str, float]. Per side ("l", "r") whose knee has a functional axis,
        its turn about the femur's long axis from the anatomical one, radians, in the sense
        of ``hip_rotation`` (:func:`functional_knee_turns`).
    """

    skeleton: Skeleton
    protocol: Protocol
    labels: list[str]
    marker_segments: np.ndarray
    marker_offsets: np.ndarray
    locked_dofs: list[str] = field(default_factory=list)
    left_out: list[str] = field(default_factory=list)
    rms: float = float("nan")
    history: list[float] = field(default_factory=list)
    source: str | None = None
    swapped: list[tuple[str, str]] = field(default_factory=list)
    centre_methods: dict[str, str] = field(default_factory=dict)
    unobservable: dict[str, float] = field(default_factory=dict)
    static_window_s: tuple[float, float] | None = None
    knee_axis_turns: dict[str, float] = field(default_factory=dict)

    @property
    def marker_weights(self) -> np.ndarray:
        """Each marker's weight in the fit (M,), from the protocol
        (:attr:`mocaplib.markersets.protocols.ProtocolMarker.weight`)."""
        return np.array([self.protocol.marker(label).weight for label in self.labels])

    @property
    def free(self) -> np.ndarray:
        """DOFs the fit may move, bool (D,)."""
        return np.array([name not in self.locked_dofs for name in DOF_NAMES])

    @property
    def swap_warnings(self) -> list[str]:
        """One sentence per pair in :attr:`swapped`, for the user."""
        return [f"calibration trial {self.source or ''}: labels {a} and {b} look exchanged "
                "(each marker lies where the other belongs); calibration exchanged them back: "
                "check the labelling" for a, b in self.swapped]


def choose_protocol(trial: Trial, protocol: Protocol | str | None = None) -> Protocol:
    """The protocol to use: the one given (object, shipped name or TOML path), else (None or
    "auto") the one :func:`mocaplib.markersets.protocols.detect_protocol` finds for the trial's labels;
    resolved by :func:`mocaplib.markersets.protocols.match_trial`, as every command resolves it."""
    if isinstance(protocol, Protocol):
        return protocol
    return match_trial(trial, "auto" if protocol is None else protocol).protocol


def calibrate(trial: Trial, /, *, protocol: Protocol | str | None = None,
              static: Trial | None = None, static_pose: str = "free",
              height: float | None = None, n_frames: int = 60,
              max_rounds: int = 8, heading_offset: float = 0.0,
              measurements: dict[str, float] | None = None,
              static_window: tuple[float, float] | None = None,
              knee_turns: dict[str, float] | None = None) -> SubjectModel:
    """Calibrate the subject's skeleton and marker offsets.

    Parameters
    ----------
    trial : the motion trial.
    protocol : Protocol, shipped name, TOML path, or None / "auto" to detect it (on the motion
        trial, also when a static is given).
    static : a static standing trial of the same subject. When given, steps 1-4 (markers,
        height, joint centres, lengths, anatomical offsets) use it and step 5 refines on the
        motion trial; otherwise every step uses the motion trial. Step 0 checks first that
        it shows the same subject and marker placement (:func:`check_same_subject`).
    static_pose : "neutral": the static subject stands in the anatomical neutral pose, every
        joint angle 0, and the marker offsets are measured in it (step 4'); "free" (default):
        the static pose is fitted like any other (steps 4 and 5). Unused without ``static``.
    height : standing height, metres; estimated from the markers when None.
    n_frames : calibration frames (the most complete ones, spread over the trial).
    max_rounds : refinement rounds at most (step 5).
    heading_offset : radians added to the neutral static's fitted heading before the offsets
        are measured (step 4'), turning every segment frame about the vertical: the correction
        a forward reference measures (:func:`mocaplib.build.workflow.forward_offsets`). Only with a
        static in the neutral pose.
    measurements : subject measurements (metres, kilograms;
        :data:`mocaplib.model.anatomy.MEASUREMENTS` keys) that override those the calibration
        trial's file stores (:attr:`Trial.measurements`); knee and ankle widths and the marker
        diameter place the knee and ankle centres (:func:`joint_centres`).
    static_window : (start, end) seconds from the static's first frame: the stretch of the
        static to calibrate on; default: the whole static when it stands still, else its
        quietest stretch (:func:`standing_part`).
    knee_turns : None (default): each knee's functional flexion axis (step 4b,
        :func:`functional_knee_turns`); else the knees' axes turned by these from the
        anatomical ones, radians per side ("l", "r"; internal rotation positive), ``{}``
        keeping the anatomical axes. Unused with a static in the neutral pose.

    Returns
    -------
    SubjectModel
    """
    if static_pose not in STATIC_POSES:
        raise CalibrationError(f"static_pose must be one of {', '.join(STATIC_POSES)}, "
                               f"got {static_pose!r}", path=getattr(static, "source", None))
    if heading_offset and (static is None or static_pose != "neutral"):
        raise CalibrationError("a heading offset turns the frame of a static in the neutral pose: "
                               "give the static with static_pose='neutral'",
                               path=getattr(static, "source", None) or trial.source)
    window = None
    if static is not None:
        static, window = standing_part(static, window=static_window)
    cal = static if static is not None else trial
    measurements = {**cal.measurements, **(measurements or {})}
    proto = choose_protocol(trial, protocol)   # on the motion, as every command resolves it
    cal_match = label_match(cal, proto)   # find_repairs finds the swaps
    X_all = cal_match.markers(cal)
    seen = np.isfinite(X_all[..., 0]).mean(axis=0) if cal.n_frames else np.zeros(len(proto.labels))
    used = np.flatnonzero(seen >= MIN_PRESENCE)
    markers = [proto.markers[j] for j in used]
    labels = [m.label for m in markers]
    segments = np.array([SEGMENT_NAMES.index(m.landmark.segment) for m in markers], dtype=int)
    n_pelvis = int((segments == SEGMENT_NAMES.index("pelvis")).sum())
    if n_pelvis < 3:
        _refuse_pelvis(cal, proto, n_pelvis)
    if static is not None:
        X_motion = _check_static(X_all[:, used], trial, proto, used, segments, labels, static)
    locked, left_out = locked_dofs(segments)
    free = np.array([name not in locked for name in DOF_NAMES])
    X = X_all[_calibration_frames(X_all[:, used], n_frames)][:, used]
    landmarks = [m.landmark.name for m in markers]
    _check_upright(X, segments, cal)
    _check_sides(X, landmarks, cal)
    nominal = proto.nominal_offsets()[1][used]        # NaN rows: tracking markers
    if height is None:
        height = estimate_height(X, segments, nominal, source=cal.source)
    scale = height / _protocols.REFERENCE_HEIGHT
    skeleton = Skeleton.from_height(height)
    nominal_scaled = nominal * scale
    offsets = nominal_scaled

    # step 3: anatomical joint centres from a nominal fit (tracking markers wait for step 4)
    known, known_offsets = landmark_markers(X, offsets)
    first = solve_poses(skeleton, known, segments, known_offsets, free=free)
    repairs = find_repairs(skeleton, known, segments, known_offsets, labels, first, free=free)
    swapped = list(dict.fromkeys(r.labels for r in repairs))
    if repairs:
        X = apply_repairs(X, labels, repairs)
        known = landmark_markers(X, offsets)[0]
        first = solve_poses(skeleton, known, segments, known_offsets, free=free)
    neutral = static is not None and static_pose == "neutral"
    centres, methods = joint_centres(
        X, landmarks, segments, skeleton, first.q, scale=scale, measurements=measurements,
        neutral=neutral)
    anatomical = _lengths_from_centres(skeleton, centres)
    skeleton = Skeleton(anatomical)
    if neutral:
        methods.update({f"knee_axis_{side}": "anatomical: a static in the neutral pose shows no "
                        "flexion axis" for side in ("l", "r") if (f"tibia_{side}", 0.0) in centres})
        offsets, rms, poses, skeleton = neutral_offsets(
            skeleton, X, segments, nominal=nominal_scaled, heading_offset=heading_offset,
            centres=centres)
        model = SubjectModel(skeleton, proto, labels, segments, offsets, locked, left_out, rms,
                             [rms], cal.source, swapped, methods, static_window_s=window)
        _check_measured(model, cal)
        return _hold_unobservable(model, poses)
    # step 4: poses with the joint centres as stiff virtual markers, then offsets
    v_seg, v_off, v_pos = _virtual_markers(skeleton, centres, len(X))
    X_known, known_offsets = landmark_markers(X, offsets)
    poses = solve_poses(skeleton, np.concatenate([X_known, v_pos], axis=1),
                        np.concatenate([segments, v_seg]), np.vstack([known_offsets, v_off]),
                        free=free, weights=np.r_[np.ones(len(labels)),
                                                 np.full(len(v_seg), CENTRE_WEIGHT)]).q
    registered = register_offsets(skeleton, poses, X, segments, nominal=nominal_scaled)
    # the pelvis, legs and arms: offsets in their anatomical frames, kept by the refinement;
    # with the subject's shoulder offset measured, the arms hang from the acromion lowered by
    # it (shoulder_shifts); otherwise from the shoulders where the torso's layout puts them
    # (the model's at the poses), not the acromion's catalogue centre: moved there (21 mm up
    # on the samples' runs) they shift v̂_l of a run calibrated from itself by up to 0.005 m/s
    # (4 m/s: -0.029 to -0.034, truth 0) (docs/guide/fitting.md)
    drops = shoulder_drops(measurements)
    X_cal, poses_cal, unshifted = X, poses, skeleton
    frames_cal = anatomical_frames(unshifted, poses_cal, X_cal, landmarks, centres, drops,
                                   level_feet=static is not None)
    in_frames_cal = offsets_in_frames(X_cal, segments, SEGMENT_NAMES, frames_cal)
    where_cal = {name: X_cal[:, i] for i, name in enumerate(landmarks)}

    def anatomical_model(knee_turns=None):
        """Offsets (M, 3), the markers kept by the refinement (M,) and the skeleton with its
        joint shifts, measured in the anatomical frames (the knees' axes turned by
        ``knee_turns``: only the legs' frames built again)."""
        frames, in_frames = dict(frames_cal), in_frames_cal.copy()
        for side, turn in (knee_turns or {}).items():
            legs = leg_frames(where_cal, centres, side, level_feet=static is not None,
                              knee_turn=turn)
            frames.update(legs)
            on = np.isin(segments, [SEGMENT_NAMES.index(name) for name in legs])
            in_frames[on] = offsets_in_frames(X_cal, segments, SEGMENT_NAMES, legs)[on]
        measured = np.isfinite(in_frames).all(axis=1)
        kept = measured & ~np.isin(segments, [SEGMENT_NAMES.index(name)
                                              for name in FOLLOWING_IN_REFINEMENT])
        placed = np.where(measured[:, None], in_frames, registered)
        return placed, kept, Skeleton(unshifted.lengths, {
            **joint_shifts(unshifted, frames),
            **shoulder_shifts(unshifted, placed, landmarks, drops)})

    offsets, kept, skeleton = anatomical_model()
    fixed_lengths = [key for key, (a, b) in _ANATOMICAL_LENGTHS.items()
                     if all(((name + side, 0.0) in centres) for name in (a, b)
                            for side in ("_l", "_r"))]
    on_motion = False
    if static is not None:
        # the static pose fixed the anatomy; the motion shows the functional axes and the
        # soft tissue of the movement, so step 5 runs on the motion's frames
        pelvis_seen = np.isfinite(X_motion[:, segments == SEGMENT_NAMES.index("pelvis"), 0])
        if (pelvis_seen.sum(axis=1) >= 3).any():
            on_motion = True
            X = X_motion[_calibration_frames(X_motion, n_frames)]
            start = solve_poses(skeleton, X, segments, offsets, free=free)
            X = apply_repairs(X, labels, find_repairs(skeleton, X, segments, offsets, labels,
                                                      start, free=free))
            poses = None
    if knee_turns is None:
        knee_turns, knee_methods = functional_knee_turns(anatomical_model, X, segments, free=free)
    else:
        knee_turns = {side: float(turn) for side, turn in knee_turns.items() if turn}
        knee_methods = {f"knee_axis_{side}": f"given: turned {np.degrees(turn):+.1f}° "
                        "(internal rotation positive) about the thigh from the anatomical axis"
                        for side, turn in knee_turns.items()}
    methods.update(knee_methods)
    if knee_turns:
        offsets, kept, skeleton = anatomical_model(knee_turns)
    if on_motion:
        # the arms' frames and elbow centres over the static's frames and the motion's
        X_both, q_both = np.concatenate([X_cal, X]), np.concatenate([poses_cal, start.q])
        arms = {name: value for name, value in anatomical_frames(
            skeleton, q_both, X_both, landmarks, joint_centres(
                X_both, landmarks, segments, skeleton, q_both, scale=scale,
                measurements=measurements)[0], drops).items()
                if name in PLACED_ON_STATIC_AND_MOTION}
        in_arms = offsets_in_frames(X_both, segments, SEGMENT_NAMES, arms)
        placed = np.isfinite(in_arms).all(axis=1)
        offsets[placed] = in_arms[placed]
        skeleton = Skeleton(skeleton.lengths, {**skeleton.shifts,
                                               **joint_shifts(skeleton, arms)})

    # step 5: alternate poses, offsets, lengths while the RMS keeps falling
    best, history = None, []
    for _ in range(max_rounds):
        fit = solve_poses(skeleton, X, segments, offsets, q0=poses, free=free)
        rms = float(np.sqrt(np.nanmean(fit.residuals ** 2)))
        history.append(rms)
        if best is not None and rms >= best.rms:
            break
        best = SubjectModel(skeleton, proto, labels, segments, offsets.copy(), locked, left_out,
                            rms, [], cal.source, swapped, methods, static_window_s=window,
                            knee_axis_turns=knee_turns)
        best_poses = fit.q
        if len(history) > 1 and rms > 0.99 * history[-2]:
            break
        poses = fit.q
        T = skeleton.forward(poses)
        registered = register_offsets(skeleton, poses, X, segments, nominal=nominal_scaled,
                                      align=ALIGNED_IN_REFINEMENT, unseen=offsets, transforms=T)
        offsets = np.where(kept[:, None], offsets, registered)
        skeleton = refine_lengths(skeleton, poses, X, segments, offsets, prior=anatomical,
                                  fixed=fixed_lengths, transforms=T)
        skeleton = Skeleton(skeleton.lengths, {
            **skeleton.shifts, **shoulder_shifts(skeleton, offsets, landmarks, drops)})
    best.history = history
    _check_measured(best, cal)
    return _hold_unobservable(best, best_poses)


def unobservable_dofs(model: SubjectModel, q: np.ndarray) -> dict[str, float]:
    """The free rotation DOFs the markers cannot see, with the standard deviation (radians)
    one frame's fit would leave each at.

    Two rules, on the markers the protocol trusts (weight 1 or more: markers it weights down,
    such as the Oxford Foot Model's midfoot markers on mocaplib's one-piece foot, steady the
    fit but do not make a DOF seen):

    * **On a line.** An end segment (a foot, a forearm, the head) whose markers lie on one line
      (fewer than three, or all within :data:`LINE_TOLERANCE` of a line) cannot show a turn
      about that line: a DOF whose axis is within :data:`LINE_ANGLE` of it is held (ankle
      inversion with only a heel and a toe marker, as Plug-in Gait's foot).
    * **Uncertain.** For poses ``q`` (F, D) the weighted least-squares fit of one frame leaves
      DOF d with the standard deviation ``σ_m sqrt((JᵀWJ)⁻¹_dd)`` (J the markers' Jacobian
      over the free DOFs, W their weights, σ_m = :data:`MARKER_SIGMA`; median over the
      poses); the worst above :data:`UNOBSERVABLE_SD` is held and the others judged again.

    A left or right DOF is held with its mirror image, so that both sides of a library have
    the same DOFs.
    """
    trusted = model.marker_weights >= 1.0
    _, J = model.skeleton.marker_jacobian(q, model.marker_segments[trusted],
                                          model.marker_offsets[trusted])
    J = J * np.sqrt(model.marker_weights[trusted])[None, :, None, None]
    J = J.reshape(len(J), -1, J.shape[-1])                   # (F, 3M, D)
    A = J.transpose(0, 2, 1) @ J
    free = model.free & ~np.isin(np.arange(len(DOF_NAMES)), SHIFTS)

    def sd_of(mask):
        sub = A[:, mask][:, :, mask] + 1e-12 * np.eye(int(mask.sum()))
        return MARKER_SIGMA * np.sqrt(median(
            np.diagonal(np.linalg.inv(sub), axis1=1, axis2=2), axis=0))

    held: dict[str, float] = {}

    def hold(name, value):
        for dof in (d for d in DOF_NAMES if d in (name, partner_name(name))):  # fixed order
            held[dof] = float(value)
            free[DOF_NAMES.index(dof)] = False

    on_line = _turns_about_marker_lines(model.marker_segments[trusted],
                                        model.marker_offsets[trusted])
    sd = dict(zip(np.array(DOF_NAMES)[free], sd_of(free)))
    for name in sorted(on_line & set(sd)):
        hold(name, max(sd[name], sd.get(partner_name(name), 0.0)))
    while free.any():
        sd = sd_of(free)
        worst = int(np.argmax(sd))
        if sd[worst] <= UNOBSERVABLE_SD:
            break
        hold(DOF_NAMES[np.flatnonzero(free)[worst]], sd[worst])
    return held


def _turns_about_marker_lines(segments: np.ndarray, offsets: np.ndarray) -> set[str]:
    """Rotation DOFs of end segments (no segment below them) whose markers (``segments`` (M,),
    ``offsets`` (M, 3) in the segment frames) lie on one line along the DOF's axis."""
    out = set()
    parents = {seg.parent for seg in SEGMENTS}
    for s, seg in enumerate(SEGMENTS):
        points = offsets[segments == s]
        if seg.name in parents or not len(points) or not seg.dofs:
            continue
        if len(points) == 1:                 # a lone marker and the joint centre: their line
            direction, spread = points[0] / np.linalg.norm(points[0]), 0.0
        else:
            centred = points - points.mean(axis=0)
            _, values, vt = np.linalg.svd(centred, full_matrices=False)
            direction = vt[0]
            spread = np.abs(centred - np.outer(centred @ direction, direction)).max() \
                if len(points) > 2 else 0.0
        if spread > LINE_TOLERANCE:
            continue
        for name in seg.dofs:
            axis = np.asarray(DOFS[DOF_NAMES.index(name)].axis)
            if abs(axis @ direction) > np.cos(LINE_ANGLE):
                out.add(name)
    return out


def _hold_unobservable(model: SubjectModel, q: np.ndarray) -> SubjectModel:
    """``model`` with its :func:`unobservable_dofs` at poses ``q`` (F, D) held at 0."""
    held = unobservable_dofs(model, q)
    model.unobservable = held
    model.locked_dofs = list(model.locked_dofs) + [d for d in held if d not in model.locked_dofs]
    return model


# ----------------------------------------------------------------------------- pieces
def _refuse_pelvis(cal: Trial, proto: Protocol, n_seen: int) -> None:
    """Raise the error for a trial with fewer than 3 usable pelvis markers, saying whether
    they are not labelled or labelled but missing in most frames."""
    labelled = [label for label in proto.labelled_in(cal)
                if proto.marker(label).landmark.segment == "pelvis"]
    if len(labelled) >= 3:
        raise CalibrationError(
            f"pelvis markers {', '.join(labelled)} are labelled but only {n_seen} of them are "
            f"seen in at least {MIN_PRESENCE:.0%} of the {cal.n_frames} frames; 3 are needed "
            "to place the pelvis", path=cal.source,
            hint="the capture is too short or those markers are missing in most frames: "
                 "check its gaps with `mocaplib inspect`")
    raise CalibrationError(
        f"only {n_seen} pelvis marker(s) of protocol {proto.name!r} are in the trial; "
        "3 are needed to place the pelvis", path=cal.source,
        hint="check the labels against the protocol, or pass --protocol")


def _check_upright(X: np.ndarray, segments: np.ndarray, cal: Trial) -> None:
    """Raise :class:`CalibrationError` naming ``cal`` when the pelvis markers of the
    calibration frames ``X`` (F, M, 3) (``segments`` (M,)) lie below the feet's in most frames:
    the file's vertical axis points down (a skeleton fitted upside down turns every joint)."""
    feet = np.isin(segments, [SEGMENT_NAMES.index("foot_l"), SEGMENT_NAMES.index("foot_r")])
    pelvis = segments == SEGMENT_NAMES.index("pelvis")
    if not feet.any() or not len(X):
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # frames without feet: NaN
        height = nanmedian(np.nanmean(X[:, pelvis, 2], axis=1) - np.nanmean(X[:, feet, 2], axis=1))
    if height < 0:
        raise CalibrationError(
            f"the pelvis markers lie {-height * 1000:.0f} mm below the feet's: the "
            "file's vertical axis points down", path=cal.source,
            hint="export the capture with the vertical axis pointing up (Z or Y up)")


def _check_sides(X: np.ndarray, landmarks: list[str], cal: Trial) -> None:
    """Raise :class:`CalibrationError` naming ``cal`` when, by every front/back cue its
    landmarks give (two at least: :func:`mocaplib.markersets.protocols.forward_cues`, which an exchange
    of sides leaves, Z up), most of its left/right landmark pairs (``landmarks`` (M,) names of
    the calibration frames ``X`` (F, M, 3)) have the left one on the subject's right: the left
    and right labels are exchanged throughout, and a mirrored body would be fitted. One cue
    alone is not trusted: a single exchange of a front and a back label turns it."""
    at = {name: X[:, i] for i, name in enumerate(landmarks)}
    pairs = [(name, "R" + name[1:]) for name in at
             if name.startswith("L_") and "R" + name[1:] in at]
    cues = _protocols.forward_cues(at, len(X))
    if len(pairs) < 3 or len(cues) < 2:
        return
    counts = []
    for forward in cues:
        left = np.stack([-forward[:, 1], forward[:, 0]], axis=1)         # up x forward
        lateral = np.array([nanmedian(((at[a][:, :2] - at[b][:, :2]) * left).sum(axis=1))
                            for a, b in pairs])
        counts.append(int((lateral < 0).sum()))
    if min(counts) > len(pairs) / 2:
        raise CalibrationError(
            f"{min(counts)} of the {len(pairs)} left markers that have a right one lie on the "
            "subject's right of it (facing from the back of the body to its front): the left "
            "and right labels are exchanged", path=cal.source,
            hint="relabel the capture's left and right markers, or check the protocol's sides")


def check_static(trial: Trial, static: Trial, model: SubjectModel) -> None:
    """Step 0 of :func:`calibrate` for a ``model`` calibrated on ``static`` with
    ``static_pose="neutral"`` (which depends on the static and protocol alone, so a batch of
    one session calibrates once): raises :class:`CalibrationError` when the motion ``trial``
    never shows the model's pelvis markers together or shows another subject or marker
    placement, naming both files."""
    used = np.array([model.protocol.labels.index(label) for label in model.labels], dtype=int)
    X_static = label_match(static, model.protocol).markers(static)[:, used]
    _check_static(X_static, trial, model.protocol, used, model.marker_segments, model.labels,
                  static)


def _check_static(X_static: np.ndarray, trial: Trial, proto: Protocol, used: np.ndarray,
                  segments: np.ndarray, labels: list[str], static: Trial) -> np.ndarray:
    """The checks of :func:`check_static` on the static's ``used`` protocol markers
    ``X_static`` (F_s, M, 3); returns the motion's (F, M, 3)."""
    X_motion = label_match(trial, proto).markers(trial)[:, used]
    _check_motion_markers(X_motion, segments, labels, proto, static=static, trial=trial)
    check_same_subject(X_static, X_motion, segments, labels, static=static, trial=trial)
    return X_motion


def _check_motion_markers(X_motion: np.ndarray, segments: np.ndarray, labels: list[str],
                          proto: Protocol, *, static: Trial, trial: Trial) -> None:
    """Refuse a static whose pelvis markers the motion trial (F, M, 3) never shows together:
    no frame of it could be fitted with the static's model (a static of another marker set)."""
    pelvis = segments == SEGMENT_NAMES.index("pelvis")
    most = int(np.isfinite(X_motion[:, pelvis, 0]).sum(axis=1).max(initial=0))
    if most >= MIN_PELVIS_MARKERS:
        return
    names = np.array(labels)[pelvis]
    present = set(proto.labelled_in(trial))
    shows = (f"never shows {MIN_PELVIS_MARKERS} of the static's pelvis markers "
             f"({', '.join(names)}, protocol {proto.name!r}) in one frame")
    if sum(name in present for name in names) >= MIN_PELVIS_MARKERS:
        raise CalibrationError(f"this motion trial {shows}: they are missing in its frames",
                               path=trial.source, hint="check its gaps with `mocaplib inspect`")
    raise CalibrationError(f"the motion trial {trial.source} {shows}: the static is of another "
                           "marker set", path=static.source,
                           hint="give the static of this capture's session, or pass --protocol")


def segment_distances(X: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Median distance (P,) metres over the frames of X (F, M, 3) of every marker pair on one
    segment (``segments`` (M,)), and the pairs (P, 2) as marker indices; NaN for a pair never
    seen together."""
    pairs = np.array([(i, j) for i in range(len(segments)) for j in range(i + 1, len(segments))
                      if segments[i] == segments[j]], dtype=int).reshape(-1, 2)
    d = nanmedian(np.linalg.norm(X[:, pairs[:, 0]] - X[:, pairs[:, 1]], axis=2), axis=0) \
        if len(X) and len(pairs) else np.full(len(pairs), np.nan)      # a pair never seen: NaN
    return d, pairs


def check_same_subject(X_static: np.ndarray, X_motion: np.ndarray, segments: np.ndarray,
                       labels: list[str], *, static: Trial, trial: Trial,
                       limit: float = SAME_SUBJECT_LIMIT) -> float:
    """Step 0: does the static trial show the motion's subject with the same markers on?

    ``X_static`` (F_s, M, 3) and ``X_motion`` (F_m, M, 3) the same M markers (``labels``) of the
    two trials (``static``, ``trial``: named in the error), ``segments`` (M,). Compares the
    within-segment distances (:func:`segment_distances`) of pairs at least
    :data:`MIN_PAIR_DISTANCE` apart seen in both. Returns the median |d_motion − d_static| (m),
    NaN when fewer than :data:`MIN_PAIRS` pairs can be compared (nothing is checked); raises
    :class:`CalibrationError` when it exceeds ``limit``, naming both files and the pairs that
    differ most.
    """
    d_static, pairs = segment_distances(X_static, segments)
    d_motion, _ = segment_distances(X_motion, segments)
    usable = np.isfinite(d_static) & np.isfinite(d_motion) & (d_static >= MIN_PAIR_DISTANCE)
    if usable.sum() < MIN_PAIRS:
        return float("nan")
    diff = d_motion[usable] - d_static[usable]
    difference = float(median(np.abs(diff)))
    if difference > limit:
        worst = np.argsort(-np.abs(diff))[:3]
        pairs_used = pairs[usable]
        examples = ", ".join(f"{labels[pairs_used[k, 0]]}-{labels[pairs_used[k, 1]]} "
                             f"{1000 * d_static[usable][k]:.0f} mm in the static, "
                             f"{1000 * d_motion[usable][k]:.0f} mm in the motion" for k in worst)
        scale = float(np.exp(median(np.log(d_motion[usable] / d_static[usable]))))
        raise CalibrationError(
            f"this static trial does not match the motion trial {trial.source or '(unnamed)'}: "
            f"distances between markers on one segment differ by "
            f"{1000 * difference:.1f} mm (median of {int(usable.sum())} pairs; one subject with "
            f"the same markers stays within {1000 * limit:.0f} mm; motion/static size ratio "
            f"{scale:.3f}); e.g. {examples}", path=static.source,
            hint="use the static recorded with this subject in this session (markers not moved "
                 "since), or calibrate from the motion itself (leave out --static)")
    return difference


def choose_static(trial: Trial, statics: Sequence[Trial], protocol: Protocol, *,
                  check_one: bool = False) -> int | None:
    """Index of the static in ``statics`` that shows ``trial``'s subject, for a batch of
    several subjects or sessions: the least step-0 difference (:func:`check_same_subject`
    over the within-segment marker pairs of ``protocol``), if within
    :data:`SAME_SUBJECT_LIMIT`. Raises :class:`CalibrationError` naming the trial and each
    static with its difference when none is within the limit or none can be compared. With
    one static, 0 (:func:`calibrate` checks it in step 0) unless ``check_one``; with none,
    None."""
    if len(statics) < 2 and not (check_one and statics):
        return 0 if statics else None
    segments = np.array([SEGMENT_NAMES.index(m.landmark.segment) for m in protocol.markers])
    X_motion = label_match(trial, protocol).markers(trial)
    gaps = np.array([check_same_subject(
        label_match(static, protocol).markers(static), X_motion,
        segments, protocol.labels, static=static, trial=trial, limit=np.inf)
        for static in statics])
    if np.isfinite(gaps).any() and np.nanmin(gaps) <= SAME_SUBJECT_LIMIT:
        return int(np.nanargmin(gaps))
    names = static_names([static.source or f"static {i + 1}" for i, static in enumerate(statics)])
    listing = "; ".join(
        f"{name} " + ("shares too few marker pairs with it (another marker set?)"
                      if np.isnan(gap) else f"{1000 * gap:.1f} mm")
        for name, gap in zip(names, gaps))
    which = (f"none of the {len(statics)} static trials shows" if len(statics) > 1
             else "the static trial does not show")
    raise CalibrationError(
        f"{which} this capture's subject with the same "
        f"markers (median difference of the distances between markers on one segment; one "
        f"subject stays within {1000 * SAME_SUBJECT_LIMIT:.0f} mm): {listing}",
        path=trial.source, hint="add the static recorded with this subject in this session, "
                                "or build this capture without --static")


def neutral_offsets(skeleton: Skeleton, X: np.ndarray, segments: np.ndarray, *,
                    nominal: np.ndarray, heading_offset: float = 0.0,
                    centres: dict[tuple[str, float], np.ndarray] | None = None
                    ) -> tuple[np.ndarray, float, np.ndarray, Skeleton]:
    """Marker offsets (M, 3) measured on a static trial in the anatomical neutral pose.

    ``X`` (F, M, 3) static markers, ``segments`` (M,), ``nominal`` (M, 3) catalogue offsets
    (scaled) for the start (NaN for tracking markers: they are left out of the root's fit).
    Every joint angle is held at 0; the root pose (pelvis 6 DOFs) is fitted to the landmark
    markers with the nominal offsets, its heading turned by ``heading_offset``
    (radians, counter-clockwise), then each offset is the mean of ``R_s^T (x − t_s)`` over the
    frames where its marker is seen (not turned onto the catalogue: the pose, not the layout,
    defines the segment frames). With the anatomical joint ``centres`` (:func:`joint_centres`)
    the skeleton's shoulders and elbows are first moved onto them (:func:`neutral_shifts`).
    Returns the offsets, the RMS (m) of the static markers about the neutral model with them,
    the poses (F, D) and the skeleton.
    """
    root = np.isin(DOF_NAMES, SEGMENTS[0].dofs)
    X_known, known = landmark_markers(X, nominal)
    q0 = np.where(root, initial_pose(skeleton, X_known, segments, known), 0.0)
    q = solve_poses(skeleton, X_known, segments, known, q0=q0, free=root, smoothing=0.0).q
    q[:, ROOT_HEADING] += heading_offset
    if centres:
        skeleton = Skeleton(skeleton.lengths, neutral_shifts(skeleton, q, centres))
    T = skeleton.forward(q)
    offsets = register_offsets(skeleton, q, X, segments, nominal=nominal, align=(), transforms=T)
    residual = np.linalg.norm(skeleton.points(q, segments, offsets, transforms=T) - X, axis=2)
    return offsets, float(np.sqrt(np.nanmean(residual ** 2))), q, skeleton


def neutral_shifts(skeleton: Skeleton, q: np.ndarray,
                   centres: dict[tuple[str, float], np.ndarray]
                   ) -> dict[str, tuple[float, float, float]]:
    """:attr:`Skeleton.shifts` (metres) that put the shoulders and elbows
    (:data:`NEUTRAL_CENTRES`) at their anatomical centres on a static in the neutral pose.

    ``q`` (F, D) the static's poses (every joint angle 0, so every segment's frame is the
    root's), ``centres`` the anatomical joint centres (:func:`joint_centres`, world, (F, 3)).
    A joint is placed after its parent (an elbow in the moved upper arm's frame), and both
    sides take the mean of their shifts, mirrored. Without the shifts a shoulder sits where
    the nominal layout puts it, straight above the hip centres, and the elbow straight below
    it: an elbow hinged about a point off the true one reads the wrong flexion, more as it
    flexes more (docs/results/fit_accuracy.md).
    """
    T = skeleton.forward(q)
    frames = {}
    for name in NEUTRAL_CENTRES:
        if (name, 0.0) in centres:
            parent = SEGMENT_NAMES.index(SEGMENTS[SEGMENT_NAMES.index(name)].parent)
            frames.setdefault(SEGMENT_NAMES[parent], (T[:, parent, :3, :3], T[:, parent, :3, 3]))
            frames[name] = (T[:, parent, :3, :3], centres[(name, 0.0)])
    return _mirrored_mean(joint_shifts(skeleton, frames))


def _mirrored_mean(shifts: dict[str, tuple[float, float, float]]
                   ) -> dict[str, tuple[float, float, float]]:
    """One shift (metres) for both sides of each segment in ``shifts``: the mean of the
    sides' own, the right's mirrored (y negated). The skeleton stays left-right symmetric
    (its lengths are the sides' means), so the shoulder line keeps the torso's heading (θ_S)."""
    sides: dict[str, list] = {}
    for name, (x, y, z) in shifts.items():
        for key, sign in ((name, 1.0), (partner_name(name), -1.0)):
            sides.setdefault(key, []).append((x, sign * y, z))
    return {name: tuple(float(v) for v in np.mean(values, axis=0))
            for name, values in sides.items()}


def anatomical_frames(skeleton: Skeleton, q: np.ndarray, X: np.ndarray, landmarks: list[str],
                      centres: dict[tuple[str, float], np.ndarray], drops: dict[str, float],
                      *, level_feet: bool = False) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """:func:`mocaplib.model.anatomy.segment_frames` of the markers ``X`` (F, M, 3) (``landmarks``
    (M,) their landmarks) and joint ``centres`` (:func:`joint_centres`), the arms hanging
    from the shoulder centres where the torso's layout puts them at the poses ``q`` (F, D)
    of ``skeleton``, except on the sides ``drops`` (:func:`shoulder_drops`) places below the
    acromion."""
    T = skeleton.forward(q)
    shoulders = {(name, 0.0): T[:, SEGMENT_NAMES.index(name), :3, 3]
                 for name in ("humerus_l", "humerus_r")
                 if (name, 0.0) in centres and name[-1] not in drops}
    return segment_frames({name: X[:, i] for i, name in enumerate(landmarks)},
                          {**centres, **shoulders}, level_feet=level_feet)


def shoulder_drops(measurements: dict[str, float]) -> dict[str, float]:
    """How far (metres) each side's shoulder centre lies below its acromion marker when the
    subject's shoulder offset is measured (``shoulder_offset_l``/``_r``, Plug-in Gait's
    ``ShoulderOffset``): that offset plus the marker radius, as Plug-in Gait places it. Keys
    "l", "r"; a side not measured is left out."""
    radius = 0.5 * measurements.get("marker_diameter", DEFAULT_MARKER_DIAMETER)
    return {side: measurements[f"shoulder_offset_{side}"] + radius for side in "lr"
            if measurements.get(f"shoulder_offset_{side}")}


def thorax_axis(where: dict[str, np.ndarray]) -> np.ndarray | None:
    """Plug-in Gait's thorax long axis, unit, (..., 3): from the middle of T10 and STRN to the
    middle of C7 and CLAV (``where`` maps landmark names to positions (..., 3)); None without
    those four landmarks."""
    if not {"C7", "CLAV", "T10", "STRN"} <= set(where):
        return None
    return _unit(where["C7"] + where["CLAV"] - where["T10"] - where["STRN"])


def shoulder_shifts(skeleton: Skeleton, offsets: np.ndarray, landmarks: list[str],
                    drops: dict[str, float]) -> dict[str, tuple[float, float, float]]:
    """:attr:`Skeleton.shifts` (metres) that hang the arms from the shoulder centres
    :func:`shoulder_drops` places: ``drops[side]`` below the acromion marker's offset (M, 3)
    in the torso's frame (``landmarks`` (M,) names the markers' landmarks). Both sides take
    the mean of their shifts, mirrored, so the shoulder line keeps the torso's heading (θ_S).
    Empty without a measured side or its acromion marker.

    Where the torso's catalogue layout puts them instead, the shoulders of the Plug-in Gait
    captures sit 36-44 mm from Plug-in Gait's centres, 17-39 mm higher: the arm swings about
    a point that far from the pivot, the distance from the shoulder centre to the wrist
    changes with the swing, and the elbow hinge takes the change up, about doubling its
    range on the walks (docs/guide/fitting.md, The arms)."""
    nominal = Skeleton(skeleton.lengths).joint_offsets()
    up = thorax_axis({name: offsets[i] for i, name in enumerate(landmarks)})
    up = np.array([0.0, 0.0, 1.0]) if up is None else up
    return _mirrored_mean({
        f"humerus_{side}": tuple(offsets[landmarks.index(f"{side.upper()}_ACROMION")] - drop * up
                                 - nominal[SEGMENT_NAMES.index(f"humerus_{side}")])
        for side, drop in drops.items() if f"{side.upper()}_ACROMION" in landmarks})


def locked_dofs(segments: np.ndarray) -> tuple[list[str], list[str]]:
    """DOFs too few markers can see, and segments with no marker on or below them.

    ``segments`` (M,) are the markers' segment indices. A joint is locked when its segment and
    descendants carry no marker, or a single marker for a 3-DOF joint (a marker and the joint
    centre leave the rotation about their line free).
    """
    counts = np.bincount(np.asarray(segments, int), minlength=len(SEGMENTS))
    below = counts.copy()
    for s in reversed(range(len(SEGMENTS))):          # children come after their parents
        parent = SEGMENTS[s].parent
        if parent is not None:
            below[SEGMENT_NAMES.index(parent)] += below[s]
    locked, left_out = [], []
    for s, seg in enumerate(SEGMENTS):
        if seg.parent is None:
            continue
        if below[s] == 0:
            left_out.append(seg.name)
        if below[s] == 0 or (len(seg.dofs) == 3 and below[s] < 2):
            locked.extend(seg.dofs)
    return locked, left_out


def _calibration_frames(X: np.ndarray, n_frames: int) -> np.ndarray:
    """Indices of up to ``n_frames`` frames among the most complete, spread evenly in time."""
    count = np.isfinite(X[..., 0]).sum(axis=1)
    if count.size == 0 or count.max() == 0:
        return np.arange(0)
    good = np.flatnonzero(count >= count.max() - max(1, X.shape[1] // 10))
    pick = np.linspace(0, len(good) - 1, min(n_frames, len(good))).round().astype(int)
    return good[distinct(pick)]


def estimate_height(X: np.ndarray, segments: np.ndarray, nominal: np.ndarray, *,
                    source: str | None = None) -> float:
    """Standing height, metres, from marker distances within segments vs nominal (1.75 m),
    clipped to 0.8-2.3 m.

    X (F, M, 3) markers; segments (M,); nominal (M, 3) catalogue positions for 1.75 m. Falls
    back to 1.75 m when no segment carries two markers seen together. Raises
    :class:`CalibrationError` naming ``source`` when the distances suggest a height outside
    :data:`PLAUSIBLE_HEIGHT` (the file's units are wrong).
    """
    ratios = []
    distances, pairs = segment_distances(X, segments)
    for (a, b), d in zip(pairs, distances):
        ref = np.linalg.norm(nominal[a] - nominal[b])
        if ref > 0.05 and np.isfinite(d):
            ratios.append(d / ref)
    if not ratios:
        return _protocols.REFERENCE_HEIGHT
    height = float(median(ratios) * _protocols.REFERENCE_HEIGHT)
    if not PLAUSIBLE_HEIGHT[0] <= height <= PLAUSIBLE_HEIGHT[1]:
        raise CalibrationError(
            f"the distances between markers on one segment suggest a subject {height:.3g} m "
            "tall: the coordinates are not in the units the file states", path=source,
            hint=UNITS_HINT)
    return float(np.clip(height, 0.8, 2.3))


def joint_centres(X: np.ndarray, landmarks: list[str], segments: np.ndarray,
                  skeleton: Skeleton, q: np.ndarray, *, scale: float,
                  measurements: dict[str, float] | None = None, neutral: bool = False
                  ) -> tuple[dict[tuple[str, float], np.ndarray], dict[str, str]]:
    """Anatomical joint centres per frame, world (F, 3) metres, and how each was found.

    Keys are ``(segment, z)``: the point ``(0, 0, z)`` of that segment's frame (z = 0: its
    joint; the wrist is the forearm's end). Hip: :func:`mocaplib.model.anatomy.harrington_hips`.
    Knee and ankle: the midpoint of the lateral and medial landmarks; else the chord
    (:func:`mocaplib.model.anatomy.chord_centre`) from the proximal centre, the lateral marker and
    the segment's other markers, with ``delta`` = (joint width + marker diameter) / 2 from
    ``measurements`` (metres; :data:`mocaplib.model.anatomy.MEASUREMENTS`) or, without them, the
    catalogue's distance from the lateral landmark to the joint; else (no other marker on
    the segment) the lateral landmark moved by its catalogue offset turned by the nominal fit
    ``q`` (F, D). Elbow: likewise; shoulder: the acromion lowered by the measured shoulder
    offset (:func:`shoulder_drops`) along Plug-in Gait's thorax axis (:func:`thorax_axis`;
    without its landmarks, the torso's), else the acromion's catalogue offset; wrist:
    mid-styloids. On a static in the neutral pose (``neutral``) catalogue offsets are turned
    by the pelvis's orientation (every segment's in that pose) and the elbow is not placed by
    the chord (:data:`NEUTRAL_CHORD_JOINTS`). A knee, ankle or elbow none of these place is
    the functional centre of three markers of each of its segments
    (:func:`mocaplib.model.anatomy.functional_centre`, the proximal centre as the hinge's hint),
    when the joint turns enough over the frames. ``scale`` = height / 1.75 scales catalogue offsets. The
    methods (str per joint, e.g. ``{"knee_l": "chord, knee width from the measurements"}``)
    are returned beside the centres.
    """
    where = {name: X[:, i] for i, name in enumerate(landmarks)}
    catalogue = _protocols.load_landmarks()
    measurements = measurements or {}
    drops = shoulder_drops(measurements)
    T = skeleton.forward(q)
    joints = skeleton.joint_offsets()
    out: dict[tuple[str, float], np.ndarray] = {}
    methods: dict[str, str] = {}
    back = _mean_of(where, ["L_PSIS", "R_PSIS"]) if {"L_PSIS", "R_PSIS"} <= set(where) \
        else where.get("SACRUM")
    if {"L_ASIS", "R_ASIS"} <= set(where) and back is not None:
        hips = dict(zip("lr", harrington_hips(where["L_ASIS"], where["R_ASIS"], back)))
        for side, centre in hips.items():
            leg = measurements.get(f"leg_length_{side}")
            if leg:
                centre = davis_hip(
                    where["L_ASIS"], where["R_ASIS"], back, side=side, leg_length=leg,
                    marker_radius=0.5 * measurements.get("marker_diameter",
                                                         DEFAULT_MARKER_DIAMETER),
                    asis_trochanter=measurements.get(f"asis_trochanter_{side}"),
                    asis_distance=measurements.get("inter_asis_distance"))
            out[(f"femur_{side}", 0.0)] = centre
            methods[f"hip_{side}"] = ("Davis (conventional gait model), leg length from the "
                                      "measurements" if leg else "Harrington regression")

    def from_catalogue(lat, child):
        mark = catalogue[lat]
        s = 0 if neutral else SEGMENT_NAMES.index(mark.segment)
        local = np.asarray(mark.position) * scale - joints[SEGMENT_NAMES.index(child)]
        return where[lat] - T[:, s, :3, :3] @ local, local

    chord_joints = NEUTRAL_CHORD_JOINTS if neutral else _CHORD_JOINTS

    for side in ("L", "R"):
        suffix = "_" + side.lower()
        for child, (lateral, medial) in _LANDMARK_JOINTS.items():
            lat, med = f"{side}_{lateral}", f"{side}_{medial}"
            joint = _JOINT_NAMES.get(child, child) + suffix
            if lat in where and med in where:
                out[(child + suffix, 0.0)] = 0.5 * (where[lat] + where[med])
                methods[joint] = "midpoint of the lateral and medial landmarks"
            elif lat in where:
                centre, local = from_catalogue(lat, child + suffix)
                parent = SEGMENT_NAMES.index(catalogue[lat].segment)
                proximal = out.get((SEGMENT_NAMES[parent], 0.0))
                wand = _wand(landmarks, segments, parent, side, (lat, med))
                wand_point, medial_hint = None, centre - where[lat]
                if child in chord_joints and proximal is not None:
                    if wand:
                        with warnings.catch_warnings():
                            warnings.simplefilter("ignore", RuntimeWarning)  # wand unseen: NaN
                            wand_point = np.nanmean(X[:, wand], axis=1)
                    elif child == "forearm":
                        torso_left = T[:, SEGMENT_NAMES.index("torso"), :3, 1]
                        axis = _elbow_axis(where, side, proximal, where[lat],
                                           medial=torso_left if side == "R" else -torso_left)
                        if axis is not None:
                            wand_point, medial_hint = where[lat] - axis, axis
                if wand_point is not None:
                    width = measurements.get(f"{_JOINT_NAMES[child]}_width{suffix}")
                    delta = (0.5 * (width + measurements.get("marker_diameter",
                                                             DEFAULT_MARKER_DIAMETER))
                             if width else float(np.linalg.norm(local)))
                    centre = chord_centre(proximal, wand_point, where[lat], delta,
                                          medial_hint=medial_hint)
                    methods[joint] = (f"chord, {_JOINT_NAMES[child]} width "
                                      + ("from the measurements" if width
                                         else "from the landmark catalogue"))
                elif child == "humerus" and suffix[1] in drops:
                    up = thorax_axis(where)
                    if up is None:
                        up = T[:, SEGMENT_NAMES.index(catalogue[lat].segment), :3, 2]
                    centre = where[lat] - drops[suffix[1]] * up
                    methods[joint] = "acromion lowered by the measured shoulder offset"
                else:
                    methods[joint] = "lateral landmark and its catalogue offset"
                out[(child + suffix, 0.0)] = centre
        for child, parent in (("tibia", "femur"), ("foot", "tibia"), ("forearm", "humerus")):
            if (child + suffix, 0.0) in out:
                continue
            frames = [_three_markers(X, segments, name + suffix) for name in (parent, child)]
            centre = None if None in frames else functional_centre(
                *frames, hint=out.get((parent + suffix, 0.0)))
            if centre is not None:
                out[(child + suffix, 0.0)] = centre
                methods[_JOINT_NAMES[child] + suffix] = \
                    f"functional (SCoRE) from the {parent}'s and {child}'s markers"
        rad, uln = f"{side}_WRIST_RAD", f"{side}_WRIST_ULN"
        if rad in where and uln in where:
            out[("forearm" + suffix, -skeleton.lengths["forearm"])] = (
                0.5 * (where[rad] + where[uln]))
            methods["wrist" + suffix] = "midpoint of the styloids"
    return out, methods


def _three_markers(X: np.ndarray, segments: np.ndarray, segment: str):
    """The rigid frames (:func:`mocaplib.model.anatomy.marker_frames`) of the three markers of
    ``segment`` seen in the most frames of X (F, M, 3), or None when it carries fewer."""
    on = np.flatnonzero(segments == SEGMENT_NAMES.index(segment))
    if len(on) < 3:
        return None
    seen = np.isfinite(X[:, on, 0]).sum(axis=0)
    return marker_frames(X[:, on[np.argsort(-seen, kind="stable")[:3]]])


def _elbow_axis(where: dict[str, np.ndarray], side: str, shoulder: np.ndarray,
                lateral: np.ndarray, *, medial: np.ndarray) -> np.ndarray | None:
    """The normal (F, 3), unit, pointing medially, of the arm's plane through the
    ``shoulder`` centre, the lateral elbow marker ``lateral`` and the middle of
    the wrist landmarks of ``side`` (each (F, 3)), turned to the side of ``medial`` (F, 3),
    the body's medial direction (the torso's). Plug-in Gait's elbow chord sets its plane with
    it (the plane of the shoulder centre, the elbow marker and a point along this normal), so
    the centre lies on this normal. None without both wrist landmarks."""
    wrist = [where.get(f"{side}_{name}") for name in ("WRIST_RAD", "WRIST_ULN")]
    if any(point is None for point in wrist):
        return None
    normal = _unit(np.cross(shoulder - lateral, 0.5 * (wrist[0] + wrist[1]) - lateral))
    return normal * np.where((normal * medial).sum(axis=-1, keepdims=True) < 0.0, -1.0, 1.0)


def _wand(landmarks: list[str], segments: np.ndarray, parent: int, side: str,
          joint_landmarks: tuple[str, str]) -> list[int]:
    """Markers (indices) whose plane with a joint line sets a chord's medial direction: the
    segment's wand landmarks (:data:`mocaplib.model.anatomy.WANDS`) when on, else its other
    markers (not the joint's own ``joint_landmarks``)."""
    names = {f"{side}_{w}" for w in WANDS.get(SEGMENT_NAMES[parent][:-2], ())}
    wand = [i for i, name in enumerate(landmarks) if name in names]
    return wand or [i for i, name in enumerate(landmarks)
                    if segments[i] == parent and name not in joint_landmarks]


def joint_shifts(skeleton: Skeleton, frames: dict[str, tuple[np.ndarray, np.ndarray]]
                 ) -> dict[str, tuple[float, float, float]]:
    """:attr:`Skeleton.shifts` (metres) that put each joint centre where the anatomical
    ``frames`` (:func:`mocaplib.model.anatomy.segment_frames`: the origin of a segment's frame is its
    joint centre) place it in its parent's frame: the median over frames, minus where the
    lengths alone put it."""
    joints = Skeleton(skeleton.lengths).joint_offsets()
    out = {}
    for name, (_, origin) in frames.items():
        parent = SEGMENTS[SEGMENT_NAMES.index(name)].parent
        if parent not in frames:
            continue
        R, at = frames[parent]
        local = np.einsum("fji,fj->fi", R, origin - at)
        shift = nanmedian(local, axis=0) - joints[SEGMENT_NAMES.index(name)]  # NaN: never seen
        if np.isfinite(shift).all():
            out[name] = tuple(float(x) for x in shift)
    return out


def functional_knee_turns(anatomical_model, X: np.ndarray, segments: np.ndarray, *,
                          free: np.ndarray) -> tuple[dict[str, float], dict[str, str]]:
    """Each knee's functional flexion axis (step 4b): its turn about the femur's long axis
    from the anatomical one, radians in the sense of ``hip_rotation`` per side ("l", "r"),
    and a sentence per side for ``SubjectModel.centre_methods`` (``knee_axis_l``...).

    ``anatomical_model(knee_turns)`` returns the model (offsets (M, 3), kept (M,), skeleton) whose
    leg frames have the knees' axes turned by ``knee_turns`` (step 4's frames,
    :func:`mocaplib.model.anatomy.segment_frames`); ``X`` (F, M, 3) are the markers of step 5 (the
    motion's), of which every :data:`KNEE_AXIS_FRAME_STEP`-th frame is fitted. The poses are
    fitted with both knees turned by each of :data:`KNEE_AXIS_TURNS`, starting from the
    anatomical axes' poses; a side's turn is the vertex of the parabola through the smallest
    mean squared residual of its thigh and shank markers and its two neighbours. A side whose
    knee flexes less than :data:`KNEE_AXIS_MIN_FLEXION` over ``X`` (a static, standing) keeps
    its anatomical axis: a hinge's axis shows only when it turns.
    """
    X = X[::KNEE_AXIS_FRAME_STEP]

    def fit(turns, q0=None):
        offsets, _, skeleton = anatomical_model(turns)
        return solve_poses(skeleton, X, segments, offsets, q0=q0, free=free)

    start = fit(None)
    sides, methods = [], {}
    for side in ("l", "r"):
        knee = DOF_NAMES.index(f"knee_flexion_{side}")
        leg = np.isin(segments, [SEGMENT_NAMES.index(f"{name}_{side}")
                                 for name in ("femur", "tibia")])
        if not free[knee] or not leg.any():
            continue
        flexion = float(np.ptp(start.q[:, knee])) if len(X) else 0.0
        if flexion < KNEE_AXIS_MIN_FLEXION:
            methods[f"knee_axis_{side}"] = (
                f"anatomical: the knee flexes {np.degrees(flexion):.0f}° in the calibration "
                f"frames, a functional axis needs {np.degrees(KNEE_AXIS_MIN_FLEXION):.0f}°")
        else:
            sides.append((side, leg, flexion))
    if not sides:
        return {}, methods
    costs = np.array([[np.nanmean(pose_fit.residuals[:, leg] ** 2) for _, leg, _ in sides]
                      for pose_fit in (fit({side: turn for side, _, _ in sides}, start.q)
                                       for turn in KNEE_AXIS_TURNS)])
    step = KNEE_AXIS_TURNS[1] - KNEE_AXIS_TURNS[0]
    turns = {}
    for (side, _, flexion), cost in zip(sides, costs.T):
        i = int(np.clip(np.argmin(cost), 1, len(cost) - 2))
        a, b, c = cost[i - 1:i + 2]
        vertex = 0.5 * step * (a - c) / (a - 2 * b + c) if a - 2 * b + c > 0 else 0.0
        turns[side] = float(np.clip(KNEE_AXIS_TURNS[i] + vertex, KNEE_AXIS_TURNS[0],
                                    KNEE_AXIS_TURNS[-1]))
        methods[f"knee_axis_{side}"] = (
            f"functional: turned {np.degrees(turns[side]):+.1f}° (internal rotation positive) "
            f"about the thigh from the anatomical axis, fitting the thigh and shank markers over "
            f"{np.degrees(flexion):.0f}° of knee flexion")
    return turns, methods


def _lengths_from_centres(skeleton: Skeleton,
                          centres: dict[tuple[str, float], np.ndarray]) -> dict[str, float]:
    """Segment lengths (metres): median distances between joint centres, else the nominal."""
    lengths = dict(skeleton.lengths)
    c = {seg: pos for (seg, z), pos in centres.items() if z == 0.0}
    wrist = {seg: pos for (seg, z), pos in centres.items() if z != 0.0}

    def dist(a, b):
        return nanmedian(np.linalg.norm(a - b, axis=1))

    def both_sides(key, a, b, table_b=c):
        values = [dist(c[a + s], table_b[b + s]) for s in ("_l", "_r")
                  if a + s in c and b + s in table_b]
        values = [v for v in values if np.isfinite(v)]
        if values:
            lengths[key] = float(np.mean(values))

    if "femur_l" in c and "femur_r" in c:
        lengths["hip_width"] = float(dist(c["femur_l"], c["femur_r"]))
    both_sides("thigh", "femur", "tibia")
    both_sides("shank", "tibia", "foot")
    both_sides("upper_arm", "humerus", "forearm")
    both_sides("forearm", "forearm", "forearm", wrist)
    if "humerus_l" in c and "humerus_r" in c:
        lengths["shoulder_width"] = float(dist(c["humerus_l"], c["humerus_r"]))
    return {k: (v if np.isfinite(v) and v > 0.01 else skeleton.lengths[k])
            for k, v in lengths.items()}


def _virtual_markers(skeleton: Skeleton, centres: dict[tuple[str, float], np.ndarray],
                     n_frames: int):
    """Joint centres as markers: segment indices (V,), offsets (V, 3), positions (F, V, 3).

    A joint centre sits at its segment's origin; the wrist (keys with z != 0) at the end of
    ``skeleton``'s forearm.
    """
    keys = list(centres)
    segs = np.array([SEGMENT_NAMES.index(seg) for seg, _ in keys], dtype=int)
    offs = np.array([(0.0, 0.0, -skeleton.lengths["forearm"] if z else 0.0)
                     for _, z in keys]).reshape(-1, 3)
    pos = np.stack([centres[k] for k in keys], axis=1) if keys else np.zeros((n_frames, 0, 3))
    return segs, offs, pos


def register_offsets(skeleton: Skeleton, q: np.ndarray, X: np.ndarray, segments: np.ndarray, *,
                     nominal: np.ndarray, align=SEGMENT_NAMES,
                     unseen: np.ndarray | None = None,
                     transforms: np.ndarray | None = None) -> np.ndarray:
    """Marker offsets (M, 3) in their segments for poses q (F, D) and markers X (F, M, 3).

    Each offset is first the least-squares one, the mean of ``R_s^T (x − t_s)`` over the frames
    where the marker is seen (never seen: its row of ``unseen``, by default ``nominal``).
    Offsets fix a segment's markers but not its frame: a constant rotation of the frame could
    be absorbed by the offsets. So each segment's offsets are then turned about their centroid
    by the rotation that best aligns its landmark markers with the catalogue layout
    ``nominal`` (M, 3) (Kabsch; with two landmark markers the segment origin joins them; a lone
    one is turned about the origin onto its nominal direction); a tracking marker (NaN row of
    ``nominal``) turns with its segment's landmark markers. The frame is thus anatomical: zero
    angles put the landmark markers in the catalogue's layout, as the DOF sign table
    describes. Only segments named in ``align`` are turned. ``transforms``:
    :meth:`Skeleton.forward` (q), when already computed.
    """
    T = (skeleton.forward(q) if transforms is None else transforms)[:, segments]
    local = np.einsum("fmji,fmj->fmi", T[..., :3, :3], X - T[..., :3, 3])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # a marker never seen: NaN
        mean = np.nanmean(local, axis=0) if len(q) else np.full_like(nominal, np.nan)
    out = np.where(np.isfinite(mean), mean, nominal if unseen is None else unseen)
    catalogued = np.isfinite(nominal).all(axis=1) & np.isfinite(out).all(axis=1)
    for s in distinct(segments):
        idx = np.flatnonzero(segments == s)
        ref = idx[catalogued[idx]]
        if SEGMENT_NAMES[s] not in align or not len(ref):
            continue
        if len(ref) == 1:                # the turn taking its direction onto the nominal one
            out[idx] = out[idx] @ _turn_between(out[ref[0]], nominal[ref[0]]).T
            continue
        reg, nom = out[ref], nominal[ref]
        if len(ref) == 2:                          # the origin fixes the turn about their line
            reg, nom = np.vstack([reg, np.zeros(3)]), np.vstack([nom, np.zeros(3)])
        c_reg, c_nom = reg.mean(axis=0), nom.mean(axis=0)
        U, _, Vt = np.linalg.svd((reg - c_reg).T @ (nom - c_nom))
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
        R = U @ D @ Vt                              # rotation taking nominal to registered
        out[idx] = c_reg + (out[idx] - c_reg) @ R
    return out


def _turn_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation (3, 3) taking the direction of ``a`` (3,) onto that of ``b``."""
    a, b = _unit(a), _unit(b)
    v, c = np.cross(a, b), float(a @ b)
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c) if c > -1.0 + 1e-12 else -np.eye(3)


def landmark_markers(X: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Markers X (F, M, 3) and offsets (M, 3) for a fit that leaves out the tracking markers
    whose offsets are not measured yet (NaN rows): their columns NaN, their offsets 0."""
    unknown = ~np.isfinite(offsets).all(axis=1)
    return (np.where(unknown[None, :, None], np.nan, X),
            np.where(unknown[:, None], 0.0, offsets))


def _check_measured(model: SubjectModel, cal: Trial) -> None:
    """Raise :class:`CalibrationError` naming the tracking markers whose offsets could not be
    measured (never seen where their segment's pose is known)."""
    bad = [label for label, o in zip(model.labels, model.marker_offsets)
           if not np.isfinite(o).all()]
    if bad:
        raise CalibrationError(
            f"cannot measure where tracking marker{'s' if len(bad) > 1 else ''} "
            f"{', '.join(bad)} sit{'' if len(bad) > 1 else 's'}: not seen in the calibration "
            "frames together with the markers that place their segment", path=cal.source,
            hint="check the marker's gaps with `mocaplib inspect`, or give a static trial "
                 "(--static) that shows it")


def refine_lengths(skeleton: Skeleton, q: np.ndarray, X: np.ndarray, segments: np.ndarray,
                   offsets: np.ndarray, *, prior: dict[str, float], fixed=(),
                   transforms: np.ndarray | None = None) -> Skeleton:
    """Segment lengths by linear least squares for fixed poses q (F, D) and offsets (M, 3).

    Marker positions are affine in the lengths (joint offsets are linear in them), so one
    solve is exact: minimise Σ ||x − p(L)||² / σ_m² + Σ (L − prior)² / σ_L² with
    σ_m = :data:`MARKER_SIGMA`, σ_L = :data:`LENGTH_PRIOR`. Lengths named in ``fixed`` keep
    their value. ``transforms``: :meth:`Skeleton.forward` (q), when already computed.
    """
    keys = list(HEIGHT_PROPORTIONS)
    L0 = np.array([skeleton.lengths[k] for k in keys])
    T = skeleton.forward(q) if transforms is None else transforms
    base = skeleton.points(q, segments, offsets, transforms=T)
    valid = np.isfinite(X).all(axis=2)
    G = skeleton.length_jacobian(q, segments, transforms=T)[valid].reshape(-1, len(keys))
    G[:, np.isin(keys, list(fixed))] = 0.0
    r = (X - base)[valid].reshape(-1)
    prior_vec = np.array([prior[k] for k in keys])
    A = G.T @ G / MARKER_SIGMA ** 2 + np.eye(len(keys)) / LENGTH_PRIOR ** 2
    b = G.T @ r / MARKER_SIGMA ** 2 + (prior_vec - L0) / LENGTH_PRIOR ** 2
    L = L0 + np.where(np.isin(keys, list(fixed)), 0.0, np.linalg.solve(A, b))
    L = np.maximum(L, 0.2 * prior_vec)
    return Skeleton(dict(zip(keys, L.tolist())), skeleton.shifts)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _mean_of(where: dict[str, np.ndarray], names: list[str]) -> np.ndarray:
    return np.mean([where[n] for n in names], axis=0)
