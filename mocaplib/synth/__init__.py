"""Synthetic captures with exact ground truth: a procedural walker that writes C3D files.

Stages, one module each: :mod:`.command` (the locomotion command and its reference path),
:mod:`.gait` (timing, footprints, feet), :mod:`.bones` (the generator's own body, apart from
the fitting skeleton), :mod:`.body` (pelvis, trunk, arms, leg inverse kinematics),
:mod:`.markers` (skin markers and artefacts), :mod:`.truth` (the body's motion in the fit's
conventions), :mod:`.capture` (one capture, its truth, writing), :mod:`.plan` (capture plans).
"""

from ..library.command import Command
from .capture import Subject, SynthCapture, min_duration, synthesize_capture, write_capture
from .markers import MarkerSettings
from .plan import Plan, PlannedCapture, check_targets, generate_plan, load_plan, locomotion_type

__all__ = ["Command", "MarkerSettings", "Plan", "PlannedCapture", "Subject", "SynthCapture",
           "check_targets", "generate_plan", "load_plan", "locomotion_type", "min_duration",
           "synthesize_capture", "write_capture"]
