"""Accuracy of a cluster set fitted with and without a static, against the synthetic truth.

    python benchmarks/cluster_accuracy.py [--markdown PATH]

Per synthetic capture of the cluster set ``cluster_fullbody`` (straight walk 1.2 m/s, run
2.5 m/s, curve of 2 m radius at 1 m/s, side-step 0.45 m/s to the right; one marker placement,
session seed 2010, as ``tests/test_cluster_without_static.py`` and ``tests/test_clusters.py``
make them), fitted as every command does (:func:`mocaplib.model.fitting.fit_capture`) once
with the session's static in the neutral pose and once calibrated from the capture itself:
the marker RMS (mm), the joint-angle RMS error against the generator's truth (degrees) of the
hip, knee and ankle flexions (worst side), of the elbows (worst side), over all DOFs, and
whether the leg flexion target (3° RMS for each, :data:`LEG_TARGET`) is met. Prints Markdown
tables (``--markdown PATH`` also writes them into a results page, :mod:`markdown_results`).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from markdown_results import add_markdown_option, markdown_page  # noqa: E402

from mocaplib.library.command import Command  # noqa: E402
from mocaplib.model.fitting import fit_capture  # noqa: E402
from mocaplib.model.ik import fit_quality  # noqa: E402
from mocaplib.skeleton import DOF_NAMES  # noqa: E402
from mocaplib.synth.capture import synthesize_capture  # noqa: E402

#: name -> (command, duration s, seed): the captures of the cluster tests.
CAPTURES = {"walk": (Command.from_kind("straight", speed=1.2), 3.0, 2),
            "run": (Command.from_kind("run", speed=2.5), 1.95, 65),
            "curve": (Command.from_kind("curve", speed=1.0, radius=2.0, side="left"), 3.6, 12),
            "side-step": (Command.from_kind("sidestep", speed=0.45, side="right"), 3.0, 7)}
#: The session's marker placement, shared by the captures and the static.
SESSION_SEED = 2010
#: Target RMS error (degrees) of each leg flexion DOF against the truth.
LEG_TARGET = 3.0
#: Joints whose flexion is reported, by DOF name prefix.
FLEXIONS = {"hip": "hip_flexion", "knee": "knee_flexion", "ankle": "ankle_dorsiflexion",
            "elbow": "elbow_flexion"}


def angle_errors(capture, fitted) -> np.ndarray:
    """RMS error (D,) degrees of each DOF of ``fitted`` against ``capture``'s truth (the
    pelvis translations left out: NaN)."""
    error = np.degrees(fitted.motion.q - capture.truth["angles"]["values"])
    rms = np.sqrt(np.mean(error ** 2, axis=0))
    rms[[i for i, name in enumerate(DOF_NAMES) if name.startswith("pelvis_t")]] = np.nan
    return rms


def worst_side(rms: np.ndarray, prefix: str) -> float:
    """The larger RMS error (degrees) of the left and right DOF ``prefix``."""
    return max(float(rms[DOF_NAMES.index(f"{prefix}_{side}")]) for side in "lr")


def tables() -> None:
    """Print one row per capture and calibration."""
    static = synthesize_capture(Command.from_kind("rest"), duration=2.0, seed=8,
                                protocol="cluster_fullbody", session_seed=SESSION_SEED)
    print("| capture | static | marker RMS (mm) | hip (°) | knee (°) | ankle (°) | elbow (°) "
          "| all DOFs (°) | leg target 3° |\n|---|---|---|---|---|---|---|---|---|")
    for name, (command, duration, seed) in CAPTURES.items():
        capture = synthesize_capture(command, duration=duration, seed=seed,
                                     protocol="cluster_fullbody", session_seed=SESSION_SEED)
        for label, kwargs in (("neutral", dict(static=static.trial, static_pose="neutral")),
                              ("none", {})):
            fitted = fit_capture(capture.trial, **kwargs)
            rms = angle_errors(capture, fitted)
            legs = [worst_side(rms, FLEXIONS[joint]) for joint in ("hip", "knee", "ankle")]
            print(f"| {name} | {label} | {fit_quality(fitted.motion)['marker_rms_mm']:.1f} | "
                  + " | ".join(f"{value:.1f}" for value in legs)
                  + f" | {worst_side(rms, FLEXIONS['elbow']):.1f} | "
                  f"{np.sqrt(np.nanmean(rms ** 2)):.1f} | "
                  f"{'met' if max(legs) <= LEG_TARGET else 'missed'} |")
    print("\nJoint-angle RMS error against the generator's truth, worst of both sides; "
          "\"all DOFs\": the root mean square over every rotation DOF.")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_markdown_option(parser)
    args = parser.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    with markdown_page(args.markdown, __file__):
        tables()
    return 0


if __name__ == "__main__":
    sys.exit(main())
