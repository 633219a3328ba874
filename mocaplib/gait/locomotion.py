"""The locomotion class of a cycle, from what the body does, never from a file's name.

The classes are those of the motion library of Truong et al. (BioRob 2010):

============  =========================================================================
class         the cycle
============  =========================================================================
rest          a standing capture's rest entry
running       its stride's events in running order: each toe-off is followed by the
              other foot's strike (a flight phase; :data:`mocaplib.gait.cycles.GAIT_ORDERS`)
nonholonomic  moves where the body faces (``|atan2(v̂_l, v̂_f)|`` within
              :data:`FACING_TOLERANCE`): straight walks and curves; or turns on the spot
              (v̂ below :data:`SPOT_SPEED` while ``|ω̂|`` reaches :data:`TURN_RATE`)
holonomic     moves at an angle to where the body faces (side-steps, diagonals, backwards)
              while its heading holds (``|ω̂|`` below :data:`TURN_RATE`); or steps in
              place (v̂ below :data:`SPOT_SPEED`, no turn)
mixed         moves at an angle to where the body faces while turning
============  =========================================================================

Velocities are the cycle's v̂ (m/s), ω̂ (rad/s, > 0 turning left), v̂_l and v̂_f (m/s).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from .cycles import GAIT_ORDERS, Cycle, event_name
from .foot_events import GaitEvent

#: Largest angle (rad) between the path and the facing direction of a nonholonomic cycle: half
#: the smallest holonomic direction of the paper's plan (60°).
FACING_TOLERANCE = math.radians(30.0)
#: Turn rate (rad/s) from which a cycle turns: half the slowest turn of the paper's plan
#: (a 3 m arc at 0.5 m/s, 0.17 rad/s).
TURN_RATE = 0.08
#: Speed (m/s) below which a cycle does not travel (turns on the spot or steps in place): half
#: the slowest travelling gait of the paper's plan (side-steps at 0.3 m/s).
SPOT_SPEED = 0.15
#: The classes :func:`locomotion_class` gives.
LOCOMOTION_CLASSES = ("rest", "running", "nonholonomic", "holonomic", "mixed")


def stride_gait(cycle: Cycle, events: Sequence[GaitEvent], /) -> str | None:
    """``"walking"`` or ``"running"``: the gait whose event order (:data:`GAIT_ORDERS`) the
    events strictly inside ``cycle`` follow from its start event; None for a rest entry or
    when the events inside match neither (an event missed)."""
    if cycle.rest:
        return None
    inside = [event_name(e) for e in sorted(events, key=lambda e: e.time_s)
              if cycle.start_s < e.time_s < cycle.end_s]
    for gait, order in GAIT_ORDERS.items():
        at = order.index(cycle.start_event)
        if inside == list(order[at + 1:] + order[:at]):
            return gait
    return None


def locomotion_class(cycle: Cycle, events: Sequence[GaitEvent], /) -> str:
    """The cycle's class (:data:`LOCOMOTION_CLASSES`, module docstring) from its velocities and
    the order of the gait ``events`` (a capture's, as :func:`mocaplib.gait.events.capture_events`
    gives them) inside it."""
    if cycle.rest:
        return "rest"
    if stride_gait(cycle, events) == "running":
        return "running"
    vel = cycle.velocities
    turning = abs(vel.omega) >= TURN_RATE
    if vel.v < SPOT_SPEED:
        return "nonholonomic" if turning else "holonomic"
    if abs(math.atan2(vel.v_l, vel.v_f)) <= FACING_TOLERANCE:
        return "nonholonomic"
    return "mixed" if turning else "holonomic"
