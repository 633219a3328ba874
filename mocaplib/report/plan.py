"""The report's target envelope and planned-capture bookkeeping, from a capture plan.

Envelope definition (documented, overridable)
---------------------------------------------
The target region of the control space is the **convex hull of the commanded velocities of the
captures in a capture plan**: each planned capture's command ``(v_f, v_l, ω)`` becomes the
point ``(v̂ = hypot(v_f, v_l), ω̂, v̂_l)``. The plan is the one given (``--envelope``), else the
plan shipped with mocaplib (:func:`mocaplib.markersets.protocols.capture_plans`, the plan of its synthetic
sample captures: a default, not the lab's plan, and the report says so). A plan (or any TOML
file) may instead carry an explicit ``[envelope]`` table, which wins (see
:meth:`mocaplib.library.coverage.Envelope.from_toml`). Without any plan the report uses
:data:`FALLBACK_ENVELOPE`, a small hand-written set of the same locomotion types, and says so.

Planned captures are matched to the library by file stem: capture ``name`` in the plan,
``<name>.c3d`` in the library (``source_file``) or in the diagnostics sidecar (``source``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import MocapError
from ..io.tomlfile import read_toml
from ..library.command import plan_command
from ..library.coverage import Envelope
from ..markersets.protocols import capture_plans

#: (v, ω, v_l) corners used when no capture plan exists: rest, on-the-spot turns at 60°/s,
#: fast straight walking, 1 m curves at 1.2 m/s, 2 m curves at 1.8 m/s, side-steps at
#: 0.5 m/s and 60° diagonals at 1.0 m/s, both sides.
FALLBACK_ENVELOPE = np.array([
    [0.0, 0.0, 0.0], [0.0, 1.05, 0.0], [0.0, -1.05, 0.0], [1.8, 0.0, 0.0],
    [1.2, 1.2, 0.0], [1.2, -1.2, 0.0], [1.8, 0.9, 0.0], [1.8, -0.9, 0.0],
    [0.5, 0.0, 0.5], [0.5, 0.0, -0.5], [1.0, 0.0, 0.866], [1.0, 0.0, -0.866],
])


def find_plan() -> Path | None:
    """The first capture plan shipped with mocaplib (:func:`mocaplib.markersets.protocols.capture_plans`,
    the same plans the build takes locomotion classes from), or None."""

    plans = capture_plans()
    return plans[0] if plans else None


def plan_commands(path: str | Path) -> pd.DataFrame:
    """Planned captures of a capture plan file (its ``[[capture]]`` tables, as
    ``mocaplib synth`` reads them): columns ``name, class, v_f, v_l, omega`` (SI). Raises
    :class:`~mocaplib.errors.MocapError` naming the file and capture for a table that is not
    a named capture with a command (:func:`mocaplib.library.command.plan_command`)."""
    data = read_toml(path, what="capture plan",
                     hint="a plan is a TOML file like protocols/paper_plan.toml")
    captures = data.get("capture")
    if not isinstance(captures, list) or not captures:
        raise MocapError("no [[capture]] entries", path=path,
                         hint="each capture needs name, class, command, duration, seed")
    rows = []
    for i, capture in enumerate(captures):
        if not isinstance(capture, dict) or not isinstance(capture.get("name"), str):
            raise MocapError(f"capture #{i + 1} must be a table with a name", path=path)
        try:
            command = plan_command(capture.get("command"))
        except MocapError as exc:
            raise MocapError(f"capture {capture['name']!r}: {exc.message}", path=path,
                             hint=exc.hint) from None
        rows.append((capture["name"], str(capture.get("class")), command.v_f, command.v_l,
                     command.omega))
    return pd.DataFrame(rows, columns=["name", "class", "v_f", "v_l", "omega"])


def default_envelope(plan: Path | None) -> tuple[Envelope, dict]:
    """The envelope from ``plan`` (or the plan :func:`find_plan` finds, or the fallback).

    ``plan`` given may also be a TOML file with just an ``[envelope]`` table (see
    :meth:`Envelope.from_toml`), which is then the envelope. Returns the envelope and a note
    ``{"text": how it was made, "plan": planned captures DataFrame or None, "plan_name": its
    file name or None, "default": True when the target is mocaplib's default (no ``plan``
    given), not one the user chose}`` for the report.
    """
    found = plan is None
    plan = plan if plan is not None else find_plan()
    why = "no capture plan shipped"
    commands = None
    if plan is not None:
        try:
            document = read_toml(plan, what="capture plan" if found else "envelope file",
                                 hint="give a TOML file with an [envelope] table, or a "
                                      "capture plan")
            if "envelope" in document and not found:
                return Envelope.from_toml(plan), {"text": f"from {Path(plan).name}",
                                                  "plan": None, "plan_name": None,
                                                  "default": False}
            commands = plan_commands(plan)
        except MocapError as exc:
            if not found:
                raise
            why = f"the shipped capture plan could not be read: {exc}"
    if commands is None:
        return (Envelope(FALLBACK_ENVELOPE, source="built-in"),
                {"text": f"mocaplib's built-in default ({why}): hull of rest, spot turns, "
                         "straight, curved, side and diagonal walking", "plan": None,
                 "plan_name": None, "default": True})
    if "envelope" in document:
        env, how = Envelope.from_toml(plan), f"[envelope] table of {Path(plan).name}"
    else:
        env = Envelope.from_commands(commands, source=str(plan))
        how = (f"convex hull of the {len(commands)} commanded velocities of the capture plan "
               f"{Path(plan).name}")
    if found:
        how = (f"mocaplib's default, the {how} shipped with mocaplib (the plan of its "
               "synthetic sample captures, not your session's)")
    return env, {"text": how, "plan": commands, "plan_name": Path(plan).name, "default": found}


def planned_status(plan: pd.DataFrame | None, plan_name: str | None, entries: list,
                   diagnostics: dict | None) -> dict | None:
    """Planned captures missing from the library or failed in the build; None without a plan.

    ``matched`` counts the planned captures found by file stem in the library or among the
    failed captures: 0 means the library's captures are not named after this plan, and the
    missing ones are not listed (they would be the whole plan, not the lab's omissions).
    ``entries``: the library's :class:`~mocaplib.library.entry.LibraryEntry` objects."""
    if plan is None:
        return None
    in_library = {Path(e.source_file).stem for e in entries}
    failed = {}
    for record in (diagnostics or {}).get("captures") or []:
        if not record.get("ok", True):
            failed[Path(str(record.get("source", ""))).stem] = (
                f"{record.get('stage') or '?'}: {record.get('error') or 'failed'}")
    rows_failed = [{"name": n, "reason": failed[n]} for n in plan["name"] if n in failed]
    n_in_library = int(plan["name"].isin(in_library).sum())
    matched = n_in_library + len(rows_failed)
    missing = [n for n in plan["name"] if n not in in_library and n not in failed]
    return {"n_planned": len(plan), "plan_name": plan_name, "n_in_library": n_in_library,
            "matched": matched, "missing": missing if matched else [], "failed": rows_failed}
