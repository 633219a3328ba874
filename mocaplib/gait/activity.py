"""What the person does in each cycle of a take, from the motion, never from a file's name.

A long take mixes activities: standing, stepping in place, turning on the spot, walking
forwards, backwards or sideways, running, going up or down stairs or a slope. Each cycle gets
one :data:`ACTIVITIES` name (:func:`cycle_activity`); consecutive cycles of one activity form
an *activity segment* (:func:`mocaplib.gait.cycles.activity_segments`), and a capture
contributes one cycle per segment (:func:`mocaplib.gait.cycles.qc_and_choice`), so a mixed
take gives its forward walk, its backward walk and its turn as separate entries.

=======================  =================================================================
activity                 the cycle
=======================  =================================================================
standing                 a standing capture's rest entry
running                  its stride's events in running order (a flight phase)
descending, ascending    its pelvis drops (rises) more than :data:`NON_LEVEL_RISE` per step:
                         stairs or a slope (:attr:`~mocaplib.gait.cycles.Cycle.rise_per_step`)
stepping in place        v̂ below :data:`~mocaplib.gait.locomotion.SPOT_SPEED`, no turn
turning on the spot      v̂ below that while ``|ω̂|`` reaches
                         :data:`~mocaplib.gait.locomotion.TURN_RATE`
forwards                 travels within :data:`~mocaplib.gait.locomotion.FACING_TOLERANCE`
                         of where the body faces (straight or curving)
backwards                travels within :data:`BACKWARD_TOLERANCE` of the opposite direction
sideways                 any other direction of travel (side-steps, diagonals)
=======================  =================================================================

Velocities are the cycle's v̂ (m/s), ω̂ (rad/s), v̂_l and v̂_f (m/s); heights in metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from .cycles import Cycle
from .foot_events import GaitEvent
from .locomotion import FACING_TOLERANCE, SPOT_SPEED, TURN_RATE, stride_gait

#: The activities :func:`cycle_activity` gives (module docstring).
ACTIVITIES = ("standing", "running", "descending", "ascending", "stepping in place",
              "turning on the spot", "forwards", "backwards", "sideways")
#: The activities that are not level locomotion: stairs or slopes.
NON_LEVEL = ("descending", "ascending")
#: Largest angle (rad) between the path and the direction opposite to where the body faces of
#: a backward walk: half the gap between the paper's steepest backward diagonal (150°) and
#: 180°, so that a 150° diagonal is always sideways (its cycles measure 149-151°).
BACKWARD_TOLERANCE = math.radians(15.0)
#: Height (m) the pelvis may rise or drop per step on level ground. The real level walks of
#: ../shared/data/c3d measure at most 0.011 m per step (07_12.c3d, every cycle), the 68
#: samples 0.0004 m; a stair's
#: riser is 0.15-0.18 m and a 1:12 ramp (the steepest wheelchair ramp) climbs 0.05 m per
#: 0.6 m step, so 0.03 m tells either from level ground.
NON_LEVEL_RISE = 0.03


def non_level(cycle: Cycle, /) -> str | None:
    """What makes a cycle of :data:`NON_LEVEL` activity not level locomotion, in words; None
    for a level one."""
    if cycle.activity not in NON_LEVEL:
        return None
    rise = cycle.rise_per_step
    return (f"not level: the pelvis {'rises' if rise > 0 else 'drops'} {abs(rise):.3f} m per "
            f"step (stairs or a slope; level walking stays within {NON_LEVEL_RISE:g} m)")


def cycle_activity(cycle: Cycle, events: Sequence[GaitEvent], /) -> str:
    """The cycle's activity (:data:`ACTIVITIES`, module docstring) from its velocities, its
    pelvis rise per step and the order of the capture's gait ``events`` inside it."""
    if cycle.rest:
        return "standing"
    if stride_gait(cycle, events) == "running":
        return "running"
    rise = cycle.rise_per_step
    if rise is not None and abs(rise) > NON_LEVEL_RISE:
        return "ascending" if rise > 0 else "descending"
    vel = cycle.velocities
    if vel.v < SPOT_SPEED:
        return "turning on the spot" if abs(vel.omega) >= TURN_RATE else "stepping in place"
    direction = abs(math.atan2(vel.v_l, vel.v_f))
    if direction <= FACING_TOLERANCE:
        return "forwards"
    return "backwards" if direction >= math.pi - BACKWARD_TOLERANCE else "sideways"


def set_activities(cycles: Sequence[Cycle], events: Sequence[GaitEvent], /) -> None:
    """Set each cycle's ``activity`` (:func:`cycle_activity`)."""
    for cycle in cycles:
        cycle.activity = cycle_activity(cycle, events)
