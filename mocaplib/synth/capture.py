"""One synthetic capture: markers as a :class:`~mocaplib.trial.Trial` plus its exact truth.

:func:`synthesize_capture` runs the generator (command → gait → body → skin markers) and
expresses the body's motion in the fit's conventions (:mod:`.truth`);
:func:`write_capture` writes ``<name>.c3d`` (with the true Foot Strike / Foot Off events in the
EVENT group) and ``<name>.truth.json``. Everything is a function of the arguments and the seed:
the same call writes byte-identical files.

Per-cycle truth (shoulder midpoint, the paper's definitions, signs of DESIGN.md)
    A cycle runs from a left toe-off to the next, T = one stride. Over the cycle, on 400 evenly
    spaced instants, the generated glenohumeral centres (L, R) give the midpoint M and
    θ_S = direction(L → R) + π/2 (unwrapped). ω̂ = (θ_S(end) − θ_S(start)) / T. The pattern is
    the path of the cycle-average of M taken in the commanded frame (an arc of radius v̂/|ω̂|,
    a line when ω = 0, a point on the spot); v̂ = its length over the cycle / T; θ_T its tangent
    along the motion; v̂_l = mean of v̂ sin(θ_T − θ_S) and v̂_f = mean of v̂ cos(θ_T − θ_S).
    Because the body's oscillations are periodic in the commanded frame and the pelvis is
    placed so that M averages to the commanded point, v̂ and ω̂ equal the command and v̂_l, v̂_f
    differ from it only by the trunk's yaw oscillation (second order: at most 0.8 % of v̂ over
    the paper plan).
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..errors import SynthError
from ..io.atomic import atomic_write_text
from ..io.c3d_write import write_c3d
from ..io.jsonvalues import json_values
from ..library.command import Command
from ..markersets.protocols import load_protocol
from ..skeleton import DOF_NAMES
from ..trial import Event, Trial
from .body import BodyMotion, body_motion, shoulder_path
from .bones import Body, synthetic_body
from .command import world_to_frame
from .gait import LEAD_S, GaitParameters, gait_parameters
from .markers import MarkerSettings, skin_markers
from .truth import extra_angles, true_angles

TRUTH_FORMAT = "mocaplib-synth-truth/2"
#: Earlier truth formats :func:`mocaplib.synth.plan.check_targets` still recognises as synth
#: outputs (format 1: the angles were the generator's own, on the fitting skeleton).
TRUTH_FORMATS = ("mocaplib-synth-truth/1", TRUTH_FORMAT)
#: What the truth's angles are, written into every truth file.
ANGLES_MAPPING = ("the fit's anatomical definitions applied to the generator's true landmarks "
                  "(no marker error) in its neutral pose, the frames carried by its bones, "
                  "each joint's rotation decomposed into the fitting skeleton's DOFs "
                  "(mocaplib.synth.truth); what those DOFs cannot hold is in 'extras'")
#: Decimals kept in the truth file: 1 µm for lengths, 1 µrad for angles.
TRUTH_DECIMALS = 6
#: Steady cycles every moving capture must hold.
MIN_CYCLES = 2
_SIDE_NAME = {"l": "Left", "r": "Right"}


@dataclass(frozen=True)
class Subject:
    """Anthropometry: standing height (m; the generator's body scaled to it), mass (kg)."""

    height: float = 1.75
    mass: float = 70.0

    def __post_init__(self):
        if not (0.5 < self.height < 2.6 and 10.0 < self.mass < 400.0):
            raise SynthError(f"subject height {self.height} m / mass {self.mass} kg out of range",
                             hint="height in (0.5, 2.6) m, mass in (10, 400) kg")


@dataclass
class SynthCapture:
    """A generated capture: the trial (markers, labels, rate, events), the truth dictionary
    written to the sidecar, and the generator's motion and body for inspection."""

    trial: Trial
    truth: dict
    motion: BodyMotion
    body: Body
    params: GaitParameters
    command: Command


def min_duration(command: Command, subject: Subject = Subject()) -> float:
    """Shortest duration (s) holding :data:`MIN_CYCLES` steady cycles after the lead-in."""
    params = gait_parameters(command, subject.height)
    return 0.0 if command.gait == "stand" else LEAD_S + MIN_CYCLES * params.stride


def check_timing(command: Command, /, *, duration: float, rate: float,
                 subject: Subject = Subject()) -> None:
    """Raise :class:`SynthError` unless ``rate`` (Hz) is > 0 and ``duration`` (s) holds
    :data:`MIN_CYCLES` steady cycles of ``command`` (and at least one frame interval)."""
    if not (np.isfinite(rate) and rate > 0):
        raise SynthError(f"frame rate must be > 0 Hz, got {rate}")
    need = min_duration(command, subject)
    if not np.isfinite(duration):
        raise SynthError(f"duration must be a finite number of seconds, got {duration}")
    if duration < max(need, 1.0 / rate):
        raise SynthError(f"duration {duration} s is too short",
                         hint=f"this command needs at least {need:.2f} s for {MIN_CYCLES} cycles")


def synthesize_capture(command: Command, /, *, duration: float, seed: int,
                       subject: Subject = Subject(), rate: float = 100.0,
                       protocol: str = "fullbody38", markers: MarkerSettings = MarkerSettings(),
                       name: str = "synthetic", session_seed: int | None = None) -> SynthCapture:
    """Generate one capture of ``duration`` seconds at ``rate`` Hz in marker set ``protocol``.

    ``session_seed`` seeds the marker placement shared by every capture of one session (see
    :mod:`~mocaplib.synth.markers`); None draws a new placement from ``seed``. The protocol's
    ``static_only`` markers are left out unless the subject stands (``command.gait``)."""
    check_timing(command, duration=duration, rate=rate, subject=subject)
    body = synthetic_body(subject.height)
    params = gait_parameters(command, subject.height)
    prot = load_protocol(protocol)
    t = np.arange(int(np.floor(duration * rate + 1e-9)) + 1) / rate
    t_mid = float(t[-1]) / 2
    motion = body_motion(command, params, body, t, t_mid=t_mid)
    rng = np.random.default_rng(seed)
    session = None if session_seed is None else np.random.default_rng(seed=session_seed)
    xyz, labels, record = skin_markers(motion, body, prot, markers, rng, rate=rate,
                                       mass=subject.mass, placement_rng=session)
    if command.gait != "stand":          # markers put on for the static trial are taken off
        keep = [i for i, m in enumerate(prot.markers) if not m.static_only]
        xyz, labels = xyz[:, keep], [labels[i] for i in keep]
    events = _events(motion, t[-1])
    trial = Trial(xyz, labels, rate, events=[Event(_SIDE_NAME[s], lab, tm)
                                             for s, lab, tm in events], source=name)
    cycles = [_cycle_truth(command, params, body, start, t_mid)
              for start in _cycle_starts(params, t[-1])]
    extras = extra_angles(body, motion.pose)
    truth = {
        "format": TRUTH_FORMAT,
        "name": name,
        "command": {**command.as_dict(), "speed": command.speed,
                    "direction": command.direction,
                    "radius": None if not np.isfinite(command.radius) else command.radius},
        "subject": asdict(subject),
        "seed": seed,
        "session_seed": session_seed,
        "rate_hz": rate,
        "frames": len(t),
        "first_frame": 1,
        "protocol": prot.name,
        "labels": labels,
        "generator": {"gait": asdict(params),
                      "cadence_steps_per_min": params.cadence if command.gait != "stand" else 0.0,
                      "lead_s": LEAD_S, "markers": markers.as_dict(), **record},
        "events": [{"side": {"l": "left", "r": "right"}[s],
                    "kind": "heel_strike" if lab == "Foot Strike" else "toe_off",
                    "context": _SIDE_NAME[s], "label": lab, "time_s": tm,
                    "frame": int(round(tm * rate))}
                   for s, lab, tm in events],
        "cycles": cycles,
        "angles": {"dof_names": list(DOF_NAMES),
                   "units": "rad; pelvis_tx/ty/tz in m",
                   "mapping": ANGLES_MAPPING,
                   "values": true_angles(body, motion.pose)},
        "extras": {"names": list(extras), "units": "rad",
                   "values": np.column_stack(list(extras.values()))},
        "shoulders": {"units": "m", "order": "left, right glenohumeral centre",
                      "values": motion.shoulders},
    }
    return SynthCapture(trial, truth, motion, body, params, command)


def _events(motion: BodyMotion, t_end: float) -> list[tuple[str, str, float]]:
    """(side, label, time) of every heel strike and toe-off inside [0, t_end]."""
    out = []
    for side, fp in motion.footprints.items():
        for label, times in (("Foot Strike", fp.heel_strike), ("Foot Off", fp.toe_off)):
            out += [(side, label, float(x)) for x in times if 0.0 <= x <= t_end]
    return sorted(out, key=lambda e: (e[2], e[0], e[1]))


def _cycle_starts(params: GaitParameters, t_end: float) -> list[float]:
    if params.gait == "stand":
        return []
    starts = LEAD_S + params.stride * np.arange(int((t_end - LEAD_S) / params.stride) + 1)
    return [float(s) for s in starts if s + params.stride <= t_end + 1e-9]


def true_cycle_velocities(t: np.ndarray, shoulders: np.ndarray, reference: tuple,
                          command: Command) -> dict:
    """The paper's per-cycle v̂, ω̂, v̂_l, v̂_f and pattern from the glenohumeral centres
    (F, 2, ≥2) (left, right; metres) and the commanded frame ``reference`` ((F, 2) m, (F,)
    rad) sampled at ``t`` (F,) s, evenly over one cycle, endpoints included (see the module
    docstring)."""
    period = t[-1] - t[0]
    left, right = shoulders[:, 0, :2], shoulders[:, 1, :2]
    mid = 0.5 * (left + right)
    lr = right - left
    theta_s = np.unwrap(np.arctan2(lr[:, 1], lr[:, 0]) + np.pi / 2)
    omega = (theta_s[-1] - theta_s[0]) / period
    xy, theta = reference
    dbar = world_to_frame(xy, theta, mid)[:-1].mean(axis=0)
    w = command.omega
    u = np.array([command.v_f - w * dbar[1], command.v_l + w * dbar[0]])
    v = float(np.hypot(*u))
    c, s = np.cos(theta[0]), np.sin(theta[0])
    start = xy[0] + np.array([c * dbar[0] - s * dbar[1], s * dbar[0] + c * dbar[1]])
    if v < 1e-9:
        v_l = v_f = 0.0
        pattern = {"type": "point", "point": start.tolist()}
    else:
        rel = theta[:-1] + np.arctan2(u[1], u[0]) - theta_s[:-1]
        v_l, v_f = float(v * np.mean(np.sin(rel))), float(v * np.mean(np.cos(rel)))
        tangent = theta[0] + np.arctan2(u[1], u[0])
        if w == 0:
            pattern = {"type": "line", "point": start.tolist(), "direction": float(tangent)}
        else:
            centre = start + (v / w) * np.array([-np.sin(tangent), np.cos(tangent)])
            pattern = {"type": "arc", "centre": centre.tolist(), "radius": v / abs(w),
                       "arc_angle": abs(w) * period}
    return {"v": v, "omega": float(omega), "v_l": v_l, "v_f": v_f, "pattern": pattern}


def _cycle_truth(command, params, body, start, t_mid) -> dict:
    grid = start + params.stride * np.arange(401) / 400
    shoulders, reference = shoulder_path(command, params, body, grid, t_mid=t_mid)
    return {"start_s": start, "end_s": start + params.stride, "T": params.stride,
            **true_cycle_velocities(grid, shoulders, reference, command)}


def write_capture(capture: SynthCapture, directory: str | os.PathLike, name: str, *,
                  integer: bool = True, extra: dict | None = None) -> tuple[Path, Path]:
    """Write ``<name>.c3d`` and ``<name>.truth.json`` in ``directory``; returns both paths.

    ``integer`` stores coordinates as 16-bit integers with a power-of-two scale (at most
    0.125 mm per step for a capture within ±4 m; half the size of float storage).
    ``extra`` entries (plan name, class...) are added to the truth.
    """
    directory = Path(directory)
    trial = capture.trial
    c3d_path = write_c3d(directory / f"{name}.c3d", trial.markers, trial.labels, trial.rate,
                         events=trial.events, units="mm", integer=integer)
    truth = {**capture.truth, "name": name, **(extra or {}),
             "storage": "int16" if integer else "float32"}
    text = json.dumps(json_values(truth, decimals=TRUTH_DECIMALS), indent=None,
                      separators=(",", ":"), allow_nan=False)
    json_path = atomic_write_text(directory / f"{name}.truth.json", text + "\n")
    return c3d_path, json_path
