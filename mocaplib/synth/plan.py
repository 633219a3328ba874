"""Capture plans: a TOML list of synthetic captures, and generating one into a folder.

A plan file (``protocols/paper_plan.toml``) has no ``[markers]`` table, so the protocol lister
ignores it. Layout::

    name = "paper"
    [defaults]                      # optional; any capture may override these
    protocol = "fullbody38"
    rate = 100.0
    height = 1.75
    mass = 70.0
    markers = { noise_sd = 0.0007 } # MarkerSettings fields
    session_seed = 2010             # marker placement shared by the captures (one session);
                                    # leave it out for a new placement per capture

    [[capture]]
    name = "walk_straight_normal"
    class = "nonholonomic"
    command = { kind = "straight", speed = 1.2 }   # or { v_f = 1.2, v_l = 0, omega = 0 }
    duration = 2.6
    seed = 3
"""

from __future__ import annotations

import difflib
import json
import math
import os
import re
from dataclasses import dataclass, fields, replace
from pathlib import Path

from ..errors import MocapError, SynthError
from ..io.c3d import read_c3d
from ..io.tomlfile import read_toml
from ..library.command import Command, plan_command
from ..markersets.protocols import load_protocol
from .capture import (TRUTH_FORMATS, Subject, SynthCapture, check_timing, min_duration,
                      synthesize_capture, write_capture)
from .markers import MarkerSettings

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


#: Speed and size parts of a capture name in the sample plan (``_fast``, ``_r2``, ``_3p5``,
#: ``_150``).
_NAME_DETAILS = r"_(slow|normal|fast|r\d|\d+p\d|\d+)(?=_|$)"


def locomotion_type(name: str, /, *, sided: bool = True) -> str:
    """Locomotion type of a capture named as in ``protocols/paper_plan.toml``: the name without
    speed and size (``walk_curve_r2_left_fast`` -> ``walk_curve_left``), and also without the
    sides when ``sided`` is false (-> ``walk_curve``; ``diag_right_150_fast`` -> ``diag``)."""
    kind = re.sub(_NAME_DETAILS, "", name)
    return kind if sided else re.sub(r"_(left|right)(?=_|$)", "", kind)


@dataclass(frozen=True)
class PlannedCapture:
    """One entry of a plan: what to generate and how."""

    name: str
    cls: str
    command: Command
    duration: float
    seed: int
    subject: Subject
    rate: float
    protocol: str
    markers: MarkerSettings
    session_seed: int | None = None

    def for_height(self, height: float) -> "PlannedCapture":
        """This capture of a subject ``height`` m tall (mass scaled with height², as body mass
        index stays), everything else the same (seeds, marker placement), lengthened to the
        cycles the command needs when the taller subject's slower cadence asks for it."""
        subject = Subject(height=height,
                          mass=self.subject.mass * (height / self.subject.height) ** 2)
        return replace(self, subject=subject,
                       duration=max(self.duration, min_duration(self.command, subject)))

    def generate(self) -> SynthCapture:
        """The capture this entry describes (change a setting first with
        ``dataclasses.replace(entry, ...)``)."""
        return synthesize_capture(self.command, duration=self.duration, seed=self.seed,
                                  subject=self.subject, rate=self.rate, protocol=self.protocol,
                                  markers=self.markers, name=self.name,
                                  session_seed=self.session_seed)


@dataclass(frozen=True)
class Plan:
    name: str
    description: str
    captures: tuple[PlannedCapture, ...]
    path: str

    def select(self, only: list[str] | None = None) -> list[PlannedCapture]:
        """The captures named in ``only`` (all when None or empty), in the plan's order.
        Raises :class:`SynthError` for a name not in the plan, with the closest names."""
        names = [c.name for c in self.captures]
        unknown = sorted(set(only or ()) - set(names))
        if unknown:
            close = sorted({m for u in unknown for m in difflib.get_close_matches(u, names, 3)})
            more = f", ... ({len(names)} in all)" if len(names) > 5 else ""
            raise SynthError(f"not in the plan: {', '.join(unknown)}", path=self.path,
                             hint=f"did you mean {', '.join(close)}?" if close else
                             f"its captures are {', '.join(names[:5])}{more}: the names of "
                             "its [[capture]] tables")
        return [c for c in self.captures if not only or c.name in only]


