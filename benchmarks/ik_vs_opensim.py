"""mocaplib's joint-angle fit vs OpenSim 4.6's InverseKinematicsTool, same model and markers.

One run: calibrate the subject with mocaplib, export the model (.osim) and the markers (.trc),
then solve every frame with OpenSim's IK (each marker task weighted as mocaplib's fit weights
the marker, coordinate ranges clamped, accuracy 1e-5) and with ``mocaplib.model.ik.fit``,
alternately ``--repeat`` times each on one thread (fastest CPU time of the solve, so that
other jobs on a shared machine do not skew the ratio); print each one's frames/s, the speed
ratio and both joint-angle RMS errors against the truth.

``--matched`` puts both solvers on the same problem: plain least squares
(``robust_scale=np.inf``) without the continuity term (``smoothing=0``), the same marker
weights; it then compares what each stopping rule reached, frame by frame: the weighted sum of
squared marker errors of mocaplib's poses against OpenSim's (evaluated on the same model), and
the angles between the two. ``--solver fit_filtered`` times what ``mocaplib fit`` runs (the
marker low-pass at ``--cutoff`` and two fits, :func:`mocaplib.model.ik.fit_filtered`) against
OpenSim's IK on the filtered markers (the filter not in OpenSim's time).

Data: synthetic captures with ground truth (``--c3d FILE...``, files or folders of them, each
with ``FILE.truth.json`` beside it, as mocaplib.synth writes them; times and frames are summed
over them; captures without truth, such as lab files, are timed and compared without it), or
by default the tests' forward-kinematics walk (gait-like angles, 6 mm soft-tissue artefact,
1 mm noise; ``--frames`` long).

    python benchmarks/ik_vs_opensim.py [--frames 1000] [--c3d FILE...]
        [--static FILE] [--cutoff HZ|auto|none] [--matched] [--solver fit|fit_filtered]
        [--markdown PATH]

``--static`` calibrates from a static trial in the anatomical neutral pose (as ``mocaplib build
--static`` does); ``--cutoff`` low-passes the markers first (:mod:`mocaplib.model.filtering`), and
both solvers then get the same filtered markers (with ``--solver fit``, the filter's time is
not in either figure).

Prints Markdown tables (``--markdown PATH`` also writes them into a results page,
:mod:`markdown_results`). Needs the bench extra (``pip install ".[bench]"``: opensim).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

# one core each: OpenSim's IK is single-threaded, and BLAS threads only fight on a busy machine
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from opensim_tools import inverse_kinematics, read_mot  # noqa: E402
from mocaplib.model.calibration import calibrate  # noqa: E402
from mocaplib.model.ik import fit, fit_filtered, model_markers  # noqa: E402
from mocaplib.export.opensim import opensim_name, write_osim, write_trc  # noqa: E402
from mocaplib.skeleton import DOF_NAMES, DOFS  # noqa: E402
from mocaplib.trial import Trial  # noqa: E402

ROTATIONS = [j for j, d in enumerate(DOFS) if not d.translation]
FLEXION = [DOF_NAMES.index(n) for n in DOF_NAMES
           if n.startswith(("hip_flexion", "knee_flexion", "ankle_dorsiflexion"))]


def load_captures(args) -> list[tuple]:
    """[(trial, true q (F, D) or None)] from --c3d files, else the forward-kinematics walk."""
    if args.c3d:
        from mocaplib.io.c3d import read_c3d

        out = []
        paths = [p for arg in map(Path, args.c3d)
                 for p in (sorted(arg.glob("*.c3d")) if arg.is_dir() else [arg])]
        for path in paths:
            truth_path = Path(path).with_suffix(".truth.json")
            q = None
            if truth_path.exists():
                angles = json.loads(truth_path.read_text())["angles"]
                values = np.asarray(angles["values"], dtype=float)
                q = values[:, [angles["dof_names"].index(name) for name in DOF_NAMES]]
            out.append((read_c3d(path), q))
        return out
    from fk_data import fk_trial

    cap = fk_trial(n_frames=args.frames, placement_mm=0, sta_mm=6, noise_mm=1, seed=args.seed)
    return [(cap.trial, cap.q)]


def run_opensim(osim_path: Path, trc_path: Path, model, t_end: float, out: Path):
    """OpenSim IK on the exported files (each marker weighted as ``model`` weights it);
    returns (CPU seconds, q (F, D) radians)."""
    start = time.process_time()
    inverse_kinematics(osim_path, trc_path, [opensim_name(label) for label in model.labels],
                       model.marker_weights, t_end, out)
    return time.process_time() - start, read_mot(out, list(DOF_NAMES), ROTATIONS)


def marker_cost(model, q: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """The least-squares objective both solvers minimise with ``--matched``, per frame (F,):
    the weighted sum of squared distances (m²) between the markers (F, M, 3) and the model's
    at poses ``q`` (F, D)."""
    points = model.skeleton.points(q, model.marker_segments, model.marker_offsets)
    squared = ((points - markers) ** 2).sum(axis=2)
    return np.where(np.isfinite(squared), squared * model.marker_weights, 0.0).sum(axis=1)


def angle_errors(q, truth) -> tuple[float, float, float]:
    """(mean, max) RMS error over rotational DOFs and the max over flexions, degrees."""
    rms = np.degrees(np.sqrt(((q - truth) ** 2).mean(axis=0)))
    return float(rms[ROTATIONS].mean()), float(rms[ROTATIONS].max()), float(rms[FLEXION].max())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--c3d", nargs="+", metavar="FILE",
                        help="synthetic captures, each with a .truth.json beside it, or "
                             "folders of them")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--static", metavar="FILE", help="static trial (neutral pose)")
    parser.add_argument("--cutoff", default="none", help="marker low-pass: Hz, auto or none")
    parser.add_argument("--matched", action="store_true",
                        help="plain least squares without the continuity term, as OpenSim")
    parser.add_argument("--solver", choices=("fit", "fit_filtered"), default="fit")
    add_markdown_option(parser)
    args = parser.parse_args()
    with markdown_page(args.markdown, __file__):
        compare(args)
    return 0


def compare(args) -> None:
    """Time both solvers on the captures the parsed ``args`` name and print the tables."""
    from mocaplib.model.filtering import filter_trial
    from mocaplib.io.c3d import read_c3d

    static = read_c3d(args.static) if args.static else None
    cutoff = args.cutoff if args.cutoff in ("auto", "none") else float(args.cutoff)
    problem = dict(robust_scale=np.inf, smoothing=0.0) if args.matched else {}

    totals = {"OpenSim": 0.0, "mocaplib": 0.0}
    errors: dict[str, list] = {"OpenSim": [], "mocaplib": []}
    n = 0
    ratios, rows, costs, angles = [], [], [], []
    failed = 0
    for raw, truth in load_captures(args):
        trial, used = filter_trial(raw, cutoff=cutoff)
        model = calibrate(trial, static=static, static_pose="neutral")
        if args.solver == "fit":
            solve = partial(fit, trial, model, **problem)
        else:
            solve = lambda: fit_filtered(raw, model, cutoff=used, **problem)[0]  # noqa: E731
        osim_times, our_times = [], []
        markers = model_markers(trial, model)
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            write_osim(model, tmp / "model.osim")
            write_trc(Trial(markers, model.labels, trial.rate), tmp / "markers.trc")
            for _ in range(args.repeat):
                seconds, q_osim = run_opensim(tmp / "model.osim", tmp / "markers.trc", model,
                                              trial.duration, tmp / "ik.mot")
                osim_times.append(seconds)
                start = time.process_time()
                motion = solve()
                our_times.append(time.process_time() - start)
        n += trial.n_frames
        totals["OpenSim"] += min(osim_times)
        totals["mocaplib"] += min(our_times)
        for name, q in (("OpenSim", q_osim), ("mocaplib", motion.q)):
            if truth is not None and len(q) == len(truth):
                errors[name].append(angle_errors(q, truth))
        if args.matched:                  # frames mocaplib could not fit are interpolated
            fitted = ~motion.failed
            theirs = marker_cost(model, q_osim[fitted], markers[fitted])
            costs.append((marker_cost(model, motion.q[fitted], markers[fitted]) - theirs)
                         / theirs)
            # the same orientation may read a full turn apart (a heading past ±180°)
            turn = (motion.q - q_osim)[fitted][:, ROTATIONS]
            angles.append(np.degrees(np.angle(np.exp(1j * turn))))
            failed += int(motion.failed.sum())
        ratios.append((min(osim_times) / min(our_times), Path(trial.source).stem))
        rows.append(f"| {Path(trial.source).name} | {trial.n_frames} | {len(model.labels)} | "
                    f"{model.protocol.name} | {ratios[-1][0]:.1f}x |")
        print(rows[-1], file=sys.stderr)
    print(f"{n} frames, mocaplib's `{args.solver}`"
          + (", plain least squares without the continuity term, as OpenSim" if args.matched
             else "") + ". Joint-angle RMS error against the truth (degrees): mean over "
          "captures of the mean over DOFs / max over captures and DOFs / max over flexions.\n")
    print("| solver | frames/s | mean RMS (deg) | max RMS (deg) | max flexion (deg) |\n"
          "|---|---|---|---|---|")
    for name, seconds in totals.items():
        if errors[name]:
            e = np.array(errors[name])
            text = f"{e[:, 0].mean():.2f} | {e[:, 1].max():.2f} | {e[:, 2].max():.2f}"
        else:
            text = "(no truth) | | "
        print(f"| {name} | {n / seconds:.0f} | {text} |")
    t_osim, t_ours = totals["OpenSim"], totals["mocaplib"]
    print(f"\nSpeed ratio mocaplib / OpenSim: **{t_osim / t_ours:.1f}x**.")
    if len(ratios) > 1:
        print("Lowest per capture: " + ", ".join(f"{name} {r:.1f}x" for r, name in
                                                 sorted(ratios)[:4]) + ".")
    if args.matched:
        cost, angle = np.concatenate(costs), np.abs(np.concatenate(angles))
        print(f"\nWhere each stopping rule left the same objective (weighted sum of squared "
              f"marker errors, per frame, over the {len(cost)} frames mocaplib fitted; "
              f"{failed} it flagged as failed, too few markers or not converged, are left "
              f"out): mocaplib's minus OpenSim's, relative to OpenSim's, "
              f"median {np.median(cost):+.2%}, 95th percentile {np.percentile(cost, 95):+.2%}, "
              f"largest {cost.max():+.2%} ({np.mean(cost <= 0):.1%} of the frames no higher "
              f"than OpenSim's). Angles between the two solutions: RMS "
              f"{np.sqrt((angle ** 2).mean()):.2f}°, 99th percentile "
              f"{np.percentile(angle, 99):.2f}°, largest {angle.max():.2f}°.")
    print("\n| capture | frames | markers | protocol | speed ratio |\n|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    sys.exit(main())
