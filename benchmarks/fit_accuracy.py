"""Accuracy of calibrate + fit: synthetic captures against their truth, real files' residuals.

    python benchmarks/fit_accuracy.py [--synth sample_c3d] [--real DIR] [--markdown PATH]
    python benchmarks/fit_accuracy.py --only budget     # running error budget
    python benchmarks/fit_accuracy.py --only statures   # 1.55 m and 1.95 m subjects
    python benchmarks/fit_accuracy.py --only model      # which body difference costs what
    python benchmarks/fit_accuracy.py --only ankle      # ankle inversion against the ankle's height

Forward kinematics: the tests' gait-like walk (``tests/fk_data.py``) with markers on the
catalogue landmarks, 6 mm soft-tissue artefact and 1 mm noise, ``--fk-seeds`` subjects.
Synthetic (every ``*.c3d`` with a ``.truth.json`` beside it): per capture, calibrated from the
capture itself, each DOF's joint-angle RMS error against the truth, in degrees, summarised per
locomotion class for the flexions (hip, knee, ankle) and the other rotations; "tracking" is the
same after removing each capture's mean error (the constant offset a placement error of the
markers leaves). Real files (the walking captures of ``--real``, the shared lab files):
protocol, markers, fitted/failed frames, mean per-frame marker RMS, largest marker error and the
marker holding it. Running error budget (``--only budget``): each running capture of the
sample plan regenerated with the artefacts switched off one group at a time (same seeds,
``mocaplib.synth``), calibrated from the session's static (neutral) and fitted with markers raw
or low-passed at Winter's cutoff, and the true angles themselves low-passed at that cutoff (what
the filter alone costs). Other statures (``--only statures``): one capture of each locomotion
type of the sample plan (:data:`STATURE_CAPTURES`) and its static regenerated for subjects of
1.55 m and 1.95 m (same seeds and marker placement; a capture too short for the taller
subject's slower cadence is lengthened to two cycles), built as the quick start's main command
builds (static, neutral pose, walk_straight_normal as forward reference) but cut at the default
toe-offs, with each capture's angle errors
as above and its v̂, ω̂, v̂_l errors against the truth. Model differences (``--only model``):
a few captures without marker artefacts, with the generator's knee and elbow made like the
fit's one feature at a time (:func:`model_differences`). Ankle pivot (``--only ankle``): the same
without artefact, a neutral static's hips and ankles moved, against the generator's subtalar
axis (:func:`ankle_pivot`). Prints Markdown tables (``--markdown
PATH`` also writes them into a results page, :mod:`markdown_results`).
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import dataclasses
import json
import sys
import tempfile
import time
import warnings
from collections import defaultdict
from pathlib import Path
from unittest import mock

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from mocaplib.model.calibration import calibrate  # noqa: E402
from mocaplib.errors import MocapError  # noqa: E402
from mocaplib.model.filtering import filter_trial, lowpass  # noqa: E402
from mocaplib.gait.fourier import encode_cycle  # noqa: E402
from mocaplib.model.ik import fit, fit_quality  # noqa: E402
from mocaplib.model.fitting import fit_capture  # noqa: E402
from mocaplib.io.c3d import read_c3d  # noqa: E402
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES  # noqa: E402
from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
from mocaplib.synth.capture import write_capture
from mocaplib.synth.plan import load_plan  # noqa: E402
from velocity_accuracy import compare  # noqa: E402

FLEXION = [DOF_NAMES.index(n) for n in DOF_NAMES
           if n.startswith(("hip_flexion", "knee_flexion", "ankle_dorsiflexion"))]
OTHER = [j for j, n in enumerate(DOF_NAMES) if j not in FLEXION and not n.startswith("pelvis_t")]
#: The real captures of people walking (or jogging) in ../shared/data/c3d.
WALKING = ["cmu/07_01.c3d", "cmu/07_12.c3d", "biomechzoo/HC030A05.c3d", "biomechzoo/HC030A22.c3d",
           "motonms_unipd/Walking1.c3d", "motonms_unipd/Walking3.c3d",
           "btkdata/PiG_Motion-FlatFoot-Full.c3d", "btkdata/Gait.c3d",
           "ezc3d_testfiles/Qualisys.c3d", "ezc3d_testfiles/BTS.c3d",
           "c3dviewer_examples/running.c3d"]


#: Calibration and marker filtering of each row of the synthetic table.
MODES = (("capture", None), ("capture", "auto"), ("static", None), ("static", "auto"))
#: The row whose errors are also reported per DOF (the quick start's settings), and the
#: targets per DOF of every capture against the independent body's truth (deg): flexion, other.
PER_DOF_MODE = ("static", "auto")
DOF_TARGETS = (2.0, 4.0)
#: One capture of each locomotion type, and the static, for ``--only statures``.
STATURE_CAPTURES = ("rest", "walk_straight_slow", "walk_straight_normal", "walk_straight_fast",
                    "walk_curve_r1_left_normal", "side_left_normal", "turn_spot_left_normal",
                    "diag_left_60_normal", "run_2p5", "run_3p5")
STATURES = (1.55, 1.95)


def fourier_orders(q: np.ndarray, rate: float, cycles: list[dict]) -> list[int]:
    """Fourier order N (tolerance 0.5 deg, 2 mm) of each true cycle of the angles q (F, D)."""
    t = np.arange(len(q)) / rate
    orders = []
    for cycle in cycles:
        inside = (t >= cycle["start_s"]) & (t < cycle["end_s"])
        q_end = np.array([np.interp(cycle["end_s"], t, column) for column in q.T])
        orders.append(encode_cycle(q[inside], t[inside] - cycle["start_s"], cycle["T"],
                                   q_end).order)
    return orders


def synthetic(folder: Path, static_path: Path | None) -> None:
    """Per calibration (the capture itself, or the static trial) and marker filter (none, or
    Winter's automatic cutoff): joint-angle errors per class and the Fourier orders."""
    captures = []
    for path in sorted(folder.glob("*.c3d")):
        truth_path = path.with_suffix(".truth.json")
        if truth_path.exists():
            captures.append((path, json.loads(truth_path.read_text())))
    static = read_c3d(static_path) if static_path and static_path.exists() else None
    orders_truth = [n for path, truth in captures
                    for n in fourier_orders(np.asarray(truth["angles"]["values"]),
                                            truth["rate_hz"], truth["cycles"])]
    print("| calibration | markers | class | captures | flexion RMS mean / max (deg) "
          "| other RMS mean / max (deg) | flexion tracking max | other tracking max "
          "| marker RMS (mm) | cutoff (Hz) | Fourier N median / max, at cap 20 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for calibration, cutoff in MODES:
        if calibration == "static" and static is None:
            continue
        rows, orders, cutoffs, errors = defaultdict(list), [], [], []
        worst: dict[str, tuple[float, str]] = {}
        squared, n_frames = np.zeros(len(DOF_NAMES)), 0
        for path, truth in captures:
            trial, used = filter_trial(read_c3d(path), cutoff=cutoff)
            cutoffs.append(np.nan if used is None else used)
            model = (calibrate(trial, static=static, static_pose="neutral")
                     if calibration == "static" else calibrate(trial))
            motion = fit(trial, model)
            error = motion.q - np.asarray(truth["angles"]["values"], dtype=float)
            rms = np.degrees(np.sqrt((error ** 2).mean(axis=0)))
            errors.append((path.stem, np.degrees(error)))
            squared, n_frames = squared + (error ** 2).sum(axis=0), n_frames + len(error)
            tracking = np.degrees(error.std(axis=0))
            orders += fourier_orders(motion.q, trial.rate, truth["cycles"])
            rows[truth.get("class", "?")].append(
                (rms[FLEXION], rms[OTHER], tracking[FLEXION], tracking[OTHER],
                 fit_quality(motion)["marker_rms_mm"]))
            for j in FLEXION + OTHER:
                if rms[j] > worst.get(DOF_NAMES[j], (0.0, ""))[0]:
                    worst[DOF_NAMES[j]] = (rms[j], path.stem)
        if (calibration, cutoff) == PER_DOF_MODE:
            per_dof = errors
        every = [r for group in rows.values() for r in group]
        orders = np.array(orders)
        fc = (f"{np.nanmin(cutoffs):.1f}–{np.nanmax(cutoffs):.1f}"
              if np.isfinite(cutoffs).any() else "none")
        for name, group in sorted(rows.items()) + [("all", every)]:
            f, o, tf, to, mk = (np.array([r[k] for r in group]) for k in range(5))
            extra = (f"{fc} | {np.median(orders):.0f} / {orders.max()}, "
                     f"{(orders >= 20).sum()} of {len(orders)}") if name == "all" else " | "
            print(f"| {calibration} | {cutoff or 'raw'} | {name} | {len(group)} | "
                  f"{f.mean():.2f} / {f.max():.2f} | {o.mean():.2f} / {o.max():.2f} | "
                  f"{tf.max():.2f} | {to.max():.2f} | {mk.mean():.1f} | {extra} |")
        means = np.mean([np.r_[r[0], r[1]] for r in every], axis=0)
        worst_dofs = sorted(zip(means, FLEXION + OTHER), reverse=True)[:4]
        print("|  |  | largest mean DOF errors: " + ", ".join(
            f"{DOF_NAMES[j]} {m:.2f} (worst {worst[DOF_NAMES[j]][0]:.2f}, "
            f"{worst[DOF_NAMES[j]][1]})" for m, j in worst_dofs) + " | | | | | | | | |")
        pooled = np.degrees(np.sqrt(squared / n_frames))
        print("|  |  | pooled over every frame of every capture, worst DOF: " + ", ".join(
            f"{group} {DOF_NAMES[j]} {pooled[j]:.2f}" for group, j in
            (("flexion", max(FLEXION, key=pooled.__getitem__)),
             ("other", max(OTHER, key=pooled.__getitem__)))) + " | | | | | | | | |")
    if static is not None:
        print()
        dof_table(per_dof)
    orders_truth = np.array(orders_truth)
    print(f"\nFourier N of the true angles over the same cycles: median "
          f"{np.median(orders_truth):.0f}, max {orders_truth.max()}, at cap 20: "
          f"{(orders_truth >= 20).sum()} of {len(orders_truth)}")


def dof_table(errors: list[tuple[str, np.ndarray]]) -> None:
    """Per DOF over the captures' angle errors ((name, (F, D) degrees) each): RMS mean and
    max (the capture), the mean |offset| (each capture's mean error) and tracking (the RMS
    about it) averaged, and the target (every capture; 2° for a DOF named for a
    flexion, 4° for the others)."""
    names = [name for name, _ in errors]
    rms = np.array([np.sqrt((e ** 2).mean(axis=0)) for _, e in errors])
    offset = np.array([np.abs(e.mean(axis=0)) for _, e in errors])
    tracking = np.array([e.std(axis=0) for _, e in errors])
    print("| DOF | RMS mean (deg) | RMS max (deg, capture) | mean \\|offset\\| (deg) "
          "| tracking mean (deg) | target (deg) | met |")
    print("|---|---|---|---|---|---|---|")
    for j in FLEXION + OTHER:
        k = int(np.argmax(rms[:, j]))
        target = DOF_TARGETS[0] if "flexion" in DOF_NAMES[j] else DOF_TARGETS[1]
        print(f"| {DOF_NAMES[j]} | {rms[:, j].mean():.2f} | {rms[k, j]:.2f} ({names[k]}) | "
              f"{offset[:, j].mean():.2f} | {tracking[:, j].mean():.2f} | {target:.0f} | "
              f"{'yes' if rms[k, j] <= target else '**no**'} |")


#: Artefact groups of the running budget: overrides of each capture's marker settings.
BUDGET = (("as shipped", {}), ("no soft tissue", {"soft_tissue": 0.0}),
          ("soft tissue only", {"placement_sd": 0.0, "noise_sd": 0.0}),
          ("none", {"soft_tissue": 0.0, "placement_sd": 0.0, "noise_sd": 0.0}))


def running_budget(plan_path: Path) -> None:
    """Flexion and other-DOF RMS error (max over DOFs, degrees) of each running capture per
    artefact group (:data:`BUDGET`) and marker filter, and the filter's cost on the truth."""
    captures = {c.name: c for c in load_plan(plan_path).captures}

    def generate(planned, overrides):
        markers = dataclasses.replace(planned.markers, **overrides)
        return dataclasses.replace(planned, markers=markers).generate()

    print("| capture | artefacts | markers | flexion RMS max (deg, DOF) "
          "| other RMS max (deg, DOF) |")
    print("|---|---|---|---|---|")
    for name in sorted(n for n, c in captures.items() if c.cls == "running"):
        for label, overrides in BUDGET:
            capture = generate(captures[name], overrides)
            static = generate(captures["rest"], overrides).trial
            truth = np.asarray(capture.truth["angles"]["values"], dtype=float)
            for cutoff in ("auto", None):
                trial, used = filter_trial(capture.trial, cutoff=cutoff)
                motion = fit(trial, calibrate(trial, static=static, static_pose="neutral"))
                rms = np.degrees(np.sqrt(((motion.q - truth) ** 2).mean(axis=0)))
                print(f"| {name} | {label} | {'raw' if used is None else f'{used:.1f} Hz'} | "
                      + " | ".join(f"{rms[j]:.2f} ({DOF_NAMES[j]})"
                                   for j in (max(group, key=lambda j: rms[j])
                                             for group in (FLEXION, OTHER))) + " |")
                if label == "as shipped" and used is not None:
                    floor = np.degrees(np.sqrt(((lowpass(truth, trial.rate, used) - truth) ** 2)
                                               .mean(axis=0)))
                    j = max(FLEXION, key=lambda j: floor[j])
                    k = max(OTHER, key=lambda k: floor[k])
                    print(f"| {name} | truth low-passed | {used:.1f} Hz | {floor[j]:.2f} "
                          f"({DOF_NAMES[j]}) | {floor[k]:.2f} ({DOF_NAMES[k]}) |")


def statures(plan_path: Path) -> None:
    """Angle and velocity errors of :data:`STATURE_CAPTURES` for subjects of :data:`STATURES`."""
    plan = [c for c in load_plan(plan_path).captures if c.name in STATURE_CAPTURES]
    print("| height | capture | flexion RMS mean / max (deg) | other RMS mean / max (deg) "
          "| Δv̂ (m/s) | Δω̂ (rad/s) | Δv̂_l (m/s) |")
    print("|---|---|---|---|---|---|---|")
    for height in STATURES:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            for planned in plan:
                write_capture(planned.for_height(height).generate(), folder, planned.name)
            settings = BuildSettings(static=str(folder / "rest.c3d"), static_pose="neutral",
                                     forward_reference=str(folder / "walk_straight_normal.c3d"))
            result = build_library([folder], settings, jobs=2, cache_dir=None, progress=False)
            result.write(folder / "library.json")
            velocities = {row["name"]: row for row in compare(folder / "library.json", folder)}
            static = read_c3d(folder / "rest.c3d")
            for planned in plan:
                path = folder / f"{planned.name}.c3d"
                truth = json.loads(path.with_suffix(".truth.json").read_text())
                motion = fit_capture(read_c3d(path), static=static, static_pose="neutral",
                                     heading_offsets=result.settings.heading_offsets).motion
                error = motion.q - np.asarray(truth["angles"]["values"], dtype=float)
                rms = np.degrees(np.sqrt((error ** 2).mean(axis=0)))
                row = velocities.get(planned.name)
                deltas = (" | ".join(f"{row[k] - row['true_' + k]:+.4f}"
                                     for k in ("v", "omega", "v_l"))
                          if row else "no entry | | ")
                worst = [max(group, key=lambda j: rms[j]) for group in (FLEXION, OTHER)]
                print(f"| {height:.2f} m | {planned.name} | " + " | ".join(
                    f"{rms[group].mean():.2f} / {rms[j]:.2f} ({DOF_NAMES[j]})"
                    for group, j in zip((FLEXION, OTHER), worst)) + f" | {deltas} |")


#: The generator's joints made like the fit's, one group at a time (``[joints]`` of
#: ``protocols/synthetic_body.toml`` overridden), for ``--only model``.
MODEL_VARIANTS = (("the body as shipped", {}),
                  ("knee without rollback", {"knee_rollback": 0.0}),
                  ("knee without screw-home", {"knee_screw_home": [0.0, 20.0]}),
                  ("knee without varus", {"knee_varus": 0.0}),
                  ("hinge knee", {"knee_rollback": 0.0, "knee_screw_home": [0.0, 20.0],
                                  "knee_varus": 0.0}),
                  ("hinge elbow", {"elbow_axis_tilt": [0.0, 0.0]}))
#: Captures of ``--only model``.
MODEL_CAPTURES = ("walk_straight_normal", "diag_right_150_fast", "run_3p0")
#: Marker settings of a capture without artefact (no placement error, soft tissue or noise).
EXACT_MARKERS = {"placement_sd": 0.0, "soft_tissue": 0.0, "noise_sd": 0.0}
#: ``--only ankle``: the generator's ankle as shipped and with its subtalar axis along the
#: foot's long axis (no elevation, no medial deviation)...
ANKLE_BODIES = (("as shipped", {}), ("subtalar axis along the foot", {"subtalar": [0.0, 0.0]}))
#: ...the joints a neutral static moves to their anatomical centres (the hips added to
#: :data:`mocaplib.model.joint_centres.NEUTRAL_CENTRES`, or not)...
ANKLE_HIPS = (("nominal", ()), ("Harrington", ("femur_l", "femur_r")))
#: ...and how far (m) the fitted ankles are then moved up; on these captures.
ANKLE_RAISES = (-0.025, 0.0, 0.025)
ANKLE_CAPTURES = ("walk_straight_normal", "run_3p0")


@contextlib.contextmanager
def generator_joints(joints: dict):
    """The generator's body with ``joints`` (``[joints]`` of ``protocols/synthetic_body.toml``)
    overridden while the block runs."""
    from mocaplib.synth import bones, truth

    original = bones._definition
    spec = copy.deepcopy(original())
    spec["joints"].update(joints)
    caches = (bones.synthetic_body, truth.convention, truth._neutral)
    bones._definition = lambda: spec
    for cached in caches:
        cached.cache_clear()
    try:
        yield
    finally:
        bones._definition = original
        for cached in caches:
            cached.cache_clear()


def exact_captures(plan_path: Path, names) -> dict:
    """The sample plan's captures ``names`` and its static ``rest`` generated without marker
    artefact (:data:`EXACT_MARKERS`), by name (:class:`mocaplib.synth.capture.SynthCapture`)."""
    captures = {c.name: c for c in load_plan(plan_path).captures}
    return {name: dataclasses.replace(captures[name], markers=dataclasses.replace(
        captures[name].markers, **EXACT_MARKERS)).generate() for name in (*names, "rest")}


def model_differences(plan_path: Path) -> None:
    """Which modelling difference costs what: :data:`MODEL_CAPTURES` and the static regenerated
    without marker artefacts (no placement error, soft tissue or noise: what is left is the two
    bodies' difference), calibrated on the static (neutral) and fitted raw, for each body
    variant of :data:`MODEL_VARIANTS`; RMS error (deg) of the leg and elbow DOFs, left side,
    the worst of the captures."""
    dofs = [DOF_NAMES.index(f"{n}_l") for n in (
        "hip_flexion", "hip_adduction", "hip_rotation", "knee_flexion", "ankle_dorsiflexion",
        "ankle_inversion", "elbow_flexion")]
    print("| generator's body | " + " | ".join(DOF_NAMES[j] for j in dofs) + " |")
    print("|---|" + "---|" * len(dofs))
    for label, joints in MODEL_VARIANTS:
        with generator_joints(joints):
            captures = exact_captures(plan_path, MODEL_CAPTURES)
            worst = np.zeros(len(DOF_NAMES))
            for name in MODEL_CAPTURES:
                capture = captures[name]
                motion = fit(capture.trial, calibrate(capture.trial, static=captures["rest"].trial,
                                                      static_pose="neutral"))
                error = motion.q - np.asarray(capture.truth["angles"]["values"])
                worst = np.maximum(worst, np.degrees(np.sqrt((error ** 2).mean(axis=0))))
        print(f"| {label} | " + " | ".join(f"{worst[j]:.2f}" for j in dofs) + " |")


def ankle_pivot(plan_path: Path) -> None:
    """Left ankle inversion and knee flexion against where a neutral static puts the hips and
    the ankle: :data:`ANKLE_CAPTURES` (a walk and ``run_3p0``) with their static, without marker
    artefact, per generator's ankle (:data:`ANKLE_BODIES`), hips (:data:`ANKLE_HIPS`) and
    ankle raise (:data:`ANKLE_RAISES`); the fitted ankle's height above the true centre
    (midway between the malleoli) on the static, the RMS errors (deg) and, on ``run_3p0``, the
    inversion error's mean in swing and in stance and its correlation with the foot's true
    rotation about the shank (which the fit's ankle has no DOF for)."""
    from mocaplib.model import calibration, joint_centres
    from mocaplib.synth.truth import extra_angles

    inversion, knee = DOF_NAMES.index("ankle_inversion_l"), DOF_NAMES.index("knee_flexion_l")
    foot = SEGMENT_NAMES.index("foot_l")
    neutral_shifts = joint_centres.neutral_shifts
    print("| generator's ankle | hips | fitted ankle above the true centre (mm) "
          "| knee_flexion_l walk / run | ankle_inversion_l walk / run "
          "| run: inversion error in swing / stance (mean) | run: correlation with the foot's "
          "rotation about the shank |")
    print("|---|---|---|---|---|---|---|")
    for body_label, joints in ANKLE_BODIES:
        with generator_joints(joints):
            captures = exact_captures(plan_path, ANKLE_CAPTURES)
            rest, run = captures["rest"], captures["run_3p0"]
            malleoli = rest.body.landmark_points(rest.motion.pose, ["L_ANKLE_LAT", "L_ANKLE_MED"])
            swing = run.motion.contact[:, 0] == 0
            turn = extra_angles(run.body, run.motion.pose)["ankle_rotation_l"]
            for hips_label, hips in ANKLE_HIPS:
                for raise_ in ANKLE_RAISES:
                    def raised(skeleton, q, centres, joints, raise_=raise_):
                        out = neutral_shifts(skeleton, q, centres, joints)
                        for name in ("foot_l", "foot_r"):
                            x, y, z = out.get(name, (0.0, 0.0, 0.0))
                            out[name] = (x, y, z + raise_)
                        return out
                    with mock.patch.object(calibration, "neutral_joints",
                                           lambda *_, hips=hips:
                                           joint_centres.NEUTRAL_CENTRES + hips), \
                            mock.patch.object(joint_centres, "neutral_shifts", raised):
                        model = calibrate(rest.trial, static=rest.trial, static_pose="neutral")
                        errors = {name: np.degrees(
                            fit(captures[name].trial, model).q
                            - np.asarray(captures[name].truth["angles"]["values"]))
                            for name in ANKLE_CAPTURES}
                    ankle = model.skeleton.forward(fit(rest.trial, model).q)[:, foot, :3, 3]
                    height = 1000 * (ankle[:, 2] - malleoli.mean(axis=1)[:, 2]).mean()
                    e = errors["run_3p0"][:, inversion]
                    rms = {j: " / ".join(f"{np.sqrt((errors[n][:, j] ** 2).mean()):.2f}"
                                         for n in ANKLE_CAPTURES) for j in (knee, inversion)}
                    print(f"| {body_label} | {hips_label} | {height:+.0f} | {rms[knee]} | "
                          f"{rms[inversion]} | {e[swing].mean():+.2f} / {e[~swing].mean():+.2f} "
                          f"| {np.corrcoef(turn, e)[0, 1]:+.2f} |")


def forward_kinematics(seeds: int) -> None:
    """The tests' FK walk (markers on the landmarks, 6 mm soft tissue, 1 mm noise), 300 frames."""
    sys.path.insert(0, str(ROOT / "tests"))
    from fk_data import fk_trial

    flex, other, marker = [], [], []
    for seed in range(seeds):
        cap = fk_trial(n_frames=300, placement_mm=0, sta_mm=6, noise_mm=1, seed=seed)
        motion = fit(cap.trial, calibrate(cap.trial))
        rms = np.degrees(np.sqrt(((motion.q - cap.q) ** 2).mean(axis=0)))
        flex.append(rms[FLEXION])
        other.append(rms[OTHER])
        marker.append(fit_quality(motion)["marker_rms_mm"])
    flex, other = np.array(flex), np.array(other)
    print(f"| forward-kinematics walk | {seeds} | {flex.mean():.2f} / {flex.max():.2f} | "
          f"{other.mean():.2f} / {other.max():.2f} | {np.mean(marker):.1f} |")


def real(folder: Path) -> None:
    """Each walking file as ``mocaplib fit`` does it: calibrated from the capture's markers
    low-passed at Winter's cutoff; fitted with outlying samples found on the raw markers,
    gapped, then low-passed (:func:`mocaplib.model.fitting.fit_capture`,
    :func:`mocaplib.model.ik.fit_filtered`); removed samples counted."""
    print("| file | protocol | markers | cutoff (Hz) | frames fitted / failed | marker RMS (mm) "
          "| max error (mm) | at marker | removed samples | seconds |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in WALKING:
        path = folder / name
        if not path.exists():
            continue
        start = time.perf_counter()
        try:
            fitted = fit_capture(read_c3d(path))
            motion, model, cutoff = fitted.motion, fitted.model, fitted.cutoff
        except MocapError as exc:
            print(f"| {name} | error: {exc} |")
            continue
        quality = fit_quality(motion)
        worst = int(np.nanargmax(np.nanmax(motion.residuals, axis=0)))
        fitted = int((~motion.failed & np.isfinite(motion.residuals).any(axis=1)).sum())
        removed = ", ".join(f"{k} {v}" for k, v in quality["rejected_per_marker"].items())
        print(f"| {name} | {model.protocol.name} | {len(model.labels)} | {cutoff:.1f} | "
              f"{fitted} / {len(quality['failed_frames'])} | {quality['marker_rms_mm']:.1f} | "
              f"{quality['max_marker_error_mm']:.1f} | {model.labels[worst]} | "
              f"{quality['rejected_samples']}{f' ({removed})' if removed else ''} | "
              f"{time.perf_counter() - start:.1f} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--synth", default=str(ROOT / "sample_c3d"))
    parser.add_argument("--real", default=str(ROOT.parent / "shared" / "data" / "c3d"))
    parser.add_argument("--static", default=str(ROOT / "sample_c3d" / "rest.c3d"),
                        help="static trial of the synthetic session (neutral pose)")
    parser.add_argument("--fk-seeds", type=int, default=5)
    parser.add_argument("--plan", default=str(ROOT / "protocols" / "paper_plan.toml"),
                        help="the sample plan, for the running budget and statures")
    parser.add_argument("--only", choices=("fk", "synth", "real", "budget", "statures", "model",
                                           "ankle"),
                        help="one table only (the budget, statures, model and ankle only "
                             "when asked)")
    add_markdown_option(parser)
    args = parser.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    with markdown_page(args.markdown, __file__):
        tables(args)
    return 0


def tables(args) -> None:
    """Print the tables the parsed ``args`` ask for."""
    if args.only in (None, "fk"):
        print("| data | captures | flexion RMS mean / max (deg) | other RMS mean / max (deg) "
              "| marker RMS (mm) |\n|---|---|---|---|---|")
        forward_kinematics(args.fk_seeds)
        print()
    if args.only in (None, "synth") and Path(args.synth).is_dir():
        synthetic(Path(args.synth), Path(args.static))
        print()
    if args.only in (None, "real") and Path(args.real).is_dir():
        real(Path(args.real))
    if args.only == "budget":
        running_budget(Path(args.plan))
    if args.only == "statures":
        statures(Path(args.plan))
    if args.only == "model":
        model_differences(Path(args.plan))
    if args.only == "ankle":
        ankle_pivot(Path(args.plan))


if __name__ == "__main__":
    sys.exit(main())