def _markers(spec) -> MarkerSettings:
    names = {f.name for f in fields(MarkerSettings)}
    unknown = set(spec) - names
    if unknown:
        raise SynthError(f"unknown marker settings {sorted(unknown)}",
                         hint=f"settings are {', '.join(sorted(names))}")
    return MarkerSettings(**spec)


def load_plan(path: str | os.PathLike) -> Plan:
    """Read and check a plan file; raises :class:`SynthError` naming the file and capture.

    Whether each capture can be generated (duration, rate, protocol) is checked by
    :func:`check_captures`: a plan read for its commands alone (the report's envelope) need not
    be generated."""
    path = os.fspath(path)
    data = read_toml(path, error=SynthError, what="capture plan",
                     hint="a plan is a TOML file like protocols/paper_plan.toml")
    defaults = data.get("defaults", {})
    entries = data.get("capture")
    if not isinstance(entries, list) or not entries:
        raise SynthError("no [[capture]] entries", path=path,
                         hint="each capture needs name, class, command, duration, seed")
    if not isinstance(defaults, dict) or not isinstance(defaults.get("markers", {}), dict):
        raise SynthError("[defaults] and its markers must be tables", path=path)
    captures, seen = [], set()
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict) or not isinstance(entry.get("markers", {}), dict):
            raise SynthError(f"capture #{i + 1} (and its markers) must be a table", path=path,
                             hint="write each capture as a [[capture]] table")
        name = entry.get("name")
        where = f"capture {name!r}" if name else f"capture #{i + 1}"
        if not isinstance(name, str) or not _NAME.match(name):
            raise SynthError(f"{where}: name must be letters, digits, _ . - (a file name)",
                             path=path)
        if name in seen:
            raise SynthError(f"{where}: name used twice", path=path)
        seen.add(name)
        missing = {"class", "command", "duration", "seed"} - set(entry)
        if missing:
            raise SynthError(f"{where}: missing {', '.join(sorted(missing))}", path=path)

        def get(key, default):
            return entry.get(key, defaults.get(key, default))

        try:
            subject = Subject(float(get("height", 1.75)), float(get("mass", 70.0)))
            placement_seed = get("session_seed", None)
            captures.append(PlannedCapture(
                name, str(entry["class"]), plan_command(entry["command"]),
                float(entry["duration"]), int(entry["seed"]), subject, float(get("rate", 100.0)),
                str(get("protocol", "fullbody38")),
                _markers({**defaults.get("markers", {}), **entry.get("markers", {})}),
                None if placement_seed is None else int(placement_seed)))
        except SynthError as exc:
            raise SynthError(f"{where}: {exc.message}", path=path, hint=exc.hint) from None
        except (TypeError, ValueError) as exc:
            raise SynthError(f"{where}: bad value ({exc})", path=path) from None
    return Plan(str(data.get("name", Path(path).stem)), str(data.get("description", "")),
                tuple(captures), path)


def check_captures(plan: Plan, captures: list[PlannedCapture], /, *,
                   protocol: str | None = None) -> None:
    """Raise :class:`SynthError` naming the plan and capture when one of ``captures`` cannot be
    generated: a duration too short for its cycles, a bad rate, an unknown protocol (its own,
    or ``protocol`` when given)."""
    for entry in captures:
        try:
            check_timing(entry.command, duration=entry.duration, rate=entry.rate,
                         subject=entry.subject)
            load_protocol(protocol or entry.protocol)
        except MocapError as exc:
            raise SynthError(f"capture {entry.name!r}: {exc.message}", path=plan.path,
                             hint=exc.hint) from None


