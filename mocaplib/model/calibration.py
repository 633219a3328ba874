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
   position, near the other's after the nominal fit of step 2; :func:`mocaplib.model.repairs.find_repairs`)
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
   Knee and elbow without landmarks in the trial (a cluster set calibrated from its
   motion): the functional centre and flexion axis of the two segments' markers (SCoRE and
   SARA, :mod:`mocaplib.model.functional`); the ankle: the foot's markers fitted rigidly to
   their catalogue layout. Knee, ankle, elbow: the midpoint of lateral
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
   landmark, :data:`NEUTRAL_CHORD_JOINTS`), and the hips, knees and ankles too when the
   motion follows the legs by clusters alone (:func:`neutral_joints`); and each marker's
   offset is then measured
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

import numpy as np

from ..errors import CalibrationError
from ..markersets import protocols as _protocols
from ..markersets.protocols import Protocol
from ..markersets.matching import label_match, match_trial
from ..numeric import distinct, median
from ..skeleton import (DOF_NAMES, DOFS, HEIGHT_PROPORTIONS, SEGMENT_NAMES, SEGMENTS, SHIFTS,
                        Skeleton, partner_name)
from ..statics import STATIC_POSES, standing_part
from ..trial import Trial
from .anatomy import flat_soles, leg_frames, offsets_in_frames
from .calibration_checks import (MIN_PRESENCE, check_sides, check_static_markers, check_upright,
                                 refuse_unmarked_pelvis)
from .joint_centres import (ANATOMICAL_LENGTHS, NEUTRAL_CENTRES, anatomical_frames,
                            estimate_height, functional_knee_turns, joint_centres, joint_shifts,
                            landmark_markers, lengths_from_centres, neutral_offsets,
                            register_offsets, shoulder_drops, shoulder_shifts)
from .motion import apply_repairs
from .repairs import find_repairs
from .solver import solve_poses
from .subject import SubjectModel

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


#: Segments whose frames stay aligned with the catalogue layout during refinement (step 5).
#: The others follow their markers, unless an anatomical frame of step 4 holds them.
ALIGNED_IN_REFINEMENT = ("pelvis", "torso", "head", "foot_r", "foot_l")


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
#: The leg joints a static in the neutral pose also moves to their anatomical centres (hips
#: Harrington's, knees and ankles the epicondyles' and malleoli's midpoints) when the motion
#: follows the thighs and shanks by tracking markers alone (:func:`neutral_joints`): nothing
#: but the model's centres then ties the clusters' motion to the joints. At the nominal layout
#: the synthetic cluster set's knees and ankles sit 24-27 mm above their landmarks and its run
#: reads ankle flexion 9.0° RMS off (walk 4.3°), placed 1.6° (0.9°)
#: (``python benchmarks/cluster_accuracy.py``); the side-step's ankle inversion then reads
#: 9.3° off instead of 4.5° (the lower pivot, :data:`NEUTRAL_CENTRES`; ``tests/test_clusters.py``).
#: A set whose knee and ankle markers stay on for the motion keeps the legs' nominal layout.
NEUTRAL_LEG_CENTRES = ("femur_r", "femur_l", "tibia_r", "tibia_l", "foot_r", "foot_l")


def choose_protocol(trial: Trial, protocol: Protocol | str | None = None) -> Protocol:
    """The protocol to use: the one given (object, shipped name or TOML path), else (None or
    "auto") the one :func:`mocaplib.markersets.matching.detect_protocol` finds for the trial's labels;
    resolved by :func:`mocaplib.markersets.matching.match_trial`, as every command resolves it."""
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
        a forward reference measures (:func:`mocaplib.build.forward.forward_offsets`). Only with a
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
        refuse_unmarked_pelvis(cal, proto, n_pelvis)
    if static is not None:
        X_motion = check_static_markers(X_all[:, used], trial, proto, used, segments, labels, static)
    locked, left_out = locked_dofs(segments)
    free = np.array([name not in locked for name in DOF_NAMES])
    calibration_frames = _calibration_frames(X_all[:, used], n_frames)
    X = X_all[calibration_frames][:, used]
    landmarks = [m.landmark.name for m in markers]
    check_upright(X, segments, cal)
    check_sides(X, landmarks, cal)
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
    centres, methods, axes = joint_centres(
        X, landmarks, segments, skeleton, first.q, scale=scale, measurements=measurements,
        neutral=neutral)
    anatomical = lengths_from_centres(skeleton, centres)
    skeleton = Skeleton(anatomical)
    if neutral:
        methods.update({f"knee_axis_{side}": "anatomical: a static in the neutral pose shows no "
                        "flexion axis" for side in ("l", "r") if (f"tibia_{side}", 0.0) in centres})
        offsets, rms, poses, skeleton = neutral_offsets(
            skeleton, X, segments, nominal=nominal_scaled, heading_offset=heading_offset,
            centres=centres, joints=neutral_joints(markers, segments, X_motion))
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
    where_cal = {name: X_cal[:, i] for i, name in enumerate(landmarks)}
    # the feet along their soles: flat on the static, or in the capture's calibration frames
    # that show each foot standing flat on its floor
    soles, sole_methods = (flat_soles(where_cal) if static is not None else flat_soles(
        {name: X_all[:, j] for name, j in zip(landmarks, used)}, rate=cal.rate,
        frames=calibration_frames))
    methods.update(sole_methods)
    frames_cal = anatomical_frames(unshifted, poses_cal, X_cal, landmarks, centres, drops,
                                   flat_feet=soles, axes=axes)
    in_frames_cal = offsets_in_frames(X_cal, segments, SEGMENT_NAMES, frames_cal)

    def anatomical_model(knee_turns=None):
        """Offsets (M, 3), the markers kept by the refinement (M,) and the skeleton with its
        joint shifts, measured in the anatomical frames (the knees' axes turned by
        ``knee_turns``: only the legs' frames built again)."""
        frames, in_frames = dict(frames_cal), in_frames_cal.copy()
        for side, turn in (knee_turns or {}).items():
            legs = leg_frames(where_cal, centres, side, flat=soles.get(side),
                              knee_turn=turn, axis=axes.get(f"femur_{side}"))
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
    fixed_lengths = [key for key, (a, b) in ANATOMICAL_LENGTHS.items()
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
                measurements=measurements)[0], drops, axes=axes).items()
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


def neutral_joints(markers: list, segments: np.ndarray, X_motion: np.ndarray
                   ) -> tuple[str, ...]:
    """The joints a static in the neutral pose moves to their anatomical centres (segment
    names): the arms' (:data:`NEUTRAL_CENTRES`), and the legs' (:data:`NEUTRAL_LEG_CENTRES`)
    when the motion ``X_motion`` (F, M, 3) of the static's ``markers`` (M,, on ``segments``)
    shows tracking markers on the thighs or shanks and no landmark marker there."""
    legs = np.flatnonzero(np.isin(segments, [SEGMENT_NAMES.index(f"{name}_{side}")
                                             for name in ("femur", "tibia") for side in "lr"]))
    seen = np.isfinite(X_motion[:, legs, 0]).mean(axis=0) >= MIN_PRESENCE
    tracking = np.array([markers[i].tracking for i in legs], dtype=bool)
    clusters = bool((seen & tracking).any() and not (seen & ~tracking).any())
    return NEUTRAL_CENTRES + (NEUTRAL_LEG_CENTRES if clusters else ())


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


