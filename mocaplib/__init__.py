"""mocaplib: optical motion capture of walking people (C3D) to a validated motion library.

Public names are imported lazily, so ``import mocaplib`` stays fast and a stage's heavy
dependencies (pyvista, matplotlib) load only when that stage is used.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

_EXPORTS = {
    "MocapError": "mocaplib.errors",
    "C3DError": "mocaplib.errors",
    "Trial": "mocaplib.trial",
    "Event": "mocaplib.trial",
    "Skeleton": "mocaplib.skeleton",
    "Motion": "mocaplib.model.motion",
    "calibrate": "mocaplib.model.calibration",
    "SubjectModel": "mocaplib.model.calibration",
    "fit": "mocaplib.model.ik",
    "filter_trial": "mocaplib.model.filtering",
    "detect_events": "mocaplib.gait.events",
    "GaitEvent": "mocaplib.gait.foot_events",
    "analyse_cycles": "mocaplib.gait.cycles",
    "Cycle": "mocaplib.gait.cycles",
    "read_c3d": "mocaplib.io.c3d",
    "load_library": "mocaplib.library.format",
    "validate_library": "mocaplib.library.format",
    "ControlSpace": "mocaplib.library.controlspace",
    "write_report": "mocaplib.report",
}


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'mocaplib' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + list(_EXPORTS))
