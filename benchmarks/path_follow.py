"""How closely the path follower keeps to a path, on the quick start's library.

    python benchmarks/path_follow.py [LIBRARY.json] [--samples sample_c3d] [--markdown PATH]

Without a library, builds the quick start's one from ``--samples`` (as
``benchmarks/control_space.py`` does). Then follows each path of :data:`PATHS` at 100 Hz
(:func:`mocaplib.library.follow.follow`, polylines at 1 m/s) and prints, per path, the cycles
synthesised (with their gaits, how many were clamped onto a cell and the largest turn warp
their path frames took, :data:`mocaplib.library.follow.MAX_TURN_WARP`),
:func:`mocaplib.library.follow.tracking_errors`: the largest distance of the root from the path,
the largest heading error, the largest frame-to-frame change of a joint angle against the
blended cycles' own, the feet once planted as `mocaplib animate` plants them (slide,
penetration, hover: :func:`mocaplib.library.planting.plant_feet`), and whether the targets
(:data:`TARGETS`) are met. Prints Markdown
(``--markdown PATH`` also writes it into a results page, :mod:`markdown_results`). Exit code 1
when a target is missed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from control_space import on_a_library  # noqa: E402
from mocaplib.library.controlspace import ControlSpace  # noqa: E402
from mocaplib.library.follow import Path as FollowedPath  # noqa: E402
from mocaplib.library.follow import follow, tracking_errors  # noqa: E402
from mocaplib.library.format import load_library  # noqa: E402
from mocaplib.library.planting import plant_feet  # noqa: E402

#: Targets: root within 5 cm of the path, heading within 5°, and the largest frame-to-frame
#: joint change at most 1 % above the blended cycles' own (the cross-fade adds no jump).
TARGETS = {"root_m": 0.05, "heading_deg": 5.0, "jump_ratio": 1.01,
           "slide_m": 0.002, "penetration_m": 0.0005, "hover_m": 0.003}


def arc(radius: float, turn: float, n: int = 40) -> np.ndarray:
    """Points (n, 2) m of a circular arc of ``radius`` m turning ``turn`` rad to the left from
    the origin, starting along +X."""
    th = np.linspace(0.0, turn, n)
    return np.column_stack([radius * np.sin(th), radius * (1.0 - np.cos(th))])


def _timeline(rows) -> FollowedPath:
    """A timeline from rows (t s, v̂ m/s, ω̂ rad/s, v̂_l m/s)."""
    rows = np.asarray(rows, dtype=float)
    return FollowedPath("timeline", t=rows[:, 0], commands=rows[:, 1:])


#: The paths: a 6 m straight line, a 3 m half circle, an S-curve of two 3 m quarter circles
#: (left then right), a 4 s pure side-step to the left at 0.4 m/s, and a walk at 1.4 m/s
#: changing to a run at 2.5 m/s after 3 s.
PATHS = {
    "straight line": FollowedPath("polyline", xy=np.array([[0.0, 0.0], [6.0, 0.0]])),
    "3 m half circle": FollowedPath("polyline", xy=arc(3.0, np.pi)),
    "S-curve": FollowedPath("polyline", xy=np.vstack([arc(3.0, np.pi / 2, 20),
                                                      [6.0, 6.0] - arc(3.0, np.pi / 2, 20)[::-1]])),
    "side-step timeline": _timeline([[0.0, 0.4, 0.0, 0.4], [4.0, 0.4, 0.0, 0.4]]),
    "walk to run timeline": _timeline([[0.0, 1.4, 0.0, 0.0], [3.0, 1.4, 0.0, 0.0],
                                       [3.01, 2.5, 0.0, 0.0], [7.0, 2.5, 0.0, 0.0]]),
}


def met(errors: dict) -> list[str]:
    """The targets ``errors`` (:func:`tracking_errors` and the planted feet's
    :class:`~mocaplib.library.planting.ContactMeasures`) misses, by name."""
    missed = [k for k in ("root_m", "heading_deg", "slide_m", "penetration_m", "hover_m")
              if errors[k] > TARGETS[k]]
    if errors["jump_deg"] > TARGETS["jump_ratio"] * errors["own_jump_deg"]:
        missed.append("jump")
    return missed


def followed_and_errors(skeleton, cs: ControlSpace, path: FollowedPath):
    """The motion following ``path`` on the control space ``cs`` (100 Hz, polylines at 1 m/s)
    and its errors: :func:`tracking_errors` and the feet planted on ``skeleton`` as `mocaplib
    animate` plants them (:class:`~mocaplib.library.planting.ContactMeasures`)."""
    followed = follow(cs, path, rate=100.0, speed=1.0)
    errors = tracking_errors(path, followed)
    errors.update(plant_feet(skeleton, followed.q, followed.rate).after.as_dict())
    return followed, errors


def table(library_path: Path) -> bool:
    """Print the table of every path on the library at ``library_path``; True when every
    target is met."""
    library = load_library(library_path)
    cs = ControlSpace.from_library(library)
    print("| path | cycles (walk / run, clamped) | turn warp (deg/s) | root (cm) | heading (deg) "
          "| largest jump (deg) | cycles' own (deg) | planted feet: slide / below / hover (mm) "
          "| targets |")
    print("|---|---|---|---|---|---|---|---|---|")
    ok = True
    for name, path in PATHS.items():
        followed, errors = followed_and_errors(library.skeleton, cs, path)
        gaits = [c.gait for c in followed.cycles]
        clamped = sum(c.clamped for c in followed.cycles)
        warp = max(abs(c.turn_warp) for c in followed.cycles)
        missed = met(errors)
        ok &= not missed
        print(f"| {name} | {len(gaits)} ({gaits.count('walk')} / {gaits.count('run')}, "
              f"{clamped}) | {np.degrees(warp):.2f} | {100 * errors['root_m']:.1f} | "
              f"{errors['heading_deg']:.2f} | {errors['jump_deg']:.2f} | "
              f"{errors['own_jump_deg']:.2f} | {1000 * errors['slide_m']:.2f} / "
              f"{1000 * errors['penetration_m']:.2f} / {1000 * errors['hover_m']:.2f} | "
              f"{'met' if not missed else 'missed: ' + ', '.join(missed)} |")
    print(f"\nTargets: root within {100 * TARGETS['root_m']:.0f} cm of the path, heading within "
          f"{TARGETS['heading_deg']:.0f}°, largest frame-to-frame joint change at most "
          f"{100 * (TARGETS['jump_ratio'] - 1):.0f} % above the blended cycles' own; the "
          f"feet planted (`mocaplib animate` plants them) slide at most "
          f"{1000 * TARGETS['slide_m']:g} mm, go at most {1000 * TARGETS['penetration_m']:g} mm "
          f"below the floor and hover at most {1000 * TARGETS['hover_m']:g} mm.")
    return ok


def main() -> int:
    return 0 if on_a_library(table, __doc__, __file__) else 1


if __name__ == "__main__":
    sys.exit(main())