def check_targets(captures: list[PlannedCapture], directory: str | os.PathLike, /, *,
                  overwrite: bool = False) -> None:
    """Raise :class:`SynthError` before anything is written when a capture's ``<name>.c3d`` or
    ``<name>.truth.json`` in ``directory`` is a folder, or (unless ``overwrite``) a file that is
    not an earlier synth output of that name.

    An earlier output is a truth file of this name (a format of :data:`TRUTH_FORMATS`) beside a C3D
    (if any) with the frames, rate and labels it records: a folder of samples can be generated
    again in place, but a lab capture copied there under a plan's name is not replaced.
    """
    directory = Path(directory)
    folders, foreign = [], []
    for entry in captures:
        c3d, truth = (directory / f"{entry.name}{end}" for end in (".c3d", ".truth.json"))
        folders += [p for p in (c3d, truth) if p.is_dir()]
        if (c3d.exists() or truth.exists()) and not (overwrite or _earlier_output(c3d, truth)):
            foreign += [p for p in (c3d, truth) if p.exists() and not p.is_dir()]
    if folders:
        raise SynthError(f"{_listed(folders)}: a folder where a capture file goes",
                         hint="move it away or choose another output folder")
    if foreign:
        raise SynthError(f"would overwrite {_listed(foreign)}: not written by mocaplib synth "
                         "under that name", hint="choose another output folder, move the "
                                                 "files away, or pass --overwrite")


def _listed(paths: list[Path], most: int = 3) -> str:
    more = f" and {len(paths) - most} more" if len(paths) > most else ""
    return ", ".join(map(str, paths[:most])) + more


def _earlier_output(c3d: Path, truth_path: Path) -> bool:
    """Whether ``c3d`` (may be absent) and ``truth_path`` are a synth output of their name."""

    name = truth_path.name[:-len(".truth.json")]
    try:
        truth = json.loads(truth_path.read_text("utf-8")) if truth_path.is_file() else None
    except (OSError, ValueError):
        return False
    if not (isinstance(truth, dict) and truth.get("format") in TRUTH_FORMATS
            and truth.get("name") == name):
        return False
    if not c3d.exists():
        return True
    try:
        trial = read_c3d(c3d)
    except MocapError:
        return False
    return (trial.labels == truth.get("labels") and trial.n_frames == truth.get("frames")
            and isinstance(truth.get("rate_hz"), (int, float))
            and math.isclose(trial.rate, truth["rate_hz"], rel_tol=1e-6))


def generate_plan(plan: Plan, directory: str | os.PathLike, /, *,
                  only: list[str] | None = None, protocol: str | None = None,
                  progress: bool = False, overwrite: bool = False) -> list[Path]:
    """Generate the plan's captures (or the ``only`` ones) into ``directory``.

    ``protocol`` overrides every capture's marker set. Returns the paths written (C3D and truth
    of each capture). Before anything is written, raises :class:`SynthError` for a name not in
    the plan, a capture that cannot be generated (:func:`check_captures`) or files that must
    not be replaced (:func:`check_targets`; ``overwrite`` replaces them).
    """
    chosen = plan.select(only)
    check_captures(plan, chosen, protocol=protocol)
    check_targets(chosen, directory, overwrite=overwrite)
    if progress:
        from tqdm import tqdm
        chosen = tqdm(chosen, desc="synth", unit="capture")
    written: list[Path] = []
    for entry in chosen:
        try:
            capture = replace(entry, protocol=protocol or entry.protocol).generate()
            written += write_capture(capture, directory, entry.name,
                                     extra={"plan": plan.name, "class": entry.cls})
        except MocapError as exc:
            raise SynthError(f"capture {entry.name!r}: {exc}", path=plan.path) from None
    return written
