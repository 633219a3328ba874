"""The gaits a control space keeps apart, and an entry's gait from its locomotion class
(:func:`mocaplib.gait.locomotion.locomotion_class`). Imports nothing: the command line names
the gaits in its options."""

from __future__ import annotations

#: The gaits a control space keeps apart (a blend never mixes them).
BLEND_GAITS = ("walk", "run")


def class_gait(locomotion_class: str | None, /) -> str:
    """The gait (:data:`BLEND_GAITS`) of an entry of class ``locomotion_class``: ``"run"`` for
    ``running``, else ``"walk"`` (rest, turns on the spot and steps in place included, and an
    entry whose class was not measured)."""
    return "run" if locomotion_class == "running" else "walk"
